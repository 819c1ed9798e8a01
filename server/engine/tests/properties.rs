//! Properties over random worlds: random valid scenes under random valid action streams
//! never give NaN or infinity, and a scene of restitution at most 1 never gains energy.
//! Seeds are fixed, so every run tries the same cases; a failure found is kept in
//! `proptest-regressions/` and replayed first.

use std::path::Path;

use proptest::prelude::*;
use proptest::test_runner::{Config, RngSeed};
use ricochet_engine::prelude::*;
use ricochet_engine::scene;

/// A body of a random scene: circle or box, size, mass, material, start velocity.
#[derive(Clone, Debug)]
struct RandomBody {
    circle: bool,
    size: f64,
    mass: f64,
    restitution: f64,
    friction: f64,
    vel: (f64, f64),
}

fn random_body() -> impl Strategy<Value = RandomBody> {
    (
        any::<bool>(),
        0.3f64..3.0,
        0.1f64..10.0,
        0.0f64..=1.0,
        0.0f64..=1.0,
        (-10.0f64..10.0, -10.0f64..10.0),
    )
        .prop_map(
            |(circle, size, mass, restitution, friction, vel)| RandomBody {
                circle,
                size,
                mass,
                restitution,
                friction,
                vel,
            },
        )
}

/// A scene of `bodies` in a grid of 4-unit cells (so none overlaps at the start) above
/// static ground, in a box of static walls, all colliding, under `solver`.
fn scene_text(bodies: &[RandomBody], solver: &str, extra: &str) -> String {
    let mut t = format!(
        "[world]\ngravity = [0, -10]\nmass_scaled_acceleration = false\nsolver = \"{solver}\"\n{extra}\n"
    );
    for (id, size, pos) in [
        ("ground", [60.0, 2.0], [0.0, -1.0]),
        ("left", [2.0, 80.0], [-31.0, 40.0]),
        ("right", [2.0, 80.0], [31.0, 40.0]),
    ] {
        t += &format!(
            "[[body]]\nid = \"{id}\"\ngroup = \"walls\"\nshape = \"rect\"\nsize = [{}, {}]\npos = [{}, {}]\nmass = 0\nrestitution = 1\nfriction = 0.5\n",
            size[0], size[1], pos[0], pos[1]
        );
    }
    for (k, b) in bodies.iter().enumerate() {
        let pos = [-26.0 + 4.0 * (k % 13) as f64, 3.0 + 4.0 * (k / 13) as f64];
        let shape = if b.circle {
            format!("shape = \"circle\"\nradius = {}", b.size / 2.0)
        } else {
            format!("shape = \"rect\"\nsize = [{}, {}]", b.size, b.size)
        };
        t += &format!(
            "[[body]]\nid = \"b{k}\"\ngroup = \"bodies\"\n{shape}\npos = [{}, {}]\nvel = [{}, {}]\nmass = {}\nrestitution = {}\nfriction = {}\n",
            pos[0], pos[1], b.vel.0, b.vel.1, b.mass, b.restitution, b.friction
        );
    }
    t + "[[interact]]\na = \"bodies\"\nb = \"walls\"\n[[interact]]\na = \"bodies\"\nb = \"bodies\"\n"
}

/// Kinetic plus potential energy of the dynamic bodies (gravity -10, unscaled).
fn energy(w: &World) -> f64 {
    w.bodies()
        .iter()
        .filter(|b| !b.is_static())
        .map(|b| b.kinetic_energy() + b.mass() * 10.0 * b.pos.y)
        .sum()
}

