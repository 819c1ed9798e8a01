//! The impulse solver's unit tests: single contacts, restitution, friction, warm starting.

use super::*;
use crate::dynamics::body::BodyKey;
use crate::dynamics::pairs::Contacts;
use crate::geometry::Shape;

fn body(key: u32, pos: DVec2, vel: DVec2, inv_mass: f64) -> Body {
    Body {
        key: BodyKey(key),
        restitution: 0.5,
        friction: 0.5,
        ..Body::for_test(Shape::rect(1.0, 1.0), pos, vel, inv_mass)
    }
}

/// One frame of one sub-step, without gravity, over `candidates`.
fn solve(
    bodies: &mut [Body],
    candidates: &mut Vec<(u32, u32)>,
    params: ImpulseParams,
    contacts: &mut Contacts,
) -> ImpulseReport {
    contacts.refill(candidates, &mut Vec::new());
    solve_frame(
        bodies,
        &mut contacts.pairs,
        params,
        &mut SolverBuffers::default(),
        &[0, 1],
        |_| DVec2::ZERO,
        &mut Vec::new(),
    )
}

/// Runs `count` frames of `start` without gravity, every pair a candidate, and calls
/// `each` with the bodies, the pairs and the report after each frame. Returns the bodies.
fn frames(
    start: &[Body],
    movers: &[u32],
    params: ImpulseParams,
    count: usize,
    mut each: impl FnMut(&[Body], &Contacts, &ImpulseReport),
) -> Vec<Body> {
    let mut bodies = start.to_vec();
    let (mut contacts, mut kept) = (Contacts::default(), Vec::new());
    for _ in 0..count {
        let n = bodies.len() as u32;
        let mut candidates: Vec<(u32, u32)> = (0..n)
            .flat_map(|a| (a + 1..n).map(move |b| (a, b)))
            .collect();
        contacts.refill(&mut candidates, &mut kept);
        let report = solve_frame(
            &mut bodies,
            &mut contacts.pairs,
            params,
            &mut SolverBuffers::default(),
            movers,
            |_| DVec2::ZERO,
            &mut Vec::new(),
        );
        each(&bodies, &contacts, &report);
    }
    bodies
}

/// Split impulses, 2 sub-steps of 2 passes and up to 6 more (as the default).
fn split_params() -> ImpulseParams {
    ImpulseParams {
        split_impulses: true,
        substeps: 2,
        iterations: 2,
        adaptive_iterations: 6,
        ..params()
    }
}

fn params() -> ImpulseParams {
    ImpulseParams {
        iterations: 8,
        adaptive_iterations: 0,
        relax_iterations: 0,
        warm_starting: true,
        baumgarte: 0.2,
        slop: 0.01,
        contact_hertz: 0.0,
        contact_damping: 10.0,
        split_impulses: false,
        dt: 1.0 / 60.0,
        substeps: 1,
        flight: crate::dynamics::config::Integrator::Symplectic,
        threads: 1,
        rest_load: None,
        support: None,
        exact_sliding: None,
        impact_propagation: false,
        still_frames: true,
    }
}

#[test]
fn a_head_on_collision_conserves_momentum_and_bounces_by_the_smaller_restitution() {
    let mut bodies = vec![
        body(0, DVec2::ZERO, DVec2::new(4.0, 0.0), 0.5),
        body(1, DVec2::new(0.999, 0.0), DVec2::new(-2.0, 0.0), 1.0 / 3.0),
    ];
    let p0 = bodies[0].vel * 2.0 + bodies[1].vel * 3.0;
    solve(
        &mut bodies,
        &mut vec![(0, 1)],
        params(),
        &mut Contacts::default(),
    );
    let p1 = bodies[0].vel * 2.0 + bodies[1].vel * 3.0;
    assert!((p1 - p0).length() < 1e-9);
    let separation = bodies[1].vel.x - bodies[0].vel.x;
    assert!((separation - 0.5 * 6.0).abs() < 1e-9, "{separation}");
}

