//! The live accuracy estimates a step reports without any reference: the energy change
//! over the step and the solver's residual (what its last pass still corrected).

mod common;

use common::{asset, set};
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

#[test]
fn nothing_touching_leaves_no_residual() {
    let mut w = under("projectile.toml", &["solver=impulses"]);
    for _ in 0..60 {
        w.step();
        assert_eq!(w.stats().residual, 0.0);
    }
}
