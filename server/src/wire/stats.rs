//! What a run's frames cost on the wire (`simulate --wire-stats`, and the lab's wire
//! report): every frame encoded exactly as `run` sends it, and decoded as a viewer does.

use std::time::Instant;

use crate::wire;
use ricochet_engine::world::World;
use ricochet_protocol::frame::{FrameDecoder, FrameEncoder, HEADER_BYTES, KIND_KEY};

/// The bytes of a run's frames, frame by frame.
#[derive(Clone, Debug)]
pub struct WireStats {
    encoder: FrameEncoder,
    /// A receiver of the frames, to time what decoding them costs.
    decoder: FrameDecoder,
    /// Seconds each frame took to encode (from the world, as `run` does), and to decode.
    pub encode_s: Vec<f64>,
    pub decode_s: Vec<f64>,
    pub statics_bytes: usize,
    pub frames: u64,
    pub bytes: u64,
    /// Key frames and their bytes.
    pub key_frames: (u64, u64),
    /// Dynamic bodies and particles summed over the frames.
    pub body_frames: u64,
    pub particle_frames: u64,
}

impl WireStats {
    /// Starts counting with the frame of `world` as it is (frame 0).
    pub fn new(world: &World, keyframe_interval: u64) -> Self {
        let mut w = WireStats {
            encoder: FrameEncoder::new(keyframe_interval),
            decoder: FrameDecoder::new(),
            encode_s: Vec::new(),
            decode_s: Vec::new(),
            statics_bytes: wire::statics_snapshot(world).len(),
            frames: 0,
            bytes: 0,
            key_frames: (0, 0),
            body_frames: 0,
            particle_frames: 0,
        };
        w.frame(world);
        w
    }

    /// Counts the frame of `world` after its last step.
    pub fn frame(&mut self, world: &World) {
        let began = Instant::now();
        let bytes = wire::encode_frame(&mut self.encoder, world, 0.0, 0);
        self.encode_s.push(began.elapsed().as_secs_f64());
        let began = Instant::now();
        let header = self.decoder.apply(&bytes).expect("own frames read back");
        self.decode_s.push(began.elapsed().as_secs_f64());
        self.frames += 1;
        self.bytes += bytes.len() as u64;
        if header.kind == KIND_KEY {
            self.key_frames.0 += 1;
            self.key_frames.1 += bytes.len() as u64;
        }
        self.body_frames += header.stats.dynamic_bodies as u64;
        self.particle_frames += header.stats.particles as u64;
    }

    pub fn bytes_per_frame(&self) -> f64 {
        per(self.bytes, self.frames)
    }

    pub fn key_frame_bytes(&self) -> f64 {
        per(self.key_frames.1, self.key_frames.0)
    }

    pub fn delta_frame_bytes(&self) -> f64 {
        per(
            self.bytes - self.key_frames.1,
            self.frames - self.key_frames.0,
        )
    }

    /// Bodies and particles a frame, on average.
    pub fn things_per_frame(&self) -> f64 {
        per(self.body_frames + self.particle_frames, self.frames)
    }

    /// Every byte of every frame, header included, per body or particle per frame.
    pub fn bytes_per_thing(&self) -> f64 {
        per(self.bytes, self.body_frames + self.particle_frames)
    }

    /// Mean and median microseconds a frame took to encode.
    pub fn encode_us(&self) -> (f64, f64) {
        mean_median_us(&self.encode_s)
    }

    /// Mean and median microseconds a frame took to decode.
    pub fn decode_us(&self) -> (f64, f64) {
        mean_median_us(&self.decode_s)
    }

    /// One line for `simulate --wire-stats`.
    pub fn summary(&self) -> String {
        format!(
            "wire: {} frames, {:.1} bytes/frame on average ({:.1} in key frames, {:.1} in delta \
             frames; {} of header each); statics snapshot {} bytes once; {:.1} dynamic bodies \
             and {:.1} particles a frame on average; {:.3} bytes per body-or-particle a frame, \
             headers and key frames included; {:.1} us to encode a frame, {:.1} to decode it \
             (means; medians {:.1} and {:.1})",
            self.frames,
            self.bytes_per_frame(),
            self.key_frame_bytes(),
            self.delta_frame_bytes(),
            HEADER_BYTES,
            self.statics_bytes,
            per(self.body_frames, self.frames),
            per(self.particle_frames, self.frames),
            self.bytes_per_thing(),
            self.encode_us().0,
            self.decode_us().0,
            self.encode_us().1,
            self.decode_us().1,
        )
    }
}

/// Mean and median of `seconds`, in microseconds.
fn mean_median_us(seconds: &[f64]) -> (f64, f64) {
    if seconds.is_empty() {
        return (0.0, 0.0);
    }
    let mut sorted = seconds.to_vec();
    sorted.sort_by(f64::total_cmp);
    let mean = seconds.iter().sum::<f64>() / seconds.len() as f64;
    (mean * 1e6, sorted[sorted.len() / 2] * 1e6)
}

pub fn per(num: u64, den: u64) -> f64 {
    if den > 0 {
        num as f64 / den as f64
    } else {
        0.0
    }
}