#[test]
fn contacts_push_but_never_pull() {
    // Separating already: no impulse at all.
    let mut bodies = vec![
        body(0, DVec2::ZERO, DVec2::new(-1.0, 0.0), 1.0),
        body(1, DVec2::new(0.99, 0.0), DVec2::new(1.0, 0.0), 1.0),
    ];
    solve(
        &mut bodies,
        &mut vec![(0, 1)],
        ImpulseParams {
            baumgarte: 0.0,
            ..params()
        },
        &mut Contacts::default(),
    );
    assert_eq!(bodies[0].vel.x, -1.0);
    assert_eq!(bodies[1].vel.x, 1.0);
}

#[test]
fn friction_stays_within_the_coulomb_cone_and_never_reverses_sliding() {
    // A box sliding at 10 units/s on a static floor, pressed down at 1 unit/s (no
    // restitution: the press is held, not bounced).
    let inelastic = |b: Body| Body {
        restitution: 0.0,
        ..b
    };
    let mut bodies = vec![
        body(0, DVec2::ZERO, DVec2::ZERO, 0.0),
        inelastic(body(1, DVec2::new(0.0, 0.999), DVec2::new(10.0, -1.0), 1.0)),
    ];
    solve(
        &mut bodies,
        &mut vec![(0, 1)],
        ImpulseParams {
            baumgarte: 0.0,
            ..params()
        },
        &mut Contacts::default(),
    );
    let v = bodies[1].vel;
    // Normal impulse 1 (to stop the approach), friction at most 0.5 of it.
    assert!((v.y - 0.0).abs() < 1e-9, "{v}");
    assert!((v.x - 9.5).abs() < 1e-9, "{v}");
    // A slow slider is stopped, not reversed.
    let mut bodies = vec![
        body(0, DVec2::ZERO, DVec2::ZERO, 0.0),
        inelastic(body(1, DVec2::new(0.0, 0.999), DVec2::new(0.2, -1.0), 1.0)),
    ];
    solve(
        &mut bodies,
        &mut vec![(0, 1)],
        ImpulseParams {
            baumgarte: 0.0,
            ..params()
        },
        &mut Contacts::default(),
    );
    assert!(bodies[1].vel.x.abs() < 1e-9, "{}", bodies[1].vel);
}

#[test]
fn a_pair_listed_twice_is_one_contact() {
    let mut bodies = vec![
        body(0, DVec2::ZERO, DVec2::new(1.0, 0.0), 1.0),
        body(1, DVec2::new(0.99, 0.0), DVec2::ZERO, 1.0),
    ];
    let r = solve(
        &mut bodies,
        &mut vec![(0, 1), (1, 0)],
        params(),
        &mut Contacts::default(),
    );
    assert_eq!(r.contacts, 1);
}

/// A ball of radius 0.5, mass 1, restitution 1, no friction.
fn ball(key: u32, x: f64, vx: f64) -> Body {
    Body {
        key: BodyKey(key),
        restitution: 1.0,
        friction: 0.0,
        ..Body::for_test(
            Shape::circle(0.5),
            DVec2::new(x, 0.0),
            DVec2::new(vx, 0.0),
            1.0,
        )
    }
}

/// One frame over every pair of `bodies` (all moving), without gravity.
fn solve_all(bodies: &mut [Body], params: ImpulseParams) {
    let n = bodies.len() as u32;
    let mut candidates: Vec<(u32, u32)> = (0..n)
        .flat_map(|i| (i + 1..n).map(move |j| (i, j)))
        .collect();
    let mut contacts = Contacts::default();
    contacts.refill(&mut candidates, &mut Vec::new());
    let movers: Vec<u32> = (0..n).collect();
    solve_frame(
        bodies,
        &mut contacts.pairs,
        params,
        &mut SolverBuffers::default(),
        &movers,
        |_| DVec2::ZERO,
        &mut Vec::new(),
    );
}

