//! The journal: every accepted command, with the frame it took effect in, so a server
//! killed at any moment can be resumed bit for bit (`run --journal FILE`, then
//! `run --resume FILE`).
//!
//! A journal is JSON Lines. The first line is the header: the world's name, its scene
//! (name and full text), the `[world]` overrides and the limits it ran under. Then, in the
//! order they happened:
//!
//! - `{"frame": F, "apply": {...}}`: a command about to be applied at the boundary after
//!   frame F (with `sender` and `id` when it had an id), written *before* it runs: a
//!   command whose line cannot be written is refused, never applied unjournaled;
//! - `{"frame": F, "load": {"name": ..., "text": ...}}`: a `load`, with the scene's text
//!   read before it runs, so a resume needs no file the server read;
//! - `{"replied": {...}}`: the reply of the command on the line before, when it had an id
//!   (a retry after a resume gets the same answer; a resume recomputes every reply, and
//!   this one is what the client was told);
//! - `{"at": F}`: frame F was stepped (and published).
//!
//! Journals of version 2 wrote a command once it ran, with its reply (`{"frame": F,
//! "command": {...}, "reply": {...}}` and `{"frame": F, "scene": ..., "reply": ...}`): they
//! still resume.
//!
//! Each line ends with a tab and the CRC-32 of the text before it (8 hexadecimal digits): a
//! line changed or damaged after it was written is refused on resume, naming it, instead
//! of resuming silently into another world (JSON text never holds a raw tab). Journals of
//! version 1 have no checksums and still resume.
//!
//! Each line is flushed to the operating system as it is written: a killed process loses
//! nothing written (a machine that loses power may lose what the OS had not yet stored).
//! A resume replays the lines in order: the same scene, commands and steps give the same
//! world, bit for bit, since the engine is deterministic; the resumed server then appends
//! to the same journal.

