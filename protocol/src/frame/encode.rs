//! The encoder: a world's state flows in as [`BodyIn`] and [`ParticlesIn`] views; frames
//! (deltas against what receivers were last told, or key frames) and statics snapshots
//! flow out as bytes.

use super::motion::{Model, RangeEncoder};
use super::records::{diff, Keyed, Records};
use super::wire::{put_str, put_svarint, put_varint};
use super::{
    Body, BodyIn, EmitterIn, FrameStats, Particle, ParticlesIn, COLLIDED, COLOR_SCALE, FINE,
    FREEZE_X, FREEZE_Y, FROZEN, HEADER_BYTES, KIND_DELTA, KIND_KEY, KIND_RESYNC, KIND_STATICS,
    MAGIC, NEW, PARTICLE_QUANTUM, PARTICLE_VEL_QUANTUM, POS, POS_STEP, SAME_GROUP, SAME_LOOK,
    SAME_MOTION, SAME_SHAPE, VEL,
};

fn quantize(v: f64, quantum: f64) -> i64 {
    let q = (v / quantum).round();
    if q.is_finite() {
        q.clamp(i64::MIN as f64 / 4.0, i64::MAX as f64 / 4.0) as i64
    } else {
        0
    }
}

/// `v / step` rounded to the nearest integer, ties away from zero.
fn steps(v: i64, step: i64) -> i64 {
    let (v, step) = (v as i128, step as i128);
    let half = step / 2;
    let q = if v >= 0 {
        (v + half) / step
    } else {
        -((-v + half) / step)
    };
    q.clamp(i64::MIN as i128, i64::MAX as i128) as i64
}

/// `v` rounded to a multiple of `step`.
fn round_to(v: i64, step: i64) -> i64 {
    steps(v, step).wrapping_mul(step)
}

/// A colour channel as a byte: `(c * 255).round().clamp(0, 255)`, without the call into
/// libm that baseline x86-64 makes of `round` (eight a particle in a key frame). Exact:
/// clamped first, the f32 plus a half is exact in f64, and truncating it rounds half up.
fn color_byte(c: f32) -> u8 {
    (f64::from((c * COLOR_SCALE).clamp(0.0, 255.0)) + 0.5) as u8
}

/// Where a frame sits in its stream: its number, and the number of the frame before it.
#[derive(Clone, Copy, Debug)]
struct At {
    frame: u64,
    prev: u64,
}

fn put_header(out: &mut Vec<u8>, kind: u8, at: At, time: f64, dt: f64, s: &FrameStats) {
    out.extend_from_slice(MAGIC);
    out.push(crate::PROTOCOL_VERSION);
    out.push(kind);
    out.extend_from_slice(&at.frame.to_le_bytes());
    out.extend_from_slice(&at.prev.to_le_bytes());
    out.extend_from_slice(&time.to_le_bytes());
    out.extend_from_slice(&dt.to_le_bytes());
    for v in [
        s.step_ms.to_bits(),
        s.contacts,
        s.solver_passes,
        s.deepest_penetration.to_bits(),
        s.kinetic_energy.to_bits(),
        s.particle_contacts,
        s.overruns,
        s.dynamic_bodies,
        s.particles,
        s.emitters,
        s.energy_change.to_bits(),
        s.residual.to_bits(),
    ] {
        out.extend_from_slice(&v.to_le_bytes());
    }
}

/// What receivers hold of a body, beside what the encoder knows of its truth.
#[derive(Clone, Debug)]
struct Sent {
    body: Body,
    /// The body's true position at the last frame, in [`FINE`] units.
    truth: [i64; 2],
}

impl Keyed for Sent {
    fn key(&self) -> u32 {
        self.body.key
    }
}

fn fine(v: [f64; 2]) -> [i64; 2] {
    v.map(|c| quantize(c, FINE))
}

/// A body's position and displacement as a NEW record states them: rounded to their
/// quanta.
fn rounded(b: &BodyIn, disp: [i64; 2]) -> [[i64; 2]; 2] {
    [
        fine(b.pos).map(|v| round_to(v, POS_STEP)),
        disp.map(|v| round_to(v, POS_STEP)),
    ]
}

