//! The binary frame: one per step on `ricochet/<world>/frame`, and the statics snapshot.
//!
//! A frame carries what changed since the previous frame; every `keyframe_interval`
//! frames (and after a reset) a key frame carries everything, so a receiver that joins
//! late or misses a frame is whole again at the next key frame. Static bodies are never in
//! frames: they are in the snapshot, fetched with a query and re-published when they
//! change.
//!
//! # Layout, version 1 (all numbers little-endian)
//!
//! ```text
//! magic      3 bytes  "RCF"
//! version    u8       1
//! kind       u8       0 delta, 1 key frame, 2 statics snapshot
//! frame      u64      steps taken
//! time       f64      simulated seconds
//! stats      10 x 4 bytes: step_ms f32, contacts u32, relaxation_iterations u32,
//!                     deepest_penetration f32, kinetic_energy f32, particle_contacts u32,
//!                     overruns u32, dynamic_bodies u32, particles u32, emitters u32
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
pub const HEADER_BYTES: usize = 3 + 1 + 1 + 8 + 8 + 40;

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

    /// Colour at `frame`: the start colour walked toward the final one, one step per
    /// update lived (as the engine computes it).
    pub fn color_at(&self, frame: u64) -> [f32; 4] {
        let elapsed = frame.saturating_sub(self.record_frame) as f32;
        let age = self.initial_life - (self.life - elapsed);
        let t = if self.initial_life != 0.0 {
            age / self.initial_life
        } else {
            0.0
        };
        std::array::from_fn(|i| {
            let (c0, c1) = (
                self.color0[i] as f32 / COLOR_SCALE,
                self.color1[i] as f32 / COLOR_SCALE,
            );
            c0 + (c1 - c0) * t
        })
    }

    /// Size at `frame`.
    pub fn size_at(&self, frame: u64) -> f32 {
        let elapsed = frame.saturating_sub(self.record_frame).min(i32::MAX as u64) as i32;
        self.size * self.size_delta.powi(elapsed)
    }
}

fn quantize(v: f64, quantum: f64) -> i64 {
    let q = (v / quantum).round();
    if q.is_finite() {
        q.clamp(i64::MIN as f64 / 4.0, i64::MAX as f64 / 4.0) as i64
    } else {
        0
    }
}

fn color_byte(c: f32) -> u8 {
    (c * COLOR_SCALE).round().clamp(0.0, 255.0) as u8
}

// ---- byte writing ------------------------------------------------------------------

fn put_varint(out: &mut Vec<u8>, mut v: u64) {
    while v >= 0x80 {
        out.push((v as u8) | 0x80);
        v >>= 7;
    }
    out.push(v as u8);
}

fn put_svarint(out: &mut Vec<u8>, v: i64) {
    put_varint(out, ((v << 1) ^ (v >> 63)) as u64);
}

fn put_str(out: &mut Vec<u8>, s: &str) {
    put_varint(out, s.len() as u64);
    out.extend_from_slice(s.as_bytes());
}

fn put_header(out: &mut Vec<u8>, kind: u8, frame: u64, time: f64, s: &FrameStats) {
    out.extend_from_slice(MAGIC);
    out.push(crate::PROTOCOL_VERSION);
    out.push(kind);
    out.extend_from_slice(&frame.to_le_bytes());
    out.extend_from_slice(&time.to_le_bytes());
    for v in [
        s.step_ms.to_bits(),
        s.contacts,
        s.relaxation_iterations,
        s.deepest_penetration.to_bits(),
        s.kinetic_energy.to_bits(),
        s.particle_contacts,
        s.overruns,
        s.dynamic_bodies,
        s.particles,
        s.emitters,
    ] {
        out.extend_from_slice(&v.to_le_bytes());
    }
}

fn body_of(b: &BodyIn) -> Body {
    Body {
        key: b.key,
        id: b.id.to_string(),
        group: b.group.to_string(),
        circle: b.circle,
        size: [b.size[0] as f32, b.size[1] as f32],
        qpos: [
            quantize(b.pos[0], POS_QUANTUM),
            quantize(b.pos[1], POS_QUANTUM),
        ],
        qvel: [
            quantize(b.vel[0], VEL_QUANTUM),
            quantize(b.vel[1], VEL_QUANTUM),
        ],
        collided: b.collided,
    }
}

