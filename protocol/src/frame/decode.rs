//! The decoder: bytes flow in, frame by frame; what a receiver knows of the world flows
//! out ([`FrameDecoder`]). Nothing read off the wire is trusted: every count is checked
//! against the bytes that remain before anything is allocated for it, and a payload that
//! fails anywhere leaves the state as it was.

use super::motion::{Model, RangeDecoder};
use super::records::{self, Change, Section};
use super::wire::Reader;
use super::{
    Body, DecodeError, EmitterIn, FrameStats, Particle, COLLIDED, FREEZE_X, FREEZE_Y, FROZEN,
    KIND_DELTA, KIND_KEY, KIND_RESYNC, KIND_STATICS, MAGIC, NEW, PARTICLE_QUANTUM,
    PARTICLE_VEL_QUANTUM, POS, POS_STEP, REMOVED, SAME_GROUP, SAME_LOOK, SAME_MOTION, SAME_SHAPE,
    VEL,
};

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
    /// Seconds a frame stands for.
    pub dt: f64,
    pub stats: FrameStats,
    /// Whether a key frame has been applied since the last gap.
    pub synced: bool,
    /// Key frames dropped because the stream's next delta followed the state held before
    /// them: a key frame that goes back or jumps ahead of the stream is not the stream's.
    pub dropped_key_frames: u64,
    /// The state before the last key frame applied in sync, until a delta confirms it.
    before: Option<Box<Held>>,
    /// The particles' list before the last frame, emptied: the next frame's particles are
    /// read into it, so a frame allocates nothing for them.
    spare_particles: Vec<Particle>,
}

/// The dynamic state a key frame replaces, kept until the next delta shows which of the
/// two the stream follows.
#[derive(Clone, Debug)]
struct Held {
    bodies: Vec<Body>,
    particles: Vec<Particle>,
    emitters: Vec<EmitterIn>,
    frame: u64,
    time: f64,
    dt: f64,
    stats: FrameStats,
}

/// The header of a payload.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Header {
    pub kind: u8,
    pub frame: u64,
    /// The frame this one follows in its stream (a key frame: its own number less the
    /// stream's steps a frame).
    pub prev: u64,
    pub time: f64,
    pub dt: f64,
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
    if kind > KIND_RESYNC {
        return Err(DecodeError::Malformed(format!("unknown kind {kind}")));
    }
    let frame = r.u64()?;
    let prev = r.u64()?;
    if prev > frame {
        return Err(DecodeError::Malformed(format!(
            "frame {frame} follows frame {prev}"
        )));
    }
    let time = f64::from_bits(r.u64()?);
    let dt = f64::from_bits(r.u64()?);
    let stats = FrameStats {
        step_ms: r.f32()?,
        contacts: r.u32()?,
        solver_passes: r.u32()?,
        deepest_penetration: r.f32()?,
        kinetic_energy: r.f32()?,
        particle_contacts: r.u32()?,
        overruns: r.u32()?,
        dynamic_bodies: r.u32()?,
        particles: r.u32()?,
        emitters: r.u32()?,
        energy_change: r.f32()?,
        residual: r.f32()?,
    };
    Ok(Header {
        kind,
        frame,
        prev,
        time,
        dt,
        stats,
    })
}

/// Reads only the header of a payload.
pub fn peek_header(bytes: &[u8]) -> Result<Header, DecodeError> {
    read_header(&mut Reader::new(bytes))
}

/// The most steps a delta frame may follow the frame before it by (a stream's frames are
/// at most this far apart): what a receiver's update of every particle is bounded by.
pub const MAX_STEPS_A_FRAME: u64 = 64;

impl FrameDecoder {
    pub fn new() -> Self {
        Self::default()
    }

