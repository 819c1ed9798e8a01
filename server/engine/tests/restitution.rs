//! Bounces: restitution 1 keeps a ball's energy in flight and through its bounces (the
//! impulse solver bounces with the speed of impact, not the speed the contact was found
//! with; the exact integrator flies without error).

mod common;

use common::{asset, body, set};
use glam::DVec2;
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

/// Every solver, and the impulse solver's variants.
const SOLVERS: [&[&str]; 5] = [
    &["solver=relaxation"],
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
fn restitution_one_keeps_the_energy_within_half_a_percent_under_every_solver() {
    for solver in SOLVERS {
        let settings = [solver, &["integrator=exact"]].concat();
        let worst = worst_energy_change(&settings);
        // The chapter's integrator, for the record (its flight is off by g dt t / 2).
        let symplectic = worst_energy_change(solver);
        eprintln!("{solver:?}: worst energy change over 10 s {worst:.2e} exact, {symplectic:.2e} symplectic");
        assert!(worst < 0.005, "{settings:?}: energy changed by {worst:.4}");
    }
}

/// The heights the ball reaches between bounces (the highest frame of each flight, the last
/// one cut by the end of the run), over `steps`, and the apex each flight's state predicts (`h + v²/2g`, at its first frame
/// in flight after a bounce).
fn flights(w: &mut World, steps: u64) -> (Vec<f64>, Vec<f64>) {
    let g = -w.config.gravity.y;
    let (mut highest, mut predicted) = (Vec::new(), Vec::new());
    let mut top = height(w);
    let mut was_rising = false;
    for _ in 0..steps {
        let before = body(w, "ball").vel.y;
        w.step();
        let vy = body(w, "ball").vel.y;
        if before < 0.0 && vy > 0.0 {
            // A bounce: the flight before it ended.
            highest.push(top);
            top = height(w);
            was_rising = true;
            continue;
        }
        if was_rising {
            predicted.push(height(w) + vy * vy / (2.0 * g));
            was_rising = false;
        }
        top = top.max(height(w));
    }
    // The last flight (ended at rest, or still going at the end of the run).
    highest.push(top);
    (highest, predicted)
}

#[test]
fn each_bounce_returns_e_squared_of_the_height_within_one_percent() {
    // The fifth bounce's impact must be above the solver's restitution threshold
    // (1 unit/s): 10 e⁴ > 1 from the scene's drop of 5 under g = 10, so e above 0.56.
    for e in [0.9, 0.8, 0.7, 0.6] {
        for solver in SOLVERS {
            let settings = [solver, &["integrator=exact"]].concat();
            let mut w = bounce(e, &settings);
            let (highest, _) = flights(&mut w, 600);
            // The drop, then five bounces at least.
            assert!(highest.len() >= 6, "{settings:?} e {e}: {highest:?}");
            for k in 1..6 {
                let ratio = highest[k] / highest[k - 1];
                assert!(
                    (ratio / (e * e) - 1.0).abs() < 0.01,
                    "{settings:?} e {e}: bounce {k} reached {:.4} of the height before, not {:.4}",
                    ratio,
                    e * e
                );
            }
        }
    }
}

#[test]
fn with_exact_flight_every_apex_is_the_drop_height_to_a_millionth() {
    for solver in SOLVERS {
        let settings = [solver, &["integrator=exact"]].concat();
        let mut w = bounce(1.0, &settings);
        let drop = height(&w);
        let (_, predicted) = flights(&mut w, 600);
        assert!(predicted.len() >= 5, "{settings:?}: {predicted:?}");
        for (k, apex) in predicted.iter().enumerate() {
            assert!(
                (apex - drop).abs() < 1e-6,
                "{settings:?}: flight {} rises to {apex}, the drop was from {drop}",
                k + 1
            );
        }
    }
}

/// Landings anywhere within a sub-step: drops from heights that do not land on a frame's
/// end, at 1 to 3 sub-steps, keep the energy to rounding with exact flight. A ball whose
/// flight ends a sub-step a hair short of the ground, while its velocity would carry it
/// there, bounces at the sub-step's end: left to the passes it landed with the approach
/// they clamp it to and lost up to `v g h / 2` at the bounce.
#[test]
fn exact_flight_keeps_the_energy_wherever_a_bounce_falls_in_the_sub_step() {
    let text = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/scenes/bounce.toml"),
    )
    .unwrap();
    assert!(text.contains("pos = [0, 5.5]"), "bounce.toml changed");
    for drop in [4.3, 3.77, 2.123456, 1.01, 0.3] {
        for substeps in ["substeps=1", "substeps=2", "substeps=3"] {
            let moved = text.replace("pos = [0, 5.5]", &format!("pos = [0, {}]", drop + 0.5));
            let mut w = common::scene(&moved);
            for s in ["solver=impulses", "integrator=exact", substeps] {
                w.apply(&set(s)).unwrap();
            }
            let e0 = energy(&w);
            let mut worst: f64 = 0.0;
            for _ in 0..(10.0 / w.config.dt).round() as u64 {
                w.step();
                worst = worst.max(((energy(&w) - e0) / e0).abs());
            }
            assert!(
                worst < 1e-9,
                "drop {drop}, {substeps}: energy changed by {worst:.3e}"
            );
        }
    }
}

