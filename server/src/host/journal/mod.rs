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
//! - `{"at": F}`: frame F was stepped (and published);
//! - `{"checkpoint": {"file": ..., "frame": F, "bytes": ..., "crc": ...}}`, right after the
//!   header (version 4): the journal starts from this checkpoint of the world at frame F,
//!   a file beside it ([`checkpoint`]); what follows happened after it. The host takes one
//!   when the journal has grown past `--journal-bytes` or replaying it would take longer
//!   than `--checkpoint-after-ms`.
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
//! Each line is handed to the operating system as it is written: a killed process loses
//! nothing written (a machine that loses power may lose what the OS had not yet stored).
//!
//! A write that fails (a full disk) leaves the journal whole: what it wrote in part is
//! cut off again, so the file ends with the last whole line. A command's line that cannot
//! be written is dropped and the command refused; a line of what happened anyway (a
//! frame stepped, a reply) is owed, kept in memory and written before any later line once
//! the disk has room, so the journal never skips a frame (at most [`MAX_OWED_BYTES`]: past
//! them it stops at its last whole line, and refuses commands). A resume drops a torn last line
//! (no newline, or a checksum that does not match, at the end of the file), saying so.
//! A resume replays the lines in order: the same scene, commands and steps give the same
//! world, bit for bit, since the engine is deterministic; the resumed server then appends
//! to the same journal.