/// A body as a NEW record states it (see [`rounded`]).
fn body_of(b: &BodyIn, disp: [i64; 2], dt: f64) -> Body {
    let [p, d] = rounded(b, disp);
    Body {
        key: b.key,
        id: b.id.to_string(),
        group: b.group.to_string(),
        circle: b.circle,
        size: [b.size[0] as f32, b.size[1] as f32],
        p,
        d,
        dt,
        collided: b.collided,
    }
}

/// The units NEW records state `p` and `d` in: the quanta, or [`FINE`] units in a
/// resync key frame.
#[derive(Clone, Copy)]
struct Units([i64; 2]);

const COARSE: Units = Units([POS_STEP, POS_STEP]);
const EXACT: Units = Units([1, 1]);

/// The previous NEW record of a section, which the next one is written against.
#[derive(Default)]
struct Previous {
    /// Of the previous record of each kind (rect, circle).
    id: [String; 2],
    group: String,
    shape: Option<(bool, [f32; 2])>,
    /// Of the previous record of each kind (rect, circle).
    p: [[i64; 2]; 2],
}

/// The length of the prefix `a` and `b` share, at a character boundary.
fn shared_prefix(a: &str, b: &str) -> usize {
    let mut n = a.bytes().zip(b.bytes()).take_while(|(x, y)| x == y).count();
    while !b.is_char_boundary(n) {
        n -= 1;
    }
    n
}

fn put_new_body(out: &mut Vec<u8>, prev: &mut Previous, b: &Body, units: Units) {
    let [pu, du] = units.0;
    let same_shape = prev.shape == Some((b.circle, b.size));
    let same_group = prev.group == b.group;
    out.push(
        NEW | if b.d != [0, 0] { VEL } else { 0 }
            | if b.collided { COLLIDED } else { 0 }
            | if same_shape { SAME_SHAPE } else { 0 }
            | if same_group { SAME_GROUP } else { 0 },
    );
    if !same_shape {
        out.push(b.circle as u8);
        out.extend_from_slice(&b.size[0].to_le_bytes());
        if !b.circle {
            out.extend_from_slice(&b.size[1].to_le_bytes());
        }
    }
    let kind = b.circle as usize;
    let shared = shared_prefix(&prev.id[kind], &b.id);
    put_varint(out, shared as u64);
    put_str(out, &b.id[shared..]);
    if !same_group {
        put_str(out, &b.group);
    }
    let p = b.p.map(|v| v / pu);
    put_svarint(out, p[0].wrapping_sub(prev.p[kind][0]));
    put_svarint(out, p[1].wrapping_sub(prev.p[kind][1]));
    if b.d != [0, 0] {
        put_svarint(out, b.d[0] / du);
        put_svarint(out, b.d[1] / du);
    }
    prev.id[kind].clear();
    prev.id[kind].push_str(&b.id);
    if !same_group {
        prev.group.clear();
        prev.group.push_str(&b.group);
    }
    prev.shape = Some((b.circle, b.size));
    prev.p[kind] = p;
}

/// The previous NEW particle record of a section, which the next one is written against.
#[derive(Default)]
struct PreviousParticle {
    q: [i64; 2],
    motion: Option<[u32; 3]>,
    look: Option<([u8; 4], u32)>,
}

/// A particle's motion and look as compared between records: the bits of its floats.
fn motion_of(p: &Particle) -> [u32; 3] {
    [p.acc[0].to_bits(), p.acc[1].to_bits(), p.drag.to_bits()]
}

/// How a NEW particle record gives position and velocity: their f32 bits (a resync), or
/// in [`PARTICLE_QUANTUM`] and [`PARTICLE_VEL_QUANTUM`] steps (the particle's `pos` and
/// `vel` are these steps dequantized).
enum Place {
    Exact,
    Steps { pos: [i64; 2], vel: [i64; 2] },
}

