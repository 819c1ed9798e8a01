//! Reading a journal back: a world rebuilt to its last journaled frame, the answers of its
//! last seconds, and the journal opened to go on appending.

use std::collections::VecDeque;
use std::fs::{File, OpenOptions};
use std::io::{BufRead, BufReader, Read, Seek, SeekFrom};
use std::path::Path;
use std::time::{Duration, Instant};

use anyhow::{anyhow, bail, Context, Result};
use ricochet_engine::world::Limits;

use super::super::answered::{Answer, Answered, Remembered, REMEMBER_FOR};
use super::super::hosted::{Handled, Hosted};
use super::super::inbox::Sender;
use super::super::HostOptions;
use super::{checkpoint, unsigned, Header, Journal, Line, VERSION};

/// The longest journal line read: a header or a `load` with a scene file of the largest
/// size read ([`crate::scenes::MAX_SCENE_FILE_BYTES`]), every byte of it escaped in JSON
/// (six bytes at most), and room for the rest of the line.
pub const MAX_LINE_BYTES: u64 = 6 * crate::scenes::MAX_SCENE_FILE_BYTES + (64 << 10);

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
    /// last line a kill or a full disk cut short: no newline, or a checksum that does not
    /// match, at the end of the file (it was never written whole, so nothing it held was
    /// answered; it is dropped, and cut off before the journal is appended to).
    ///
    /// The bytes are read before they are taken as text, so a line torn inside a
    /// character is torn, like any other; a whole line that is not UTF-8, or whose
    /// checksum does not match, with more after it is refused, naming it. A line is read
    /// up to [`MAX_LINE_BYTES`]: a longer one is refused, not read on.
    fn next(&mut self, path: &Path) -> Result<Option<(usize, &str)>> {
        self.bytes.clear();
        let got = (&mut self.reader)
            .take(MAX_LINE_BYTES + 1)
            .read_until(b'\n', &mut self.bytes)
            .with_context(|| format!("cannot read the journal {}", path.display()))?;
        let n = self.n + 1;
        if got as u64 > MAX_LINE_BYTES {
            bail!(
                "journal {} line {n}: longer than {MAX_LINE_BYTES} bytes (no journal line is)",
                path.display()
            );
        }
        if got == 0 {
            return Ok(None);
        }
        if self.bytes.last() != Some(&b'\n') {
            tracing::warn!(
                journal = %path.display(),
                line = n,
                bytes = got,
                "the journal's last line was cut short (no newline): dropped"
            );
            return Ok(None);
        }
        self.bytes.pop();
        let at_end = self
            .reader
            .fill_buf()
            .with_context(|| format!("cannot read the journal {}", path.display()))?
            .is_empty();
        let torn = |why: &str| {
            tracing::warn!(
                journal = %path.display(),
                line = n,
                bytes = got,
                "the journal's last line {why}: taken as cut short by a kill or a full disk, dropped"
            );
        };
        let Ok(line) = std::str::from_utf8(&self.bytes) else {
            if at_end {
                torn("is not UTF-8");
                return Ok(None);
            }
            bail!("journal {} line {n}: not UTF-8 text", path.display());
        };
        // A journal of version 1 has lines without checksums, and those a resumed server
        // appended with them.
        let had_sum = line.contains('\t');
        let text = if !self.signed && !had_sum {
            Some(line)
        } else {
            unsigned(line)
        };
        let Some(text) = text else {
            if at_end {
                torn("does not match its checksum");
                return Ok(None);
            }
            bail!(
                "journal {} line {n}: its checksum does not match (the line was changed or damaged after it was written)",
                path.display()
            );
        };
        self.n = n;
        self.whole += got as u64;
        self.had_sum = had_sum;
        Ok(Some((n, text)))
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
    let at = |n: usize| format!("journal {} line {n}", path.display());
    let mut lines = Lines::new(BufReader::new(open(path)?), 1);
    let (header, signed, opts) = read_header(&mut lines, path, opts)?;
    let replay = Instant::now();
    // A journal of version 4 may start from a checkpoint: its second line names it.
    let second = lines.next(path)?.map(|(n, raw)| (n, raw.to_string()));
    let reference = match &second {
        Some((_, raw)) => match serde_json::from_str::<Line>(raw) {
            Ok(Line::Checkpoint { checkpoint }) => Some(checkpoint),
            _ => None,
        },
        None => None,
    };
    let (host, saved, checkpoint_file, pending) = match reference {
        Some(reference) => {
            if header.journal < 4 {
                bail!(
                    "{}: a checkpoint in a journal of version {}",
                    at(2),
                    header.journal
                );
            }
            let restored = checkpoint::restore(path, &reference, &opts).with_context(|| at(2))?;
            let saved = (restored.frame, restored.answers);
            (restored.host, Some(saved), Some(reference.file), None)
        }
        None => {
            let mut host =
                Hosted::load(header.scene.text.clone(), header.scene.name.clone(), &opts)
                    .with_context(|| format!("{}: the journal's scene", at(1)))?;
            host.accuracy = header.accuracy.clone();
            (host, None, None, second)
        }
    };
    let mut first = FirstPass::new(host);
    first.replay(&mut lines, pending, path)?;
    let replay_ms = replay.elapsed().as_secs_f64() * 1e3;
    let whole = lines.whole;
    drop(lines);
    let answered = first.answers(path, whole, signed, saved)?;
    let mut host = first.host;
    // What the server counts from here is what it does live, not the replay.
    host.accounts.health = Default::default();
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
    checkpoint::remove_strays(path, checkpoint_file.as_deref());
    Ok(Resumed {
        world: header.world,
        host,
        answered,
        journal: {
            let mut journal =
                Journal::appending(file, path, whole, opts.checkpoints, checkpoint_file);
            journal.since.bytes = whole;
            journal.since.step_ms = replay_ms;
            journal
        },
        opts,
    })
}