fn put_new_body(out: &mut Vec<u8>, b: &Body) {
    out.push(NEW | POS | VEL | if b.collided { COLLIDED } else { 0 });
    out.push(b.circle as u8);
    out.extend_from_slice(&b.size[0].to_le_bytes());
    out.extend_from_slice(&b.size[1].to_le_bytes());
    put_str(out, &b.id);
    put_str(out, &b.group);
    for v in b.qpos.iter().chain(&b.qvel) {
        put_svarint(out, *v);
    }
}

fn put_new_particle(out: &mut Vec<u8>, p: &Particle) {
    out.push(NEW | POS);
    put_svarint(out, p.qpos[0]);
    put_svarint(out, p.qpos[1]);
    out.extend_from_slice(&p.color0);
    out.extend_from_slice(&p.color1);
    for v in [p.initial_life, p.life, p.size, p.size_delta] {
        out.extend_from_slice(&v.to_le_bytes());
    }
}

fn put_emitters(out: &mut Vec<u8>, emitters: &[EmitterIn]) {
    put_varint(out, emitters.len() as u64);
    for e in emitters {
        out.extend_from_slice(&e.x.to_le_bytes());
        out.extend_from_slice(&e.y.to_le_bytes());
        put_varint(out, e.remaining as u64);
    }
}

/// Encodes the statics snapshot: every static body, as NEW records.
pub fn encode_statics(frame: u64, time: f64, statics: &[BodyIn]) -> Vec<u8> {
    let mut out = Vec::with_capacity(HEADER_BYTES + statics.len() * 40);
    put_header(&mut out, KIND_STATICS, frame, time, &FrameStats::default());
    put_varint(&mut out, 0);
    let mut bodies: Vec<Body> = statics.iter().map(body_of).collect();
    bodies.sort_by_key(|b| b.key);
    put_varint(&mut out, bodies.len() as u64);
    let mut prev = 0u32;
    for b in &bodies {
        put_varint(&mut out, (b.key - prev) as u64);
        prev = b.key;
        put_new_body(&mut out, b);
    }
    put_varint(&mut out, 0);
    out
}

/// Turns a world's states into frames, remembering what receivers were last told.
#[derive(Clone, Debug)]
pub struct FrameEncoder {
    bodies: Vec<Body>,
    particles: Vec<Particle>,
    keyframe_interval: u64,
    since_key: u64,
    force_key: bool,
    /// Header and emitters of the last frame encoded, for [`FrameEncoder::resync_frame`].
    last: Option<(u64, f64, FrameStats, Vec<EmitterIn>)>,
}

impl FrameEncoder {
    /// A key frame every `keyframe_interval` frames (at least 1).
    pub fn new(keyframe_interval: u64) -> Self {
        FrameEncoder {
            bodies: Vec::new(),
            particles: Vec::new(),
            keyframe_interval: keyframe_interval.max(1),
            since_key: 0,
            force_key: true,
            last: None,
        }
    }

    /// A key frame of what receivers know after the last frame encoded: a late joiner
    /// applies it, then the delta frames that follow it. `None` before the first frame.
    pub fn resync_frame(&self) -> Option<Vec<u8>> {
        let (frame, time, stats, emitters) = self.last.as_ref()?;
        let mut out =
            Vec::with_capacity(HEADER_BYTES + self.bodies.len() * 40 + self.particles.len() * 30);
        put_header(&mut out, KIND_KEY, *frame, *time, stats);
        put_emitters(&mut out, emitters);
        put_varint(&mut out, self.bodies.len() as u64);
        let mut prev = 0;
        for b in &self.bodies {
            put_varint(&mut out, (b.key - prev) as u64);
            prev = b.key;
            put_new_body(&mut out, b);
        }
        put_varint(&mut out, self.particles.len() as u64);
        let mut prev = 0;
        for p in &self.particles {
            put_varint(&mut out, (p.id - prev) as u64);
            prev = p.id;
            let elapsed = frame.saturating_sub(p.record_frame);
            let now = Particle {
                life: p.life - elapsed as f32,
                size: p.size_at(*frame),
                record_frame: *frame,
                ..p.clone()
            };
            put_new_particle(&mut out, &now);
        }
        Some(out)
    }

