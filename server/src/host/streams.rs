//! The frame streams: every step's frame, and reduced-rate tiers for viewers whose link
//! cannot carry every step: a tier carries one frame in `every` steps and one particle in
//! `every` (by id), every body (births and expiries, most of a fire's bytes, would not
//! get fewer with fewer frames alone). Each stream has its own
//! encoder, so its deltas, and its receivers' prediction, follow its own frames; zenoh
//! fans each out to all its subscribers, so a frame is encoded once per stream, whatever
//! the number of viewers.
//!
//! In: the world after each step. Out: the frames due (stream by stream), the state of a
//! stream for its late joiners, and each stream's bytes a second. Every stream is encoded
//! whether anyone watches it or not, so its rate is measured, not guessed (births and
//! expiries cost the same in every stream: a tier is not its stride times cheaper); a
//! stream nobody watches is not published, and when it is watched again its next frame is
//! a key frame. A tier's key frames come `every` times further apart in its frames (so
//! `every`² times further apart in time): a receiver of a tier that lost a frame waits
//! that long for the next.

use std::time::{Duration, Instant};

use crate::wire;
use ricochet_engine::world::World;
use ricochet_protocol::command::StreamRate;
use ricochet_protocol::frame::FrameEncoder;
use ricochet_protocol::keys::STREAMS;

/// How many whole seconds a stream's reported rate is the peak of: a link must carry a
/// stream's bursts (a fire's births come in bursts), not only its mean.
const RATE_SECONDS: usize = 5;

/// The bytes a stream sent in the current second, and in the last whole ones.
#[derive(Clone, Debug)]
struct Rate {
    since: Instant,
    bytes: u64,
    /// The last whole seconds' rates, newest last.
    seconds: Vec<f64>,
}

impl Rate {
    fn add(&mut self, bytes: u64, now: Instant) {
        let elapsed = now.duration_since(self.since);
        if elapsed >= Duration::from_secs(1) {
            if self.seconds.len() == RATE_SECONDS {
                self.seconds.remove(0);
            }
            self.seconds.push(self.bytes as f64 / elapsed.as_secs_f64());
            self.bytes = 0;
            self.since = now;
        }
        self.bytes += bytes;
    }

    /// The highest rate of the last whole seconds.
    fn peak(&self) -> f64 {
        self.seconds.iter().copied().fold(0.0, f64::max)
    }
}

/// One stream.
pub struct Stream {
    /// Steps a frame of the stream stands for.
    pub every: u64,
    encoder: FrameEncoder,
    /// Whether anyone subscribes.
    pub watched: bool,
    rate: Rate,
}

/// Every stream of a world.
pub struct Streams {
    pub streams: Vec<Stream>,
}

impl Streams {
    pub fn new(keyframe_interval: u64) -> Self {
        let now = Instant::now();
        Streams {
            streams: STREAMS
                .iter()
                .enumerate()
                .map(|(i, &every)| Stream {
                    every,
                    // A tier's key frames (all of the world at once) are what a slow link
                    // takes longest to carry: one in `every` times as many frames. The
                    // streams' key frames fall in different steps (a key frame of a busy
                    // world takes ten times a delta to encode): stream `i` of `n` at
                    // `i / n` of the full stream's interval past its key frames.
                    encoder: FrameEncoder::new(keyframe_interval.saturating_mul(every))
                        .with_key_schedule(
                            every,
                            (i as u64 * keyframe_interval / STREAMS.len() as u64) / every,
                        ),
                    watched: every == 1,
                    rate: Rate {
                        since: now,
                        bytes: 0,
                        seconds: Vec::with_capacity(RATE_SECONDS),
                    },
                })
                .collect(),
        }
    }

    /// Every stream's next frame is a key frame (a new world).
    pub fn force_key_frame(&mut self) {
        for s in &mut self.streams {
            s.encoder.force_key_frame();
        }
    }

    /// Says whether stream `i` (in [`STREAMS`] order) has subscribers; one that had none
    /// is brought back with a key frame.
    pub fn set_watched(&mut self, i: usize, watched: bool) {
        if let Some(s) = self.streams.get_mut(i) {
            if watched && !s.watched {
                s.encoder.force_key_frame();
            }
            s.watched = watched;
        }
    }

    /// The frames due after the world's last step, as (stream index, bytes): each stream's
    /// on the steps it carries, to publish where it is watched.
    pub fn encode(&mut self, world: &World, step_ms: f32, overruns: u32) -> Vec<(usize, Vec<u8>)> {
        let now = Instant::now();
        let frame = world.frame();
        let mut out = Vec::new();
        // The world read once for every stream due now.
        let mut source = None;
        for (i, s) in self.streams.iter_mut().enumerate() {
            if !frame.is_multiple_of(s.every) {
                continue;
            }
            let source =
                source.get_or_insert_with(|| wire::FrameSource::of(world, step_ms, overruns));
            let bytes = source.encode(&mut s.encoder, s.every as u32);
            s.rate.add(bytes.len() as u64, now);
            if s.watched {
                out.push((i, bytes));
            }
        }
        out
    }

    /// A key frame of what the receivers of the stream of `every` hold (`None` before its
    /// first frame, or for no such stream).
    pub fn resync(&self, every: u64) -> Option<Vec<u8>> {
        self.streams
            .iter()
            .find(|s| s.every == every)?
            .encoder
            .resync_frame()
    }

    /// Each stream's bytes a second: the peak of the last whole seconds.
    pub fn rates(&self) -> Vec<StreamRate> {
        self.streams
            .iter()
            .map(|s| StreamRate {
                every: s.every,
                bytes_per_second: s.rate.peak(),
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ricochet_protocol::frame::{peek_header, KIND_KEY};

    #[test]
    fn no_two_streams_make_their_periodic_key_frames_in_the_same_step() {
        let scene = "[[body]]\nid = \"box\"\nshape = \"rect\"\nsize = [1, 1]\npos = [0, 5]\n";
        let mut world =
            ricochet_engine::scene::parse(scene, std::path::Path::new("box.toml"), &[]).unwrap();
        let mut streams = Streams::new(60);
        for s in &mut streams.streams {
            s.watched = true;
        }
        let mut keys = vec![0u64; STREAMS.len()];
        // Two of the slowest tier's intervals (8 frames of 60 x 8 steps apart).
        for _ in 0..2 * 60 * 8 * 8 + 1 {
            let frames = streams.encode(&world, 0.0, 0);
            let keyed: Vec<usize> = frames
                .iter()
                .filter(|(_, f)| peek_header(f).unwrap().kind == KIND_KEY)
                .map(|(i, _)| *i)
                .collect();
            if world.frame() > 0 {
                assert!(keyed.len() <= 1, "frame {}: {keyed:?}", world.frame());
            }
            for i in keyed {
                keys[i] += 1;
            }
            world.step();
        }
        // Each stream keeps its interval: 60 of its frames.
        for (i, &every) in STREAMS.iter().enumerate() {
            let periodic = 2 * 60 * 8 * 8 / (60 * every * every);
            assert_eq!(keys[i], 1 + periodic, "stream of one in {every}");
        }
    }
}
