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
    // A box sliding at 10 units/s on a static floor, pressed down at 1 unit/s.
    let mut bodies = vec![
        body(0, DVec2::ZERO, DVec2::ZERO, 0.0),
        body(1, DVec2::new(0.0, 0.999), DVec2::new(10.0, -1.0), 1.0),
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
        body(1, DVec2::new(0.0, 0.999), DVec2::new(0.2, -1.0), 1.0),
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
