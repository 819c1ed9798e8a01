//! Checkpoints: a journal's bound. When the journal has grown past a size, or replaying
//! it would take longer than a bound, the host writes the world as it is (with what the
//! host adds to it: the scene, the `step` count, the answers it remembers) to a file
//! beside the journal, then starts the journal again from that checkpoint. A resume
//! restores the checkpoint and replays only what followed, so a run of any length resumes
//! in about the bound's time and its files hold about the bound's bytes plus the world.
//!
//! The switch is safe at any kill: the checkpoint is written to a temporary file, synced
//! and renamed into place; then the new journal (its header and a line naming the
//! checkpoint with its size and CRC-32) is written, synced and renamed over the old one;
//! only then is the previous checkpoint removed. A kill leaves either the old journal
//! with its checkpoint or the new one with its own.
//!
//! A checkpoint file: `RCJ`, a version byte, then the host's state in CBOR (the world as
//! [`World::save`] writes it).

use std::fs::{File, OpenOptions};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{anyhow, bail, Context, Result};
use ricochet_engine::world::World;
use serde::{Deserialize, Serialize};

use super::super::answered::{Answered, Remembered};
use super::super::hosted::Hosted;
use super::super::travel::Travel;
use super::super::HostOptions;
use super::{signed, Header, Journal, Line};

const MAGIC: &[u8; 3] = b"RCJ";
const FILE_VERSION: u8 = 1;

/// When the host takes a checkpoint (`run --journal-bytes`, `--checkpoint-after-ms`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Checkpoints {
    /// The journal's bytes after which a checkpoint is taken.
    pub journal_bytes: u64,
    /// Milliseconds of stepping since the last checkpoint after which one is taken: what
    /// a resume replays, about.
    pub replay_ms: f64,
}

impl Default for Checkpoints {
    fn default() -> Self {
        Checkpoints {
            journal_bytes: 16 << 20,
            replay_ms: 250.0,
        }
    }
}

/// The journal's line naming its checkpoint: `{"checkpoint": {...}}`, right after the
/// header.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CheckpointRef {
    /// The file's name, in the journal's directory (a name, never a path).
    pub file: String,
    /// The frame the world was at.
    pub frame: u64,
    pub bytes: u64,
    /// CRC-32 of the file, 8 hexadecimal digits.
    pub crc: String,
}

/// What a checkpoint holds.
#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct State {
    scene_name: PathBuf,
    scene_text: String,
    paused: bool,
    steps_run: u64,
    generation: u64,
    accuracy: Option<String>,
    answers: Vec<Remembered>,
    #[serde(with = "serde_bytes")]
    pub(super) world: Vec<u8>,
    /// The host's saves, history and frame hashes: a resumed server restores and rewinds
    /// as the live one did.
    #[serde(default)]
    travel: Option<Travel>,
}

/// A restored checkpoint: the host and the answers it remembered (ages as at the
/// checkpoint).
pub struct Restored {
    pub host: Hosted,
    pub answers: Vec<Remembered>,
    pub frame: u64,
}

/// Writes `bytes` to `path` through a temporary file, synced, then renamed into place.
fn write_whole(path: &Path, bytes: &[u8]) -> Result<()> {
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(".tmp");
    let tmp = PathBuf::from(tmp);
    let mut file =
        File::create(&tmp).with_context(|| format!("cannot create {}", tmp.display()))?;
    if let Err(e) = file.write_all(bytes).and_then(|()| file.sync_all()) {
        // A full disk: what was written in part goes, not to hold the room it took.
        drop(file);
        let _ = std::fs::remove_file(&tmp);
        return Err(e).with_context(|| format!("cannot write {}", tmp.display()));
    }
    std::fs::rename(&tmp, path)
        .with_context(|| format!("cannot rename {} to {}", tmp.display(), path.display()))
}

/// A checkpoint being written on its own thread, and the journal's lines since its frame
/// (the new journal's, once the checkpoint is on disk).
pub(super) struct Pending {
    writing: std::thread::JoinHandle<Result<CheckpointRef>>,
    /// The new journal's header.
    header: String,
    /// The lines written since the checkpoint's frame, signed.
    pub(super) lines: Vec<String>,
}

impl Journal {
    /// Whether the journal has grown past its bound (in bytes or in replay time) and no
    /// checkpoint is being written. Never while lines are owed: they happened before the
    /// checkpoint's frame, and belong to the journal it would replace.
    pub fn checkpoint_due(&self) -> bool {
        self.pending.is_none()
            && self.owed.is_empty()
            && (self.since.bytes >= self.policy.journal_bytes
                || self.since.step_ms >= self.policy.replay_ms)
    }