/// An action a client could send, valid or not.
fn random_action() -> impl Strategy<Value = Action> {
    let point = (-40.0f64..40.0, -5.0f64..60.0).prop_map(|(x, y)| [x, y]);
    prop_oneof![
        point.clone().prop_map(|at| Action::SpawnDumbMinion { at }),
        point
            .clone()
            .prop_map(|at| Action::SpawnMinion { at, shape: None }),
        (point.clone(), 0u32..200).prop_map(|(at, count)| Action::SpawnParticles {
            preset: "fire".into(),
            at,
            count
        }),
        (point.clone(), 0u32..200).prop_map(|(at, count)| Action::StartEmitter {
            preset: "fire".into(),
            count,
            at
        }),
        point
            .clone()
            .prop_map(|at| Action::Select { at, group: None }),
        point.clone().prop_map(|to| Action::Drag { to }),
        (0.0f64..200.0).prop_map(|s| Action::Agitate { strength: Some(s) }),
        Just(Action::Clear {
            group: "dumb_minions".into()
        }),
        // Bodies by id: some exist in the scene, some do not.
        prop_oneof![Just("hero"), Just("minion/0"), Just("nobody")].prop_map(|id| {
            Action::Remove {
                body: id.to_string(),
            }
        }),
        (point.clone(), prop_oneof![Just("hero"), Just("nobody")]).prop_map(|(p, id)| {
            Action::Impulse {
                body: id.to_string(),
                impulse: p,
            }
        }),
        (point.clone(), point.clone(), 0u8..4).prop_map(|(p, v, which)| Action::SetBody {
            body: "hero".into(),
            pos: (which & 1 == 1).then_some(p),
            vel: (which & 2 == 2).then_some(v),
        }),
        prop_oneof![
            Just("solver=impulses"),
            Just("solver=relaxation"),
            Just("substeps=3"),
            Just("impulse_iterations=2"),
            Just("relaxation_iterations=40"),
            Just("split_impulses=true"),
            Just("contact_hertz=30"),
            Just("ccd=true"),
            Just("sleeping=true"),
            Just("broad_phase=grid"),
            Just("broad_phase=all_pairs"),
            Just("integrator=explicit"),
            Just("dt=0.05"),
            Just("gravity=[0, -500]"),
        ]
        .prop_map(|s| Action::Set(Setting::parse(s).unwrap())),
    ]
}

fn config(seed: u64, cases: u32) -> Config {
    Config {
        cases,
        rng_seed: RngSeed::Fixed(seed),
        ..Config::default()
    }
}

proptest! {
    #![proptest_config(config(0xb0d1e5, 48))]

    #[test]
    fn random_worlds_under_random_actions_stay_finite(
        bodies in proptest::collection::vec(random_body(), 1..30),
        impulses in any::<bool>(),
        actions in proptest::collection::vec((0u64..120, random_action()), 0..30),
    ) {
        let solver = if impulses { "impulses" } else { "relaxation" };
        let text = scene_text(&bodies, solver, "") + "[[interact]]\na = \"particles\"\nb = \"walls\"\n";
        let mut w = scene::parse(&text, Path::new("random.toml"), &[]).unwrap();
        let mut actions = actions;
        actions.sort_by_key(|(f, _)| *f);
        let mut next = actions.iter().peekable();
        for frame in 0..120 {
            while let Some((_, a)) = next.next_if(|(f, _)| *f == frame) {
                let _ = w.apply(a);
            }
            w.step();
            for b in w.bodies() {
                prop_assert!(b.pos.is_finite() && b.vel.is_finite(), "frame {frame}: {b:?}");
            }
            let p = w.particles();
            prop_assert!(p.x.iter().chain(&p.y).all(|v| v.is_finite()), "frame {frame}");
            prop_assert!(w.stats().kinetic_energy.is_finite());
        }
    }
}

proptest! {
    #![proptest_config(config(0xe4e76, 48))]

    #[test]
    fn with_restitution_at_most_one_energy_never_grows(
        bodies in proptest::collection::vec(random_body(), 1..20),
        impulses in any::<bool>(),
    ) {
        let (solver, extra) = if impulses {
            ("impulses", "substeps = 2\n")
        } else {
            ("relaxation", "")
        };
        let text = scene_text(&bodies, solver, extra);
        let mut w = scene::parse(&text, Path::new("random.toml"), &[]).unwrap();
        let e0 = energy(&w);
        // Resolving contacts moves bodies by up to their penetration: allow each body the
        // potential energy of a hundredth of its size, plus rounding.
        let slack: f64 = w
            .bodies()
            .iter()
            .filter(|b| !b.is_static())
            .map(|b| b.mass() * 10.0 * 0.01 * b.shape.size().max_element())
            .sum::<f64>()
            + 1e-9 * e0.abs();
        let mut worst = e0;
        for _ in 0..300 {
            w.step();
            worst = worst.max(energy(&w));
        }
        prop_assert!(
            worst <= e0 + slack,
            "energy grew from {e0} to {worst} (slack {slack})"
        );
    }
}
