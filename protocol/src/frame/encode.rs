//! The encoder: a world's state flows in as [`BodyIn`] and [`ParticlesIn`] views; frames
//! (deltas against what receivers were last told, or key frames) and statics snapshots
//! flow out as bytes.

use super::records::{diff, Keyed, Records};
use super::wire::{put_str, put_svarint, put_varint};
use super::{
    Body, BodyIn, EmitterIn, FrameStats, Particle, ParticlesIn, ACC, ACC_STEP, COLLIDED,
    COLOR_SCALE, DISP_STEP, DISP_TOLERANCE, FINE, HALT, HEADER_BYTES, KIND_DELTA, KIND_KEY,
    KIND_RESYNC, KIND_STATICS, MAGIC, NEW, PARTICLE_QUANTUM, POS, POS_STEP, POS_TOLERANCE,
    SAME_GROUP, SAME_SHAPE, VEL,
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

fn color_byte(c: f32) -> u8 {
    (c * COLOR_SCALE).round().clamp(0.0, 255.0) as u8
}

fn put_header(out: &mut Vec<u8>, kind: u8, frame: u64, time: f64, dt: f64, s: &FrameStats) {
    out.extend_from_slice(MAGIC);
    out.push(crate::PROTOCOL_VERSION);
    out.push(kind);
    out.extend_from_slice(&frame.to_le_bytes());
    out.extend_from_slice(&time.to_le_bytes());
    out.extend_from_slice(&dt.to_le_bytes());
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
    /// Its true displacement over the last frame.
    disp: [i64; 2],
    /// The change of that displacement at the last frame.
    accel: [i64; 2],
}

impl Keyed for Sent {
    fn key(&self) -> u32 {
        self.body.key
    }
}

fn fine(v: [f64; 2]) -> [i64; 2] {
    v.map(|c| quantize(c, FINE))
}

/// A body as a key frame or a snapshot states it: its position, displacement and
/// acceleration rounded to their quanta.
fn body_of(b: &BodyIn, disp: [i64; 2], accel: [i64; 2], dt: f64) -> Body {
    Body {
        key: b.key,
        id: b.id.to_string(),
        group: b.group.to_string(),
        circle: b.circle,
        size: [b.size[0] as f32, b.size[1] as f32],
        p: fine(b.pos).map(|v| round_to(v, POS_STEP)),
        d: disp.map(|v| round_to(v, DISP_STEP)),
        a: accel.map(|v| round_to(v, ACC_STEP)),
        dt,
        collided: b.collided,
    }
}

/// The units NEW records state `p`, `d` and `a` in: the quanta, or [`FINE`] units in a
/// resync key frame.
#[derive(Clone, Copy)]
struct Units([i64; 3]);

const COARSE: Units = Units([POS_STEP, DISP_STEP, ACC_STEP]);
const EXACT: Units = Units([1, 1, 1]);

/// The previous NEW record of a section, which the next one is written against.
#[derive(Default)]
struct Previous {
    id: String,
    group: String,
    shape: Option<(bool, [f32; 2])>,
    p: [i64; 2],
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
    let [pu, du, au] = units.0;
    let same_shape = prev.shape == Some((b.circle, b.size));
    let same_group = prev.group == b.group;
    out.push(
        NEW | POS
            | if b.d != [0, 0] { VEL } else { 0 }
            | if b.a != [0, 0] { ACC } else { 0 }
            | if b.collided { COLLIDED } else { 0 }
            | if same_shape { SAME_SHAPE } else { 0 }
            | if same_group { SAME_GROUP } else { 0 },
    );
    if !same_shape {
        out.push(b.circle as u8);
        out.extend_from_slice(&b.size[0].to_le_bytes());
        out.extend_from_slice(&b.size[1].to_le_bytes());
    }
    let shared = shared_prefix(&prev.id, &b.id);
    put_varint(out, shared as u64);
    put_str(out, &b.id[shared..]);
    if !same_group {
        put_str(out, &b.group);
    }
    let p = b.p.map(|v| v / pu);
    put_svarint(out, p[0].wrapping_sub(prev.p[0]));
    put_svarint(out, p[1].wrapping_sub(prev.p[1]));
    if b.d != [0, 0] {
        put_svarint(out, b.d[0] / du);
        put_svarint(out, b.d[1] / du);
    }
    if b.a != [0, 0] {
        put_svarint(out, b.a[0] / au);
        put_svarint(out, b.a[1] / au);
    }
    prev.id.clear();
    prev.id.push_str(&b.id);
    if !same_group {
        prev.group.clear();
        prev.group.push_str(&b.group);
    }
    prev.shape = Some((b.circle, b.size));
    prev.p = p;
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
        frame,
        time,
        0.0,
        &FrameStats::default(),
    );
    put_varint(&mut out, 0);
    let mut bodies: Vec<Body> = statics
        .iter()
        .map(|b| body_of(b, [0; 2], [0; 2], 0.0))
        .collect();
    bodies.sort_by_key(|b| b.key);
    put_bodies(&mut out, &bodies, COARSE);
    put_varint(&mut out, 0);
    out
}