use std::fs::File;
use std::io::{Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use ricochet_protocol::command::{Command, Reply};
use serde::{Deserialize, Serialize};

use super::hosted::Hosted;
use super::inbox::Sender;
use super::HostOptions;

/// The journal's format version: 4 may start from a checkpoint; 3 writes a command before
/// it runs, 2 once it ran; all have a checksum on every line, 1 none.
pub const VERSION: u32 = 4;

/// The most bytes of lines a journal owes while its disk is full: about four hours of
/// frames at 60 Hz. Past it the journal stops at its last whole line (what it holds
/// resumes, every accepted command included) and every command is refused: the memory a
/// full disk takes is bounded.
pub const MAX_OWED_BYTES: usize = 16 << 20;

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

impl Header {
    /// The header of a journal of `host`'s world named `world`, run under `opts`.
    fn of(world: &str, host: &Hosted, opts: &HostOptions) -> Header {
        Header {
            journal: VERSION,
            world: world.to_string(),
            scene: SceneText {
                name: host.source.name.clone(),
                text: host.source.text.clone(),
            },
            overrides: opts.overrides.clone(),
            limits: toml::to_string(&opts.limits).expect("limits serialise"),
            accuracy: host.accuracy.clone(),
        }
    }
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
    Checkpoint {
        checkpoint: CheckpointRef,
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
    out: File,
    path: PathBuf,
    /// Bytes of the whole lines on disk: where the file is cut back to when a write
    /// fails part way.
    len: u64,
    /// Whether a failed write may have left bytes after `len` that are still to be cut.
    cut: bool,
    /// Lines of what happened (frames stepped, replies) whose write failed, in order:
    /// written before any later line.
    owed: String,
    /// The most bytes owed: past it the journal stops (see [`Journal::write`]).
    max_owed: usize,
    /// Stopped at its last whole line: every command is refused until a resume.
    stopped: bool,
    /// When to take a checkpoint, and how far the journal has come since the last.
    policy: Checkpoints,
    since: Since,
    /// The checkpoint the journal starts from (its file name), if any.
    checkpoint: Option<String>,
    /// A checkpoint being written.
    pending: Option<checkpoint::Pending>,
}

/// How much the journal has grown since its last checkpoint (or its start).
#[derive(Clone, Copy, Debug, Default)]
struct Since {
    bytes: u64,
    /// Milliseconds the steps journaled took.
    step_ms: f64,
}

impl Journal {
    /// Starts a journal at `path` (replacing any file there) for `host`'s world.
    pub fn create(path: &Path, world: &str, host: &Hosted, opts: &HostOptions) -> Result<Journal> {
        let file = File::create(path)
            .with_context(|| format!("cannot create the journal {}", path.display()))?;
        let mut journal = Journal::appending(file, path, 0, opts.checkpoints, None);
        let header = Header::of(world, host, opts);
        journal.write(
            &serde_json::to_string(&header).expect("headers serialise"),
            false,
        )?;
        Ok(journal)
    }

    /// A journal appending to `file` (at `path`, `len` bytes of whole lines), starting
    /// from `checkpoint` if it names one.
    fn appending(
        file: File,
        path: &Path,
        len: u64,
        policy: Checkpoints,
        checkpoint: Option<String>,
    ) -> Journal {
        Journal {
            out: file,
            path: path.to_path_buf(),
            len,
            cut: false,
            owed: String::new(),
            max_owed: MAX_OWED_BYTES,
            stopped: false,
            policy,
            since: Since::default(),
            checkpoint,
            pending: None,
        }
    }

    /// Writes `line` after any owed ones. On a failure nothing of it stays on disk; the
    /// line is then owed if `owed` (what happened anyway), or dropped.
    fn write(&mut self, line: &str, owed: bool) -> Result<()> {
        if self.stopped {
            bail!(
                "the journal {} stopped at its last whole line while its disk was full (more than {} bytes of lines owed); resume it (--resume) to go on",
                self.path.display(),
                self.max_owed
            );
        }
        let line = signed(line);
        let mut text = std::mem::take(&mut self.owed);
        let before = text.len();
        text.push_str(&line);
        text.push('\n');
        match self.put(&text) {
            Ok(()) => {
                if before > 0 {
                    tracing::warn!(
                        journal = %self.path.display(),
                        bytes = before,
                        "the journal can be written again: the lines owed are written"
                    );
                }
                self.since.bytes += text.len() as u64;
                if let Some(pending) = self.pending.as_mut() {
                    pending.lines.extend(text.lines().map(str::to_string));
                }
                Ok(())
            }
            Err(e) => {
                if !owed {
                    text.truncate(before);
                }
                self.owed = text;
                if self.owed.len() > self.max_owed {
                    self.stopped = true;
                    self.owed = String::new();
                    tracing::error!(
                        journal = %self.path.display(),
                        "the journal stops at its last whole line: its disk has been full for longer than the {} bytes of lines it keeps owed; it resumes to there, and every command is refused until a restart with --resume",
                        self.max_owed
                    );
                }
                Err(e).with_context(|| format!("cannot write the journal {}", self.path.display()))
            }
        }
    }

    /// Appends `text` (whole lines) to the file, or nothing: what a failed write left is
    /// cut off, now or before the next write.
    fn put(&mut self, text: &str) -> std::io::Result<()> {
        if self.cut {
            self.out.set_len(self.len)?;
            self.out.seek(SeekFrom::Start(self.len))?;
            self.cut = false;
        }
        match self.out.write_all(text.as_bytes()) {
            Ok(()) => {
                self.len += text.len() as u64;
                Ok(())
            }
            Err(e) => {
                self.cut = true;
                let cut = self
                    .out
                    .set_len(self.len)
                    .and_then(|()| self.out.seek(SeekFrom::Start(self.len)));
                if cut.is_ok() {
                    self.cut = false;
                }
                Err(e)
            }
        }
    }

    /// Writes a line of what happened: owed if it cannot be written. Said once when
    /// the journal starts to owe, and once when it has paid (not every frame between).
    fn line(&mut self, line: &Line) {
        if self.stopped {
            return;
        }
        let text = serde_json::to_string(line).expect("journal lines serialise");
        let owing = !self.owed.is_empty();
        match self.write(&text, true) {
            Err(e) if !owing => tracing::error!(
                "{e:#}: the lines of what happens are kept in memory until it can, and commands refused"
            ),
            Err(_) | Ok(()) => {}
        }
    }

    /// Frame `frame` was stepped, in `step_ms` milliseconds (what its replay will take).
    pub fn stepped(&mut self, frame: u64, step_ms: f64) {
        self.since.step_ms += step_ms;
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
        self.write(
            &serde_json::to_string(&line).expect("journal lines serialise"),
            false,
        )
    }

    /// A journal every write to fails, as on a full disk: `/dev/full`.
    #[cfg(test)]
    pub(super) fn full() -> Journal {
        let path = PathBuf::from("/dev/full");
        let file = std::fs::OpenOptions::new()
            .write(true)
            .open(&path)
            .expect("/dev/full");
        Journal::appending(file, &path, 0, Checkpoints::default(), None)
    }

    /// The reply of the command [`Journal::before`] wrote last, if it had an id.
    pub fn replied(&mut self, reply: &Reply) {
        if reply.id.is_some() {
            // The bodies a `bodies` reply reports and the hashes of `hashes` are the
            // world's: a replay makes them again, and the journal does not grow by them.
            let replied = Reply {
                ok: reply.ok,
                frame: reply.frame,
                ids: reply.ids.clone(),
                error: reply.error.clone(),
                id: reply.id.clone(),
                hash: reply.hash.clone(),
                ..Reply::default()
            };
            self.line(&Line::Replied { replied });
        }
    }
}

mod checkpoint;
mod files;
mod resume;
pub use checkpoint::{remove_strays, CheckpointRef, Checkpoints};
pub use resume::{resume, Resumed};

#[cfg(test)]
mod fuzz;
#[cfg(test)]
mod tests;