    /// The next frame will be a key frame (after a reset or a new scene).
    pub fn force_key_frame(&mut self) {
        self.force_key = true;
    }

    /// Encodes one frame. `bodies` are the dynamic bodies and `particles` the particles,
    /// each in increasing key (id) order, as the engine keeps them.
    pub fn encode(
        &mut self,
        frame: u64,
        time: f64,
        stats: &FrameStats,
        emitters: &[EmitterIn],
        bodies: &[BodyIn],
        particles: &ParticlesIn,
    ) -> Vec<u8> {
        let key = self.force_key || self.since_key + 1 >= self.keyframe_interval;
        if key {
            self.force_key = false;
            self.since_key = 0;
            self.bodies.clear();
            self.particles.clear();
        } else {
            self.since_key += 1;
        }
        let mut out =
            Vec::with_capacity(HEADER_BYTES + 64 + bodies.len() * 8 + particles.id.len() * 6);
        put_header(
            &mut out,
            if key { KIND_KEY } else { KIND_DELTA },
            frame,
            time,
            stats,
        );
        put_emitters(&mut out, emitters);
        self.encode_bodies(&mut out, bodies);
        self.encode_particles(&mut out, frame, particles);
        self.last = Some((frame, time, *stats, emitters.to_vec()));
        out
    }

    fn encode_bodies(&mut self, out: &mut Vec<u8>, bodies: &[BodyIn]) {
        let mut records = Vec::new();
        let mut count = 0u64;
        let mut prev = 0u32;
        let mut next = Vec::with_capacity(bodies.len());
        let mut sent = std::mem::take(&mut self.bodies).into_iter().peekable();
        let mut record = |records: &mut Vec<u8>, key: u32| {
            put_varint(records, (key - prev) as u64);
            prev = key;
            count += 1;
        };
        for b in bodies {
            let now = body_of(b);
            while let Some(old) = sent.next_if(|s| s.key < now.key) {
                record(&mut records, old.key);
                records.push(REMOVED);
            }
            match sent.next_if(|s| s.key == now.key) {
                Some(old)
                    if old.id == now.id
                        && old.size == now.size
                        && old.circle == now.circle
                        && old.group == now.group =>
                {
                    let moved = old.qpos != now.qpos;
                    let sped = old.qvel != now.qvel;
                    if moved || sped || old.collided != now.collided {
                        record(&mut records, now.key);
                        records.push(
                            (moved as u8 * POS)
                                | (sped as u8 * VEL)
                                | (now.collided as u8 * COLLIDED),
                        );
                        if moved {
                            put_svarint(&mut records, now.qpos[0] - old.qpos[0]);
                            put_svarint(&mut records, now.qpos[1] - old.qpos[1]);
                        }
                        if sped {
                            put_svarint(&mut records, now.qvel[0] - old.qvel[0]);
                            put_svarint(&mut records, now.qvel[1] - old.qvel[1]);
                        }
                    }
                }
                _ => {
                    record(&mut records, now.key);
                    put_new_body(&mut records, &now);
                }
            }
            next.push(now);
        }
        for old in sent {
            record(&mut records, old.key);
            records.push(REMOVED);
        }
        put_varint(out, count);
        out.extend_from_slice(&records);
        self.bodies = next;
    }