fn put_new_particle(out: &mut Vec<u8>, prev: &mut PreviousParticle, p: &Particle, place: Place) {
    let motion = motion_of(p);
    let look = (p.color0, p.size_delta.to_bits());
    let frozen = p.frozen[0] as u8 | (p.frozen[1] as u8) << 1;
    let same_motion = prev.motion == Some(motion);
    let same_look = prev.look == Some(look);
    out.push(
        NEW | if frozen != 0 { FROZEN } else { 0 }
            | if same_motion { SAME_MOTION } else { 0 }
            | if same_look { SAME_LOOK } else { 0 },
    );
    if frozen != 0 {
        out.push(frozen);
    }
    match place {
        Place::Exact => {
            for v in p.pos.iter().chain(&p.vel) {
                out.extend_from_slice(&v.to_bits().to_le_bytes());
            }
        }
        Place::Steps { pos, vel } => {
            put_svarint(out, pos[0].wrapping_sub(prev.q[0]));
            put_svarint(out, pos[1].wrapping_sub(prev.q[1]));
            prev.q = pos;
            for v in vel {
                put_svarint(out, v);
            }
        }
    }
    if !same_motion {
        for v in [p.acc[0], p.acc[1], p.drag] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        prev.motion = Some(motion);
    }
    if !same_look {
        out.extend_from_slice(&p.color0);
        out.extend_from_slice(&p.size_delta.to_le_bytes());
        prev.look = Some(look);
    }
    out.extend_from_slice(&p.color1);
    out.extend_from_slice(&p.initial_life.to_le_bytes());
    put_varint(out, (p.initial_life - p.life).max(0.0).round() as u64);
    out.extend_from_slice(&p.size.to_le_bytes());
}

/// A value as receivers get it from `quantum` steps.
fn dequantize(v: f32, quantum: f64) -> f32 {
    (quantize(v as f64, quantum) as f64 * quantum) as f32
}

/// What receivers hold of a particle, beside its true position at the last frame.
#[derive(Clone, Debug)]
struct ParticleSent {
    p: Particle,
    truth: [f32; 2],
}

impl Keyed for ParticleSent {
    fn key(&self) -> u32 {
        self.p.id
    }
}

/// A true move smaller than this on an axis (units) holds a particle still on it.
const HELD: f64 = PARTICLE_QUANTUM / 4.0;

fn put_emitters(out: &mut Vec<u8>, emitters: &[EmitterIn]) {
    put_varint(out, emitters.len() as u64);
    for e in emitters {
        out.extend_from_slice(&e.x.to_le_bytes());
        out.extend_from_slice(&e.y.to_le_bytes());
        put_varint(out, e.remaining as u64);
    }
}

/// A whole section of NEW records: a key frame's, or the snapshot's.
fn put_all<T>(
    out: &mut Vec<u8>,
    items: &[T],
    key: impl Fn(&T) -> u32,
    mut put: impl FnMut(&mut Vec<u8>, &T),
) {
    let mut records = Records::with_capacity(items.len() * 32);
    for item in items {
        put(records.start(key(item)), item);
    }
    records.finish(out);
}

fn put_bodies(out: &mut Vec<u8>, bodies: &[Body], units: Units) {
    let mut prev = Previous::default();
    put_all(
        out,
        bodies,
        |b| b.key,
        |out, b| put_new_body(out, &mut prev, b, units),
    );
}

/// Encodes the statics snapshot: every static body, as NEW records.
pub fn encode_statics(frame: u64, time: f64, statics: &[BodyIn]) -> Vec<u8> {
    let mut out = Vec::with_capacity(HEADER_BYTES + statics.len() * 40);
    put_header(
        &mut out,
        KIND_STATICS,
        At { frame, prev: frame },
        time,
        0.0,
        &FrameStats::default(),
    );
    put_varint(&mut out, 0);
    let mut bodies: Vec<Body> = statics.iter().map(|b| body_of(b, [0; 2], 0.0)).collect();
    bodies.sort_by_key(|b| b.key);
    put_bodies(&mut out, &bodies, COARSE);
    put_varint(&mut out, 0);
    out
}

