//! A refused scene, said two ways. Its `Display` is the short form a network client gets
//! (`load` over zenoh): file, line, field and a message that quotes nothing of a file that
//! failed to parse, since a file named as a scene may not be one and may hold secrets.
//! [`SceneError::report`] is the long form for the reader of their own file: the line
//! with a caret under the text at fault, its column, the parser's whole message with the
//! values in it, and a "did you mean".

use std::ops::Range;
use std::path::{Path, PathBuf};

use annotate_snippets::{AnnotationKind, Group, Level, Renderer, Snippet};

/// A refused scene: where and why.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{}:{line}: {field}: {message}", file.display())]
pub struct SceneError {
    pub file: PathBuf,
    /// 1-based line of the offending field (or of its table when the field is missing).
    pub line: usize,
    /// 1-based column (in characters) of the text at fault; 0 when not known.
    pub column: usize,
    /// The field at fault, with its table: `body[2].radius`, `world.dt`.
    pub field: String,
    /// The message, quoting no value of a file that failed to parse.
    pub message: String,
    /// What only the long form ([`SceneError::report`]) shows.
    pub local: Box<Local>,
}

/// What a refused scene's long form adds to the short one.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Local {
    /// Where in the scene's text the fault is (bytes), for the report's caret.
    pub span: Option<Range<usize>>,
    /// The message with the values it quotes, for the file's own reader; `message` when
    /// none was taken out.
    pub detail: Option<String>,
    /// What the reader may have meant: "did you mean `ground`?".
    pub help: Option<String>,
}

impl SceneError {
    /// An error not located in the text (an unreadable file, a `--set` assignment).
    pub(super) fn unplaced(file: &Path, field: &str, message: String) -> SceneError {
        SceneError {
            file: file.to_path_buf(),
            line: 0,
            column: 0,
            field: field.to_string(),
            message,
            local: Box::default(),
        }
    }

    /// What the reader may have meant ("did you mean `ground`?"), if anything.
    pub fn help(&self) -> Option<&str> {
        self.local.help.as_deref()
    }

    /// The error for the reader of the scene `text` (the text it was parsed from): the
    /// file, line and column, the line with a caret under the fault, the whole message
    /// and a suggestion. Plain text, no colours; the first line is the short form with
    /// the values the short form leaves out (a binary's `Error: ` goes before it).
    pub fn report(&self, text: &str) -> String {
        let message = self.local.detail.as_deref().unwrap_or(&self.message);
        let path = self.file.display().to_string();
        // The short form's `file:line: field:` first, for editors and `grep`.
        let title = match self.line {
            0 => format!("{path}: {}: {message}", self.field),
            line => format!("{path}:{line}: {}: {message}", self.field),
        };
        let span = self
            .local
            .span
            .clone()
            .filter(|s| s.start <= s.end && s.end <= text.len())
            .filter(|s| text.is_char_boundary(s.start) && text.is_char_boundary(s.end));
        let mut groups = Vec::new();
        match span {
            Some(span) => groups.push(
                Level::ERROR.primary_title(&title).element(
                    Snippet::source(text)
                        .path(&path)
                        .fold(true)
                        .annotation(AnnotationKind::Primary.span(span)),
                ),
            ),
            None => groups.push(Group::with_title(Level::ERROR.primary_title(&title))),
        }
        if let Some(help) = &self.local.help {
            groups.push(Group::with_title(Level::HELP.secondary_title(help)));
        }
        let rendered = Renderer::plain().render(&groups);
        let rendered = rendered
            .strip_prefix("error: ")
            .unwrap_or(&rendered)
            .to_string();
        rendered
    }
}

/// The candidate nearest to `found` by edit distance, if near enough to be a typo (at
/// most a third of its length, and at least one edit).
pub(super) fn nearest<'a>(
    found: &str,
    candidates: impl IntoIterator<Item = &'a str>,
) -> Option<&'a str> {
    let allowed = (found.chars().count() / 3).max(1);
    candidates
        .into_iter()
        .filter(|c| *c != found)
        .map(|c| (strsim::damerau_levenshtein(found, c), c))
        .filter(|(d, _)| *d <= allowed)
        .min_by_key(|(d, _)| *d)
        .map(|(_, c)| c)
}

/// "did you mean `x`?" for the nearest of `candidates`.
pub(super) fn did_you_mean<'a>(
    found: &str,
    candidates: impl IntoIterator<Item = &'a str>,
) -> Option<String> {
    nearest(found, candidates).map(|c| format!("did you mean `{c}`?"))
}

/// The scene's text and name, for locating errors.
pub(super) struct Ctx<'a> {
    pub(super) text: &'a str,
    pub(super) file: &'a Path,
}

