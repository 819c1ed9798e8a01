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
//! # Layout, version 5 (all numbers little-endian)
//!
//! ```text
//! magic      3 bytes  "RCF"
//! version    u8       5
//! kind       u8       0 delta, 1 key frame, 2 statics snapshot, 3 resync key frame
//! frame      u64      steps taken
//! prev       u64      the frame this one follows in its stream (a delta applies only
//!                     on it; a stream may carry every k-th step); in a key frame, its
//!                     own number less the stream's steps a frame
//! time       f64      simulated seconds
//! dt         f64      the world's step, seconds
//! stats      12 x 4 bytes: step_ms f32, contacts u32, solver_passes u32,
//!                     deepest_penetration f32, kinetic_energy f32, particle_contacts u32,
//!                     overruns u32, dynamic_bodies u32, particles u32, emitters u32,
//!                     energy_change f32, residual f32
//! emitters   varint n, then n x (x f32, y f32, remaining varint)
//! bodies     varint n, then n body records, in increasing key order; in a delta frame
//!            then the motion of the bodies held (varint length, range-coded bytes)
//! particles  varint n, then n particle records, in increasing id order
//! ```
//!
//! A varint is LEB128 (7 bits a byte, low first); a signed varint is zigzag-encoded first.
//!
//! ## Bodies: predicted, and every frame the residual, range-coded
//!
//! A receiver holds each dynamic body's state in integers of [`FINE`] units (2^-24): its
//! position `p` and its displacement over the last frame `d`. At every delta frame a
//! receiver moves every body it holds on, axis by axis, `p <- p + d`, and the frame gives
//! the residual `r` of each body and axis: how many [`POS_QUANTUM`]s (1/1024 units) the
//! body's true position is from that prediction, rounded to the nearest. The receiver
//! adds `r` quanta to both `p` and `d`. So a receiver's position is within
//! [`POS_BOUND`] (1/2048 units) of the server's on each axis at every frame, and its
//! displacement, what its position moved over the last frame, is within twice that of the
//! body's. A body at rest, or moving steadily, has residuals of 0; a falling one, a
//! residual that repeats. Its velocity is `d / (dt (frame - prev))`.
//!
//! Body section of a delta frame: `n` varint, then `n` records of bodies new to receivers
//! (NEW, whole; a body under a key receivers hold is replaced) or gone (REMOVED), then the
//! motion: varint `L` and `L` bytes, the residuals of every other body receivers hold,
//! in increasing key order, range-coded (`motion`, where the coding is laid out). In a
//! key frame, a resync key frame and a snapshot, `n` NEW records and no motion.
//!
//! Body record: `key gap` varint (key minus the previous record's key, the first from 0),
//! `flags` u8, then by flag:
//! - `NEW` (0x01): the body whole. Unless `SAME_SHAPE` (0x40): shape u8 (0 rect,
//!   1 circle), then a rect's width and height as two f32, a circle's diameter as one;
//!   else those of the previous NEW record of the section. The id as the length of the
//!   prefix it shares with the id of the previous NEW record of the same kind (rect or
//!   circle; varint), then the rest (varint length + UTF-8). Unless `SAME_GROUP` (0x80):
//!   the group (varint length + UTF-8); else the previous NEW record's. Then `p` as two
//!   signed varints, the change from the `p` of the previous NEW record of the same kind
//!   (from 0 for the first); `d` if `VEL` (0x04), two signed varints (else 0). In a key
//!   frame, a delta and a snapshot these are in units of [`POS_QUANTUM`] (`d` within half
//!   of one of the body's displacement over the last frame); in a resync key frame (kind
//!   3, the answer to the state query, which restates what receivers hold mid-stream), in
//!   [`FINE`] units;
//! - `COLLIDED` (0x08): the value of the collided flag (in the motion: whether it
//!   changed);
//! - `REMOVED` (0x10): the body is gone; nothing follows.
//!
//! ## Particles: moved by every receiver as the engine moves them
//!
//! A receiver holds each particle's position and velocity as f32, with its acceleration
//! and drag, and at every delta frame, before reading its records, moves every particle it
//! holds that is not frozen exactly as the engine does (f32 arithmetic, `dt` as f32), once
//! for each step since the frame before (`frame - prev`):
//!
//! ```text
//! v <- (v + a dt) drag;  p <- p + v dt
//! ```
//!
//! The server runs the same update on what receivers hold and sends a correction only
//! where a particle is more than [`PARTICLE_BOUND`] from it on an axis (a shape pushed it
//! out): a receiver's particle is within 1/512 units of the server's at every frame. An
//! axis on which a shape holds a particle still is frozen: receivers stop moving the
//! particle on it until a record gives it a velocity again. Its colour and size at a later frame follow from its birth
//! record (as the engine computes them) and are never sent again.
//!
//! Particle record: `id gap` varint, `flags` u8, then by flag:
//! - `NEW` (0x01): the particle whole: if `FROZEN` (0x20), a byte of the axes frozen
//!   (bit 0 x, bit 1 y); position as two signed varints, the change from the previous NEW
//!   record's (from 0 for the first); velocity as two signed varints; unless `SAME_MOTION` (0x40), acceleration x and y and drag as three
//!   f32; unless `SAME_LOOK` (0x80), start colour as 4 bytes (value x 31.875, so 0 to 8) and
//!   size factor f32 (else those of the previous NEW record); final colour as 4 bytes;
//!   initial life f32; age varint (updates lived; its life is the initial life minus its
//!   age); size f32. Position and velocity are in units of [`PARTICLE_QUANTUM`] and
//!   [`PARTICLE_VEL_QUANTUM`], but in a resync key frame (kind 3) they are the f32 bits
//!   (two u32 each) of what receivers hold;
//! - `POS` (0x02): a correction of the position moved on, two signed varints of
//!   [`PARTICLE_QUANTUM`];
//! - `VEL` (0x04): the velocity, two signed varints of [`PARTICLE_VEL_QUANTUM`]; the
//!   particle moves again on both axes;
//! - `FREEZE_X` (0x20), `FREEZE_Y` (0x40): the particle is frozen on that axis (after `VEL`);
//! - `REMOVED` (0x10): the particle expired.

