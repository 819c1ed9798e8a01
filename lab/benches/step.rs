//! Micro-benchmarks of the engine's hot parts (divan): `cargo bench -p ricochet-lab --bench step`.
//!
//! The report commands (`ricochet-lab bench`, `tradeoff`) measure whole scenes over
//! whole runs for the docs; these time the pieces a change to the solver or the broad
//! phase touches, on the shipped scenes, so a regression shows before the report is run.

use std::path::Path;

use glam::DVec2;
use ricochet_engine::geometry::{collide, Shape};
use ricochet_engine::scene;
use ricochet_engine::world::World;

fn main() {
    divan::main();
}

fn load(name: &str, overrides: &[&str]) -> World {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../assets/scenes")
        .join(name);
    let text = std::fs::read_to_string(&path).expect("a shipped scene");
    let overrides: Vec<String> = overrides.iter().map(|s| s.to_string()).collect();
    scene::parse(&text, &path, &overrides).expect("the scene loads")
}

/// One step of a shipped scene, from the state it reaches after a second.
#[divan::bench(args = ["pyramid-10.toml", "stack-20.toml", "emitters.toml", "particles-10k.toml"])]
fn step(bencher: divan::Bencher, scene: &str) {
    let mut world = load(scene, &[]);
    world.step_n(60);
    bencher
        .with_inputs(|| world.clone())
        .bench_local_values(|mut w| {
            w.step();
            w
        });
}

/// One step of the 10-level pyramid under each solver setting of the large one.
#[divan::bench(args = [
    "solver=relaxation",
    "solver=impulses",
    "broad_phase=grid",
    "broad_phase=sweep",
    "broad_phase=all_pairs",
])]
fn pyramid_10_under(bencher: divan::Bencher, setting: &str) {
    let mut world = load("pyramid-10.toml", &["solver=impulses", setting]);
    world.step_n(60);
    bencher
        .with_inputs(|| world.clone())
        .bench_local_values(|mut w| {
            w.step();
            w
        });
}

/// The narrow phase: one pair of each kind, overlapping.
#[divan::bench(args = ["rect-rect", "circle-circle", "rect-circle"])]
fn narrow_phase(bencher: divan::Bencher, pair: &str) {
    let (a, b) = match pair {
        "rect-rect" => (Shape::rect(2.0, 1.0), Shape::rect(1.0, 3.0)),
        "circle-circle" => (Shape::circle(1.0), Shape::circle(0.5)),
        _ => (Shape::rect(2.0, 1.0), Shape::circle(0.5)),
    };
    let (pa, pb) = (DVec2::new(0.0, 0.0), DVec2::new(0.9, 0.4));
    bencher.bench(|| {
        collide(
            divan::black_box(&a),
            divan::black_box(pa),
            divan::black_box(&b),
            divan::black_box(pb),
        )
    });
}
