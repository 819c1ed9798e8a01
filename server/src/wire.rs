//! The world as the wire protocol sends it: frames of dynamic state and the statics
//! snapshot ([`ricochet_protocol::frame`]).

use ricochet_protocol::frame::{
    encode_statics, BodyIn, EmitterIn, FrameEncoder, FrameStats, ParticlesIn,
};

use crate::dynamics::Body;
use crate::geometry::Shape;
use crate::world::World;

fn body_in<'a>(world: &'a World, b: &'a Body) -> BodyIn<'a> {
    let size = b.shape.size();
    BodyIn {
        key: b.key.0,
        id: &b.id,
        group: world.group_name(b.group),
        circle: matches!(b.shape, Shape::Circle { .. }),
        size: [size.x, size.y],
        pos: [b.pos.x, b.pos.y],
        vel: [b.vel.x, b.vel.y],
        collided: b.collided,
    }
}

/// The static bodies as a snapshot.
pub fn statics_snapshot(world: &World) -> Vec<u8> {
    let statics: Vec<BodyIn> = world
        .bodies()
        .iter()
        .filter(|b| b.is_static())
        .map(|b| body_in(world, b))
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
    let stats = world.stats();
    let p = world.particles();
    let bodies: Vec<BodyIn> = world
        .bodies()
        .iter()
        .filter(|b| !b.is_static())
        .map(|b| body_in(world, b))
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
    };
    let particles = ParticlesIn {
        id: &p.id,
        x: &p.x,
        y: &p.y,
        life: &p.life,
        initial_life: &p.initial_life,
        size: &p.size,
        size_delta: &p.size_delta,
        color: &p.color,
        color_delta: &p.color_delta,
    };
    encoder.encode(
        world.frame(),
        world.time(),
        &figures,
        &emitters,
        &bodies,
        &particles,
    )
}