    /// Applies a frame or a snapshot. A delta frame is refused unless it follows the last
    /// frame applied; the state is unchanged by a refused payload.
    ///
    /// A key frame applies at once (frame numbers restart after a reset), but the state it
    /// replaced is kept until the next delta: a delta that follows that state, not the key
    /// frame, puts it back and drops the key frame ([`FrameDecoder::dropped_key_frames`]).
    /// So a key frame that is not the stream's (numbered far ahead, or back) costs a
    /// receiver one frame, not its sync.
    pub fn apply(&mut self, bytes: &[u8]) -> Result<Header, DecodeError> {
        let header = peek_header(bytes)?;
        if header.kind != KIND_DELTA {
            return self.apply_one(bytes);
        }
        let stray = self.synced
            && header.prev != self.frame
            && self.before.as_ref().is_some_and(|h| h.frame == header.prev);
        if let Some(mut held) = self.before.take_if(|_| stray) {
            // The delta follows the state before the key frame: it comes back, and the key
            // frame goes, unless the delta itself is refused.
            self.exchange(&mut held);
            return match self.apply_one(bytes) {
                Ok(h) => {
                    self.dropped_key_frames += 1;
                    Ok(h)
                }
                Err(e) => {
                    self.exchange(&mut held);
                    self.before = Some(held);
                    Err(e)
                }
            };
        }
        let applied = self.apply_one(bytes);
        if applied.is_ok() {
            // The key frame is confirmed by a delta that follows it.
            self.before = None;
        }
        applied
    }

    fn apply_one(&mut self, bytes: &[u8]) -> Result<Header, DecodeError> {
        let mut r = Reader::new(bytes);
        let header = read_header(&mut r)?;
        // A key frame always applies (frame numbers restart after a reset); a delta frame
        // not newer than the state held was already folded into it.
        if header.kind == KIND_DELTA && self.synced && header.frame <= self.frame {
            return Err(DecodeError::Stale {
                frame: header.frame,
            });
        }
        if header.kind == KIND_DELTA && !(self.synced && self.frame == header.prev) {
            self.synced = false;
            return Err(DecodeError::OutOfSync {
                held: self.frame,
                follows: header.prev,
            });
        }
        // Steps since the frame before: what receivers move particles by, and what a
        // body's displacement spans.
        let steps = header.frame - header.prev;
        if header.kind == KIND_DELTA && !(1..=MAX_STEPS_A_FRAME).contains(&steps) {
            return Err(DecodeError::Malformed(format!(
                "{steps} steps from frame {} to {}",
                header.prev, header.frame
            )));
        }
        let frame_dt = header.dt * steps.max(1) as f64;
        // An emitter is at least 9 bytes: two f32 and a varint.
        let mut emitters = Vec::with_capacity(r.count(9)?);
        for _ in 0..emitters.capacity() {
            emitters.push(EmitterIn {
                x: r.f32()?,
                y: r.f32()?,
                remaining: u32::try_from(r.varint()?)
                    .map_err(|_| DecodeError::Malformed("emitter count over 32 bits".into()))?,
            });
        }
        // A delta is read against what is held; a key frame or a snapshot against nothing.
        let delta = header.kind == KIND_DELTA;
        let bodies = read_bodies(
            &mut r,
            if delta { &self.bodies } else { &[] },
            header.kind,
            frame_dt,
        )?;
        let mut particles = std::mem::take(&mut self.spare_particles);
        read_particles(
            &mut r,
            if delta { &self.particles } else { &[] },
            &mut particles,
            header.kind,
            header.frame,
            header.dt as f32,
            steps,
        )?;
        if r.at != bytes.len() {
            return Err(DecodeError::Malformed(format!(
                "{} bytes left over",
                bytes.len() - r.at
            )));
        }
        // All of it was read and checked: now it is applied.
        if header.kind == KIND_STATICS {
            self.statics.clear();
            records::fold(&mut self.statics, bodies, patch_body, |_| {});
            return Ok(header);
        }
        if !delta {
            let held = Held {
                bodies: std::mem::take(&mut self.bodies),
                particles: std::mem::take(&mut self.particles),
                emitters: std::mem::take(&mut self.emitters),
                frame: self.frame,
                time: self.time,
                dt: self.dt,
                stats: self.stats,
            };
            // The state just replaced (a real key frame then a stray one: the real one's).
            self.before = self.synced.then(|| Box::new(held));
        }
        // In a delta every body held has a record or its motion; in a key frame every
        // body is new.
        records::fold(&mut self.bodies, bodies, patch_body, |_| {});
        self.spare_particles = std::mem::replace(&mut self.particles, particles);
        self.spare_particles.clear();
        self.emitters = emitters;
        self.frame = header.frame;
        self.time = header.time;
        self.dt = header.dt;
        self.stats = header.stats;
        self.synced = true;
        Ok(header)
    }

