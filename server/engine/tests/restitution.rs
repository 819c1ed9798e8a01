//! Bounces: restitution 1 keeps a ball's energy in flight and through its bounces (the
//! impulse solver bounces with the speed of impact, not the speed the contact was found
//! with; the exact integrator flies without error).

mod common;

use common::{asset, body, set};
use ricochet_engine::prelude::*;

/// The shipped bounce scene, `restitution` on both ball and ground, under `settings`.
fn bounce(restitution: f64, settings: &[&str]) -> World {
    let mut w = asset("bounce.toml");
    let text = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/scenes/bounce.toml"),
    )
    .unwrap();
    assert_eq!(
        text.matches("restitution = 1\n").count(),
        2,
        "bounce.toml changed"
    );
    if restitution != 1.0 {
        w = common::scene(&text.replace(
            "restitution = 1\n",
            &format!("restitution = {restitution}\n"),
        ));
    }
    for s in settings {
        w.apply(&set(s)).unwrap();
    }
    w
}

/// The ball's height above where it rests on the ground (its centre a radius above the
/// ground's top).
fn height(w: &World) -> f64 {
    body(w, "ball").pos.y - 0.5
}

/// Energy per unit mass, zero at rest on the ground.
fn energy(w: &World) -> f64 {
    let ball = body(w, "ball");
    0.5 * ball.vel.length_squared() - w.config.gravity.y * height(w)
}

/// The impulse solver's variants. (The relaxation solver still loses about 10% over the
/// run: its bounce is the chapter's, from the velocity after the ball sank in.)
const SOLVERS: [&[&str]; 4] = [
    &["solver=impulses"],
    &["solver=impulses", "substeps=4"],
    &["solver=impulses", "split_impulses=true"],
    &["solver=impulses", "contact_hertz=30"],
];

/// Worst relative change of the ball's energy over 10 s.
fn worst_energy_change(settings: &[&str]) -> f64 {
    let mut w = bounce(1.0, settings);
    let e0 = energy(&w);
    let steps = (10.0 / w.config.dt).round() as u64;
    let mut worst: f64 = 0.0;
    for _ in 0..steps {
        w.step();
        worst = worst.max(((energy(&w) - e0) / e0).abs());
    }
    worst
}

#[test]
fn restitution_one_keeps_the_energy_within_half_a_percent_under_the_impulse_solver() {
    for solver in SOLVERS {
        let settings = [solver, &["integrator=exact"]].concat();
        let worst = worst_energy_change(&settings);
        assert!(worst < 0.005, "{settings:?}: energy changed by {worst:.4}");
    }
}