use std::fmt;

use glam::Vec4;

mod decode;
mod encode;
mod motion;
mod records;
#[cfg(test)]
mod tests;
mod wire;

pub use decode::{peek_header, read_key_particles, FrameDecoder, Header, MAX_STEPS_A_FRAME};
pub use encode::{encode_statics, FrameEncoder};

/// The particles' colour model, as receivers predict it: the start colour plus `delta`
/// for each update of `age` (the engine's; the server's tests hold the two equal).
pub fn color_after(start: Vec4, delta: Vec4, age: f32) -> Vec4 {
    start + delta * age
}

/// The particles' size model: `size` scaled by `size_delta` once per update, `updates`
/// updates later (the engine's; the server's tests hold the two equal).
pub fn size_after(size: f32, size_delta: f32, updates: i32) -> f32 {
    size * size_delta.powi(updates)
}

/// A receiver holds bodies' positions, displacements and their changes in integers of
/// this many units (2^-24).
pub const FINE: f64 = 1.0 / 16_777_216.0;
/// A body's residual travels in integers of this many units (1/1024).
pub const POS_QUANTUM: f64 = 1.0 / 1024.0;
/// A receiver's position is within this many units of the server's (1/2048), on each axis
/// (and half a [`FINE`] unit, the grid it is held on); its displacement over a frame,
/// within twice that.
pub const POS_BOUND: f64 = 1.0 / 2048.0;
/// [`POS_QUANTUM`] in [`FINE`] units.
const POS_STEP: i64 = 1 << 14;
/// Positions of particles travel as integers of this many units (1/1024).
pub const PARTICLE_QUANTUM: f64 = 1.0 / 1024.0;
/// A receiver's particle is within this many units of the server's (1/512), on each axis.
pub const PARTICLE_BOUND: f64 = 1.0 / 512.0;
/// Velocities of particles travel as integers of this many units per second (1/256).
pub const PARTICLE_VEL_QUANTUM: f64 = 1.0 / 256.0;
/// A colour component travels as `round(c * COLOR_SCALE)` in a byte: 0 to 8 (the fire
/// preset's final red reaches 4.5).
pub const COLOR_SCALE: f32 = 31.875;