    fn encode_particles(&mut self, out: &mut Vec<u8>, frame: u64, p: &ParticlesIn) {
        let n = p.id.len();
        let mut records = Vec::with_capacity(n * 4);
        let mut count = 0u64;
        let mut prev = 0u32;
        let mut next = Vec::with_capacity(n);
        let mut sent = std::mem::take(&mut self.particles).into_iter().peekable();
        let mut record = |records: &mut Vec<u8>, id: u32| {
            put_varint(records, (id - prev) as u64);
            prev = id;
            count += 1;
        };
        for i in 0..n {
            let id = p.id[i];
            let qpos = [
                quantize(p.x[i] as f64, PARTICLE_QUANTUM),
                quantize(p.y[i] as f64, PARTICLE_QUANTUM),
            ];
            while let Some(old) = sent.next_if(|s| s.id < id) {
                record(&mut records, old.id);
                records.push(REMOVED);
            }
            match sent.next_if(|s| s.id == id) {
                Some(mut old) => {
                    if old.qpos != qpos {
                        record(&mut records, id);
                        records.push(POS);
                        put_svarint(&mut records, qpos[0] - old.qpos[0]);
                        put_svarint(&mut records, qpos[1] - old.qpos[1]);
                        old.qpos = qpos;
                    }
                    next.push(old);
                }
                None => {
                    let color0 = p.color[i];
                    let life0 = p.initial_life[i];
                    let color1: [f32; 4] =
                        std::array::from_fn(|c| color0[c] + p.color_delta[i][c] * life0);
                    let particle = Particle {
                        id,
                        qpos,
                        color0: color0.map(color_byte),
                        color1: color1.map(color_byte),
                        initial_life: life0,
                        life: p.life[i],
                        size: p.size[i],
                        size_delta: p.size_delta[i],
                        record_frame: frame,
                    };
                    record(&mut records, id);
                    put_new_particle(&mut records, &particle);
                    next.push(particle);
                }
            }
        }
        for old in sent {
            record(&mut records, old.id);
            records.push(REMOVED);
        }
        put_varint(out, count);
        out.extend_from_slice(&records);
        self.particles = next;
    }
}

// ---- decoding ----------------------------------------------------------------------

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

struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize) -> Result<&'a [u8], DecodeError> {
        let end = self.at.checked_add(n).filter(|&e| e <= self.bytes.len());
        let end =
            end.ok_or_else(|| DecodeError::Malformed(format!("cut short at byte {}", self.at)))?;
        let s = &self.bytes[self.at..end];
        self.at = end;
        Ok(s)
    }
    fn u8(&mut self) -> Result<u8, DecodeError> {
        Ok(self.take(1)?[0])
    }
    fn u32(&mut self) -> Result<u32, DecodeError> {
        Ok(u32::from_le_bytes(self.take(4)?.try_into().unwrap()))
    }
    fn f32(&mut self) -> Result<f32, DecodeError> {
        Ok(f32::from_bits(self.u32()?))
    }
    fn u64(&mut self) -> Result<u64, DecodeError> {
        Ok(u64::from_le_bytes(self.take(8)?.try_into().unwrap()))
    }
    fn varint(&mut self) -> Result<u64, DecodeError> {
        let mut v = 0u64;
        for shift in (0..64).step_by(7) {
            let b = self.u8()?;
            v |= ((b & 0x7f) as u64) << shift;
            if b & 0x80 == 0 {
                return Ok(v);
            }
        }
        Err(DecodeError::Malformed("varint longer than 64 bits".into()))
    }
    fn svarint(&mut self) -> Result<i64, DecodeError> {
        let v = self.varint()?;
        Ok(((v >> 1) as i64) ^ -((v & 1) as i64))
    }
    fn str(&mut self) -> Result<String, DecodeError> {
        let n = self.varint()? as usize;
        let bytes = self.take(n)?;
        String::from_utf8(bytes.to_vec())
            .map_err(|_| DecodeError::Malformed("a name is not UTF-8".into()))
    }
    fn count(&mut self, min_record: usize) -> Result<usize, DecodeError> {
        let n = self.varint()? as usize;
        // Refuse counts the remaining bytes cannot hold, before allocating for them.
        if n.saturating_mul(min_record) > self.bytes.len() - self.at {
            return Err(DecodeError::Malformed(format!("{n} records cannot fit")));
        }
        Ok(n)
    }
}

/// What a receiver knows of a world, kept up to date frame by frame.
#[derive(Clone, Debug, Default)]
pub struct FrameDecoder {
    /// Dynamic bodies, by increasing key.
    pub bodies: Vec<Body>,
    /// Static bodies from the latest snapshot, by increasing key.
    pub statics: Vec<Body>,
    /// Particles, by increasing id.
    pub particles: Vec<Particle>,
    pub emitters: Vec<EmitterIn>,
    pub frame: u64,
    pub time: f64,
    pub stats: FrameStats,
    /// Whether a key frame has been applied since the last gap.
    pub synced: bool,
}

/// The header of a payload.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Header {
    pub kind: u8,
    pub frame: u64,
    pub time: f64,
    pub stats: FrameStats,
}