/// The header of a frame, for [`FrameEncoder::resync_frame`].
#[derive(Clone, Debug)]
struct Last {
    at: At,
    time: f64,
    dt: f64,
    stats: FrameStats,
    emitters: Vec<EmitterIn>,
}

/// What the bodies' section of one frame is written with.
struct Tracking {
    /// The previous NEW record.
    prev: Previous,
    /// The coder of a delta's motion and its model; none in a key frame.
    motion: Option<(RangeEncoder, Model)>,
    /// Seconds the frame stands for.
    dt: f64,
}

impl Tracking {
    /// Writes what receivers need of `now`, given what they hold of it (`held`, updated
    /// in place): its residuals in a delta, its NEW record in a key frame. A body they
    /// do not hold, or a different body under its key, is sent whole (a NEW record, its
    /// displacement from its velocity) and returned.
    fn track(
        &mut self,
        records: &mut Records,
        held: Option<&mut Sent>,
        now: &BodyIn,
    ) -> Option<Sent> {
        let truth = fine(now.pos);
        let size = [now.size[0] as f32, now.size[1] as f32];
        let same = held.filter(|old| {
            let b = &old.body;
            b.id == now.id && b.size == size && b.circle == now.circle && b.group == now.group
        });
        let Some(old) = same else {
            let disp = fine(now.vel.map(|v| v * self.dt));
            let body = body_of(now, disp, self.dt);
            put_new_body(records.start(now.key), &mut self.prev, &body, COARSE);
            return Some(Sent { body, truth });
        };
        let disp = [
            truth[0].wrapping_sub(old.truth[0]),
            truth[1].wrapping_sub(old.truth[1]),
        ];
        old.truth = truth;
        let b = &mut old.body;
        b.dt = self.dt;
        let Some((coder, model)) = self.motion.as_mut() else {
            // The body it already is, restated: no new id or group strings.
            [b.p, b.d] = rounded(now, disp);
            b.collided = now.collided;
            put_new_body(records.start(now.key), &mut self.prev, b, COARSE);
            return None;
        };
        let p = b.predicted();
        let r = [0, 1].map(|i| steps(truth[i].wrapping_sub(p[i]), POS_STEP));
        model.residuals(coder, b.d, POS_STEP, r);
        model.collided(coder, b.collided, b.collided != now.collided);
        for i in 0..2 {
            let step = r[i].wrapping_mul(POS_STEP);
            b.p[i] = p[i].wrapping_add(step);
            b.d[i] = b.d[i].wrapping_add(step);
        }
        b.collided = now.collided;
        None
    }
}

/// Turns a world's states into frames, remembering what receivers were last told.
#[derive(Clone, Debug)]
pub struct FrameEncoder {
    bodies: Vec<Sent>,
    particles: Vec<ParticleSent>,
    keyframe_interval: u64,
    /// Periodic key frames come at the frames (steps) that are `key_at` past a multiple
    /// of `key_every`.
    key_every: u64,
    key_at: u64,
    force_key: bool,
    /// Header and emitters of the last frame encoded.
    last: Option<Last>,
}

impl FrameEncoder {
    /// For a stream of one frame in `every` steps: its periodic key frames come at the
    /// steps that are `phase` of its frames past a multiple of its interval (by default
    /// at the multiples of the interval, counted in steps from the world's frame 0).
    /// Streams encoded side by side with different phases never make their key frames,
    /// the costliest frames to encode, in the same step.
    pub fn with_key_schedule(mut self, every: u64, phase: u64) -> Self {
        let every = every.max(1);
        self.key_every = self.keyframe_interval.saturating_mul(every);
        self.key_at = (phase % self.keyframe_interval) * every;
        self
    }

    /// A key frame every `keyframe_interval` frames (at least 1).
    pub fn new(keyframe_interval: u64) -> Self {
        FrameEncoder {
            bodies: Vec::new(),
            particles: Vec::new(),
            keyframe_interval: keyframe_interval.max(1),
            key_every: keyframe_interval.max(1),
            key_at: 0,
            force_key: true,
            last: None,
        }
    }

