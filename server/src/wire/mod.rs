//! The engine's world in the protocol's forms: an engine [`World`] flows in; frames of
//! dynamic state and the statics snapshot ([`ricochet_protocol::frame`]) and dump records
//! ([`ricochet_protocol::dump`]) flow out; and the wire's actions become the engine's
//! ([`to_engine`]). The only place where engine types meet the codec's: the protocol
//! crate knows no physics. [`stats`] counts what a run's frames cost on the wire.

use std::io::Write;

use ricochet_engine::dynamics::Body;
use ricochet_engine::geometry::Shape;
use ricochet_engine::world::{BodyInfo, World};

pub mod replay;
pub mod stats;

pub use replay::{Replay, Replayed};

use ricochet_protocol::command::{BodyState, MAX_BODIES_A_REPLY};
use ricochet_protocol::dump::{BodyRecord, FrameRecord, ParticleRecord, StatsRecord};
use ricochet_protocol::frame::{
    encode_statics, BodyIn, EmitterIn, FrameEncoder, FrameStats, ParticlesIn,
};
use ricochet_protocol::text::short;

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
    ricochet_protocol::frame::HEADER_BYTES as u64
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
    FrameSource::of(world, step_ms, overruns).encode(encoder, one_in)
}

/// A world's frame as the encoder reads it (its dynamic bodies, emitters and figures),
/// gathered once and encoded for every stream due at that step.
pub struct FrameSource<'a> {
    world: &'a World,
    bodies: Vec<BodyIn<'a>>,
    emitters: Vec<EmitterIn>,
    figures: FrameStats,
}

impl<'a> FrameSource<'a> {
    /// The frame of `world` after its last step; `step_ms` is the wall time the step took
    /// and `overruns` the server's count of late steps (0 offline).
    pub fn of(world: &'a World, step_ms: f32, overruns: u32) -> Self {
        let stats = world.stats();
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
            solver_passes: clamp(stats.solver_passes),
            deepest_penetration: stats.deepest_penetration as f32,
            kinetic_energy: stats.kinetic_energy as f32,
            particle_contacts: clamp(stats.particle_contacts),
            overruns,
            dynamic_bodies: bodies.len() as u32,
            particles: world.particles().len() as u32,
            emitters: emitters.len() as u32,
            energy_change: stats.energy_change as f32,
            residual: stats.residual as f32,
        };
        FrameSource {
            world,
            bodies,
            emitters,
            figures,
        }
    }

    /// The frame with one particle in `one_in` (1: all of them), through `encoder`.
    pub fn encode(&self, encoder: &mut FrameEncoder, one_in: u32) -> Vec<u8> {
        let world = self.world;
        let p = world.particles();
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
            &self.figures,
            &self.emitters,
            &self.bodies,
            &particles,
        )
    }
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
        passes: s.solver_passes,
        deepest_penetration: s.deepest_penetration,
        kinetic_energy: s.kinetic_energy,
        particle_contacts: s.particle_contacts,
        sleeping: s.sleeping,
        energy_change: s.energy_change,
        residual: s.residual,
    }
}

/// The bodies a `bodies` command asks for: those named in `ids` (in that order), else
/// those whose centre lies `within`, else every body; refused, saying why, for an unknown
/// id, a box that is not one, or more than [`MAX_BODIES_A_REPLY`].
pub fn bodies(
    world: &World,
    ids: &[String],
    within: Option<[[f64; 2]; 2]>,
) -> Result<Vec<BodyState>, String> {
    if ids.len() > MAX_BODIES_A_REPLY {
        return Err(format!(
            "`ids` names {} bodies: at most {MAX_BODIES_A_REPLY} a reply",
            ids.len()
        ));
    }
    let mut picked: Vec<(&Body, &BodyInfo)> = if ids.is_empty() {
        world.bodies().iter().zip(world.infos()).collect()
    } else {
        ids.iter()
            .map(|id| {
                world
                    .body(id)
                    .zip(world.info(id))
                    .ok_or_else(|| format!("no body `{}` in this world", short(id, 64)))
            })
            .collect::<Result<_, _>>()?
    };
    if let Some([lo, hi]) = within {
        let ok = lo.iter().chain(&hi).all(|v| v.is_finite()) && lo[0] <= hi[0] && lo[1] <= hi[1];
        if !ok {
            return Err(
                "`within` must be [[x0, y0], [x1, y1]], finite, x0 <= x1 and y0 <= y1".into(),
            );
        }
        picked.retain(|(b, _)| {
            (lo[0]..=hi[0]).contains(&b.pos.x) && (lo[1]..=hi[1]).contains(&b.pos.y)
        });
    }
    if picked.len() > MAX_BODIES_A_REPLY {
        return Err(format!(
            "{} bodies match: at most {MAX_BODIES_A_REPLY} a reply (name them in `ids`, or narrow `within`)",
            picked.len()
        ));
    }
    Ok(picked
        .into_iter()
        .map(|(b, info)| {
            let size = b.shape.size();
            BodyState {
                id: info.id.clone(),
                group: world.group_name(b.group).to_string(),
                shape: match b.shape {
                    Shape::Circle { .. } => "circle",
                    Shape::Rect { .. } => "rect",
                }
                .to_string(),
                size: [size.x, size.y],
                pos: [b.pos.x, b.pos.y],
                vel: [b.vel.x, b.vel.y],
                mass: if b.inv_mass > 0.0 {
                    1.0 / b.inv_mass
                } else {
                    0.0
                },
                collided: b.collided,
            }
        })
        .collect())
}