fn read_header(r: &mut Reader) -> Result<Header, DecodeError> {
    if r.take(3)? != MAGIC {
        return Err(DecodeError::Malformed("no RCF magic".into()));
    }
    let version = r.u8()?;
    if version != crate::PROTOCOL_VERSION {
        return Err(DecodeError::Version(version));
    }
    let kind = r.u8()?;
    if kind > KIND_STATICS {
        return Err(DecodeError::Malformed(format!("unknown kind {kind}")));
    }
    let frame = r.u64()?;
    let time = f64::from_bits(r.u64()?);
    let stats = FrameStats {
        step_ms: r.f32()?,
        contacts: r.u32()?,
        relaxation_iterations: r.u32()?,
        deepest_penetration: r.f32()?,
        kinetic_energy: r.f32()?,
        particle_contacts: r.u32()?,
        overruns: r.u32()?,
        dynamic_bodies: r.u32()?,
        particles: r.u32()?,
        emitters: r.u32()?,
    };
    Ok(Header {
        kind,
        frame,
        time,
        stats,
    })
}

/// Reads only the header of a payload.
pub fn peek_header(bytes: &[u8]) -> Result<Header, DecodeError> {
    read_header(&mut Reader { bytes, at: 0 })
}

impl FrameDecoder {
    pub fn new() -> Self {
        Self::default()
    }

    /// Applies a frame or a snapshot. A delta frame is refused unless it follows the last
    /// frame applied; the state is unchanged by a refused payload.
    pub fn apply(&mut self, bytes: &[u8]) -> Result<Header, DecodeError> {
        let mut r = Reader { bytes, at: 0 };
        let header = read_header(&mut r)?;
        // A key frame always applies (frame numbers restart after a reset); a delta frame
        // not newer than the state held was already folded into it.
        if header.kind == KIND_DELTA && self.synced && header.frame <= self.frame {
            return Err(DecodeError::Stale {
                frame: header.frame,
            });
        }
        if header.kind == KIND_DELTA && !(self.synced && header.frame == self.frame + 1) {
            self.synced = false;
            return Err(DecodeError::OutOfSync {
                expected: self.frame + 1,
                got: header.frame,
            });
        }
        let mut emitters = Vec::new();
        for _ in 0..r.count(9)? {
            emitters.push(EmitterIn {
                x: r.f32()?,
                y: r.f32()?,
                remaining: r.varint()? as u32,
            });
        }
        let fresh = header.kind != KIND_DELTA;
        let base = match header.kind {
            KIND_STATICS => Vec::new(),
            KIND_KEY => Vec::new(),
            _ => self.bodies.clone(),
        };
        let bodies = read_bodies(&mut r, base, fresh)?;
        let base = if fresh {
            Vec::new()
        } else {
            self.particles.clone()
        };
        let particles = read_particles(&mut r, base, header.frame)?;
        if r.at != bytes.len() {
            return Err(DecodeError::Malformed(format!(
                "{} bytes left over",
                bytes.len() - r.at
            )));
        }
        if header.kind == KIND_STATICS {
            self.statics = bodies;
            return Ok(header);
        }
        self.bodies = bodies;
        self.particles = particles;
        self.emitters = emitters;
        self.frame = header.frame;
        self.time = header.time;
        self.stats = header.stats;
        self.synced = true;
        Ok(header)
    }

    /// The body with this id, dynamic or static.
    pub fn body(&self, id: &str) -> Option<&Body> {
        self.bodies.iter().chain(&self.statics).find(|b| b.id == id)
    }
}