    /// A key frame of what receivers hold after the last frame encoded, exactly (its
    /// bodies in [`FINE`] units): a late joiner applies it, then the delta frames that
    /// follow it. `None` before the first frame.
    pub fn resync_frame(&self) -> Option<Vec<u8>> {
        let last = self.last.as_ref()?;
        let mut out =
            Vec::with_capacity(HEADER_BYTES + self.bodies.len() * 40 + self.particles.len() * 30);
        put_header(
            &mut out,
            KIND_RESYNC,
            last.at,
            last.time,
            last.dt,
            &last.stats,
        );
        put_emitters(&mut out, &last.emitters);
        let bodies: Vec<Body> = self.bodies.iter().map(|s| s.body.clone()).collect();
        put_bodies(&mut out, &bodies, EXACT);
        // Each particle as receivers hold it, its life and size as of this frame.
        let mut prev = PreviousParticle::default();
        put_all(
            &mut out,
            &self.particles,
            |s| s.p.id,
            |out, s| put_new_particle(out, &mut prev, &s.p.as_of(last.at.frame), Place::Exact),
        );
        Some(out)
    }

    /// The next frame will be a key frame, and what the encoder knew of the bodies'
    /// motion is forgotten (after a reset or a new scene: the frames from there on are
    /// the same whatever came before).
    pub fn force_key_frame(&mut self) {
        self.force_key = true;
        self.bodies.clear();
    }

    /// Encodes one frame. `dt` is the world's step; a frame follows the frame encoded
    /// before it, however many steps apart (a stream may carry every `k`-th step);
    /// `bodies` are the dynamic bodies and `particles` the particles, each in increasing
    /// key (id) order, as the engine keeps them.
    #[allow(clippy::too_many_arguments)]
    pub fn encode(
        &mut self,
        frame: u64,
        time: f64,
        dt: f64,
        stats: &FrameStats,
        emitters: &[EmitterIn],
        bodies: &[BodyIn],
        particles: &ParticlesIn,
    ) -> Vec<u8> {
        // The frame this one follows in the stream; after a reset (frame numbers start
        // again) or before the first, the step before.
        let prev = match &self.last {
            Some(l) if l.at.frame < frame => l.at.frame,
            _ => {
                self.force_key = true;
                frame.saturating_sub(1)
            }
        };
        let at = At { frame, prev };
        let steps = (frame - prev).max(1);
        // A new dt changes what a displacement per frame means: receivers start afresh.
        let dt_changed = self.last.as_ref().is_some_and(|l| l.dt != dt);
        let key = self.force_key || dt_changed || frame % self.key_every == self.key_at;
        if key {
            self.force_key = false;
            self.particles.clear();
        }
        let mut out =
            Vec::with_capacity(HEADER_BYTES + 64 + bodies.len() * 8 + particles.id.len() * 6);
        put_header(
            &mut out,
            if key { KIND_KEY } else { KIND_DELTA },
            at,
            time,
            dt,
            stats,
        );
        put_emitters(&mut out, emitters);
        self.encode_bodies(&mut out, key, dt * steps as f64, bodies);
        self.encode_particles(&mut out, frame, dt as f32, steps, particles);
        self.last = Some(Last {
            at,
            time,
            dt,
            stats: *stats,
            emitters: emitters.to_vec(),
        });
        out
    }