fn open(path: &Path) -> Result<File> {
    super::files::open_regular(path, "journal").map(|(file, _)| file)
}

/// The journal's header, whether its lines carry checksums, and the options it sets over
/// `opts` (its scene, world, overrides and limits, checked against this server's).
fn read_header<R: BufRead>(
    lines: &mut Lines<R>,
    path: &Path,
    opts: &HostOptions,
) -> Result<(Header, bool, HostOptions)> {
    let at = |n: usize| format!("journal {} line {n}", path.display());
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
        (2..=VERSION, true) | (1, false) => {}
        (v @ 2..=VERSION, false) => {
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
    Ok((header, signed, opts))
}

/// The first pass over a journal: the world rebuilt line by line, and what the second
/// pass needs to recall the answers of the last window of frames.
struct FirstPass {
    host: Hosted,
    /// Frames a remembered id is kept for, and how often a frame's place is marked.
    window: u64,
    mark_every: u64,
    /// Where the lines of a frame start (frame, byte offset, line number), about once a
    /// second of frames, only as far back as the window of remembered ids: the second
    /// pass starts at the last mark before the window.
    marks: VecDeque<(u64, u64, usize)>,
    /// The `step`s with ids whose steps had not all run (line, due at step): answered
    /// when they have.
    running: Vec<(usize, u64)>,
    /// The answers of the commands with ids written before they ran (version 3), as the
    /// replay recomputes them, for the last window of frames: (frame, sender, id, answer).
    recent: VecDeque<(u64, Sender, String, Answer)>,
}

impl FirstPass {
    fn new(host: Hosted) -> FirstPass {
        let dt = host.world.config.dt;
        let window = (REMEMBER_FOR.as_secs_f64() / dt).ceil() as u64;
        let mark_every = ((1.0 / dt).round() as u64).max(1);
        FirstPass {
            host,
            window,
            mark_every,
            marks: VecDeque::with_capacity((window / mark_every + 3) as usize),
            running: Vec::new(),
            recent: VecDeque::new(),
        }
    }

    /// Replays every line after the header (`pending` first, if read already).
    fn replay<R: BufRead>(
        &mut self,
        lines: &mut Lines<R>,
        mut pending: Option<(usize, String)>,
        path: &Path,
    ) -> Result<()> {
        loop {
            let (n, raw) = match pending.take() {
                Some(first) => first,
                None => match lines.next(path)? {
                    Some((n, raw)) => (n, raw.to_string()),
                    None => return Ok(()),
                },
            };
            let at = format!("journal {} line {n}", path.display());
            let line: Line = serde_json::from_str(&raw).map_err(|e| anyhow!("{at}: {e}"))?;
            self.line(line, n, lines.whole, &at)?;
        }
    }

    /// One line of the journal, line `n`, the whole lines before the next one `whole`
    /// bytes long.
    fn line(&mut self, line: Line, n: usize, whole: u64, at: &str) -> Result<()> {
        let (host, window) = (&mut self.host, self.window);
        match line {
            Line::At { at: frame } => {
                host.advance();
                if host.world.frame() != frame {
                    bail!(
                        "{at}: frame {frame} stepped, but the rebuilt world is at frame {}",
                        host.world.frame()
                    );
                }
                let steps_run = host.stepping.steps_run;
                self.running.retain(|&(_, due)| due > steps_run);
                if frame % self.mark_every == 0 {
                    let marks = &mut self.marks;
                    // The lines after this one act at this frame's boundary or later.
                    while marks.len() >= 2 && marks[1].0 + window <= frame {
                        marks.pop_front();
                    }
                    if marks.len() == marks.capacity() {
                        marks.pop_front();
                    }
                    marks.push_back((frame, whole, n + 1));
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
                    check_frame(host, frame, at)?;
                    let handled = host.handle(&command);
                    if !handled.reply.ok {
                        bail!(
                            "{at}: applied when journaled, refused now: {}",
                            handled.reply.error.unwrap_or_default()
                        );
                    }
                    if id.is_some() && handled.due_at_step > host.stepping.steps_run {
                        self.running.push((n, handled.due_at_step));
                    }
                }
            }
            Line::Scene { frame, scene, .. } => {
                check_frame(host, frame, at)?;
                host.adopt_scene(scene.text, scene.name)
                    .map_err(|e| anyhow!("{at}: the loaded scene: {e}"))?;
            }
            // Written before it ran: replayed as it ran then, refused or not.
            Line::Apply {
                frame,
                apply,
                sender,
                id,
            } => {
                check_frame(host, frame, at)?;
                let handled = host.handle(&apply);
                keep_answer(&mut self.recent, frame, sender, id, handled, window);
            }
            Line::Load {
                frame,
                load,
                sender,
                id,
            } => {
                check_frame(host, frame, at)?;
                let handled = host.handle_scene(load.text, load.name);
                keep_answer(&mut self.recent, frame, sender, id, handled, window);
            }
            Line::Replied { .. } => {}
            Line::Checkpoint { .. } => {
                bail!("{at}: a checkpoint is named only right after the header")
            }
        }
        Ok(())
    }

    /// The second pass: the answers of the last window of frames, read from the last mark
    /// before it to the end of the whole lines (`whole` bytes), after those a checkpoint
    /// `saved` (the oldest).
    fn answers(
        &mut self,
        path: &Path,
        whole: u64,
        signed: bool,
        saved: Option<(u64, Vec<Remembered>)>,
    ) -> Result<Answered> {
        let at = |n: usize| format!("journal {} line {n}", path.display());
        let dt = self.host.world.config.dt;
        let last = self.host.world.frame();
        let (from, below, first) = match self.marks.front() {
            Some(&(frame, offset, n)) if frame + self.window <= last => (frame, offset, n),
            _ => (0, 0, 1),
        };
        let mut file = open(path)?;
        file.seek(SeekFrom::Start(below))?;
        let mut lines = Lines::new(BufReader::new(file).take(whole - below), first);
        lines.signed = signed;
        if below == 0 {
            lines.next(path)?; // the header
        }
        let now = Instant::now();
        let ago = |frame: u64| {
            let age = Duration::from_secs_f64(last.saturating_sub(frame) as f64 * dt);
            now.checked_sub(age).unwrap_or(now)
        };
        let mut answered = Answered::default();
        // The answers the checkpoint kept come first: they are the oldest.
        if let Some((frame, answers)) = saved {
            let since = last.saturating_sub(frame) as f64 * dt;
            for r in answers {
                let age = Duration::from_secs_f64((r.age + since).max(0.0));
                let answer = Answer {
                    reply: r.reply.into_bytes().into_boxed_slice(),
                    due_at_step: r.due_at_step,
                };
                answered.remember_at(r.sender, r.id, answer, now.checked_sub(age).unwrap_or(now));
            }
        }
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
                        // A `step` still running when the server stopped is answered once
                        // its steps have run.
                        let due = self
                            .running
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
            answered.remember_at(sender, id, Answer::new(&reply, due_at_step), ago(frame));
        }
        let window = self.window;
        for (frame, sender, id, answer) in self.recent.drain(..).filter(|r| r.0 + window > last) {
            answered.remember_at(sender, id, answer, ago(frame));
        }
        Ok(answered)
    }
}

/// Keeps the answer of a replayed command with an id, and only the last `window` frames'.
fn keep_answer(
    recent: &mut VecDeque<(u64, Sender, String, Answer)>,
    frame: u64,
    sender: Sender,
    id: Option<String>,
    handled: Handled,
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
