//! The engine's world in the protocol's forms: an engine [`World`] flows in; frames of
//! dynamic state and the statics snapshot ([`crate::frame`]) and dump records
//! ([`crate::dump`]) flow out. The only module of the codec that reads engine types.

use std::io::Write;

use ricochet_engine::dynamics::Body;
use ricochet_engine::geometry::Shape;
use ricochet_engine::world::{BodyInfo, World};

use crate::dump::{BodyRecord, FrameRecord, ParticleRecord, StatsRecord};
use crate::frame::{encode_statics, BodyIn, EmitterIn, FrameEncoder, FrameStats, ParticlesIn};

fn body_in<'a>(world: &'a World, b: &'a Body, info: &'a BodyInfo) -> BodyIn<'a> {
    let size = b.shape.size();
    BodyIn {
        key: b.key.0,
        id: &info.id,
        group: world.group_name(b.group),
        circle: matches!(b.shape, Shape::Circle { .. }),
        size: [size.x, size.y],
        pos: [b.pos.x, b.pos.y],
        vel: [b.vel.x, b.vel.y],
        collided: b.collided,
    }
}

/// Bytes of a key frame record at most, beside the names: a key gap and flags (6), a
/// body's shape byte and size (9), two string lengths (10) and four coordinates (40).
pub const KEY_BODY_BYTES: u64 = 6 + 9 + 10 + 40;
/// Bytes of a particle's key frame record at most: a key gap and flags (6), two
/// coordinates (20), two colours (8) and four numbers (16).
pub const KEY_PARTICLE_BYTES: u64 = 6 + 20 + 8 + 16;
/// Bytes of an emitter in a frame at most.
pub const EMITTER_BYTES: u64 = 8 + 10;

/// The bytes of a key frame of `world` at most, with `more_bodies` dynamic bodies (names
/// of `more_name_bytes` in all) and `more_particles` particles besides its own: every
/// dynamic body, every particle alive or still to come from an emitter, every emitter, at
/// the largest size of each record. A bound to refuse scenes and actions by, before they
/// run; the frames sent are smaller (quantised coordinates take 2 to 4 bytes, not 10).
pub fn key_frame_bytes(
    world: &World,
    more_bodies: u64,
    more_name_bytes: u64,
    more_particles: u64,
) -> u64 {
    let (mut bodies, mut names) = (more_bodies, more_name_bytes);
    for (b, info) in world.bodies().iter().zip(world.infos()) {
        if !b.is_static() {
            bodies += 1;
            names += (info.id.len() + world.group_name(b.group).len()) as u64;
        }
    }
    let particles = world.particles().len() as u64
        + world
            .emitters()
            .iter()
            .map(|e| u64::from(e.remaining))
            .sum::<u64>()
        + more_particles;
    crate::frame::HEADER_BYTES as u64
        + 3 * 10
        + world.emitters().len() as u64 * EMITTER_BYTES
        + bodies * KEY_BODY_BYTES
        + names
        + particles * KEY_PARTICLE_BYTES
}

/// The static bodies as a snapshot.
pub fn statics_snapshot(world: &World) -> Vec<u8> {
    let statics: Vec<BodyIn> = world
        .bodies()
        .iter()
        .zip(world.infos())
        .filter(|(b, _)| b.is_static())
        .map(|(b, info)| body_in(world, b, info))
        .collect();
    encode_statics(world.frame(), world.time(), &statics)
}

/// The world's state after its last step as a frame. `step_ms` is the wall time the step
/// took and `overruns` the server's count of late steps (0 offline).
pub fn encode_frame(
    encoder: &mut FrameEncoder,
    world: &World,
    step_ms: f32,
    overruns: u32,
) -> Vec<u8> {
    encode_frame_thinned(encoder, world, step_ms, overruns, 1)
}

/// The particles whose id is a multiple of `one_in`, copied out of `p`.
struct Thinned {
    id: Vec<u32>,
    f: [Vec<f32>; 11],
    color: Vec<[f32; 4]>,
    color_delta: Vec<[f32; 4]>,
}

impl Thinned {
    fn of(p: &ricochet_engine::particles::Particles, one_in: u32) -> Self {
        let keep: Vec<usize> = (0..p.len())
            .filter(|&i| p.id[i].is_multiple_of(one_in))
            .collect();
        let pick = |v: &[f32]| keep.iter().map(|&i| v[i]).collect::<Vec<f32>>();
        Thinned {
            id: keep.iter().map(|&i| p.id[i]).collect(),
            f: [
                pick(&p.x),
                pick(&p.y),
                pick(&p.vx),
                pick(&p.vy),
                pick(&p.ax),
                pick(&p.ay),
                pick(&p.drag),
                pick(&p.life),
                pick(&p.initial_life),
                pick(&p.size),
                pick(&p.size_delta),
            ],
            color: keep.iter().map(|&i| p.color[i]).collect(),
            color_delta: keep.iter().map(|&i| p.color_delta[i]).collect(),
        }
    }
}