fn read_bodies(r: &mut Reader, base: Vec<Body>, fresh: bool) -> Result<Vec<Body>, DecodeError> {
    let n = r.count(2)?;
    let mut out = Vec::with_capacity(base.len() + n);
    let mut old = base.into_iter().peekable();
    let mut key = 0u32;
    for _ in 0..n {
        key = key
            .checked_add(
                r.varint()?
                    .try_into()
                    .map_err(|_| DecodeError::Malformed("key gap".into()))?,
            )
            .ok_or_else(|| DecodeError::Malformed("key overflow".into()))?;
        while let Some(b) = old.next_if(|b| b.key < key) {
            out.push(b);
        }
        let existing = old.next_if(|b| b.key == key);
        let flags = r.u8()?;
        if flags & REMOVED != 0 {
            if existing.is_none() {
                return Err(DecodeError::Malformed(format!(
                    "removal of unknown body {key}"
                )));
            }
            continue;
        }
        if flags & NEW != 0 {
            let circle = r.u8()? != 0;
            let size = [r.f32()?, r.f32()?];
            let id = r.str()?;
            let group = r.str()?;
            let qpos = [r.svarint()?, r.svarint()?];
            let qvel = [r.svarint()?, r.svarint()?];
            out.push(Body {
                key,
                id,
                group,
                circle,
                size,
                qpos,
                qvel,
                collided: flags & COLLIDED != 0,
            });
            continue;
        }
        let mut b = existing.ok_or_else(|| {
            DecodeError::Malformed(format!(
                "update of unknown body {key}{}",
                if fresh { " in a key frame" } else { "" }
            ))
        })?;
        if flags & POS != 0 {
            b.qpos[0] += r.svarint()?;
            b.qpos[1] += r.svarint()?;
        }
        if flags & VEL != 0 {
            b.qvel[0] += r.svarint()?;
            b.qvel[1] += r.svarint()?;
        }
        b.collided = flags & COLLIDED != 0;
        out.push(b);
    }
    out.extend(old);
    Ok(out)
}