    /// The bodies' section: in a key frame every body NEW, its state rounded to the
    /// quanta; in a delta, NEW and REMOVED records for bodies added, replaced or gone,
    /// then the motion of every other body (its residuals, range-coded). The truth about
    /// each body (its last position) is kept across key frames.
    fn encode_bodies(&mut self, out: &mut Vec<u8>, key: bool, dt: f64, bodies: &[BodyIn]) {
        let mut records = Records::with_capacity(if key { bodies.len() * 12 } else { 16 });
        let mut t = Tracking {
            prev: Previous::default(),
            motion: (!key).then(|| (RangeEncoder::new(), Model::new())),
            dt,
        };
        let mut sent = std::mem::take(&mut self.bodies);
        if key {
            // A key frame states what is; receivers drop what it does not name.
            sent.retain(|s| bodies.binary_search_by_key(&s.body.key, |b| b.key).is_ok());
        }
        let same_keys =
            sent.len() == bodies.len() && sent.iter().zip(bodies).all(|(s, b)| s.body.key == b.key);
        self.bodies = if same_keys {
            // No body added or removed (most frames): what receivers hold is updated in
            // place.
            for (held, now) in sent.iter_mut().zip(bodies) {
                if let Some(new) = t.track(&mut records, Some(held), now) {
                    *held = new;
                }
            }
            sent
        } else {
            diff(
                sent,
                bodies.iter(),
                |b| b.key,
                &mut records,
                |records, old, now| match old {
                    Some(mut held) => t.track(records, Some(&mut held), now).unwrap_or(held),
                    None => t
                        .track(records, None, now)
                        .expect("a new body is sent whole"),
                },
            )
        };
        records.finish(out);
        if let Some((coder, _)) = t.motion {
            let bytes = coder.finish();
            put_varint(out, bytes.len() as u64);
            out.extend_from_slice(&bytes);
        }
    }

    /// The particles' section: NEW records for the born (and, in a key frame, for every
    /// particle), REMOVED for the expired, and a record for each particle that the update
    /// receivers run missed by more than [`PARTICLE_BOUND`](super::PARTICLE_BOUND).
    fn encode_particles(
        &mut self,
        out: &mut Vec<u8>,
        frame: u64,
        dt: f32,
        steps: u64,
        p: &ParticlesIn,
    ) {
        let n = p.id.len();
        let mut records = Records::with_capacity(n * 2);
        let mut prev = PreviousParticle::default();
        // What receivers hold, merged with the particles now in place: a particle held
        // moves down over the ones that expired before it (`w` trails `r`), the newborn
        // (ids beyond every one held) go at the end. Copying every particle into a new
        // list each frame cost more than all the rest of the encoding.
        let mut sent = std::mem::take(&mut self.particles);
        let (mut r, mut w) = (0, 0);
        for i in 0..n {
            let id = p.id[i];
            while sent.get(r).is_some_and(|s| s.p.id < id) {
                records.removed(sent[r].p.id);
                r += 1;
            }
            if sent.get(r).is_some_and(|s| s.p.id == id) {
                sent.swap(w, r);
                track_particle(&mut records, &mut sent[w], p, i, dt, steps);
                r += 1;
            } else {
                let new = new_particle(&mut records, &mut prev, p, i, frame);
                if w < r {
                    // The slot of one that expired.
                    sent[w] = new;
                } else {
                    sent.insert(w, new);
                    r += 1;
                }
            }
            w += 1;
        }
        for s in &sent[r..] {
            records.removed(s.p.id);
        }
        sent.truncate(w);
        self.particles = sent;
        records.finish(out);
    }
}

/// A particle receivers do not hold: its NEW record, and what they hold of it then.
fn new_particle(
    records: &mut Records,
    prev: &mut PreviousParticle,
    p: &ParticlesIn,
    i: usize,
    frame: u64,
) -> ParticleSent {
    let id = p.id[i];
    let truth = [p.x[i], p.y[i]];
    let color0 = p.color[i];
    let life0 = p.initial_life[i];
    let color1: [f32; 4] = std::array::from_fn(|c| color0[c] + p.color_delta[i][c] * life0);
    // Quantized once: the record gives these steps, and receivers hold them dequantized.
    let pos = truth.map(|v| quantize(v as f64, PARTICLE_QUANTUM));
    let vel = [p.vx[i], p.vy[i]].map(|v| quantize(v as f64, PARTICLE_VEL_QUANTUM));
    let particle = Particle {
        id,
        pos: pos.map(|q| (q as f64 * PARTICLE_QUANTUM) as f32),
        vel: vel.map(|q| (q as f64 * PARTICLE_VEL_QUANTUM) as f32),
        acc: [p.ax[i], p.ay[i]],
        drag: p.drag[i],
        frozen: [false; 2],
        color0: color0.map(color_byte),
        color1: color1.map(color_byte),
        initial_life: life0,
        life: life0 - (life0 - p.life[i]).max(0.0).round(),
        size: p.size[i],
        size_delta: p.size_delta[i],
        record_frame: frame,
    };
    put_new_particle(
        records.start(id),
        prev,
        &particle,
        Place::Steps { pos, vel },
    );
    ParticleSent { p: particle, truth }
}

