//! The engines of the benchmark behind one face: build a scene fresh, step it, and show
//! the criteria monitor where its dynamic bodies are. Ricochet itself lives here; the
//! peers in `box2d.rs` and `rapier.rs`.

use anyhow::Result;
use glam::DVec2;
use ricochet_engine::criteria::Monitor;
use ricochet_engine::world::World;

use crate::scene::Scene;

/// The engines, in the order of the first round: Ricochet's default on one thread and on
/// two, then the peers (each on one thread).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum EngineKind {
    Ricochet,
    Ricochet2,
    Box2d,
    Rapier,
}

impl EngineKind {
    pub const ALL: [EngineKind; 4] = [
        EngineKind::Ricochet,
        EngineKind::Ricochet2,
        EngineKind::Box2d,
        EngineKind::Rapier,
    ];

    /// The name the tables use.
    pub fn name(self) -> &'static str {
        match self {
            EngineKind::Ricochet => "Ricochet",
            EngineKind::Ricochet2 => "Ricochet, 2 threads",
            EngineKind::Box2d => "Box2D v3",
            EngineKind::Rapier => "rapier2d",
        }
    }

    /// The scene built in this engine, before its first step.
    pub fn build(self, scene: &Scene) -> Result<Box<dyn Engine>> {
        Ok(match self {
            EngineKind::Ricochet => Box::new(Ricochet::new(scene.fresh_world()?)),
            EngineKind::Ricochet2 => {
                let mut world = scene.fresh_world()?;
                world.config.threads = 2;
                Box::new(Ricochet::new(world))
            }
            EngineKind::Box2d => Box::new(crate::box2d::Box2dScene::build(scene)?),
            EngineKind::Rapier => Box::new(crate::rapier::RapierScene::build(scene)),
        })
    }
}

/// A scene built in one engine.
pub trait Engine {
    /// One step of the scene's `dt`.
    fn step(&mut self) -> Result<()>;
    /// Shows `monitor` where the dynamic bodies are after a step.
    fn observe(&mut self, monitor: &mut Monitor) -> Result<()>;
    /// A digest of every body's position and velocity bits (Ricochet only: the one- and
    /// two-thread runs must agree bit for bit).
    fn digest(&self) -> Option<u64> {
        None
    }
    /// What the solver's passes did over the run so far (Ricochet only).
    fn work(&self) -> Option<crate::limit::Work> {
        None
    }
}

/// Ricochet under its default, as the scene file builds it (its `threads` set by the
/// benchmark), counting its solver's work from each step's figures.
struct Ricochet {
    world: World,
    work: crate::limit::Work,
}

impl Ricochet {
    fn new(world: World) -> Ricochet {
        Ricochet {
            world,
            work: crate::limit::Work::default(),
        }
    }
}

impl Engine for Ricochet {
    fn step(&mut self) -> Result<()> {
        self.world.step();
        self.work.add(&self.world);
        Ok(())
    }

    fn observe(&mut self, monitor: &mut Monitor) -> Result<()> {
        monitor.observe(&self.world);
        Ok(())
    }

    fn digest(&self) -> Option<u64> {
        use std::hash::{Hash, Hasher};
        let mut h = std::collections::hash_map::DefaultHasher::new();
        for b in self.world.bodies() {
            for x in [b.pos.x, b.pos.y, b.vel.x, b.vel.y] {
                x.to_bits().hash(&mut h);
            }
        }
        Some(h.finish())
    }

    fn work(&self) -> Option<crate::limit::Work> {
        Some(self.work)
    }
}

/// Observes a peer's step: `states` (a buffer kept between calls) gets the position and
/// velocity of each dynamic body in the monitor's order, read through `read` from the
/// peer's handle of that body, as (x, y) pairs; the monitor then observes them.
pub fn observe_dynamic<H: Copy>(
    monitor: &mut Monitor,
    handles: &[Option<H>],
    states: &mut Vec<(DVec2, DVec2)>,
    mut read: impl FnMut(H) -> Result<([f64; 2], [f64; 2])>,
) -> Result<()> {
    states.clear();
    for &i in monitor.dynamic() {
        let handle = handles[i as usize]
            .ok_or_else(|| anyhow::anyhow!("dynamic body {i} has no peer body"))?;
        let (p, v) = read(handle)?;
        states.push((DVec2::from(p), DVec2::from(v)));
    }
    monitor.observe_dynamic(states);
    Ok(())
}
