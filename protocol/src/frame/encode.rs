//! The encoder: a world's state flows in as [`BodyIn`] and [`ParticlesIn`] views; frames
//! (deltas against what receivers were last told, or key frames) and statics snapshots
//! flow out as bytes.

use super::records::{diff, Records};
use super::wire::{put_str, put_svarint, put_varint};
use super::{
    Body, BodyIn, EmitterIn, FrameStats, Particle, ParticlesIn, COLLIDED, COLOR_SCALE,
    HEADER_BYTES, KIND_DELTA, KIND_KEY, KIND_STATICS, MAGIC, NEW, PARTICLE_QUANTUM, POS,
    POS_QUANTUM, VEL, VEL_QUANTUM,
};

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
        s.energy_change.to_bits(),
        s.residual.to_bits(),
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

/// A whole section of NEW records: a key frame's, or the snapshot's.
fn put_all<T>(
    out: &mut Vec<u8>,
    items: &[T],
    key: impl Fn(&T) -> u32,
    put: impl Fn(&mut Vec<u8>, &T),
) {
    let mut records = Records::with_capacity(items.len() * 32);
    for item in items {
        put(records.start(key(item)), item);
    }
    records.finish(out);
}

/// Encodes the statics snapshot: every static body, as NEW records.
pub fn encode_statics(frame: u64, time: f64, statics: &[BodyIn]) -> Vec<u8> {
    let mut out = Vec::with_capacity(HEADER_BYTES + statics.len() * 40);
    put_header(&mut out, KIND_STATICS, frame, time, &FrameStats::default());
    put_varint(&mut out, 0);
    let mut bodies: Vec<Body> = statics.iter().map(body_of).collect();
    bodies.sort_by_key(|b| b.key);
    put_all(&mut out, &bodies, |b| b.key, put_new_body);
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
        put_all(&mut out, &self.bodies, |b| b.key, put_new_body);
        // A particle's birth record restated as of this frame.
        put_all(
            &mut out,
            &self.particles,
            |p| p.id,
            |out, p| put_new_particle(out, &p.as_of(*frame)),
        );
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
        let mut records = Records::with_capacity(bodies.len() * 4);
        let sent = std::mem::take(&mut self.bodies);
        // A body sent before is updated in place (its id and group strings kept): only a
        // new body, or a different one under a reused key, allocates.
        self.bodies = diff(
            sent,
            bodies.iter(),
            |b| b.key,
            &mut records,
            |records, old, now| {
                let size = [now.size[0] as f32, now.size[1] as f32];
                match old {
                    Some(mut old)
                        if old.id == now.id
                            && old.size == size
                            && old.circle == now.circle
                            && old.group == now.group =>
                    {
                        let qpos = [
                            quantize(now.pos[0], POS_QUANTUM),
                            quantize(now.pos[1], POS_QUANTUM),
                        ];
                        let qvel = [
                            quantize(now.vel[0], VEL_QUANTUM),
                            quantize(now.vel[1], VEL_QUANTUM),
                        ];
                        let moved = old.qpos != qpos;
                        let sped = old.qvel != qvel;
                        if moved || sped || old.collided != now.collided {
                            let out = records.start(now.key);
                            out.push(
                                (moved as u8 * POS)
                                    | (sped as u8 * VEL)
                                    | (now.collided as u8 * COLLIDED),
                            );
                            if moved {
                                put_svarint(out, qpos[0] - old.qpos[0]);
                                put_svarint(out, qpos[1] - old.qpos[1]);
                            }
                            if sped {
                                put_svarint(out, qvel[0] - old.qvel[0]);
                                put_svarint(out, qvel[1] - old.qvel[1]);
                            }
                        }
                        old.qpos = qpos;
                        old.qvel = qvel;
                        old.collided = now.collided;
                        old
                    }
                    // New, or a different body under a reused key: sent whole.
                    _ => {
                        let body = body_of(now);
                        put_new_body(records.start(now.key), &body);
                        body
                    }
                }
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