    /// Starts a checkpoint of `host` (and the answers it remembers): the world is copied
    /// here, and written on a thread of its own, so the step waits for a copy, not for the
    /// disk ([`Journal::poll`] switches the journal once the file is whole). The journal
    /// goes on as it is meanwhile; on an error nothing is lost, and the next attempt waits
    /// for the bound to be passed again.
    pub fn checkpoint(
        &mut self,
        host: &Hosted,
        answered: &Answered,
        world: &str,
        opts: &HostOptions,
    ) {
        if self.pending.is_some() {
            return;
        }
        let frame = host.world.frame();
        let dir = self
            .path
            .parent()
            .map(Path::to_path_buf)
            .unwrap_or_default();
        let stem = self
            .path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|| "journal".into());
        let file = format!("{stem}.{frame}.checkpoint");
        let copy = host.world.clone();
        let (scene_name, scene_text) = (host.source.name.clone(), host.source.text.clone());
        let (paused, steps_run, generation) = (
            host.stepping.paused,
            host.stepping.steps_run,
            host.wire.generation,
        );
        let accuracy = host.accuracy.clone();
        let travel = host.travel.clone();
        let answers = answered.export(Instant::now());
        let writing = std::thread::Builder::new()
            .name("checkpoint".into())
            .spawn(move || {
                let state = State {
                    scene_name,
                    scene_text,
                    paused,
                    steps_run,
                    generation,
                    accuracy,
                    answers,
                    world: copy.save(),
                    travel: Some(travel),
                };
                drop(copy);
                let mut bytes = MAGIC.to_vec();
                bytes.push(FILE_VERSION);
                ciborium::into_writer(&state, &mut bytes)
                    .expect("a checkpoint serialises into memory");
                write_whole(&dir.join(&file), &bytes)?;
                Ok(CheckpointRef {
                    file,
                    frame,
                    bytes: bytes.len() as u64,
                    crc: format!("{:08x}", crc32fast::hash(&bytes)),
                })
            });
        match writing {
            Ok(writing) => {
                self.pending = Some(Pending {
                    writing,
                    header: serde_json::to_string(&Header::of(world, host, opts))
                        .expect("headers serialise"),
                    lines: Vec::new(),
                });
                self.since = Default::default();
            }
            Err(e) => {
                tracing::error!("checkpoint not started: {e}");
                self.since = Default::default();
            }
        }
    }

    /// A checkpoint of `host` taken now and waited for (the last one, as the server
    /// stops): a checkpoint being written is finished first. The checkpoint's file, once
    /// the journal starts from it.
    pub fn checkpoint_now(
        &mut self,
        host: &Hosted,
        answered: &Answered,
        world: &str,
        opts: &HostOptions,
    ) -> Result<PathBuf> {
        self.poll(true);
        self.checkpoint(host, answered, world, opts);
        self.poll(true);
        let frame = host.world.frame();
        match &self.checkpoint {
            Some(file) if file.ends_with(&format!(".{frame}.checkpoint")) => Ok(self
                .path
                .parent()
                .map(Path::to_path_buf)
                .unwrap_or_default()
                .join(file)),
            _ => bail!(
                "the checkpoint of frame {frame} was not taken (the journal {} goes on whole)",
                self.path.display()
            ),
        }
    }

    /// Once a checkpoint being written is whole on disk: the journal starts again from it
    /// (its header, the line naming it, and the lines written since its frame), and the
    /// checkpoint before it is removed. Does nothing while it is being written, unless
    /// `wait`.
    pub fn poll(&mut self, wait: bool) {
        if !self
            .pending
            .as_ref()
            .is_some_and(|p| wait || p.writing.is_finished())
        {
            return;
        }
        let pending = self.pending.take().expect("a checkpoint pending");
        let written = pending
            .writing
            .join()
            .unwrap_or_else(|_| Err(anyhow!("the checkpoint's thread panicked")));
        let result =
            written.and_then(|reference| self.switch(reference, &pending.header, &pending.lines));
        if let Err(e) = result {
            tracing::error!("checkpoint not taken: {e:#}");
            // The journal went on whole; the next attempt waits for the bound again.
            self.since = Default::default();
        }
    }

    /// Starts the journal again from the checkpoint `reference` names.
    fn switch(&mut self, reference: CheckpointRef, header: &str, lines: &[String]) -> Result<()> {
        let dir = self
            .path
            .parent()
            .map(Path::to_path_buf)
            .unwrap_or_default();
        let file = reference.file.clone();
        let frame = reference.frame;
        let mut text = signed(header) + "\n";
        text += &(signed(
            &serde_json::to_string(&Line::Checkpoint {
                checkpoint: reference,
            })
            .expect("lines serialise"),
        ) + "\n");
        for line in lines {
            text += line;
            text.push('\n');
        }
        write_whole(&self.path, text.as_bytes())?;
        let appended = OpenOptions::new()
            .append(true)
            .open(&self.path)
            .with_context(|| format!("cannot append to the journal {}", self.path.display()))?;
        self.out = appended;
        self.len = text.len() as u64;
        self.cut = false;
        if let Some(old) = self.checkpoint.replace(file.clone()) {
            if old != file {
                let _ = std::fs::remove_file(dir.join(old));
            }
        }
        self.since.bytes = text.len() as u64;
        tracing::info!(
            journal = %self.path.display(),
            checkpoint = %dir.join(&file).display(),
            frame,
            "checkpoint taken; the journal starts from it"
        );
        Ok(())
    }
}