impl Ctx<'_> {
    pub(super) fn line_of(&self, offset: usize) -> usize {
        let offset = offset.min(self.text.len());
        self.text[..offset].bytes().filter(|&b| b == b'\n').count() + 1
    }

    /// The 1-based column, in characters, of byte `offset`.
    pub(super) fn column_of(&self, offset: usize) -> usize {
        let mut offset = offset.min(self.text.len());
        while !self.text.is_char_boundary(offset) {
            offset -= 1;
        }
        let start = self.text[..offset].rfind('\n').map_or(0, |i| i + 1);
        self.text[start..offset].chars().count() + 1
    }

    /// The value of `field = ...` inside the span of a table (bytes, to the end of its
    /// line), or the table's header when the field is left out.
    fn field_span(&self, span: &Range<usize>, field: &str) -> Range<usize> {
        let (start, end) = (
            span.start.min(self.text.len()),
            span.end.min(self.text.len()),
        );
        let mut offset = start;
        for line in self.text[start..end].split_inclusive('\n') {
            let trimmed = line.trim_start();
            if let Some(rest) = trimmed.strip_prefix(field) {
                if let Some(value) = rest.trim_start().strip_prefix('=') {
                    let value_start = offset + line.len() - value.trim_start().len();
                    let value_end = offset + line.trim_end().len();
                    return value_start..value_end.max(value_start);
                }
            }
            offset += line.len();
        }
        // A field left out: point at the table's header, the line before its body.
        let before = self.text[..start].trim_end();
        if before.ends_with(']') {
            let header = before.rfind('\n').map_or(0, |i| i + 1);
            let header = header + (before.len() - header - before[header..].trim_start().len());
            return header..before.len();
        }
        start..start
    }

    /// An error at `span` (bytes of the text).
    pub(super) fn error_at(&self, span: Range<usize>, field: String, message: &str) -> SceneError {
        SceneError {
            file: self.file.to_path_buf(),
            line: self.line_of(span.start),
            column: self.column_of(span.start),
            field,
            message: message.to_string(),
            local: Box::new(Local {
                span: Some(span),
                ..Local::default()
            }),
        }
    }

    pub(super) fn field_error(
        &self,
        table: &str,
        span: Range<usize>,
        field: &str,
        message: &str,
    ) -> SceneError {
        let at = self.field_span(&span, field);
        self.error_at(at, format!("{table}.{field}"), message)
    }

    /// The table the byte `offset` lies in, as errors name it (`world`, `body[1]`,
    /// `preset.smoke`), from the headers above it; `None` before the first header.
    fn table_at(&self, offset: usize) -> Option<String> {
        let offset = offset.min(self.text.len());
        let mut table = None;
        let mut counts: Vec<(&str, usize)> = Vec::new();
        for line in self.text[..offset].lines() {
            let line = line.trim();
            if let Some(name) = line.strip_prefix("[[").and_then(|l| l.strip_suffix("]]")) {
                let name = name.trim();
                if !is_name(name) {
                    return None;
                }
                let k = match counts.iter_mut().find(|(n, _)| *n == name) {
                    Some((_, k)) => {
                        *k += 1;
                        *k
                    }
                    None => {
                        counts.push((name, 0));
                        0
                    }
                };
                table = Some(format!("{name}[{k}]"));
            } else if let Some(name) = line.strip_prefix('[').and_then(|l| l.strip_suffix(']')) {
                let name = name.trim();
                table = is_name(name).then(|| name.to_string());
            }
        }
        table
    }

    pub(super) fn parse_error(&self, e: &toml::de::Error) -> SceneError {
        // The parser's message, on one line (a syntax error's runs over several).
        let full = e
            .message()
            .trim()
            .lines()
            .map(str::trim)
            .filter(|l| !l.is_empty())
            .collect::<Vec<_>>()
            .join("; ");
        let named = backticked(&full).filter(|k| is_name(k));
        let (line, column, field) = match e.span() {
            Some(span) => {
                let line = self.line_of(span.start);
                let text_line = self.text.lines().nth(line - 1).unwrap_or("");
                let key = text_line
                    .split_once('=')
                    .map(|(k, _)| k.trim().to_string())
                    .filter(|k| is_name(k));
                // A table header as written (`[[body]`), where its name has a name's form.
                let header = Some(text_line.trim())
                    .filter(|l| l.starts_with('[') && l.len() <= 68)
                    .filter(|l| is_name(l.trim_matches(['[', ']'])))
                    .map(str::to_string);
                let missing = full
                    .starts_with("missing field")
                    .then_some(named)
                    .flatten()
                    .map(str::to_string);
                let table = self.table_at(span.start);
                let in_header = header.is_some();
                let in_table = |name: String| match &table {
                    Some(t) if !in_header => format!("{t}.{name}"),
                    _ => name,
                };
                let field = match (missing, key, header) {
                    (Some(name), _, _) => in_table(name),
                    (None, Some(key), _) => in_table(key),
                    (None, None, Some(header)) => header,
                    (None, None, None) => named
                        .map(|n| in_table(n.to_string()))
                        .unwrap_or_else(|| "scene".to_string()),
                };
                (line, self.column_of(span.start), field)
            }
            None => (0, 0, named.unwrap_or("scene").to_string()),
        };
        // No text of the file is quoted in the short form (a file that is not a scene may
        // hold secrets): a field only where it has the form of a name, and the message
        // with every quoted value taken out.
        let message = crate::world::short(&unquoted(&full), 300);
        let help = unknown_name(&full)
            .and_then(|(found, expected)| did_you_mean(found, expected.iter().copied()));
        SceneError {
            file: self.file.to_path_buf(),
            line,
            column,
            field,
            local: Box::new(Local {
                detail: (message != full).then(|| crate::world::short(&full, usize::MAX)),
                span: e.span(),
                help,
            }),
            message,
        }
    }
}

