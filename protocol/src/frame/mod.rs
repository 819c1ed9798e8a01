//! The binary frame: one per step on `ricochet/<world>/frame`, and the statics snapshot.
//!
//! In (encoder): views of a world's bodies and particles, step by step. Out: bytes. In
//! (decoder): bytes from anyone. Out: what a receiver knows of the world, or a refusal
//! that leaves it as it was. Files: `wire` (varints, the bounds-checked reader),
//! `records` (the delta tracking both sides share), `encode`, `decode`.
//!
//! A frame carries what changed since the previous frame; every `keyframe_interval`
//! frames (and after a reset) a key frame carries everything, so a receiver that joins
//! late or misses a frame is whole again at the next key frame. Static bodies are never in
//! frames: they are in the snapshot, fetched with a query and re-published when they
//! change.
//!
//! # Layout, version 2 (all numbers little-endian)
//!
//! ```text
//! magic      3 bytes  "RCF"
//! version    u8       2
//! kind       u8       0 delta, 1 key frame, 2 statics snapshot
//! frame      u64      steps taken
//! time       f64      simulated seconds
//! stats      12 x 4 bytes: step_ms f32, contacts u32, relaxation_iterations u32,
//!                     deepest_penetration f32, kinetic_energy f32, particle_contacts u32,
//!                     overruns u32, dynamic_bodies u32, particles u32, emitters u32,
//!                     energy_change f32, residual f32 (version 2)
//! emitters   varint n, then n x (x f32, y f32, remaining varint)
//! bodies     varint n, then n body records, in increasing key order
//! particles  varint n, then n particle records, in increasing id order
//! ```
//!
//! A varint is LEB128 (7 bits a byte, low first); a signed varint is zigzag-encoded first.
//! Positions are sent as integers of [`POS_QUANTUM`] (bodies) or [`PARTICLE_QUANTUM`]
//! (particles), velocities of [`VEL_QUANTUM`]; a record sends the change of those integers
//! since the last record of the same body, so a body or particle that did not move by a
//! quantum costs nothing.
//!
//! Body record: `key gap` varint (key minus the previous record's key, the first from 0),
//! `flags` u8, then by flag:
//! - `NEW` (0x01): shape u8 (0 rect, 1 circle), width f32, height f32 (a circle: 2r, 2r),
//!   id and group (varint length + UTF-8), position and velocity as absolute signed varints;
//! - `POS` (0x02): position change, two signed varints;
//! - `VEL` (0x04): velocity change, two signed varints;
//! - `COLLIDED` (0x08): the value of the collided flag (every record carries it);
//! - `REMOVED` (0x10): the body is gone; nothing follows.
//!
//! Particle record: `id gap` varint, `flags` u8, then by flag:
//! - `NEW` (0x01): position as absolute signed varints, start colour and final colour as
//!   4 + 4 bytes (value x 63.75, so 0 to 4), initial life f32, life f32, size f32,
//!   size factor f32. A particle's colour and size at a later frame follow from these (as
//!   the engine computes them) and are never sent again;
//! - `POS` (0x02): position change, two signed varints;
//! - `REMOVED` (0x10): the particle expired.

use std::fmt;

use glam::Vec4;
use ricochet_engine::particles::{color_after, size_after};

mod decode;
mod encode;
mod records;
#[cfg(test)]
mod tests;
mod wire;

pub use decode::{peek_header, FrameDecoder, Header};
pub use encode::{encode_statics, FrameEncoder};

/// Positions of bodies travel as integers of this many units (1/1024).
pub const POS_QUANTUM: f64 = 1.0 / 1024.0;
/// Velocities of bodies travel as integers of this many units per second (1/256).
pub const VEL_QUANTUM: f64 = 1.0 / 256.0;
/// Positions of particles travel as integers of this many units (1/256).
pub const PARTICLE_QUANTUM: f64 = 1.0 / 256.0;
/// A colour component travels as `round(c * COLOR_SCALE)` in a byte: 0 to 4.
pub const COLOR_SCALE: f32 = 63.75;

pub const MAGIC: &[u8; 3] = b"RCF";
pub const KIND_DELTA: u8 = 0;
pub const KIND_KEY: u8 = 1;
pub const KIND_STATICS: u8 = 2;

const NEW: u8 = 0x01;
const POS: u8 = 0x02;
const VEL: u8 = 0x04;
const COLLIDED: u8 = 0x08;
const REMOVED: u8 = 0x10;

/// Header bytes before the sections.
pub const HEADER_BYTES: usize = 3 + 1 + 1 + 8 + 8 + 48;

/// The figures of the step that produced a frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FrameStats {
    /// Wall time the step took, in milliseconds.
    pub step_ms: f32,
    pub contacts: u32,
    pub relaxation_iterations: u32,
    pub deepest_penetration: f32,
    pub kinetic_energy: f32,
    pub particle_contacts: u32,
    /// Steps the server has run late since it started (its clock fell behind real time).
    pub overruns: u32,
    pub dynamic_bodies: u32,
    pub particles: u32,
    pub emitters: u32,
    /// The bodies' mechanical energy change over the step (kinetic plus potential, actions
    /// between steps included): an accuracy estimate that needs no reference.
    pub energy_change: f32,
    /// What the solver's last pass still corrected, as a distance (units): near 0, the
    /// passes converged.
    pub residual: f32,
}

