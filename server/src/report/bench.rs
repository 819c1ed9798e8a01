//! Benchmarks of the engine: figures and ratios, not pass/fail (`ricochet-server bench`).
//!
//! Each case builds its world in code, steps it, and reports the median wall time per
//! step with an accuracy figure where one applies. Run them on a quiet machine, in a
//! release build; the numbers are this machine's.

use std::time::Instant;

use glam::{DVec2, Vec2};

use ricochet_engine::dynamics::config::{Solver, WorldConfig};
use ricochet_engine::dynamics::BodyDef;
use ricochet_engine::dynamics::BroadPhase;
use ricochet_engine::geometry::Shape;
use ricochet_engine::particles::ParticleDef;
use ricochet_engine::world::World;

/// One measured case.
#[derive(Clone, Debug)]
pub struct Figure {
    pub case: String,
    pub setting: String,
    pub steps: u64,
    /// Median wall time of one step, in milliseconds.
    pub ms_per_step: f64,
    /// The case's own accuracy or size figure, named in `extra_name`.
    pub extra: f64,
    pub extra_name: &'static str,
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn timed(world: &mut World, steps: u64) -> Vec<f64> {
    (0..steps)
        .map(|_| {
            let t = Instant::now();
            world.step();
            t.elapsed().as_secs_f64() * 1e3
        })
        .collect()
}

/// The brief's "large pyramid": `levels` levels of 1 x 1 boxes on static ground, gravity
/// -10, rotation locked (no rotation exists here), 1/60 s steps.
pub fn pyramid(levels: u32, config: WorldConfig) -> World {
    let mut w = World::new(WorldConfig {
        gravity: DVec2::new(0.0, -10.0),
        mass_scaled_acceleration: false,
        ..config
    });
    w.add_body(BodyDef {
        id: "ground".into(),
        group: "ground".into(),
        shape: Shape::rect(levels as f64 * 4.0, 2.0),
        pos: DVec2::new(0.0, -1.0),
        mass: 0.0,
        ..BodyDef::default()
    })
    .expect("valid ground");
    let mut k = 0;
    for level in 0..levels {
        let n = levels - level;
        for i in 0..n {
            let x = i as f64 - (n - 1) as f64 * 0.5;
            w.add_body(BodyDef {
                id: format!("pyramid/{k}"),
                group: "boxes".into(),
                shape: Shape::rect(1.0, 1.0),
                pos: DVec2::new(x, 0.5 + level as f64),
                restitution: 0.0,
                friction: 0.6,
                ..BodyDef::default()
            })
            .expect("valid box");
            k += 1;
        }
    }
    w.add_interaction("boxes", "ground", true)
        .expect("groups exist");
    w.add_interaction("boxes", "boxes", true)
        .expect("groups exist");
    w
}

/// Worst distance of a box from where it started, in box sizes.
fn worst_drift(start: &[DVec2], world: &World) -> f64 {
    world
        .bodies()
        .iter()
        .zip(start)
        .map(|(b, p)| (b.pos - *p).length())
        .fold(0.0, f64::max)
}

/// The large pyramid under one setting: median ms per step over `steps`, worst drift at
/// the end.
pub fn pyramid_case(levels: u32, setting: &str, config: WorldConfig, steps: u64) -> Figure {
    let mut w = pyramid(levels, config);
    let start: Vec<DVec2> = w.bodies().iter().map(|b| b.pos).collect();
    let times = timed(&mut w, steps);
    let drift = worst_drift(&start, &w);
    let nan = w.bodies().iter().any(|b| !b.pos.is_finite());
    Figure {
        case: format!("pyramid-{levels} ({} boxes)", levels * (levels + 1) / 2),
        setting: setting.to_string(),
        steps,
        ms_per_step: median(times),
        extra: if nan { f64::NAN } else { drift },
        extra_name: "worst drift (box sizes)",
    }
}

/// `base` with the impulse solver, split impulses (baumgarte 0.5, slop 1e-4) and the grid
/// broad phase: the large pyramid's setting (`docs/bench/README.md`).
pub fn split_setting(base: &WorldConfig, iterations: u32, substeps: u32) -> WorldConfig {
    WorldConfig {
        solver: Solver::Impulses,
        impulse_iterations: iterations,
        substeps,
        split_impulses: true,
        baumgarte: 0.5,
        slop: 0.0001,
        broad_phase: BroadPhase::Grid,
        ..base.clone()
    }
}

/// The settings the pyramid is measured under: the chapter's relaxation, the impulse
/// solver with the sweep broad phase (before the grid), then with the grid, split
/// impulses and soft contacts.
pub fn pyramid_settings() -> Vec<(String, WorldConfig)> {
    let base = WorldConfig::default();
    let impulses = |iterations: u32, substeps: u32| WorldConfig {
        solver: Solver::Impulses,
        impulse_iterations: iterations,
        substeps,
        ..base.clone()
    };
    let grid = |iterations: u32, substeps: u32| WorldConfig {
        broad_phase: BroadPhase::Grid,
        ..impulses(iterations, substeps)
    };
    let split = |iterations: u32, substeps: u32| split_setting(&base, iterations, substeps);
    vec![
        (
            "relaxation 15 (chapter), sweep".into(),
            WorldConfig {
                solver: Solver::Relaxation,
                ..base.clone()
            },
        ),
        ("impulses 4 it, 2 sub-steps, sweep".into(), impulses(4, 2)),
        ("impulses 4 it, 2 sub-steps, grid".into(), grid(4, 2)),
        ("impulses 8 it, 1 sub-step, grid".into(), grid(8, 1)),
        (
            "impulses 6 it, 1 sub-step, split (baumgarte 0.5, slop 1e-4), grid".into(),
            split(6, 1),
        ),
        (
            "impulses 4 it, 2 sub-steps, split (baumgarte 0.5, slop 1e-4), grid".into(),
            split(4, 2),
        ),
        (
            "impulses 8 it, 2 sub-steps, split (baumgarte 0.5, slop 1e-4), grid".into(),
            split(8, 2),
        ),
        (
            "soft (30 Hz) 1 it + 1 relax, 4 sub-steps, grid".into(),
            WorldConfig {
                relax_iterations: 1,
                contact_hertz: 30.0,
                ..grid(1, 4)
            },
        ),
    ]
}

/// `count` particles of zero gravity scattered over the arena, none expiring, moving.
fn particle_world(count: usize, shapes: usize) -> World {
    let mut w = World::new(WorldConfig {
        particle_gravity: DVec2::ZERO,
        ..WorldConfig::default()
    });
    for k in 0..shapes {
        let (x, y) = (10.0 + (k % 10) as f64 * 19.0, 8.0 + (k / 10) as f64 * 10.0);
        w.add_body(BodyDef {
            id: format!("shape/{k}"),
            group: "shapes".into(),
            shape: if k % 2 == 0 {
                Shape::rect(6.0, 3.0)
            } else {
                Shape::circle(2.5)
            },
            pos: DVec2::new(x, y),
            mass: 0.0,
            ..BodyDef::default()
        })
        .expect("valid shape");
    }
    if shapes > 0 {
        w.add_interaction("particles", "shapes", true)
            .expect("groups exist");
    }
    // A deterministic scatter (no generator needed): a low-discrepancy sequence.
    for i in 0..count {
        let fx = (i as f64 * 0.618_033_988_75).fract();
        let fy = (i as f64 * 0.754_877_666_25).fract();
        w.add_particle(&ParticleDef {
            pos: Vec2::new((fx * 200.0) as f32, (fy * 112.5) as f32),
            vel: Vec2::new(((fy - 0.5) * 20.0) as f32, ((fx - 0.5) * 20.0) as f32),
            life: 1e9,
            drag: 1.0,
            ..ParticleDef::default()
        })
        .expect("valid particle");
    }
    w
}

/// Particles against shapes: median ns per particle per step.
pub fn particle_case(count: usize, shapes: usize, steps: u64) -> Figure {
    let mut w = particle_world(count, shapes);
    let ms = median(timed(&mut w, steps));
    Figure {
        case: format!("{count} particles, {shapes} shapes"),
        setting: "default".into(),
        steps,
        ms_per_step: ms,
        extra: ms * 1e6 / count as f64,
        extra_name: "ns per particle per step",
    }
}

/// One hero on a floor among `platforms` static platforms: ms per step.
pub fn statics_case(platforms: usize, steps: u64) -> Figure {
    let mut w = World::new(WorldConfig::default());
    let cols = (platforms as f64).sqrt().ceil() as usize;
    for k in 0..platforms {
        let (i, j) = (k % cols, k / cols);
        w.add_body(BodyDef {
            id: format!("platform/{k}"),
            group: "platforms".into(),
            shape: Shape::rect(30.0, 3.75),
            pos: DVec2::new(i as f64 * 40.0, j as f64 * 20.0),
            mass: 0.0,
            ..BodyDef::default()
        })
        .expect("valid platform");
    }
    w.add_body(BodyDef {
        id: "hero".into(),
        group: "hero".into(),
        shape: Shape::rect(16.0, 22.0),
        pos: DVec2::new(0.0, 40.0),
        mass: 0.7,
        restitution: 0.3,
        ..BodyDef::default()
    })
    .expect("valid hero");
    w.add_interaction("hero", "platforms", true)
        .expect("groups exist");
    let ms = median(timed(&mut w, steps));
    Figure {
        case: format!("hero among {platforms} static platforms"),
        setting: "default".into(),
        steps,
        ms_per_step: ms,
        extra: platforms as f64,
        extra_name: "platforms",
    }
}