#[test]
fn a_row_of_touching_elastic_balls_hands_the_first_ones_speed_to_the_last() {
    // Solving the row's contacts at once shares the speed out (8 balls at v/8 keep an
    // eighth of the energy); collisions one pair at a time pass it down the row.
    for reversed in [false, true] {
        let mut bodies: Vec<Body> = (0..8)
            .map(|k| ball(k, k as f64, if k == 0 { 6.0 } else { 0.0 }))
            .collect();
        if reversed {
            bodies.reverse();
        }
        solve_all(&mut bodies, params());
        let speed = |k: u32| bodies.iter().find(|b| b.key == BodyKey(k)).unwrap().vel.x;
        assert!(
            (speed(7) - 6.0).abs() < 1e-9,
            "reversed {reversed}: {}",
            speed(7)
        );
        for k in 0..7 {
            assert!(
                speed(k).abs() < 1e-9,
                "reversed {reversed}: ball {k} at {}",
                speed(k)
            );
        }
    }
}

#[test]
fn an_elastic_ball_that_meets_a_wall_within_the_step_bounces_where_it_meets() {
    // 0.05 from the wall at 6 units/s: it meets after 1/120 s, then leaves for the rest
    // of the 1/60 s step, ending 0.05 from the wall again, moving away at 6.
    let mut bodies = vec![
        Body {
            restitution: 1.0,
            ..body(0, DVec2::new(1.0, 0.0), DVec2::ZERO, 0.0)
        },
        ball(1, -0.05, 6.0),
    ];
    solve_all(&mut bodies, params());
    assert!((bodies[1].vel.x + 6.0).abs() < 1e-9, "{}", bodies[1].vel);
    assert!((bodies[1].pos.x + 0.05).abs() < 1e-9, "{}", bodies[1].pos);
}

/// How many contacts one frame of two boxes 1 across, `gap` apart along x, both at `vel`,
/// of restitution `restitution`, under `gravity`, solves.
fn contacts_made(gap: f64, vel: DVec2, restitution: f64, gravity: DVec2) -> usize {
    let mut bodies = vec![
        Body {
            restitution,
            ..body(0, DVec2::ZERO, vel, 1.0)
        },
        Body {
            restitution,
            ..body(1, DVec2::new(1.0 + gap, 0.0), vel, 1.0)
        },
    ];
    let mut contacts = Contacts::default();
    contacts.refill(&mut vec![(0, 1)], &mut Vec::new());
    let mut buffers = SolverBuffers::default();
    solve_frame(
        &mut bodies,
        &mut contacts.pairs,
        params(),
        &mut buffers,
        &[0, 1],
        |_| gravity,
        &mut Vec::new(),
    );
    buffers.last_contacts
}

/// A pair that nothing pulls and that cannot bounce (still, or without restitution)
/// becomes a contact only within the gap a resting contact holds: two still boxes 5% of
/// a size apart cost the passes nothing. Moving with restitution, or under gravity, the
/// same pair is a contact within a tenth of its size (a body struck or turned back within
/// the step may meet it at any speed); 15% apart and closing at nothing, it is none.
/// (Two bodies moving together close at nothing: only gravity counts their own speed.)
#[test]
fn a_pair_a_few_hundredths_apart_is_a_contact_only_if_it_may_bounce_or_fall() {
    let (still, along) = (DVec2::ZERO, DVec2::new(0.0, 3.0));
    let down = DVec2::new(0.0, -9.8);
    assert_eq!(contacts_made(0.05, still, 0.5, DVec2::ZERO), 0);
    assert_eq!(contacts_made(0.05, along, 0.0, DVec2::ZERO), 0);
    assert_eq!(contacts_made(0.05, along, 0.5, DVec2::ZERO), 1);
    assert_eq!(contacts_made(0.05, still, 0.0, down), 1);
    assert_eq!(contacts_made(0.01, still, 0.0, DVec2::ZERO), 1);
    assert_eq!(contacts_made(0.15, along, 0.5, DVec2::ZERO), 0);
    assert_eq!(contacts_made(0.15, still, 0.5, down), 0);
}