use std::collections::VecDeque;
use std::fs::{File, OpenOptions};
use std::io::{BufRead, BufReader, BufWriter, Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{anyhow, bail, Context, Result};
use ricochet_engine::world::Limits;
use ricochet_protocol::command::{Command, Reply};
use serde::{Deserialize, Serialize};

use super::answered::{Answer, Answered, REMEMBER_FOR};
use super::hosted::Hosted;
use super::inbox::Sender;
use super::HostOptions;

/// The journal's format version: 3 writes a command before it runs, 2 once it ran; both
/// have a checksum on every line, 1 none.
pub const VERSION: u32 = 3;

/// A journal line as written: its text, a tab and the text's CRC-32.
fn signed(text: &str) -> String {
    format!("{text}\t{:08x}", crc32fast::hash(text.as_bytes()))
}

/// The text of a journal line: without its checksum, if it has one that matches; as it
/// is, if it has none (version 1); `None` if its checksum does not match.
pub fn text_of(line: &str) -> Option<&str> {
    if line.contains('\t') {
        unsigned(line)
    } else {
        Some(line)
    }
}

/// The text of a signed line, if its checksum matches.
fn unsigned(line: &str) -> Option<&str> {
    let (text, sum) = line.rsplit_once('\t')?;
    (sum.len() == 8 && u32::from_str_radix(sum, 16).ok()? == crc32fast::hash(text.as_bytes()))
        .then_some(text)
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct Header {
    journal: u32,
    world: String,
    scene: SceneText,
    overrides: Vec<String>,
    /// The limits as TOML (which, unlike JSON, spells an infinite work limit).
    limits: String,
    /// Why the overrides include a setting picked for an accuracy target (what `info`
    /// reports), when one was.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    accuracy: Option<String>,
}

#[derive(Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct SceneText {
    name: PathBuf,
    text: String,
}

#[derive(Serialize, Deserialize)]
#[serde(untagged)]
enum Line {
    At {
        at: u64,
    },
    Command {
        frame: u64,
        command: Command,
        reply: Reply,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        sender: Option<String>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        id: Option<String>,
    },
    Scene {
        frame: u64,
        scene: SceneText,
        reply: Reply,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        sender: Option<String>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        id: Option<String>,
    },
    Apply {
        frame: u64,
        apply: Command,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        sender: Option<String>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        id: Option<String>,
    },
    Load {
        frame: u64,
        load: SceneText,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        sender: Option<String>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        id: Option<String>,
    },
    Replied {
        replied: Reply,
    },
}

/// What a command is about to do, as the journal writes it before it runs.
pub enum Intent<'a> {
    /// Any command but a `load`.
    Apply(&'a Command),
    /// A `load`, with the scene's text as read.
    Load { name: &'a Path, text: &'a str },
}

/// An open journal, appended to.
pub struct Journal {
    out: BufWriter<File>,
    path: PathBuf,
}

impl Journal {
    /// Starts a journal at `path` (replacing any file there) for `host`'s world.
    pub fn create(path: &Path, world: &str, host: &Hosted, opts: &HostOptions) -> Result<Journal> {
        let file = File::create(path)
            .with_context(|| format!("cannot create the journal {}", path.display()))?;
        let mut journal = Journal {
            out: BufWriter::new(file),
            path: path.to_path_buf(),
        };
        let header = Header {
            journal: VERSION,
            world: world.to_string(),
            scene: SceneText {
                name: host.scene_name.clone(),
                text: host.scene_text.clone(),
            },
            overrides: opts.overrides.clone(),
            limits: toml::to_string(&opts.limits).expect("limits serialise"),
            accuracy: host.accuracy.clone(),
        };
        journal.write(&serde_json::to_string(&header).expect("headers serialise"))?;
        Ok(journal)
    }

    fn write(&mut self, line: &str) -> Result<()> {
        writeln!(self.out, "{}", signed(line))
            .and_then(|()| self.out.flush())
            .with_context(|| format!("cannot write the journal {}", self.path.display()))
    }

    fn line(&mut self, line: &Line) {
        let text = serde_json::to_string(line).expect("journal lines serialise");
        if let Err(e) = self.write(&text) {
            tracing::error!("{e:#}");
        }
    }

    /// Frame `frame` was stepped.
    pub fn stepped(&mut self, frame: u64) {
        self.line(&Line::At { at: frame });
    }

    /// Writes what a command is about to do, before it runs: an error means the line
    /// was not written, and the command must not run.
    pub fn before(
        &mut self,
        intent: Intent<'_>,
        frame: u64,
        sender: &Sender,
        id: &Option<String>,
    ) -> Result<()> {
        let (sender, id) = (sender.clone(), id.clone());
        let line = match intent {
            Intent::Apply(command) => Line::Apply {
                frame,
                apply: command.clone(),
                sender,
                id,
            },
            Intent::Load { name, text } => Line::Load {
                frame,
                load: SceneText {
                    name: name.to_path_buf(),
                    text: text.to_string(),
                },
                sender,
                id,
            },
        };
        self.write(&serde_json::to_string(&line).expect("journal lines serialise"))
    }

    /// A journal every write to fails, as on a full disk: `/dev/full`.
    #[cfg(test)]
    pub(super) fn full() -> Journal {
        let path = PathBuf::from("/dev/full");
        let file = OpenOptions::new()
            .write(true)
            .open(&path)
            .expect("/dev/full");
        Journal {
            out: BufWriter::new(file),
            path,
        }
    }

    /// The reply of the command [`Journal::before`] wrote last, if it had an id.
    pub fn replied(&mut self, reply: &Reply) {
        if reply.id.is_some() {
            self.line(&Line::Replied {
                replied: reply.clone(),
            });
        }
    }
}

/// A world rebuilt from its journal.
pub struct Resumed {
    pub world: String,
    pub host: Hosted,
    pub answered: Answered,
    pub journal: Journal,
    /// The options the journal's header set (scene, overrides, limits).
    pub opts: HostOptions,
}

/// Reads a journal a line at a time (a journal may hold hours of commands, and only the
/// world it builds is kept), numbering lines and counting the bytes of whole lines.
struct Lines<R> {
    reader: R,
    /// The line's bytes as read (a torn line may end inside a character).
    bytes: Vec<u8>,
    /// Lines read, counting the first line read as `first`.
    n: usize,
    /// Bytes of the whole lines read.
    whole: u64,
    /// Whether every line carries a checksum (journals of version 2 on); else only those
    /// that have one are checked.
    signed: bool,
    /// Whether the last line read had a checksum (that matched).
    had_sum: bool,
}

impl<R: BufRead> Lines<R> {
    fn new(reader: R, first: usize) -> Self {
        Lines {
            reader,
            bytes: Vec::new(),
            n: first - 1,
            whole: 0,
            signed: true,
            had_sum: false,
        }
    }

    /// The next line, without its newline, and its number; `None` at the end, and for a
    /// last line the kill cut short (no newline: it was never flushed whole, so nothing it
    /// held was answered).
    ///
    /// The bytes are read before they are taken as text, so a line torn inside a
    /// character is torn, like any other; a whole line that is not UTF-8 is refused,
    /// naming it.
    fn next(&mut self, path: &Path) -> Result<Option<(usize, &str)>> {
        self.bytes.clear();
        let got = self
            .reader
            .read_until(b'\n', &mut self.bytes)
            .with_context(|| format!("cannot read the journal {}", path.display()))?;
        if got == 0 || self.bytes.last() != Some(&b'\n') {
            return Ok(None);
        }
        self.n += 1;
        self.whole += got as u64;
        self.bytes.pop();
        let line = std::str::from_utf8(&self.bytes)
            .map_err(|_| anyhow!("journal {} line {}: not UTF-8 text", path.display(), self.n))?;
        // A journal of version 1 has lines without checksums, and those a resumed server
        // appended with them.
        self.had_sum = line.contains('\t');
        if !self.signed && !self.had_sum {
            return Ok(Some((self.n, line)));
        }
        let text = unsigned(line).ok_or_else(|| {
            anyhow!(
                "journal {} line {}: its checksum does not match (the line was changed or damaged after it was written)",
                path.display(),
                self.n
            )
        })?;
        Ok(Some((self.n, text)))
    }
}

/// Rebuilds the world `path` journals, to its last journaled frame, and opens the journal
/// to go on appending. `opts` gives what the journal does not (network, rates, ...).
///
/// Two passes: the first rebuilds the world; the second reads again only the last
/// [`REMEMBER_FOR`] of frames and remembers their answered ids, as old as they were when
/// the server stopped (an id older than that would be forgotten by now). The answers are
/// made after the world, so when they are forgotten their memory goes back whole, not as
/// holes between the world's.
pub fn resume(path: &Path, opts: &HostOptions) -> Result<Resumed> {
    let open =
        || File::open(path).with_context(|| format!("cannot open the journal {}", path.display()));
    let at = |n: usize| format!("journal {} line {n}", path.display());
    let mut lines = Lines::new(BufReader::new(open()?), 1);
    // The header says whether the lines carry checksums: it is read as it is (checked
    // against its own checksum if it has one).
    lines.signed = false;
    let Some((_, raw)) = lines.next(path)? else {
        bail!("{}: empty, or its header cut short", at(1));
    };
    let raw = raw.to_string();
    let signed = lines.had_sum;
    let header: Header =
        serde_json::from_str(&raw).with_context(|| format!("{}: not a journal header", at(1)))?;
    match (header.journal, signed) {
        (VERSION | 2, true) | (1, false) => {}
        (v @ (2 | VERSION), false) => {
            bail!("{}: a version {v} header without its checksum", at(1))
        }
        (v, _) => bail!(
            "{}: journal version {v} (this server reads 1 to {VERSION})",
            at(1)
        ),
    }
    lines.signed = signed;
    let limits: Limits =
        toml::from_str(&header.limits).with_context(|| format!("{}: limits", at(1)))?;
    // A journal is a file like any other: its limits are checked as an operator's, and
    // never raise this server's own (`--limit`).
    limits
        .validate()
        .with_context(|| format!("{}: limits", at(1)))?;
    if let Some((name, theirs, ours)) = limits.above(&opts.limits) {
        bail!(
            "{}: the journal's limit {name} = {theirs} is above this server's {ours}; resume with --limit {name}={theirs} to allow it",
            at(1)
        );
    }
    let mut opts = opts.clone();
    opts.overrides = header.overrides.clone();
    opts.limits = limits;
    opts.scene = Some(header.scene.name.clone());
    opts.world = header.world.clone();
    let mut host = Hosted::load(header.scene.text.clone(), header.scene.name.clone(), &opts)
        .with_context(|| format!("{}: the journal's scene", at(1)))?;
    host.accuracy = header.accuracy.clone();
    // Where the lines of a frame start (byte offset, line number), about once a second of
    // frames, only as far back as the window of remembered ids: the second pass starts at
    // the last mark before the window.
    let dt = host.world.config.dt;
    let window = (REMEMBER_FOR.as_secs_f64() / dt).ceil() as u64;
    let mark_every = ((1.0 / dt).round() as u64).max(1);
    let mut marks: VecDeque<(u64, u64, usize)> =
        VecDeque::with_capacity((window / mark_every + 3) as usize);
    // The `step`s with ids whose steps had not all run (line, due at step): answered when
    // they have.
    let mut running: Vec<(usize, u64)> = Vec::new();
    // The answers of the commands with ids written before they ran (version 3), as the
    // replay recomputes them, for the last window of frames: (frame, sender, id, answer).
    let mut recent: VecDeque<(u64, Sender, String, Answer)> = VecDeque::new();
    while let Some((n, raw)) = lines.next(path)? {
        let line: Line = serde_json::from_str(raw).map_err(|e| anyhow!("{}: {e}", at(n)))?;
        match line {
            Line::At { at: frame } => {
                host.advance();
                if host.world.frame() != frame {
                    bail!(
                        "{}: frame {frame} stepped, but the rebuilt world is at frame {}",
                        at(n),
                        host.world.frame()
                    );
                }
                running.retain(|&(_, due)| due > host.steps_run);
                if frame % mark_every == 0 {
                    // The lines after this one act at this frame's boundary or later.
                    while marks.len() >= 2 && marks[1].0 + window <= frame {
                        marks.pop_front();
                    }
                    if marks.len() == marks.capacity() {
                        marks.pop_front();
                    }
                    marks.push_back((frame, lines.whole, n + 1));
                }
            }
            Line::Command {
                frame,
                command,
                reply,
                id,
                ..
            } => {
                if reply.ok {
                    check_frame(&host, frame, &at(n))?;
                    let handled = host.handle(&command);
                    if !handled.reply.ok {
                        bail!(
                            "{}: applied when journaled, refused now: {}",
                            at(n),
                            handled.reply.error.unwrap_or_default()
                        );
                    }
                    if id.is_some() && handled.due_at_step > host.steps_run {
                        running.push((n, handled.due_at_step));
                    }
                }
            }
            Line::Scene { frame, scene, .. } => {
                check_frame(&host, frame, &at(n))?;
                host.adopt_scene(scene.text, scene.name)
                    .map_err(|e| anyhow!("{}: the loaded scene: {e}", at(n)))?;
            }
            // Written before it ran: replayed as it ran then, refused or not.
            Line::Apply {
                frame,
                apply,
                sender,
                id,
            } => {
                check_frame(&host, frame, &at(n))?;
                let handled = host.handle(&apply);
                keep_answer(&mut recent, frame, sender, id, handled, window);
            }
            Line::Load {
                frame,
                load,
                sender,
                id,
            } => {
                check_frame(&host, frame, &at(n))?;
                let handled = host.handle_scene(load.text, load.name);
                keep_answer(&mut recent, frame, sender, id, handled, window);
            }
            Line::Replied { .. } => {}
        }
    }
    let whole = lines.whole;
    drop(lines);

    // The second pass: the answers of the window.
    let last = host.world.frame();
    let (from, below, first) = match marks.front() {
        Some(&(frame, offset, n)) if frame + window <= last => (frame, offset, n),
        _ => (0, 0, 1),
    };
    let mut file = open()?;
    file.seek(SeekFrom::Start(below))?;
    let mut lines = Lines::new(BufReader::new(file).take(whole - below), first);
    lines.signed = signed;
    if below == 0 {
        lines.next(path)?; // the header
    }
    let now = Instant::now();
    let mut answered = Answered::default();
    while let Some((n, raw)) = lines.next(path)? {
        let (frame, reply, sender, id, due_at_step) =
            match serde_json::from_str(raw).map_err(|e| anyhow!("{}: {e}", at(n)))? {
                Line::Command {
                    frame,
                    reply,
                    sender,
                    id: Some(id),
                    ..
                } => {
                    // A `step` still running when the server stopped is answered once its steps
                    // have run.
                    let due = running
                        .iter()
                        .find(|&&(line, _)| line == n)
                        .map_or(0, |&(_, due)| due);
                    (frame, reply, sender, id, due)
                }
                Line::Scene {
                    frame,
                    reply,
                    sender,
                    id: Some(id),
                    ..
                } => (frame, reply, sender, id, 0),
                _ => continue,
            };
        if frame < from {
            continue;
        }
        let age = Duration::from_secs_f64(last.saturating_sub(frame) as f64 * dt);
        answered.remember_at(
            sender,
            id,
            Answer::new(&reply, due_at_step),
            now.checked_sub(age).unwrap_or(now),
        );
    }
    for (frame, sender, id, answer) in recent.into_iter().filter(|r| r.0 + window > last) {
        let age = Duration::from_secs_f64(last.saturating_sub(frame) as f64 * dt);
        answered.remember_at(sender, id, answer, now.checked_sub(age).unwrap_or(now));
    }
    // What the server counts from here is what it does live, not the replay.
    host.health = Default::default();
    // Go on appending, after a line cut short if there is one.
    let file = OpenOptions::new()
        .append(true)
        .open(path)
        .with_context(|| format!("cannot append to the journal {}", path.display()))?;
    // A line cut short is garbage in the middle of the journal once more is appended: cut
    // it off.
    if file.metadata()?.len() > whole {
        file.set_len(whole)?;
    }
    Ok(Resumed {
        world: header.world,
        host,
        answered,
        journal: Journal {
            out: BufWriter::new(file),
            path: path.to_path_buf(),
        },
        opts,
    })
}

/// Keeps the answer of a replayed command with an id, and only the last `window` frames'.
fn keep_answer(
    recent: &mut VecDeque<(u64, Sender, String, Answer)>,
    frame: u64,
    sender: Sender,
    id: Option<String>,
    handled: super::hosted::Handled,
    window: u64,
) {
    while recent.front().is_some_and(|r| r.0 + window <= frame) {
        recent.pop_front();
    }
    if let Some(id) = id {
        let mut reply = handled.reply;
        reply.id = Some(id.clone());
        recent.push_back((frame, sender, id, Answer::new(&reply, handled.due_at_step)));
    }
}

fn check_frame(host: &Hosted, frame: u64, at: &str) -> Result<()> {
    if host.world.frame() != frame {
        bail!(
            "{at}: a command of frame {frame}, but the rebuilt world is at frame {}",
            host.world.frame()
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use std::io::Write as _;

    use super::*;

    fn options() -> HostOptions {
        HostOptions::for_tests("journaled")
    }

    /// A journal of `steps` stepped frames of the shipped bounce scene, and the world's
    /// frame at its end.
    fn journal_of(path: &Path, steps: usize) -> u64 {
        let opts = options();
        let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/../assets/scenes/bounce.toml");
        let text = std::fs::read_to_string(scene).unwrap();
        let mut host = Hosted::load(text, PathBuf::from(scene), &opts).unwrap();
        let mut journal = Journal::create(path, "journaled", &host, &opts).unwrap();
        for _ in 0..steps {
            host.step();
            journal.stepped(host.world.frame());
        }
        host.world.frame()
    }

    fn append(path: &Path, bytes: &[u8]) {
        let mut file = OpenOptions::new().append(true).open(path).unwrap();
        file.write_all(bytes).unwrap();
    }

    #[test]
    fn a_last_line_cut_short_is_not_replayed_and_is_cut_off() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("world.journal");
        let frame = journal_of(&path, 5);
        let whole = std::fs::metadata(&path).unwrap().len();
        // The kill cut the next step's line short: even a line that parses is not whole
        // without its newline (it was never flushed whole, so never answered).
        append(&path, format!("{{\"at\":{}}}", frame + 1).as_bytes());
        let resumed = resume(&path, &options()).unwrap();
        assert_eq!(resumed.host.world.frame(), frame);
        assert_eq!(std::fs::metadata(&path).unwrap().len(), whole);
        // Resumed once more, the journal is whole: the same frame again.
        drop(resumed);
        assert_eq!(resume(&path, &options()).unwrap().host.world.frame(), frame);
    }

    /// The refusal of a journal that must not resume.
    fn refusal(path: &Path, opts: &HostOptions) -> String {
        match resume(path, opts) {
            Ok(_) => panic!("{} resumed", path.display()),
            Err(e) => format!("{e:#}"),
        }
    }

    #[test]
    fn a_last_line_torn_inside_a_character_is_torn_like_any_other() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("world.journal");
        let frame = journal_of(&path, 5);
        // The first byte of a two-byte character, then the kill.
        append(&path, b"{\"at\":\"\xc3");
        assert_eq!(resume(&path, &options()).unwrap().host.world.frame(), frame);
        // A whole line that is not text is refused, naming its line.
        append(&path, b"\xff\xfe\n");
        let e = refusal(&path, &options());
        assert!(e.contains("line 7") && e.contains("not UTF-8"), "{e}");
    }

    #[test]
    fn a_journals_limits_never_raise_the_servers_own() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("world.journal");
        journal_of(&path, 2);
        let text = std::fs::read_to_string(&path).unwrap();
        // The operator resumes under --limit bodies=60: a journal written under the
        // default (100 000 bodies) would raise it, and is refused with what to do.
        let strict = HostOptions {
            limits: Limits::default().with(&["bodies=60".into()]).unwrap(),
            ..options()
        };
        let e = refusal(&path, &strict);
        assert!(
            e.contains("bodies") && e.contains("--limit bodies=100000"),
            "{e}"
        );
        // A header whose work limit is not a number is refused, not read as no limit (even
        // with its checksum made again, as an operator's edit would).
        let nan = text.replacen("step_work = 100000000.0", "step_work = nan", 1);
        assert_ne!(nan, text, "the header spells step_work as expected");
        std::fs::write(&path, resigned(&nan)).unwrap();
        let e = refusal(&path, &options());
        assert!(e.contains("step_work"), "{e}");
    }

    /// Every line of `text` with its checksum made again.
    fn resigned(text: &str) -> String {
        text.lines()
            .map(|l| signed(l.rsplit_once('\t').map_or(l, |(t, _)| t)) + "\n")
            .collect()
    }

    #[test]
    fn a_line_changed_after_it_was_written_is_refused_naming_it() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("world.journal");
        journal_of(&path, 4);
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text.lines().all(|l| unsigned(l).is_some()), "{text}");
        // One digit of a stepped frame changed: another world, were it replayed.
        let changed = text.replacen("{\"at\":3}", "{\"at\":5}", 1);
        assert_ne!(changed, text);
        std::fs::write(&path, &changed).unwrap();
        let e = refusal(&path, &options());
        assert!(e.contains("line 4") && e.contains("checksum"), "{e}");
        // The header too.
        let header = text.replacen("\"journaled\"", "\"journalex\"", 1);
        std::fs::write(&path, &header).unwrap();
        let e = refusal(&path, &options());
        assert!(e.contains("line 1") && e.contains("checksum"), "{e}");
    }

    #[test]
    fn a_journal_of_version_2_with_commands_written_after_they_ran_still_resumes() {
        use ricochet_protocol::command::Action;
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("world.journal");
        let frame = journal_of(&path, 3);
        // Version 2: the command with its reply, once it ran, then more steps.
        let press = Command::World(Action::Set(
            serde_json::from_str(r#"{"name":"gravity","value":[0,-9]}"#).unwrap(),
        ));
        let opts = options();
        let text = std::fs::read_to_string(&path).unwrap();
        let header = text.lines().next().unwrap().rsplit_once('\t').unwrap().0;
        let header = header.replacen(&format!("\"journal\":{VERSION}"), "\"journal\":2", 1);
        let mut lines = vec![signed(&header)];
        lines.extend(text.lines().skip(1).map(str::to_string));
        let reply = Reply {
            ok: true,
            frame,
            ids: Vec::new(),
            error: None,
            id: Some("p".into()),
        };
        let line = Line::Command {
            frame,
            command: press.clone(),
            reply,
            sender: Some("peer".into()),
            id: Some("p".into()),
        };
        lines.push(signed(&serde_json::to_string(&line).unwrap()));
        lines.push(signed(&format!("{{\"at\":{}}}", frame + 1)));
        std::fs::write(&path, lines.join("\n") + "\n").unwrap();
        let resumed = resume(&path, &opts).unwrap();
        assert_eq!(resumed.host.world.frame(), frame + 1);
        assert_eq!(
            resumed.host.world.config.gravity.y, -9.0,
            "the command was replayed"
        );
        assert!(resumed.answered.get(&Some("peer".into()), "p").is_some());
    }

    #[test]
    fn a_journal_of_version_1_without_checksums_still_resumes() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("world.journal");
        let frame = journal_of(&path, 4);
        let text = std::fs::read_to_string(&path).unwrap();
        let v1: String = text
            .lines()
            .map(|l| l.rsplit_once('\t').unwrap().0.to_string() + "\n")
            .collect::<String>()
            .replacen(&format!("\"journal\":{VERSION}"), "\"journal\":1", 1);
        assert!(!v1.contains('\t') && v1.contains("\"journal\":1"), "{v1}");
        std::fs::write(&path, &v1).unwrap();
        let mut resumed = resume(&path, &options()).unwrap();
        assert_eq!(resumed.host.world.frame(), frame);
        // The resumed server appends lines with checksums; the mixed journal resumes.
        resumed.host.step();
        resumed.journal.stepped(resumed.host.world.frame());
        drop(resumed);
        assert_eq!(
            resume(&path, &options()).unwrap().host.world.frame(),
            frame + 1
        );
    }

    #[test]
    fn a_resumed_server_still_says_why_its_setting_was_picked() {
        let dir = tempfile::tempdir().unwrap();
        let (picked, plain) = (dir.path().join("picked.journal"), dir.path().join("plain"));
        let opts = options();
        let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/../assets/scenes/bounce.toml");
        let text = std::fs::read_to_string(scene).unwrap();
        let mut host = Hosted::load(text, PathBuf::from(scene), &opts).unwrap();
        host.accuracy = Some("picked impulses 8 it for a target of 0.01".into());
        Journal::create(&picked, "journaled", &host, &opts).unwrap();
        let resumed = resume(&picked, &options()).unwrap();
        assert_eq!(resumed.host.info().accuracy, host.accuracy);
        // A journal of a server without a target says none (and has no such field).
        journal_of(&plain, 1);
        assert!(!std::fs::read_to_string(&plain)
            .unwrap()
            .contains("accuracy"));
        assert_eq!(
            resume(&plain, &options()).unwrap().host.info().accuracy,
            None
        );
    }

    #[test]
    fn a_bad_line_in_the_middle_is_refused_naming_its_line() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("world.journal");
        let frame = journal_of(&path, 3);
        append(&path, b"{\"at\":garbage}\n");
        append(&path, format!("{{\"at\":{}}}\n", frame + 1).as_bytes());
        let error = format!("{:#}", resume(&path, &options()).err().unwrap());
        // The header, three steps, then the bad line: line 5.
        assert!(error.contains("world.journal line 5"), "{error}");
    }

    #[test]
    fn an_empty_journal_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("world.journal");
        std::fs::write(&path, "").unwrap();
        let error = format!("{:#}", resume(&path, &options()).err().unwrap());
        assert!(error.contains("line 1: empty"), "{error}");
    }

    #[test]
    fn a_resume_remembers_the_ids_of_its_last_seconds_as_old_as_they_were() {
        use ricochet_protocol::command::{Action, Direction, ServerCommand};
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("world.journal");
        let opts = options();
        let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/../assets/scenes/bounce.toml");
        let text = std::fs::read_to_string(scene).unwrap();
        let mut host = Hosted::load(text, PathBuf::from(scene), &opts).unwrap();
        let mut journal = Journal::create(&path, "journaled", &host, &opts).unwrap();
        let window = (REMEMBER_FOR.as_secs_f64() / host.world.config.dt).ceil() as u64;
        let sender: Sender = Some("peer".into());
        let press = Command::World(Action::Press {
            dir: Direction::Left,
        });
        let end = window + 300;
        let mut step_due = 0;
        for _ in 0..end {
            let frame = host.world.frame();
            let id = match frame {
                10 => Some("old"),
                f if f == end - 100 => Some("new"),
                _ => None,
            };
            if let Some(id) = id {
                let id = Some(id.to_string());
                journal
                    .before(Intent::Apply(&press), frame, &sender, &id)
                    .unwrap();
                let mut reply = host.handle(&press).reply;
                reply.id = id;
                journal.replied(&reply);
            }
            if frame == end - 50 {
                let step = Command::Server(ServerCommand::Step { n: 1000 });
                let id = Some("steps".to_string());
                journal
                    .before(Intent::Apply(&step), frame, &sender, &id)
                    .unwrap();
                let mut handled = host.handle(&step);
                step_due = handled.due_at_step;
                handled.reply.id = id;
                journal.replied(&handled.reply);
            }
            host.advance();
            journal.stepped(host.world.frame());
        }
        drop(journal);
        let resumed = resume(&path, &options()).unwrap();
        assert_eq!(resumed.host.steps_run, host.steps_run);
        let answered = &resumed.answered;
        assert!(
            answered.get(&sender, "old").is_none(),
            "older than REMEMBER_FOR when the server stopped"
        );
        let new = answered.get(&sender, "new").expect("remembered");
        assert_eq!(new.due_at_step, 0);
        assert!(answered.get(&None, "new").is_none(), "per sender");
        let steps = answered.get(&sender, "steps").expect("remembered");
        assert!(step_due > resumed.host.steps_run);
        assert_eq!(
            steps.due_at_step, step_due,
            "still running: due when its steps have run"
        );
        assert_eq!(answered.len(), 2);
    }
}