    /// Swaps the dynamic state held with `other`.
    fn exchange(&mut self, other: &mut Held) {
        std::mem::swap(&mut self.bodies, &mut other.bodies);
        std::mem::swap(&mut self.particles, &mut other.particles);
        std::mem::swap(&mut self.emitters, &mut other.emitters);
        std::mem::swap(&mut self.frame, &mut other.frame);
        std::mem::swap(&mut self.time, &mut other.time);
        std::mem::swap(&mut self.dt, &mut other.dt);
        std::mem::swap(&mut self.stats, &mut other.stats);
    }

    /// The body with this id, dynamic or static.
    pub fn body(&self, id: &str) -> Option<&Body> {
        self.bodies.iter().chain(&self.statics).find(|b| b.id == id)
    }
}

/// A held body's state after a record, read and checked.
struct BodyPatch {
    p: [i64; 2],
    d: [i64; 2],
    dt: f64,
    collided: bool,
}

fn patch_body(b: &mut Body, p: BodyPatch) {
    (b.p, b.d, b.dt, b.collided) = (p.p, p.d, p.dt, p.collided);
}

/// Two signed varints, times `unit` (wrapping, as the encoder computes).
fn pair(r: &mut Reader, unit: i64) -> Result<[i64; 2], DecodeError> {
    Ok([
        r.svarint()?.wrapping_mul(unit),
        r.svarint()?.wrapping_mul(unit),
    ])
}

/// The previous NEW record of a section, which the next one is read against.
#[derive(Default)]
struct Previous {
    /// Of the previous record of each kind (rect, circle).
    id: [String; 2],
    group: String,
    shape: Option<(bool, [f32; 2])>,
    /// Of the previous record of each kind (rect, circle).
    p: [[i64; 2]; 2],
}

fn read_new_body(
    r: &mut Reader,
    prev: &mut Previous,
    key: u32,
    flags: u8,
    units: [i64; 2],
    dt: f64,
) -> Result<Body, DecodeError> {
    let (circle, size) = if flags & SAME_SHAPE != 0 {
        prev.shape
            .ok_or_else(|| DecodeError::Malformed(format!("body {key}: no shape before")))?
    } else {
        let circle = r.u8()? != 0;
        let w = r.f32()?;
        (circle, [w, if circle { w } else { r.f32()? }])
    };
    let kind = circle as usize;
    let shared = usize::try_from(r.varint()?).unwrap_or(usize::MAX);
    if shared > prev.id[kind].len() || !prev.id[kind].is_char_boundary(shared) {
        return Err(DecodeError::Malformed(format!(
            "body {key}: id prefix of {shared} bytes"
        )));
    }
    let mut id = String::with_capacity(shared + 8);
    id.push_str(&prev.id[kind][..shared]);
    id.push_str(&r.str()?);
    let group = if flags & SAME_GROUP != 0 {
        prev.group.clone()
    } else {
        r.str()?
    };
    let step = [r.svarint()?, r.svarint()?];
    let pu = [
        prev.p[kind][0].wrapping_add(step[0]),
        prev.p[kind][1].wrapping_add(step[1]),
    ];
    let p = pu.map(|v| v.wrapping_mul(units[0]));
    let d = if flags & VEL != 0 {
        pair(r, units[1])?
    } else {
        [0; 2]
    };
    prev.id[kind].clone_from(&id);
    prev.group.clone_from(&group);
    prev.shape = Some((circle, size));
    prev.p[kind] = pu;
    Ok(Body {
        key,
        id,
        group,
        circle,
        size,
        p,
        d,
        dt,
        collided: flags & COLLIDED != 0,
    })
}