/// A crowd packed into a box past what fits, every body still: its frames run as
/// push-out only, with the bits of the full passes, and its velocities stay 0.
#[test]
fn a_still_crowd_pushes_out_with_the_bits_of_the_full_passes() {
    let circle = |key: u32, pos: DVec2| Body {
        key: BodyKey(key),
        restitution: 0.2,
        friction: 0.2,
        ..Body::for_test(Shape::circle(0.5), pos, DVec2::ZERO, 1.0)
    };
    let wall = |key: u32, pos: DVec2, half: DVec2| Body {
        key: BodyKey(key),
        ..Body::for_test(
            Shape::rect(2.0 * half.x, 2.0 * half.y),
            pos,
            DVec2::ZERO,
            0.0,
        )
    };
    // Walls around a square 3.6 wide; a 4 x 4 grid of circles 1 across, 0.9 apart,
    // the inner ones moved off the grid a little so the pushes do not cancel.
    let mut start = vec![
        wall(0, DVec2::new(0.0, -1.9), DVec2::new(2.0, 0.1)),
        wall(1, DVec2::new(0.0, 1.9), DVec2::new(2.0, 0.1)),
        wall(2, DVec2::new(-1.9, 0.0), DVec2::new(0.1, 2.0)),
        wall(3, DVec2::new(1.9, 0.0), DVec2::new(0.1, 2.0)),
    ];
    for i in 0..4 {
        for j in 0..4 {
            let k = start.len() as u32;
            let nudge = DVec2::new(0.013 * f64::from(k % 3), 0.007 * f64::from(k % 5));
            let pos = DVec2::new(-1.35 + 0.9 * f64::from(i), -1.35 + 0.9 * f64::from(j));
            start.push(circle(k, pos + nudge));
        }
    }
    let movers: Vec<u32> = (4..start.len() as u32).collect();
    let run = |still_frames: bool| {
        let mut passes = 0;
        let params = ImpulseParams {
            slop: 0.0001,
            still_frames,
            ..split_params()
        };
        let bodies = frames(&start, &movers, params, 30, |_, _, report| {
            passes += report.passes;
        });
        (bodies, passes)
    };
    let (still, still_passes) = run(true);
    let (full, full_passes) = run(false);
    // The full passes ran the collision stage and adaptive passes the still frames skip.
    assert!(still_passes < full_passes, "{still_passes} {full_passes}");
    let mut moved = 0.0_f64;
    for ((s, f), b) in still.iter().zip(&full).zip(&start) {
        let bits = |p: DVec2| (p.x.to_bits(), p.y.to_bits());
        assert_eq!(bits(s.pos), bits(f.pos), "{} {} {}", s.key.0, s.pos, f.pos);
        assert_eq!(s.vel, DVec2::ZERO);
        assert_eq!(f.vel, DVec2::ZERO);
        moved = moved.max((s.pos - b.pos).length());
    }
    // The crowd was pushed about: the frames did work.
    assert!(moved > 0.01, "{moved}");
}

#[test]
fn a_block_at_rest_sits_out_the_frames_until_a_body_reaches_it_to_the_bit() {
    // A 4 x 4 block of touching boxes at rest, no gravity, and a box flying at it from
    // 3 units off: the block's island cannot change until the box touches it.
    let mut start = vec![body(0, DVec2::new(-4.0, 0.25), DVec2::new(12.0, 0.0), 0.5)];
    for i in 0..4 {
        for j in 0..4 {
            let k = start.len() as u32;
            let pos = DVec2::new(f64::from(i), f64::from(j) - 1.5);
            start.push(body(k, pos, DVec2::ZERO, 4.0));
        }
    }
    let movers: Vec<u32> = (0..start.len() as u32).collect();
    let run = |still_frames: bool| {
        let (mut parked, mut seen) = (Vec::new(), Vec::new());
        let params = ImpulseParams {
            impact_propagation: true,
            still_frames,
            ..split_params()
        };
        let bodies = frames(&start, &movers, params, 30, |bodies, contacts, report| {
            parked.push(report.parked);
            let bits = |v: DVec2| (v.x.to_bits(), v.y.to_bits());
            seen.push((
                bodies
                    .iter()
                    .map(|b| (bits(b.pos), bits(b.vel)))
                    .collect::<Vec<_>>(),
                contacts
                    .pairs
                    .iter()
                    .map(|p| (p.normal_impulse.to_bits(), p.tangent_impulse.to_bits()))
                    .collect::<Vec<_>>(),
            ));
        });
        (seen, parked, bodies)
    };
    let (parked_frames, parked, bodies) = run(true);
    let (full_frames, none, _) = run(false);
    assert!(none.iter().all(|&p| p == 0));
    // The block's 42 contacts (24 sides, 18 corners) sat out the first frames, and none
    // once the box reached it.
    assert_eq!(parked[0], 42, "{parked:?}");
    let reached = parked
        .iter()
        .position(|&p| p == 0)
        .expect("the box reaches the block");
    assert!(
        reached >= 5 && parked[reached..].iter().all(|&p| p == 0),
        "{parked:?}"
    );
    // The block was struck: the frames after did work.
    assert!(bodies[16].vel.x > 0.1, "{}", bodies[16].vel);
    for (k, (p, f)) in parked_frames.iter().zip(&full_frames).enumerate() {
        assert_eq!(p, f, "frame {k}");
    }
}

