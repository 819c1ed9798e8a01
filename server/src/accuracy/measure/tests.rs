use super::*;

#[test]
fn a_candidate_is_overrides_separated_by_semicolons() {
    let c = Candidate::parse("solver=impulses; impulse_iterations=8").unwrap();
    assert_eq!(c.overrides, ["solver=impulses", "impulse_iterations=8"]);
    assert!(Candidate::parse(" ; ").is_err());
    let e = Candidate::parse("solver=impulses;fast")
        .unwrap_err()
        .to_string();
    assert!(e.contains("`fast` is not NAME=VALUE"), "{e}");
}

#[test]
fn a_scene_without_contacts_tries_no_solver_passes() {
    let free = default_candidates(&Features {
        dynamic: 1,
        ..Features::default()
    });
    assert!(free
        .iter()
        .all(|c| !c.overrides.iter().any(|o| o.contains("iterations"))));
    let touching = default_candidates(&Features {
        dynamic: 1,
        contacts: true,
        ..Features::default()
    });
    assert!(touching
        .iter()
        .any(|c| c.overrides.iter().any(|o| o.contains("impulse_iterations"))));
    assert!(touching.len() > free.len());
}

fn shipped(name: &str, steps: u64) -> Subject {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../assets/scenes")
        .join(name);
    Subject::read(&path, steps, Vec::new()).unwrap()
}

/// The reference's worst error over the run against a closed form of the first
/// dynamic body's position at time t.
fn reference_error(report: &Report, dt: f64, exact: impl Fn(f64) -> DVec2) -> f64 {
    report
        .reference
        .run
        .bodies
        .iter()
        .enumerate()
        .map(|(k, p)| (*p - exact((k + 1) as f64 * dt)).length())
        .fold(0.0, f64::max)
}

/// The smallest error the tool reports for any candidate.
fn smallest_error(report: &Report) -> f64 {
    report
        .rows
        .iter()
        .map(|r| r.worst_error)
        .fold(f64::INFINITY, f64::min)
}

#[test]
fn the_reference_beats_every_candidate_against_a_closed_form() {
    let hidden = indicatif::ProgressBar::hidden();
    // The projectile: p0 + v0 t + g t²/2.
    let subject = shipped("projectile.toml", 120);
    let w = subject.world(&[]).unwrap();
    let (b, g, dt) = (&w.bodies()[0], w.config.gravity, w.config.dt);
    let (p0, v0) = (b.pos, b.vel);
    let report = measure(&subject, None, &Options::default(), &hidden).unwrap();
    let error = reference_error(&report, dt, |t| p0 + v0 * t + g * (0.5 * t * t));
    let best = smallest_error(&report);
    assert!(error < best, "reference {error:e}, best candidate {best:e}");
    // Symplectic Euler lags the closed form by |g| dt t / 2, worst at the end: 1/6
    // after 2 s at 1/60 under gravity 10.
    let symplectic = report
        .rows
        .iter()
        .find(|r| r.name == "symplectic, 1 sub-step")
        .unwrap();
    let lag = g.length() * dt * 2.0 / 2.0;
    assert!(
        (symplectic.worst_error - lag).abs() < 1e-9,
        "{}",
        symplectic.worst_error
    );
    assert!(!report.features.contacts);

    // The slide: p0 + v0 t on frictionless ground.
    let subject = shipped("slide.toml", 120);
    let w = subject.world(&[]).unwrap();
    let b = w.body("box").unwrap();
    let (p0, v0, dt) = (b.pos, b.vel, w.config.dt);
    let report = measure(&subject, None, &Options::default(), &hidden).unwrap();
    assert!(report.features.contacts);
    let error = reference_error(&report, dt, |t| p0 + v0 * t);
    let best = smallest_error(&report);
    assert!(error < best, "reference {error:e}, best candidate {best:e}");
}