/// An unknown field's or variant's name and the names serde expected instead, from its
/// message ("unknown field `siz`, expected one of `id`, `size`").
fn unknown_name(message: &str) -> Option<(&str, Vec<&str>)> {
    let rest = message
        .strip_prefix("unknown field ")
        .or_else(|| message.strip_prefix("unknown variant "))?;
    let (found, expected) = rest.split_once("expected")?;
    let found = backticked(found)?;
    let expected = expected
        .split('`')
        .skip(1)
        .step_by(2)
        .filter(|n| is_name(n))
        .collect();
    Some((found, expected))
}

/// Whether `s` has the form of a TOML key or table name (letters, digits, `_`, `-`,
/// `.`; at most 64 bytes): only such a piece of a file is named in an error.
pub(super) fn is_name(s: &str) -> bool {
    !s.is_empty()
        && s.len() <= 64
        && s.bytes()
            .all(|b| b.is_ascii_alphanumeric() || matches!(b, b'_' | b'-' | b'.'))
}

/// A parser's message with what it quotes of the file taken out: text in double quotes
/// becomes `"…"`, and a backticked piece `` `…` `` unless it is what the parser
/// expected (names and tokens such as `` `=` ``) or an unknown field's name.
pub(super) fn unquoted(message: &str) -> String {
    let mut out = String::with_capacity(message.len());
    let mut rest = message;
    while let Some(k) = rest.find(['"', '`']) {
        let q = rest[k..].chars().next().expect("found");
        out.push_str(&rest[..k]);
        let after = &rest[k + 1..];
        let Some(end) = after.find(q) else {
            out.push(q);
            out.push('…');
            return out;
        };
        let inner = &after[..end];
        // Kept: the parser's alternatives (after "expected") and an unknown field's name;
        // a value it quotes (an unknown variant, a number of the wrong type) is not.
        let told = out.contains("expected") || out.ends_with("field ");
        let keep =
            q == '`' && told && (is_name(inner) || inner.bytes().all(|b| b.is_ascii_punctuation()));
        out.push(q);
        out.push_str(if keep { inner } else { "…" });
        out.push(q);
        rest = &after[end + 1..];
    }
    out.push_str(rest);
    out
}

/// The first `name` in backticks of a serde message ("unknown field `siz`").
pub(super) fn backticked(message: &str) -> Option<&str> {
    let start = message.find('`')? + 1;
    let len = message[start..].find('`')?;
    Some(&message[start..start + len])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_a_near_name_is_suggested() {
        assert_eq!(nearest("grund", ["ground", "ball"]), Some("ground"));
        assert_eq!(nearest("siz", ["size", "pos"]), Some("size"));
        assert_eq!(nearest("velocity", ["vel", "pos"]), None);
        assert_eq!(nearest("ball", ["ball"]), None);
    }

    #[test]
    fn the_table_of_an_offset_counts_arrays_of_tables() {
        let text = "[world]\ndt = 1\n[[body]]\nid = 1\n[[body]]\nsiz = 2\n";
        let ctx = Ctx {
            text,
            file: Path::new("s.toml"),
        };
        assert_eq!(ctx.table_at(0), None);
        assert_eq!(ctx.table_at(10).as_deref(), Some("world"));
        assert_eq!(
            ctx.table_at(text.find("siz").unwrap()).as_deref(),
            Some("body[1]")
        );
        assert_eq!(ctx.column_of(text.find("= 2").unwrap()), 5);
    }
}