impl Drop for Journal {
    /// A checkpoint being written is finished and switched to (a server stopping after
    /// `--max-frames` leaves no stray file).
    fn drop(&mut self) {
        self.poll(true);
    }
}

/// Removes the checkpoints of the journal at `journal` other than `keep` (and temporary
/// files of unfinished ones): what a kill in the middle of a switch leaves.
pub fn remove_strays(journal: &Path, keep: Option<&str>) {
    let (Some(dir), Some(stem)) = (journal.parent(), journal.file_name()) else {
        return;
    };
    let dir = if dir.as_os_str().is_empty() {
        Path::new(".")
    } else {
        dir
    };
    let prefix = format!("{}.", stem.to_string_lossy());
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        let Some(rest) = name.strip_prefix(&prefix) else {
            continue;
        };
        let frame = rest
            .strip_suffix(".tmp")
            .unwrap_or(rest)
            .strip_suffix(".checkpoint");
        let ours = frame.is_some_and(|f| !f.is_empty() && f.bytes().all(|b| b.is_ascii_digit()));
        if ours && Some(name.as_str()) != keep {
            let _ = std::fs::remove_file(entry.path());
        }
    }
}

/// The largest checkpoint a world within `limits` can make, about: a generous size per
/// body (its solver data, id, contacts and grid box) and per particle, and room for the
/// scene's text and the answers a host remembers. A checkpoint is read at most this far.
pub fn max_bytes(limits: &ricochet_engine::world::Limits) -> u64 {
    (64 << 20) + u64::from(limits.bodies) * 4096 + u64::from(limits.particles) * 256
}

/// Reads the checkpoint a journal at `journal` names, checked against its line, and
/// restores the host it holds under `opts` (its limits, not the checkpoint's).
pub fn restore(journal: &Path, reference: &CheckpointRef, opts: &HostOptions) -> Result<Restored> {
    let name = &reference.file;
    let plain = !name.is_empty()
        && name != "."
        && name != ".."
        && !name.contains(['/', '\\'])
        && Path::new(name)
            .file_name()
            .is_some_and(|n| n == name.as_str());
    if !plain {
        bail!(
            "the checkpoint must be a file name in the journal's directory, not `{}`",
            ricochet_engine::world::short(name, 64)
        );
    }
    let dir = journal.parent().map(Path::to_path_buf).unwrap_or_default();
    let path = dir.join(name);
    let bytes = super::files::read_bounded(
        &path,
        "checkpoint",
        reference.bytes.min(max_bytes(&opts.limits)),
    )?;
    if bytes.len() as u64 != reference.bytes
        || format!("{:08x}", crc32fast::hash(&bytes)) != reference.crc
    {
        bail!(
            "the checkpoint {} is not the one the journal names (its size or checksum differs: changed or damaged)",
            path.display()
        );
    }
    if bytes.len() < 4 || &bytes[..3] != MAGIC || bytes[3] != FILE_VERSION {
        bail!(
            "{}: not a checkpoint of version {FILE_VERSION}",
            path.display()
        );
    }
    let state: State = ciborium::from_reader(&bytes[4..]).map_err(|e| {
        anyhow!(
            "{}: unreadable: {}",
            path.display(),
            ricochet_engine::world::short(&e.to_string(), 200)
        )
    })?;
    let world = World::restore(&state.world, opts.limits.clone())
        .with_context(|| format!("the checkpoint {}", path.display()))?;
    if world.frame() != reference.frame {
        bail!(
            "the checkpoint {} holds frame {}, the journal says {}",
            path.display(),
            world.frame(),
            reference.frame
        );
    }
    let mut host = Hosted::with_world(world, state.scene_text, state.scene_name, opts);
    host.stepping.paused = state.paused;
    host.stepping.steps_run = state.steps_run;
    host.wire.generation = state.generation;
    host.accuracy = state.accuracy;
    if let Some(travel) = state.travel {
        host.travel = travel.with_limits(opts.travel);
    }
    Ok(Restored {
        host,
        answers: state.answers,
        frame: reference.frame,
    })
}

#[cfg(test)]
#[path = "checkpoint_tests.rs"]
mod tests;
