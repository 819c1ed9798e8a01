//! What leaves the stepping thread each frame: the frames of every watched stream and the
//! statics when due, handed to the frames thread ([`FramesOut`]), and the dump's line.
//!
//! Every frame leaves with `Drop` congestion control: a slow subscriber loses frames (and
//! resyncs from the next key frame or the state query), it never holds the clock.

use std::io::Write;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use crate::wire;
use anyhow::{Context, Result};

use super::frames_out::FramesOut;
use super::hosted::Hosted;

/// The stepping thread's side of publishing.
pub(super) struct Publisher {
    out: FramesOut,
    /// The index of the snapshot's publisher in `out`.
    snapshot: usize,
    /// Every published frame as a dump line (`run --dump`).
    dump: Option<std::io::BufWriter<std::fs::File>>,
    last_drop_warning: Option<Instant>,
}

impl Publisher {
    pub fn new(out: FramesOut, snapshot: usize, dump: Option<&std::path::Path>) -> Result<Self> {
        let dump = match dump {
            Some(path) => Some(std::io::BufWriter::new(
                std::fs::File::create(path)
                    .with_context(|| format!("cannot create dump {}", path.display()))?,
            )),
            None => None,
        };
        Ok(Publisher {
            out,
            snapshot,
            dump,
            last_drop_warning: None,
        })
    }

    /// Publishes the statics snapshot if it is due ([`Hosted::snapshot_due`]).
    pub fn statics(&mut self, h: &mut Hosted) {
        if let Some(snapshot) = h.snapshot_due(Instant::now()) {
            if !self
                .out
                .send(self.snapshot, h.world.frame() as u32, snapshot)
            {
                tracing::warn!("the snapshot of frame {} was dropped", h.world.frame());
            }
        }
    }

    /// Publishes the world's current frame on every watched stream (and the statics if
    /// due), and writes it to the dump.
    pub fn frame(&mut self, h: &mut Hosted) {
        h.stepping.fresh = false;
        self.statics(h);
        // A stream is published only while someone subscribes to it (the frames thread
        // asks zenoh twice a second); a stream watched again starts with a key frame.
        for i in 0..h.wire.streams.streams.len() {
            h.wire.streams.set_watched(i, self.out.watched(i));
        }
        for (i, bytes) in h.encode_frames() {
            // The source names this session, which holds the world's token: clients take
            // frames from it only.
            if !self.out.send(i, h.world.frame() as u32, bytes)
                && self
                    .last_drop_warning
                    .is_none_or(|at| at.elapsed() >= Duration::from_secs(1))
            {
                self.last_drop_warning = Some(Instant::now());
                tracing::warn!(
                    frame = h.world.frame(),
                    dropped = self.out.dropped.load(Ordering::Relaxed),
                    "frames wait longer to leave than the queue holds: dropped"
                );
            }
        }
        if let Some(out) = self.dump.as_mut() {
            let written = wire::write_frame(out, &h.world).and_then(|()| out.flush());
            if let Err(e) = written {
                tracing::warn!("writing frame {} to the dump failed: {e}", h.world.frame());
            }
        }
    }
}