#[test]
fn a_pile_against_its_reference_gains_from_more_passes_and_sub_steps() {
    let hidden = indicatif::ProgressBar::hidden();
    let subject = shipped("pyramid-10.toml", 60);
    let candidates = [
        // Cold, the push-out in the velocities: how far the pile strays depends on them.
        "solver=impulses;impulse_iterations=2;split_impulses=false;rest_load=false;shock_propagation=false",
        "solver=impulses;impulse_iterations=8;substeps=4;split_impulses=false;rest_load=false;shock_propagation=false",
    ]
    .map(|c| Candidate::parse(c).unwrap())
    .to_vec();
    let opts = Options {
        max_refinements: 2,
        ..Options::default()
    };
    let report = measure(&subject, Some(candidates), &opts, &hidden).unwrap();
    let [few, many] = [&report.rows[0], &report.rows[1]];
    assert!(
        many.worst_error < few.worst_error / 4.0,
        "{:e} against {:e}",
        many.worst_error,
        few.worst_error
    );
    assert!(many.work > few.work, "the solver work counts passes");
    assert!(many.worst_error >= report.reference.resolution);
    assert!(!report.features.particles && report.rows.iter().all(|r| r.particle_error.is_none()));
}

/// An elastic world (no gravity, restitution 1 and no friction everywhere) keeps its
/// energy: a candidate that loses it fails the criteria, as one that makes it would, and
/// an accuracy target never picks it however cheap it is.
#[test]
fn in_an_elastic_world_a_candidate_that_loses_energy_fails() {
    let hidden = indicatif::ProgressBar::hidden();
    let mut text = String::from(
        "[world]\ngravity = [0, 0]\nbounds = [[0, 0], [20, 20]]\n\
         [[generate]]\nkind = \"row\"\nid = \"wall\"\ngroup = \"walls\"\nshape = \"rect\"\n\
         size = [20, 1]\nstart = [10, 0]\nstep = [0, 20]\ncount = 2\nmass = 0\n\
         restitution = 1\nfriction = 0\n\
         [[generate]]\nkind = \"row\"\nid = \"side\"\ngroup = \"walls\"\nshape = \"rect\"\n\
         size = [1, 20]\nstart = [0, 10]\nstep = [20, 0]\ncount = 2\nmass = 0\n\
         restitution = 1\nfriction = 0\n\
         [[interact]]\na = \"gas\"\nb = \"gas\"\n[[interact]]\na = \"gas\"\nb = \"walls\"\n",
    );
    for k in 0..24 {
        let (x, y) = (3.0 + 2.5 * (k % 6) as f64, 4.0 + 3.0 * (k / 6) as f64);
        let (vx, vy) = (((k * 7) % 11) as f64 - 5.0, ((k * 5) % 9) as f64 - 4.0);
        text.push_str(&format!(
            "[[body]]\nid = \"g{k}\"\ngroup = \"gas\"\nshape = \"circle\"\nradius = 0.5\n\
             pos = [{x}, {y}]\nvel = [{vx}, {vy}]\nrestitution = 1\nfriction = 0\n"
        ));
    }
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("gas.toml");
    std::fs::write(&path, &text).unwrap();
    let subject = Subject::read(&path, 240, Vec::new()).unwrap();
    let candidates = ["solver=impulses", "solver=impulses;relax_iterations=2"]
        .map(|c| Candidate::parse(c).unwrap())
        .to_vec();
    let opts = Options {
        max_refinements: 1,
        ..Options::default()
    };
    let report = measure(&subject, Some(candidates), &opts, &hidden).unwrap();
    let [keeps, loses] = [&report.rows[0], &report.rows[1]];
    assert!(keeps.fails.is_empty(), "{:?}", keeps.fails);
    assert!(
        loses.fails.contains(&"energy_change".to_string()),
        "{:?}",
        loses.fails
    );
    // With friction on the walls the world is not elastic: losing energy is allowed.
    let rough = text.replace(
        "restitution = 1\nfriction = 0\n[[generate]]",
        "restitution = 1\nfriction = 0.5\n[[generate]]",
    );
    assert_ne!(rough, text);
    std::fs::write(&path, &rough).unwrap();
    let subject = Subject::read(&path, 240, Vec::new()).unwrap();
    let candidates = vec![Candidate::parse("solver=impulses;relax_iterations=2").unwrap()];
    let report = measure(&subject, Some(candidates), &opts, &hidden).unwrap();
    assert!(
        !report.rows[0].fails.contains(&"energy_change".to_string()),
        "{:?}",
        report.rows[0].fails
    );
}