fn read_particles(
    r: &mut Reader,
    base: Vec<Particle>,
    frame: u64,
) -> Result<Vec<Particle>, DecodeError> {
    let n = r.count(2)?;
    let mut out = Vec::with_capacity(base.len() + n);
    let mut old = base.into_iter().peekable();
    let mut id = 0u32;
    for _ in 0..n {
        id = id
            .checked_add(
                r.varint()?
                    .try_into()
                    .map_err(|_| DecodeError::Malformed("id gap".into()))?,
            )
            .ok_or_else(|| DecodeError::Malformed("particle id overflow".into()))?;
        while let Some(p) = old.next_if(|p| p.id < id) {
            out.push(p);
        }
        let existing = old.next_if(|p| p.id == id);
        let flags = r.u8()?;
        if flags & REMOVED != 0 {
            continue;
        }
        if flags & NEW != 0 {
            let qpos = [r.svarint()?, r.svarint()?];
            let color0: [u8; 4] = r.take(4)?.try_into().unwrap();
            let color1: [u8; 4] = r.take(4)?.try_into().unwrap();
            let (initial_life, life, size, size_delta) = (r.f32()?, r.f32()?, r.f32()?, r.f32()?);
            out.push(Particle {
                id,
                qpos,
                color0,
                color1,
                initial_life,
                life,
                size,
                size_delta,
                record_frame: frame,
            });
            continue;
        }
        let mut p = existing
            .ok_or_else(|| DecodeError::Malformed(format!("update of unknown particle {id}")))?;
        if flags & POS != 0 {
            p.qpos[0] += r.svarint()?;
            p.qpos[1] += r.svarint()?;
        }
        out.push(p);
    }
    out.extend(old);
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn body(key: u32, id: &str, pos: [f64; 2]) -> BodyIn<'_> {
        BodyIn {
            key,
            id,
            group: "g",
            circle: key.is_multiple_of(2),
            size: [2.0, 3.0],
            pos,
            vel: [1.0, -2.0],
            collided: false,
        }
    }

    #[derive(Default)]
    struct Cloud {
        id: Vec<u32>,
        x: Vec<f32>,
        y: Vec<f32>,
        life: Vec<f32>,
        initial_life: Vec<f32>,
        size: Vec<f32>,
        size_delta: Vec<f32>,
        color: Vec<[f32; 4]>,
        color_delta: Vec<[f32; 4]>,
    }

    impl Cloud {
        fn push(&mut self, id: u32, x: f32, y: f32) {
            self.id.push(id);
            self.x.push(x);
            self.y.push(y);
            self.life.push(10.0);
            self.initial_life.push(10.0);
            self.size.push(2.0);
            self.size_delta.push(0.5);
            self.color.push([1.0, 0.0, 0.0, 1.0]);
            self.color_delta.push([0.3, 0.0, 0.0, -0.05]);
        }
        fn view(&self) -> ParticlesIn<'_> {
            ParticlesIn {
                id: &self.id,
                x: &self.x,
                y: &self.y,
                life: &self.life,
                initial_life: &self.initial_life,
                size: &self.size,
                size_delta: &self.size_delta,
                color: &self.color,
                color_delta: &self.color_delta,
            }
        }
    }

    #[test]
    fn deltas_rebuild_the_state_and_resting_things_cost_nothing() {
        let mut enc = FrameEncoder::new(60);
        let mut dec = FrameDecoder::new();
        let mut cloud = Cloud::default();
        cloud.push(3, 10.0, 20.0);
        cloud.push(7, 11.0, 21.0);
        let bodies = [
            body(0, "a", [1.0, 2.0]),
            body(1, "b", [5.0, 5.0]),
            body(4, "c", [9.0, 9.0]),
        ];
        let f0 = enc.encode(0, 0.0, &FrameStats::default(), &[], &bodies, &cloud.view());
        assert_eq!(dec.apply(&f0).unwrap().kind, KIND_KEY);
        assert_eq!(dec.bodies.len(), 3);
        assert_eq!(dec.body("c").unwrap().pos(), [9.0, 9.0]);
        assert_eq!(dec.particles.len(), 2);

        // Nothing changes: a delta frame of the header and three empty sections.
        let f1 = enc.encode(1, 0.1, &FrameStats::default(), &[], &bodies, &cloud.view());
        assert_eq!(f1.len(), HEADER_BYTES + 3);
        dec.apply(&f1).unwrap();

        // b moves, a is removed, d is new; particle 3 moves, 7 expires, 9 is born.
        let moved = [
            body(1, "b", [5.5, 5.0]),
            body(4, "c", [9.0, 9.0]),
            body(6, "d", [0.0, 0.0]),
        ];
        let mut cloud2 = Cloud::default();
        cloud2.push(3, 10.5, 20.0);
        cloud2.push(9, 0.0, 0.0);
        let f2 = enc.encode(
            2,
            0.2,
            &FrameStats::default(),
            &[EmitterIn {
                x: 1.0,
                y: 2.0,
                remaining: 7,
            }],
            &moved,
            &cloud2.view(),
        );
        dec.apply(&f2).unwrap();
        let ids: Vec<&str> = dec.bodies.iter().map(|b| b.id.as_str()).collect();
        assert_eq!(ids, ["b", "c", "d"]);
        assert_eq!(dec.body("b").unwrap().pos(), [5.5, 5.0]);
        assert_eq!(
            dec.particles.iter().map(|p| p.id).collect::<Vec<_>>(),
            [3, 9]
        );
        assert_eq!(dec.particles[0].pos(), [10.5, 20.0]);
        assert_eq!(
            dec.emitters,
            [EmitterIn {
                x: 1.0,
                y: 2.0,
                remaining: 7
            }]
        );
    }

    #[test]
    fn particle_colour_and_size_follow_from_the_birth_record() {
        let mut enc = FrameEncoder::new(60);
        let mut dec = FrameDecoder::new();
        let mut cloud = Cloud::default();
        cloud.push(1, 0.0, 0.0);
        cloud.life[0] = 6.0; // born 4 updates ago
        cloud.size[0] = 2.0;
        dec.apply(&enc.encode(100, 0.0, &FrameStats::default(), &[], &[], &cloud.view()))
            .unwrap();
        let p = &dec.particles[0];
        // Colour at frame 100 = start + delta * age(4); final = start + delta * 10.
        let c = p.color_at(100);
        assert!(
            (c[0] - 2.2).abs() < 0.02 && (c[3] - 0.8).abs() < 0.02,
            "{c:?}"
        );
        let c = p.color_at(106);
        assert!(
            (c[0] - 4.0).abs() < 0.02 && (c[3] - 0.5).abs() < 0.02,
            "{c:?}"
        );
        assert_eq!(p.size_at(102), 0.5);
    }

    #[test]
    fn a_missed_frame_waits_for_the_next_key_frame() {
        let mut enc = FrameEncoder::new(3);
        let mut dec = FrameDecoder::new();
        let cloud = Cloud::default();
        let frames: Vec<Vec<u8>> = (0..7)
            .map(|k| {
                enc.encode(
                    k,
                    0.0,
                    &FrameStats::default(),
                    &[],
                    &[body(0, "a", [k as f64, 0.0])],
                    &cloud.view(),
                )
            })
            .collect();
        let kinds: Vec<u8> = frames
            .iter()
            .map(|f| peek_header(f).unwrap().kind)
            .collect();
        assert_eq!(
            kinds,
            [KIND_KEY, KIND_DELTA, KIND_DELTA, KIND_KEY, KIND_DELTA, KIND_DELTA, KIND_KEY]
        );
        dec.apply(&frames[0]).unwrap();
        // Frame 1 is lost: frame 2 is refused, frame 3 (key) resynchronises.
        assert_eq!(
            dec.apply(&frames[2]),
            Err(DecodeError::OutOfSync {
                expected: 1,
                got: 2
            })
        );
        assert!(!dec.synced);
        dec.apply(&frames[3]).unwrap();
        dec.apply(&frames[4]).unwrap();
        assert_eq!(dec.body("a").unwrap().pos(), [4.0, 0.0]);
    }

    #[test]
    fn a_late_joiner_resyncs_from_the_encoders_state_and_follows_the_deltas() {
        let mut enc = FrameEncoder::new(1000);
        let mut early = FrameDecoder::new();
        let mut cloud = Cloud::default();
        cloud.push(1, 0.0, 0.0);
        assert!(enc.resync_frame().is_none());
        let mut frames = Vec::new();
        for k in 0..10u64 {
            cloud.x[0] = k as f32;
            cloud.life[0] = 10.0 - k as f32;
            cloud.size[0] = 2.0 * 0.5f32.powi(k as i32);
            frames.push(enc.encode(
                k,
                k as f64,
                &FrameStats::default(),
                &[],
                &[body(0, "a", [k as f64, 1.0])],
                &cloud.view(),
            ));
            early.apply(frames.last().unwrap()).unwrap();
        }
        // Joining after frame 9: the resync frame, then frame 9 again (stale) is ignored.
        let mut late = FrameDecoder::new();
        late.apply(&enc.resync_frame().unwrap()).unwrap();
        assert_eq!(late.apply(&frames[9]), Err(DecodeError::Stale { frame: 9 }));
        assert_eq!(late.apply(&frames[8]), Err(DecodeError::Stale { frame: 8 }));
        assert!(late.synced);
        cloud.x[0] = 10.0;
        let next = enc.encode(
            10,
            10.0,
            &FrameStats::default(),
            &[],
            &[body(0, "a", [10.0, 1.0])],
            &cloud.view(),
        );
        early.apply(&next).unwrap();
        late.apply(&next).unwrap();
        assert_eq!(late.bodies, early.bodies);
        assert_eq!(late.particles[0].qpos, early.particles[0].qpos);
        assert_eq!(
            late.particles[0].color_at(10),
            early.particles[0].color_at(10)
        );
        assert_eq!(
            late.particles[0].size_at(10),
            early.particles[0].size_at(10)
        );
    }

    #[test]
    fn statics_are_a_snapshot_of_their_own() {
        let statics = [body(2, "floor", [0.0, 0.0]), body(5, "wall", [100.0, 50.0])];
        let snap = encode_statics(12, 0.2, &statics);
        let mut dec = FrameDecoder::new();
        assert_eq!(dec.apply(&snap).unwrap().kind, KIND_STATICS);
        assert_eq!(dec.statics.len(), 2);
        assert_eq!(dec.body("wall").unwrap().pos(), [100.0, 50.0]);
        assert!(dec.bodies.is_empty());
    }

    #[test]
    fn garbage_is_refused_without_panicking() {
        let mut dec = FrameDecoder::new();
        let good = FrameEncoder::new(1).encode(
            0,
            0.0,
            &FrameStats::default(),
            &[],
            &[body(0, "a", [1.0, 1.0])],
            &Cloud::default().view(),
        );
        for cut in 0..good.len() {
            assert!(
                dec.apply(&good[..cut]).is_err(),
                "a frame cut at {cut} was accepted"
            );
        }
        let mut bad_version = good.clone();
        bad_version[3] = 9;
        assert_eq!(dec.apply(&bad_version), Err(DecodeError::Version(9)));
        let mut huge_count = good[..HEADER_BYTES].to_vec();
        huge_count.extend_from_slice(&[0xff, 0xff, 0xff, 0xff, 0x0f]);
        assert!(matches!(
            dec.apply(&huge_count),
            Err(DecodeError::Malformed(_))
        ));
        dec.apply(&good).unwrap();
    }
}