/// Reads a body section: its records, and in a delta the motion of every body held that
/// no record removes or replaces (`motion`), as patches in increasing key order.
fn read_bodies(
    r: &mut Reader,
    held: &[Body],
    kind: u8,
    dt: f64,
) -> Result<Section<Body, BodyPatch>, DecodeError> {
    let units = if kind == KIND_RESYNC {
        [1, 1]
    } else {
        [POS_STEP, POS_STEP]
    };
    let mut prev = Previous::default();
    let mut section = records::read(r, held, |r, key, flags, existing| {
        if flags & REMOVED != 0 {
            return match existing {
                Some(_) => Ok(Change::Removed),
                None => Err(DecodeError::Malformed(format!(
                    "removal of unknown body {key}"
                ))),
            };
        }
        if flags & NEW != 0 {
            return Ok(Change::New(read_new_body(
                r, &mut prev, key, flags, units, dt,
            )?));
        }
        Err(DecodeError::Malformed(format!(
            "body {key}: a record neither NEW nor REMOVED"
        )))
    })?;
    if kind == KIND_DELTA {
        let n = usize::try_from(r.varint()?).unwrap_or(usize::MAX);
        section.patches = motion(r.take(n)?, held, &section, dt)?;
    }
    Ok(section)
}

/// Decodes a delta's motion: for each body held that `section` does not remove or
/// replace, its residuals and whether its collided flag changed, applied to its
/// prediction.
fn motion(
    bytes: &[u8],
    held: &[Body],
    section: &Section<Body, BodyPatch>,
    dt: f64,
) -> Result<Vec<(u32, BodyPatch)>, DecodeError> {
    let mut coder = RangeDecoder::new(bytes);
    let mut model = Model::new();
    let mut removed = section.removed.iter().peekable();
    let mut news = section.news.iter().map(|b| b.key).peekable();
    let mut patches = Vec::with_capacity(held.len());
    for b in held {
        while removed.next_if(|&&k| k < b.key).is_some() {}
        while news.next_if(|&k| k < b.key).is_some() {}
        if removed.next_if(|&&k| k == b.key).is_some() || news.next_if(|&k| k == b.key).is_some() {
            continue;
        }
        let (mut p, mut d) = (b.predicted(), b.d);
        let r = model.residuals(&mut coder, d, POS_STEP, [0; 2]);
        let changed = model.collided(&mut coder, b.collided, false);
        for i in 0..2 {
            let step = r[i].wrapping_mul(POS_STEP);
            p[i] = p[i].wrapping_add(step);
            d[i] = d[i].wrapping_add(step);
        }
        patches.push((
            b.key,
            BodyPatch {
                p,
                d,
                dt,
                collided: b.collided != changed,
            },
        ));
    }
    coder.finish()?;
    Ok(patches)
}

/// The previous NEW particle record of a section, which the next one is read against.
#[derive(Default)]
struct PreviousParticle {
    q: [i64; 2],
    motion: Option<([f32; 2], f32)>,
    look: Option<([u8; 4], f32)>,
}