/// The header of a frame, for [`FrameEncoder::resync_frame`].
#[derive(Clone, Debug)]
struct Last {
    frame: u64,
    time: f64,
    dt: f64,
    stats: FrameStats,
    emitters: Vec<EmitterIn>,
}

/// Turns a world's states into frames, remembering what receivers were last told.
#[derive(Clone, Debug)]
pub struct FrameEncoder {
    bodies: Vec<Sent>,
    particles: Vec<Particle>,
    keyframe_interval: u64,
    since_key: u64,
    force_key: bool,
    /// Header and emitters of the last frame encoded.
    last: Option<Last>,
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
            last.frame,
            last.time,
            last.dt,
            &last.stats,
        );
        put_emitters(&mut out, &last.emitters);
        let bodies: Vec<Body> = self.bodies.iter().map(|s| s.body.clone()).collect();
        put_bodies(&mut out, &bodies, EXACT);
        // A particle's birth record restated as of this frame.
        put_all(
            &mut out,
            &self.particles,
            |p| p.id,
            |out, p| put_new_particle(out, &p.as_of(last.frame)),
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

    /// Encodes one frame. `dt` is the time a frame stands for (the world's step);
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
        // A new dt changes what a displacement per frame means: receivers start afresh.
        let dt_changed = self.last.as_ref().is_some_and(|l| l.dt != dt);
        let key = self.force_key || dt_changed || self.since_key + 1 >= self.keyframe_interval;
        if key {
            self.force_key = false;
            self.since_key = 0;
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
            dt,
            stats,
        );
        put_emitters(&mut out, emitters);
        self.encode_bodies(&mut out, key, dt, bodies);
        self.encode_particles(&mut out, frame, particles);
        self.last = Some(Last {
            frame,
            time,
            dt,
            stats: *stats,
            emitters: emitters.to_vec(),
        });
        out
    }

    /// The bodies' section: in a key frame every body NEW, its state rounded to the
    /// quanta; in a delta, a record for each body the prediction missed by more than half
    /// a quantum (and for each new, changed or removed body). The truth about each body
    /// (its last position, displacement and acceleration) is kept across key frames.
    fn encode_bodies(&mut self, out: &mut Vec<u8>, key: bool, dt: f64, bodies: &[BodyIn]) {
        let mut records = Records::with_capacity(bodies.len() * if key { 12 } else { 4 });
        let mut prev = Previous::default();
        let mut sent = std::mem::take(&mut self.bodies);
        if key {
            // A key frame states what is; receivers drop what it does not name.
            sent.retain(|s| bodies.binary_search_by_key(&s.body.key, |b| b.key).is_ok());
        }
        self.bodies = diff(
            sent,
            bodies.iter(),
            |b| b.key,
            &mut records,
            |records, old, now| {
                let truth = fine(now.pos);
                let size = [now.size[0] as f32, now.size[1] as f32];
                let same = old.filter(|old| {
                    let b = &old.body;
                    b.id == now.id
                        && b.size == size
                        && b.circle == now.circle
                        && b.group == now.group
                });
                let Some(mut old) = same else {
                    // New, or a different body under a reused key: sent whole, its
                    // displacement from its velocity.
                    let disp = fine(now.vel.map(|v| v * dt));
                    let body = body_of(now, disp, [0; 2], dt);
                    put_new_body(records.start(now.key), &mut prev, &body, COARSE);
                    return Sent {
                        body,
                        truth,
                        disp,
                        accel: [0; 2],
                    };
                };
                let disp = [
                    truth[0].wrapping_sub(old.truth[0]),
                    truth[1].wrapping_sub(old.truth[1]),
                ];
                let accel = [
                    disp[0].wrapping_sub(old.disp[0]),
                    disp[1].wrapping_sub(old.disp[1]),
                ];
                (old.truth, old.disp, old.accel) = (truth, disp, accel);
                let b = &mut old.body;
                b.dt = dt;
                if key {
                    let fresh = body_of(now, disp, accel, dt);
                    (b.p, b.d, b.a, b.collided) = (fresh.p, fresh.d, fresh.a, fresh.collided);
                    put_new_body(records.start(now.key), &mut prev, b, COARSE);
                    return old;
                }
                let (p, d) = b.predicted();
                let strayed = (0..2).any(|i| truth[i].wrapping_sub(p[i]).abs() > POS_TOLERANCE);
                let rp: [i64; 2] = if strayed {
                    std::array::from_fn(|i| steps(truth[i].wrapping_sub(p[i]), POS_STEP))
                } else {
                    [0; 2]
                };
                let off = |i: usize| disp[i].wrapping_sub(d[i]).abs() > DISP_TOLERANCE;
                let moved = rp != [0, 0];
                let record = moved || off(0) || off(1) || b.collided != now.collided;
                // A record sets the displacement and its change to the truth's: to 0 at
                // once for a body that holds still, else corrected by a quantum.
                let still = disp.iter().all(|v| v.abs() <= DISP_STEP / 2);
                let halt = record && still && (d != [0, 0] || b.a != [0, 0]);
                let (rd, ra) = if record && !halt {
                    (
                        [0, 1].map(|i| steps(disp[i].wrapping_sub(d[i]), DISP_STEP)),
                        [0, 1].map(|i| steps(accel[i].wrapping_sub(b.a[i]), ACC_STEP)),
                    )
                } else {
                    ([0; 2], [0; 2])
                };
                let (sped, accelerated) = (rd != [0, 0], ra != [0, 0]);
                if record {
                    let out = records.start(now.key);
                    out.push(
                        (moved as u8 * POS)
                            | (sped as u8 * VEL)
                            | (accelerated as u8 * ACC)
                            | (halt as u8 * HALT)
                            | (now.collided as u8 * COLLIDED),
                    );
                    for (on, r) in [(moved, rp), (sped, rd), (accelerated, ra)] {
                        if on {
                            put_svarint(out, r[0]);
                            put_svarint(out, r[1]);
                        }
                    }
                }
                b.p = [0, 1].map(|i| p[i].wrapping_add(rp[i].wrapping_mul(POS_STEP)));
                if halt {
                    (b.d, b.a) = ([0; 2], [0; 2]);
                } else {
                    b.d = [0, 1].map(|i| d[i].wrapping_add(rd[i].wrapping_mul(DISP_STEP)));
                    b.a = [0, 1].map(|i| b.a[i].wrapping_add(ra[i].wrapping_mul(ACC_STEP)));
                }
                b.collided = now.collided;
                old
            },
        );
        records.finish(out);
    }

    fn encode_particles(&mut self, out: &mut Vec<u8>, frame: u64, p: &ParticlesIn) {
        let n = p.id.len();
        let mut records = Records::with_capacity(n * 4);
        let sent = std::mem::take(&mut self.particles);
        self.particles = diff(
            sent,
            0..n,
            |&i| p.id[i],
            &mut records,
            |records, old, i| {
                let id = p.id[i];
                let qpos = [
                    quantize(p.x[i] as f64, PARTICLE_QUANTUM),
                    quantize(p.y[i] as f64, PARTICLE_QUANTUM),
                ];
                match old {
                    Some(mut old) => {
                        if old.qpos != qpos {
                            let out = records.start(id);
                            out.push(POS);
                            put_svarint(out, qpos[0] - old.qpos[0]);
                            put_svarint(out, qpos[1] - old.qpos[1]);
                            old.qpos = qpos;
                        }
                        old
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
                        put_new_particle(records.start(id), &particle);
                        particle
                    }
                }
            },
        );
        records.finish(out);
    }
}