#[test]
fn every_mover_asleep_or_awake_gets_its_deepest_overlap_on_any_thread_count() {
    // 100 x 100 unit boxes 0.05 into their neighbours, one in seven asleep: blocks, and
    // contacts enough for the work around the passes to split on two threads.
    let n = 100u32;
    let start: Vec<Body> = (0..n * n)
        .map(|k| {
            let at = DVec2::new(f64::from(k % n), f64::from(k / n)) * 0.95;
            let mut b = body(k, at, DVec2::ZERO, 1.0);
            if k % 7 == 3 {
                b.asleep = Some(crate::dynamics::body::Sleeper { inv_mass: 1.0 });
                b.inv_mass = 0.0;
            }
            b
        })
        .collect();
    let movers: Vec<u32> = (0..n * n).collect();
    let run = |threads: u32| {
        let mut bodies = start.clone();
        let mut candidates: Vec<(u32, u32)> = (0..n * n)
            .flat_map(|k| {
                let right = (k % n + 1 < n).then_some((k, k + 1));
                let up = (k + n < n * n).then_some((k, k + n));
                right.into_iter().chain(up)
            })
            .collect();
        let mut contacts = Contacts::default();
        contacts.refill(&mut candidates, &mut Vec::new());
        let mut buffers = SolverBuffers::default();
        let params = ImpulseParams {
            threads,
            ..split_params()
        };
        let (mut flagged, mut first) = (Vec::new(), Vec::new());
        for frame in 0..2 {
            flagged.clear();
            solve_frame(
                &mut bodies,
                &mut contacts.pairs,
                params,
                &mut buffers,
                &movers,
                |_| DVec2::ZERO,
                &mut flagged,
            );
            if frame == 0 {
                first = buffers.depths().to_vec();
            }
        }
        let places: Vec<[u64; 4]> = bodies
            .iter()
            .map(|b| [b.pos.x, b.pos.y, b.vel.x, b.vel.y].map(f64::to_bits))
            .collect();
        let impulses: Vec<[u64; 3]> = contacts
            .pairs
            .iter()
            .map(|p| [p.normal_impulse, p.tangent_impulse, p.pseudo_impulse].map(f64::to_bits))
            .collect();
        (first, buffers.depths().to_vec(), places, impulses, flagged)
    };
    let one = run(1);
    // The first frame starts every body, asleep or not, 0.05 into its neighbours.
    assert_eq!(one.0.len(), movers.len());
    for (k, d) in one.0.iter().enumerate() {
        assert!((d - 0.05).abs() < 1e-9, "mover {k}: {d}");
    }
    // The push-out moved the awake bodies apart (what is stored changed).
    let moved = one
        .2
        .iter()
        .zip(&start)
        .filter(|(p, b)| p[0] != b.pos.x.to_bits());
    assert!(moved.count() > 1000);
    assert!(one == run(2), "two threads differ from one");
}