fn read_new_particle(
    r: &mut Reader,
    prev: &mut PreviousParticle,
    id: u32,
    flags: u8,
    exact: bool,
    frame: u64,
) -> Result<Particle, DecodeError> {
    let frozen = if flags & FROZEN != 0 { r.u8()? } else { 0 };
    let (pos, vel) = if exact {
        ([r.f32()?, r.f32()?], [r.f32()?, r.f32()?])
    } else {
        let step = [r.svarint()?, r.svarint()?];
        let q = [
            prev.q[0].wrapping_add(step[0]),
            prev.q[1].wrapping_add(step[1]),
        ];
        prev.q = q;
        let v = [r.svarint()?, r.svarint()?];
        (
            q.map(|q| (q as f64 * PARTICLE_QUANTUM) as f32),
            v.map(|v| (v as f64 * PARTICLE_VEL_QUANTUM) as f32),
        )
    };
    let (acc, drag) = if flags & SAME_MOTION != 0 {
        prev.motion
            .ok_or_else(|| DecodeError::Malformed(format!("particle {id}: no motion before")))?
    } else {
        let m = ([r.f32()?, r.f32()?], r.f32()?);
        prev.motion = Some(m);
        m
    };
    let (color0, size_delta) = if flags & SAME_LOOK != 0 {
        prev.look
            .ok_or_else(|| DecodeError::Malformed(format!("particle {id}: no look before")))?
    } else {
        let l = (r.bytes4()?, r.f32()?);
        prev.look = Some(l);
        l
    };
    let color1 = r.bytes4()?;
    let initial_life = r.f32()?;
    let age = r.varint()?;
    let size = r.f32()?;
    Ok(Particle {
        id,
        pos,
        vel,
        acc,
        drag,
        frozen: [frozen & 1 != 0, frozen & 2 != 0],
        color0,
        color1,
        initial_life,
        life: initial_life - age as f32,
        size,
        size_delta,
        record_frame: frame,
    })
}

/// The particles of a key frame's particle section (`section`: from its record count to
/// the payload's end), as [`FrameDecoder::apply`] reads them: for readers that hold
/// particles their own way (the Python package's native module). `exact` in a resync key
/// frame; `frame` the frame's number. A record that is not NEW, or bytes left over, is
/// refused.
pub fn read_key_particles(
    section: &[u8],
    exact: bool,
    frame: u64,
) -> Result<Vec<Particle>, DecodeError> {
    let mut r = Reader::new(section);
    let mut out = Vec::new();
    let kind = if exact { KIND_RESYNC } else { KIND_KEY };
    read_particles(&mut r, &[], &mut out, kind, frame, 0.0, 0)?;
    if r.at != section.len() {
        return Err(DecodeError::Malformed(format!(
            "{} bytes left over",
            section.len() - r.at
        )));
    }
    Ok(out)
}

/// Reads a frame's particles against `held` into `out` (emptied first).
fn read_particles(
    r: &mut Reader,
    held: &[Particle],
    out: &mut Vec<Particle>,
    kind: u8,
    frame: u64,
    dt: f32,
    steps: u64,
) -> Result<(), DecodeError> {
    let advance = |p: &mut Particle| {
        for _ in 0..steps {
            p.advance(dt);
        }
    };
    let mut prev = PreviousParticle::default();
    let exact = kind == KIND_RESYNC;
    records::read_into_copy(
        r,
        held,
        out,
        |r, id, flags, existing| {
            if flags & REMOVED != 0 {
                return Ok(None);
            }
            if flags & NEW != 0 {
                return Ok(Some(read_new_particle(
                    r, &mut prev, id, flags, exact, frame,
                )?));
            }
            let mut p = existing.ok_or_else(|| {
                DecodeError::Malformed(format!("update of unknown particle {id}"))
            })?;
            advance(&mut p);
            if flags & POS != 0 {
                let q = [r.svarint()?, r.svarint()?];
                for (pos, q) in p.pos.iter_mut().zip(q) {
                    *pos = (*pos as f64 + q as f64 * PARTICLE_QUANTUM) as f32;
                }
            }
            if flags & VEL != 0 {
                let v = [r.svarint()?, r.svarint()?];
                p.vel = v.map(|v| (v as f64 * PARTICLE_VEL_QUANTUM) as f32);
                p.frozen = [false; 2];
            }
            p.frozen[0] |= flags & FREEZE_X != 0;
            p.frozen[1] |= flags & FREEZE_Y != 0;
            Ok(Some(p))
        },
        advance,
    )
}