/// Without gravity the default's flights are straight and its bounces meet at their
/// instant in the sub-step, so a table of bouncing balls moves the same under any number
/// of sub-steps (to rounding): a fork under more sub-steps does not drift from its parent.
/// Under gravity the sub-steps change the flights, and the runs part.
#[test]
fn a_gravity_free_table_moves_the_same_under_any_number_of_sub_steps() {
    let mut table = String::from(
        "[world]\ngravity = [0, 0]\nbounds = [[0, 0], [40, 20]]\n\
         [[body]]\nid = \"floor\"\ngroup = \"walls\"\nshape = \"rect\"\nsize = [40, 1]\npos = [20, 0]\nmass = 0\n\
         [[body]]\nid = \"roof\"\ngroup = \"walls\"\nshape = \"rect\"\nsize = [40, 1]\npos = [20, 20]\nmass = 0\n\
         [[body]]\nid = \"left\"\ngroup = \"walls\"\nshape = \"rect\"\nsize = [1, 20]\npos = [0, 10]\nmass = 0\n\
         [[body]]\nid = \"right\"\ngroup = \"walls\"\nshape = \"rect\"\nsize = [1, 20]\npos = [40, 10]\nmass = 0\n\
         [[interact]]\na = \"balls\"\nb = \"balls\"\n[[interact]]\na = \"balls\"\nb = \"walls\"\n",
    );
    for k in 0..8 {
        let pos = [5.0 + 4.0 * k as f64, 6.0 + 7.0 * (k % 2) as f64];
        let vel = [
            2.0 * ((k * 7) % 11) as f64 - 9.0,
            2.0 * ((k * 5) % 9) as f64 - 7.0,
        ];
        table.push_str(&format!(
            "[[body]]\nid = \"ball-{k}\"\ngroup = \"balls\"\nshape = \"circle\"\nradius = 1\n\
             pos = {pos:?}\nvel = {vel:?}\nrestitution = 0.9\nfriction = 0.1\n"
        ));
    }
    let run = |text: &str, substeps: u32| -> Vec<Vec<DVec2>> {
        let mut w = common::scene(text);
        w.apply(&set(&format!("substeps={substeps}"))).unwrap();
        (0..600)
            .map(|_| {
                w.step();
                w.bodies().iter().map(|b| b.pos).collect()
            })
            .collect()
    };
    let apart = |a: &[Vec<DVec2>], b: &[Vec<DVec2>]| -> f64 {
        a.iter()
            .zip(b)
            .flat_map(|(x, y)| x.iter().zip(y).map(|(p, q)| (*p - *q).length()))
            .fold(0.0, f64::max)
    };
    let two = run(&table, 2);
    // The first ball (after the four walls) bounces: it moves both ways along x.
    let dx: Vec<f64> = two.windows(2).map(|f| f[1][4].x - f[0][4].x).collect();
    assert!(dx.iter().any(|d| *d > 0.0) && dx.iter().any(|d| *d < 0.0));
    for substeps in [1, 4, 8] {
        let worst = apart(&two, &run(&table, substeps));
        assert!(
            worst < 1e-9,
            "{substeps} sub-steps part from 2 by {worst:.3e}"
        );
    }
    let tilted = table.replace("gravity = [0, 0]", "gravity = [0, -2]");
    let worst = apart(&run(&tilted, 2), &run(&tilted, 4));
    assert!(
        worst > 1e-3,
        "under gravity 4 sub-steps stayed within {worst:.3e} of 2"
    );
}