/// The engine's action for the wire's `action`: the two have one shape, so the wire form
/// reads as the engine's; what only the engine knows (a `set`'s name and the type of its
/// value) is checked here, and a refusal names the field as a malformed command's does.
pub fn to_engine(action: &ricochet_protocol::action::Action) -> Result<EngineAction, String> {
    let value = serde_json::to_value(action).map_err(|e| e.to_string())?;
    let name = value
        .get("do")
        .and_then(|d| d.as_str())
        .unwrap_or("")
        .to_string();
    serde_json::from_value(value).map_err(|e| format!("`{name}`: {e}"))
}

/// The engine's form of a world action.
pub type EngineAction = ricochet_engine::action::Action;

#[cfg(test)]
mod tests {
    use super::*;
    use ricochet_protocol::action::Action;
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

    #[test]
    fn the_wire_and_the_engine_have_the_same_actions_of_the_same_shape() {
        assert_eq!(Action::NAMES, EngineAction::NAMES);
        assert_eq!(
            ricochet_protocol::action::SETTING_NAMES,
            ricochet_engine::dynamics::Setting::NAMES
        );
        for json in [
            r#"{"do":"press","dir":"up"}"#,
            r#"{"do":"release","dir":"left"}"#,
            r#"{"do":"fire_dye_pack","at":[50.5,60]}"#,
            r#"{"do":"spawn_minion","at":[1,2],"shape":"rect"}"#,
            r#"{"do":"spawn_minion","at":[1,2]}"#,
            r#"{"do":"spawn_dumb_minion","at":[3,4]}"#,
            r#"{"do":"select","at":[1,2],"group":"minions"}"#,
            r#"{"do":"drag","to":[0.1,1e300]}"#,
            r#"{"do":"deselect"}"#,
            r#"{"do":"agitate","strength":2.5}"#,
            r#"{"do":"clear","group":"g"}"#,
            r#"{"do":"spawn_particles","preset":"fire","at":[1,2],"count":7}"#,
            r#"{"do":"start_emitter","preset":"fire","count":7,"at":[1,2]}"#,
            r#"{"do":"remove","body":"ball/3"}"#,
            r#"{"do":"impulse","body":"cue","impulse":[4.5,-1]}"#,
            r#"{"do":"set_body","body":"cue","pos":[1,2]}"#,
            r#"{"do":"set_body","body":"cue","vel":[0,0.5]}"#,
            r#"{"do":"set_body","body":"cue","pos":[1,2],"vel":[3,4]}"#,
            r#"{"do":"spawn","template":"ball","at":[1,2],"vel":[3,4]}"#,
            r#"{"do":"spawn","body":{"shape":"circle","radius":0.5,"pos":[1,2]}}"#,
            r#"{"do":"spawn","body":{"id":"cue","group":"balls","shape":"rect","size":[1,2],"vel":[0,1],"mass":2,"restitution":1,"friction":0,"gravity":[0,0]},"at":[3,4]}"#,
            r#"{"do":"set","name":"gravity","value":[0.0,-9.8]}"#,
            r#"{"do":"set","name":"solver","value":"relaxation"}"#,
        ] {
            let wire: Action = serde_json::from_str(json).unwrap();
            let engine: EngineAction = serde_json::from_str(json).unwrap();
            assert_eq!(to_engine(&wire).unwrap(), engine, "{json}");
            // And back: what the engine writes reads as the same wire action.
            let back: Action =
                serde_json::from_value(serde_json::to_value(&engine).unwrap()).unwrap();
            assert_eq!(back, wire, "{json}");
        }
    }

    #[test]
    fn a_setting_only_the_engine_knows_is_refused_naming_it() {
        let wire: Action =
            serde_json::from_str(r#"{"do":"set","name":"gravty","value":[0,-9.8]}"#).unwrap();
        let e = to_engine(&wire).unwrap_err();
        assert!(e.starts_with("`set`:") && e.contains("gravty"), "{e}");
        let wire: Action =
            serde_json::from_str(r#"{"do":"set","name":"gravity","value":"down"}"#).unwrap();
        assert!(to_engine(&wire).unwrap_err().contains("`set`"));
    }

    #[test]
    fn receivers_predict_particles_by_the_engines_model() {
        use glam::Vec4;
        use ricochet_engine::particles::{color_after, size_after};
        let (start, delta) = (
            Vec4::new(1.0, 0.1, 0.2, 1.0),
            Vec4::new(0.013, -0.002, 0.001, -0.003),
        );
        for age in [0.0f32, 1.0, 17.0, 229.5] {
            assert_eq!(
                ricochet_protocol::frame::color_after(start, delta, age),
                color_after(start, delta, age)
            );
        }
        for updates in [0, 1, 30, 230] {
            assert_eq!(
                ricochet_protocol::frame::size_after(5.5, 0.98, updates),
                size_after(5.5, 0.98, updates)
            );
        }
    }

    #[test]
    fn the_network_page_lists_every_settable_name() {
        let page = include_str!("../../../docs/network.md");
        let row = page
            .lines()
            .find(|l| l.starts_with("| `set` |"))
            .expect("docs/network.md has a row for `set`");
        for name in ricochet_engine::dynamics::Setting::NAMES {
            assert!(
                row.contains(name),
                "docs/network.md's `set` row misses {name}"
            );
        }
    }
}