/// [`encode_frame`] of a level of detail for slow links: only the particles whose id is a
/// multiple of `one_in` (one in `one_in` of them, spread over the world as the emitters
/// spread their ids), every body.
pub fn encode_frame_thinned(
    encoder: &mut FrameEncoder,
    world: &World,
    step_ms: f32,
    overruns: u32,
    one_in: u32,
) -> Vec<u8> {
    let stats = world.stats();
    let p = world.particles();
    let bodies: Vec<BodyIn> = world
        .bodies()
        .iter()
        .zip(world.infos())
        .filter(|(b, _)| !b.is_static())
        .map(|(b, info)| body_in(world, b, info))
        .collect();
    let emitters: Vec<EmitterIn> = world
        .emitters()
        .iter()
        .map(|e| EmitterIn {
            x: e.pos.x,
            y: e.pos.y,
            remaining: e.remaining,
        })
        .collect();
    let clamp = |v: u64| v.min(u32::MAX as u64) as u32;
    let figures = FrameStats {
        step_ms,
        contacts: clamp(stats.contacts),
        relaxation_iterations: clamp(stats.relaxation_iterations),
        deepest_penetration: stats.deepest_penetration as f32,
        kinetic_energy: stats.kinetic_energy as f32,
        particle_contacts: clamp(stats.particle_contacts),
        overruns,
        dynamic_bodies: bodies.len() as u32,
        particles: p.len() as u32,
        emitters: emitters.len() as u32,
        energy_change: stats.energy_change as f32,
        residual: stats.residual as f32,
    };
    let thinned = (one_in > 1).then(|| Thinned::of(p, one_in));
    let particles = match &thinned {
        None => ParticlesIn {
            id: &p.id,
            x: &p.x,
            y: &p.y,
            vx: &p.vx,
            vy: &p.vy,
            ax: &p.ax,
            ay: &p.ay,
            drag: &p.drag,
            life: &p.life,
            initial_life: &p.initial_life,
            size: &p.size,
            size_delta: &p.size_delta,
            color: &p.color,
            color_delta: &p.color_delta,
        },
        Some(t) => {
            let [x, y, vx, vy, ax, ay, drag, life, initial_life, size, size_delta] = &t.f;
            ParticlesIn {
                id: &t.id,
                x,
                y,
                vx,
                vy,
                ax,
                ay,
                drag,
                life,
                initial_life,
                size,
                size_delta,
                color: &t.color,
                color_delta: &t.color_delta,
            }
        }
    };
    encoder.encode(
        world.frame(),
        world.time(),
        world.config.dt,
        &figures,
        &emitters,
        &bodies,
        &particles,
    )
}

/// The world's state now as a dump record.
pub fn frame_record(world: &World) -> FrameRecord {
    let particles = world.particles();
    FrameRecord {
        frame: world.frame(),
        t: world.time(),
        bodies: world
            .bodies()
            .iter()
            .zip(world.infos())
            .map(|(b, info)| BodyRecord {
                id: info.id.clone(),
                x: b.pos.x,
                y: b.pos.y,
                vx: b.vel.x,
                vy: b.vel.y,
                collided: b.collided,
            })
            .collect(),
        particles: (0..particles.len())
            .map(|i| ParticleRecord {
                x: particles.x[i],
                y: particles.y[i],
                size: particles.size[i],
                color: particles.color_of(i).to_array(),
            })
            .collect(),
        emitters: world.emitters().len(),
    }
}

/// Writes one line: the world's state as JSON.
pub fn write_frame(out: &mut impl Write, world: &World) -> std::io::Result<()> {
    serde_json::to_writer(&mut *out, &frame_record(world))?;
    out.write_all(b"\n")
}

/// The figures of the world's last step as a stats record.
pub fn stats_record(world: &World) -> StatsRecord {
    let s = world.stats();
    StatsRecord {
        frame: world.frame(),
        contacts: s.contacts,
        passes: s.relaxation_iterations,
        deepest_penetration: s.deepest_penetration,
        kinetic_energy: s.kinetic_energy,
        particle_contacts: s.particle_contacts,
        sleeping: s.sleeping,
        energy_change: s.energy_change,
        residual: s.residual,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    #[test]
    fn the_key_frame_bound_holds_on_shipped_scenes_as_they_run() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/scenes");
        for name in [
            "emitters.toml",
            "particles-10k.toml",
            "pyramid-10.toml",
            "suite/rain.toml",
        ] {
            let path = root.join(name);
            let text = std::fs::read_to_string(&path).unwrap();
            let mut world = ricochet_engine::scene::parse(&text, &path, &[]).unwrap();
            let mut encoder = FrameEncoder::new(1);
            for step in 0..120 {
                world.step();
                let bytes = encode_frame(&mut encoder, &world, 0.0, 0).len() as u64;
                let bound = key_frame_bytes(&world, 0, 0, 0);
                assert!(
                    bytes <= bound,
                    "{name} step {step}: {bytes} bytes over the bound {bound}"
                );
            }
        }
    }
}
