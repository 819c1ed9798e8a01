//! The live accuracy estimates a step reports without any reference: the energy change
//! over the step and the solver's residual (what its last pass still corrected).

mod common;

use common::{asset, scene, set};
use ricochet_engine::prelude::*;

fn under(name: &str, settings: &[&str]) -> World {
    let mut w = asset(name);
    for s in settings {
        w.apply(&set(s)).unwrap();
    }
    w
}

#[test]
fn the_energy_changes_add_up_to_the_run_and_vanish_in_exact_flight() {
    for (integrator, lossless) in [("exact", true), ("symplectic", false)] {
        let mut w = under("projectile.toml", &[&format!("integrator={integrator}")]);
        let e0 = w.mechanical_energy();
        let (mut sum, mut worst) = (0.0, 0.0f64);
        for _ in 0..120 {
            w.step();
            sum += w.stats().energy_change;
            worst = worst.max(w.stats().energy_change.abs());
        }
        let e = w.stats().energy;
        assert_eq!(e, w.mechanical_energy());
        assert!(
            (sum - (e - e0)).abs() <= 1e-9 * e0.abs().max(1.0),
            "{integrator}: the changes sum to {sum}, the run changed by {}",
            e - e0
        );
        if lossless {
            assert!(worst <= 1e-9 * e0.abs().max(1.0), "{integrator}: {worst}");
        } else {
            // Symplectic Euler's flight changes the energy every step.
            assert!(worst > 1e-6 * e0.abs(), "{integrator}: {worst}");
        }
    }
}

/// The mean residual over the first `steps` steps of the pile under `settings`.
fn mean_residual(settings: &[&str], steps: usize) -> f64 {
    let mut w = under("pyramid-10.toml", settings);
    let mut sum = 0.0;
    for _ in 0..steps {
        w.step();
        let r = w.stats().residual;
        assert!(r.is_finite() && r >= 0.0, "{r}");
        sum += r;
    }
    sum / steps as f64
}

#[test]
fn more_solver_passes_leave_a_smaller_residual() {
    let few = mean_residual(&["solver=impulses", "impulse_iterations=2"], 60);
    let many = mean_residual(&["solver=impulses", "impulse_iterations=32"], 60);
    assert!(few > 0.0, "a pile's contacts still correct after 2 passes");
    assert!(many < few / 4.0, "32 passes {many:e}, 2 passes {few:e}");
    // With relax passes the last pass measured is a relax pass.
    let relaxed = mean_residual(
        &[
            "solver=impulses",
            "impulse_iterations=8",
            "relax_iterations=4",
        ],
        60,
    );
    assert!(relaxed.is_finite());

    // The relaxation solver: the overlap its last pass still found.
    let few = mean_residual(&["solver=relaxation", "relaxation_iterations=1"], 60);
    let many = mean_residual(&["solver=relaxation", "relaxation_iterations=50"], 60);
    assert!(few > 0.0);
    assert!(many < few, "50 passes {many:e}, 1 pass {few:e}");
}

/// Three boxes dropped one above another onto the ground, a unit apart: they fall
/// together, so nothing touches until the lowest lands, then they stack (restitution 0:
/// they land, not bounce, and the passes hold them).
const DROPPED_COLUMN: &str = r#"
[world]
gravity = [0, -10]
mass_scaled_acceleration = false

[[body]]
id = "ground"
group = "ground"
shape = "rect"
size = [20, 2]
pos = [0, -1]
mass = 0

[[generate]]
kind = "stack"
id = "box"
group = "boxes"
shape = "rect"
size = [1, 1]
count = 3
base = [0, 3]
gap = 1
restitution = 0

[[interact]]
a = "boxes"
b = "ground"

[[interact]]
a = "boxes"
b = "boxes"
"#;

#[test]
fn nothing_touching_leaves_no_residual() {
    let mut w = scene(DROPPED_COLUMN);
    // Every pair is the solver's every step, apart or not.
    w.apply(&set("broad_phase=all_pairs")).unwrap();
    let (mut apart, mut landed) = (0, 0.0f64);
    for _ in 0..120 {
        let lowest = w
            .bodies()
            .iter()
            .filter(|b| !b.is_static())
            .map(|b| b.pos.y)
            .fold(f64::MAX, f64::min);
        w.step();
        let s = w.stats();
        // The lowest box's bottom a unit above the ground: nothing is near touching.
        if lowest > 0.0 + 0.5 + 1.0 {
            assert_eq!(s.residual, 0.0, "apart, frame {}", w.frame());
            apart += 1;
        } else {
            landed = landed.max(s.residual);
        }
    }
    assert!(apart > 10, "{apart} frames apart");
    assert!(
        landed > 0.0,
        "the stack's contacts leave a residual once they touch"
    );
}