pub const MAGIC: &[u8; 3] = b"RCF";
pub const KIND_DELTA: u8 = 0;
pub const KIND_KEY: u8 = 1;
pub const KIND_STATICS: u8 = 2;
pub const KIND_RESYNC: u8 = 3;

const NEW: u8 = 0x01;
const POS: u8 = 0x02;
const VEL: u8 = 0x04;
const COLLIDED: u8 = 0x08;
const REMOVED: u8 = 0x10;
const SAME_SHAPE: u8 = 0x40;
const SAME_GROUP: u8 = 0x80;
/// A NEW particle record carries the axes it is frozen on.
const FROZEN: u8 = 0x20;
/// In a particle record that is not NEW: frozen on x, on y.
const FREEZE_X: u8 = 0x20;
const FREEZE_Y: u8 = 0x40;
/// A NEW particle moves as the previous NEW particle (acceleration and drag).
const SAME_MOTION: u8 = 0x40;
/// A NEW particle starts as the previous NEW particle looks (start colour, size factor).
const SAME_LOOK: u8 = 0x80;

/// Header bytes before the sections.
pub const HEADER_BYTES: usize = 3 + 1 + 1 + 8 + 8 + 8 + 8 + 48;

/// The figures of the step that produced a frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FrameStats {
    /// Wall time the step took, in milliseconds.
    pub step_ms: f32,
    pub contacts: u32,
    pub solver_passes: u32,
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
    pub vx: &'a [f32],
    pub vy: &'a [f32],
    pub ax: &'a [f32],
    pub ay: &'a [f32],
    pub drag: &'a [f32],
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
    /// Position, in [`FINE`] units.
    pub p: [i64; 2],
    /// Displacement over the last frame, in [`FINE`] units.
    pub d: [i64; 2],
    /// Seconds a frame stands for (of the frame that last moved the body; 0 for a static).
    pub dt: f64,
    pub collided: bool,
}

impl Body {
    pub fn pos(&self) -> [f64; 2] {
        self.p.map(|v| v as f64 * FINE)
    }

    /// The displacement over the last frame over the frame's time, units per second.
    pub fn vel(&self) -> [f64; 2] {
        if self.dt > 0.0 {
            self.d.map(|v| v as f64 * FINE / self.dt)
        } else {
            [0.0; 2]
        }
    }

    /// One frame on, as every receiver predicts a body: `p + d` (wrapping: a server
    /// keeps these near the body's true state, far from 64 bits).
    fn predicted(&self) -> [i64; 2] {
        [
            self.p[0].wrapping_add(self.d[0]),
            self.p[1].wrapping_add(self.d[1]),
        ]
    }
}

/// A particle as a receiver knows it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Particle {
    pub id: u32,
    pub pos: [f32; 2],
    pub vel: [f32; 2],
    pub acc: [f32; 2],
    pub drag: f32,
    /// Axes on which a shape holds it still: not moved on them until a record gives it a
    /// velocity.
    pub frozen: [bool; 2],
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
        self.pos
    }

    /// One update of its motion, as the engine's (`Particles::update`) and every
    /// receiver's: `v = (v + a dt) drag; p += v dt` in f32, on each axis not frozen.
    pub fn advance(&mut self, dt: f32) {
        for i in 0..2 {
            if !self.frozen[i] {
                self.vel[i] = (self.vel[i] + self.acc[i] * dt) * self.drag;
                self.pos[i] += self.vel[i] * dt;
            }
        }
    }

    /// Colour at `frame`, by the particles' model ([`color_after`]) from the colours of the
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

    /// Size at `frame`, by the particles' model ([`size_after`]).
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
            ..*self
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
    /// A delta frame that does not follow the last frame applied (`held`): it follows
    /// frame `follows`. Wait for a key frame, or fetch the state.
    OutOfSync { held: u64, follows: u64 },
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
            DecodeError::OutOfSync { held, follows } => write!(
                f,
                "a delta frame follows frame {follows}, this receiver holds frame {held}; \
                 waiting for a key frame"
            ),
            DecodeError::Stale { frame } => write!(f, "frame {frame} is older than the state held"),
        }
    }
}

impl std::error::Error for DecodeError {}