/// A particle receivers hold (`s`, updated): moved on as they move it, and a record
/// where that missed it by more than [`PARTICLE_BOUND`](super::PARTICLE_BOUND).
fn track_particle(
    records: &mut Records,
    s: &mut ParticleSent,
    p: &ParticlesIn,
    i: usize,
    dt: f32,
    steps: u64,
) {
    let truth = [p.x[i], p.y[i]];
    for _ in 0..steps {
        s.p.advance(dt);
    }
    let moved = [0, 1].map(|k| (truth[k] as f64 - s.truth[k] as f64).abs());
    s.truth = truth;
    let err = [0, 1].map(|k| truth[k] as f64 - s.p.pos[k] as f64);
    if err.iter().all(|e| e.abs() <= super::PARTICLE_BOUND) {
        return;
    }
    let r = err.map(|e| quantize(e, PARTICLE_QUANTUM));
    let held = moved.map(|m| m <= HELD);
    // A frozen axis the particle now moves on needs its velocity back.
    let thaw = (0..2).any(|k| s.p.frozen[k] && !held[k]);
    let freeze: [bool; 2] = std::array::from_fn(|k| held[k] && (thaw || !s.p.frozen[k]));
    let out = records.start(s.p.id);
    out.push(
        POS | if thaw { VEL } else { 0 }
            | if freeze[0] { FREEZE_X } else { 0 }
            | if freeze[1] { FREEZE_Y } else { 0 },
    );
    put_svarint(out, r[0]);
    put_svarint(out, r[1]);
    for (pos, r) in s.p.pos.iter_mut().zip(r) {
        *pos = (*pos as f64 + r as f64 * PARTICLE_QUANTUM) as f32;
    }
    if thaw {
        for (vel, v) in s.p.vel.iter_mut().zip([p.vx[i], p.vy[i]]) {
            put_svarint(out, quantize(v as f64, PARTICLE_VEL_QUANTUM));
            *vel = dequantize(v, PARTICLE_VEL_QUANTUM);
        }
        s.p.frozen = [false; 2];
    }
    for (frozen, freeze) in s.p.frozen.iter_mut().zip(freeze) {
        *frozen |= freeze;
    }
}

#[cfg(test)]
mod tests {
    use super::{color_byte, COLOR_SCALE};
    use proptest::prelude::*;

    fn reference(c: f32) -> u8 {
        (c * COLOR_SCALE).round().clamp(0.0, 255.0) as u8
    }

    #[test]
    fn a_colour_byte_is_the_rounded_channel_at_every_half() {
        for k in -4..=(2 * 255 + 4) {
            let at = k as f32 / (2.0 * COLOR_SCALE);
            for c in [at.next_down(), at, at.next_up()] {
                assert_eq!(color_byte(c), reference(c), "{c:e}");
            }
        }
        for c in [
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::MAX,
            f32::MIN,
            -0.0,
        ] {
            assert_eq!(color_byte(c), reference(c), "{c:e}");
        }
    }

    proptest! {
        #[test]
        fn a_colour_byte_is_the_rounded_channel(bits in any::<u32>(), c in -0.5f32..1.5) {
            let any = f32::from_bits(bits);
            prop_assert_eq!(color_byte(any), reference(any));
            prop_assert_eq!(color_byte(c), reference(c));
        }
    }
}
