//! Writes a world's state as the JSON Lines records of [`ricochet_protocol::dump`].

use std::io::Write;

use ricochet_protocol::dump::{BodyRecord, FrameRecord, ParticleRecord};

use crate::world::World;

/// The world's state now as a dump record.
pub fn frame_record(world: &World) -> FrameRecord {
    let particles = world.particles();
    FrameRecord {
        frame: world.frame(),
        t: world.time(),
        bodies: world
            .bodies()
            .iter()
            .map(|b| BodyRecord {
                id: b.id.clone(),
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