/// A body as the encoder reads it from the world.
#[derive(Clone, Copy, Debug)]
pub struct BodyIn<'a> {
    pub key: u32,
    pub id: &'a str,
    pub group: &'a str,
    pub circle: bool,
    /// Width and height (a circle: its diameter twice).
    pub size: [f64; 2],
    pub pos: [f64; 2],
    pub vel: [f64; 2],
    pub collided: bool,
}

/// The world's particle arrays as the encoder reads them (all of the same length).
#[derive(Clone, Copy, Debug, Default)]
pub struct ParticlesIn<'a> {
    pub id: &'a [u32],
    pub x: &'a [f32],
    pub y: &'a [f32],
    pub life: &'a [f32],
    pub initial_life: &'a [f32],
    pub size: &'a [f32],
    pub size_delta: &'a [f32],
    /// Start colour.
    pub color: &'a [[f32; 4]],
    /// Colour change per update.
    pub color_delta: &'a [[f32; 4]],
}

/// An emitter: where, and how many particles it still has to release.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EmitterIn {
    pub x: f32,
    pub y: f32,
    pub remaining: u32,
}

/// A body as a receiver knows it.
#[derive(Clone, Debug, PartialEq)]
pub struct Body {
    pub key: u32,
    pub id: String,
    pub group: String,
    pub circle: bool,
    pub size: [f32; 2],
    pub qpos: [i64; 2],
    pub qvel: [i64; 2],
    pub collided: bool,
}

impl Body {
    pub fn pos(&self) -> [f64; 2] {
        [
            self.qpos[0] as f64 * POS_QUANTUM,
            self.qpos[1] as f64 * POS_QUANTUM,
        ]
    }

    pub fn vel(&self) -> [f64; 2] {
        [
            self.qvel[0] as f64 * VEL_QUANTUM,
            self.qvel[1] as f64 * VEL_QUANTUM,
        ]
    }
}

/// A particle as a receiver knows it.
#[derive(Clone, Debug, PartialEq)]
pub struct Particle {
    pub id: u32,
    pub qpos: [i64; 2],
    pub color0: [u8; 4],
    pub color1: [u8; 4],
    pub initial_life: f32,
    /// Life at `record_frame`.
    pub life: f32,
    /// Size at `record_frame`.
    pub size: f32,
    pub size_delta: f32,
    /// The frame of its NEW record.
    pub record_frame: u64,
}

impl Particle {
    pub fn pos(&self) -> [f32; 2] {
        [
            (self.qpos[0] as f64 * PARTICLE_QUANTUM) as f32,
            (self.qpos[1] as f64 * PARTICLE_QUANTUM) as f32,
        ]
    }

    /// Colour at `frame`, by the engine's model ([`color_after`]) from the colours of the
    /// birth record: the start colour plus its change per update, times the age.
    pub fn color_at(&self, frame: u64) -> [f32; 4] {
        let elapsed = frame.saturating_sub(self.record_frame) as f32;
        let age = self.initial_life - (self.life - elapsed);
        let start = Vec4::from(self.color0.map(|c| c as f32 / COLOR_SCALE));
        let end = Vec4::from(self.color1.map(|c| c as f32 / COLOR_SCALE));
        let delta = if self.initial_life != 0.0 {
            (end - start) / self.initial_life
        } else {
            Vec4::ZERO
        };
        color_after(start, delta, age).to_array()
    }

    /// Size at `frame`, by the engine's model ([`size_after`]).
    pub fn size_at(&self, frame: u64) -> f32 {
        let elapsed = frame.saturating_sub(self.record_frame).min(i32::MAX as u64) as i32;
        size_after(self.size, self.size_delta, elapsed)
    }

    /// The birth record restated as of `frame` (a resync key frame sends this).
    pub fn as_of(&self, frame: u64) -> Particle {
        let elapsed = frame.saturating_sub(self.record_frame);
        Particle {
            life: self.life - elapsed as f32,
            size: self.size_at(frame),
            record_frame: frame,
            ..self.clone()
        }
    }
}

// ---- decoding errors ---------------------------------------------------------------

/// Why a payload could not be read.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum DecodeError {
    /// Not a Ricochet frame, or cut short, or inconsistent.
    Malformed(String),
    /// A frame of another protocol version.
    Version(u8),
    /// A delta frame that does not follow the last frame applied: wait for a key frame.
    OutOfSync { expected: u64, got: u64 },
    /// A frame not newer than the state already held (after a resync); ignored.
    Stale { frame: u64 },
}

impl fmt::Display for DecodeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DecodeError::Malformed(why) => write!(f, "malformed frame: {why}"),
            DecodeError::Version(v) => write!(
                f,
                "frame version {v}, this reader knows {}",
                crate::PROTOCOL_VERSION
            ),
            DecodeError::OutOfSync { expected, got } => write!(
                f,
                "delta frame {got} does not follow frame {expected}; waiting for a key frame"
            ),
            DecodeError::Stale { frame } => write!(f, "frame {frame} is older than the state held"),
        }
    }
}

impl std::error::Error for DecodeError {}
