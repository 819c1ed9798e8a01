//! Collision resolution by relaxation ("Resolving Collisions and Applying Friction",
//! "Adding the Relaxation Loop for Stability").
//!
//! Each interaction between two groups runs its own relaxation loop: up to
//! `relaxation_iterations` passes over its pairs, each pass projecting overlapping pairs
//! apart by `correction_rate` of their depth, damping their tangential velocity and
//! applying a restitution impulse; a pass that finds no collision ends the loop early.
//!
//! Departures from the chapter, each a defect of its code:
//! - the loop runs exactly N passes at most (the chapter decrements before testing, so N
//!   ran N-1 passes and a count of 1 ran none);
//! - a pair whose inverse masses sum to 0 (two static bodies) is never resolved, instead
//!   of dividing by zero;
//! - friction on the second body had the wrong sign and sped it up; here friction always
//!   opposes a body's own tangential motion and is clamped so it never reverses it.

use glam::DVec2;

use super::body::Body;
use crate::geometry::{collide, Aabb, CollisionInfo};

/// Below this tangential speed friction is skipped, as in the chapter (units/s).
pub const FRICTION_REST_SPEED: f64 = 0.01;

/// The solver settings one interaction needs.
#[derive(Clone, Copy, Debug)]
pub struct RelaxationParams {
    pub iterations: u32,
    pub correction_rate: f64,
    /// Bounce with the speed the pair had when it met, not the speed it has found sunk in
    /// by the depth (`v_s² = v² + 2 a_n d`, its relative acceleration `a_n` along the
    /// normal): the projection lifts it back to the surface, and bouncing with the deeper
    /// speed would add the energy of that lift. `None`: the chapter's bounce. Used with
    /// the exact integrator, whose flight holds the energy this keeps.
    pub impact: Option<Gravity>,
}

/// The acceleration bodies feel, as the integrator applies it.
#[derive(Clone, Copy, Debug)]
pub struct Gravity {
    pub world: DVec2,
    /// Scaled by the inverse mass (the chapter's `mass_scaled_acceleration`).
    pub mass_scaled: bool,
}

impl Gravity {
    fn of(&self, body: &Body) -> DVec2 {
        if body.inv_mass == 0.0 {
            return DVec2::ZERO;
        }
        super::integrate::acceleration_under(body, self.world, self.mass_scaled)
    }
}

impl RelaxationParams {
    /// The share of friction applied per resolution, `1 / iterations` (the chapter's
    /// `mRelaxationOffset`).
    pub fn relaxation_offset(&self) -> f64 {
        1.0 / self.iterations.max(1) as f64
    }
}

/// What one interaction did in one step.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RelaxationReport {
    /// Pair resolutions (or detections, for a detect-only interaction).
    pub contacts: u64,
    /// Passes run, the last included.
    pub iterations: u32,
    /// The deepest penetration detected.
    pub deepest: f64,
    /// The deepest penetration the last pass found (0 when it found none).
    pub residual: f64,
}

/// Two distinct elements of a slice, both mutable.
fn pair_mut<T>(items: &mut [T], i: usize, j: usize) -> (&mut T, &mut T) {
    debug_assert_ne!(i, j);
    if i < j {
        let (lo, hi) = items.split_at_mut(j);
        (&mut lo[i], &mut hi[0])
    } else {
        let (lo, hi) = items.split_at_mut(i);
        (&mut hi[0], &mut lo[j])
    }
}

/// Detects the collision of bodies `i` and `j`, or `None` when they cannot interact
/// (the same body, both static, or apart).
#[inline]
fn detect(bodies: &[Body], i: usize, j: usize) -> Option<CollisionInfo> {
    if i == j {
        return None;
    }
    let (a, b) = (&bodies[i], &bodies[j]);
    if a.inv_mass + b.inv_mass == 0.0 {
        return None;
    }
    if !Aabb::of(&a.shape, a.pos).overlaps(&Aabb::of(&b.shape, b.pos)) {
        return None;
    }
    collide(&a.shape, a.pos, &b.shape, b.pos)
}

/// Runs one interaction's relaxation loop over every ordered pair (a in `group_a`, b in
/// `group_b`), in the order the groups list them. A group against itself tests every
/// ordered pair of distinct members, as the chapter does.
pub fn relax(
    bodies: &mut [Body],
    group_a: &[u32],
    group_b: &[u32],
    params: RelaxationParams,
) -> RelaxationReport {
    relax_passes(bodies, params, || {
        group_a
            .iter()
            .flat_map(|&i| group_b.iter().map(move |&j| (i, j)))
    })
}

/// Runs one interaction's relaxation loop over candidate pairs from a broad phase (in the
/// all-pairs order): the same passes as [`relax`], over fewer pairs.
pub fn relax_pairs(
    bodies: &mut [Body],
    pairs: &[(u32, u32)],
    params: RelaxationParams,
) -> RelaxationReport {
    relax_passes(bodies, params, || pairs.iter().copied())
}

/// The relaxation loop: up to `iterations` passes over `pairs()`, stopping after a pass
/// that found no collision.
fn relax_passes<I: Iterator<Item = (u32, u32)>>(
    bodies: &mut [Body],
    params: RelaxationParams,
    pairs: impl Fn() -> I,
) -> RelaxationReport {
    let mut report = RelaxationReport::default();
    let offset = params.relaxation_offset();
    for _ in 0..params.iterations.max(1) {
        report.iterations += 1;
        let mut any = false;
        report.residual = 0.0;
        for (i, j) in pairs() {
            let (i, j) = (i as usize, j as usize);
            if let Some(info) = detect(bodies, i, j) {
                any = true;
                report.contacts += 1;
                report.deepest = report.deepest.max(info.depth);
                report.residual = report.residual.max(info.depth);
                let (a, b) = pair_mut(bodies, i, j);
                let sunk = params.impact.map(|g| Sunk {
                    depth: info.depth,
                    accel: (g.of(b) - g.of(a)).dot(info.normal),
                });
                resolve_collision(a, b, &info, params.correction_rate, offset, sunk);
            }
        }
        if !any {
            break;
        }
    }
    report
}

/// Flags every colliding pair without moving anything (the bounds demo).
pub fn detect_only(bodies: &mut [Body], group_a: &[u32], group_b: &[u32]) -> RelaxationReport {
    let mut report = RelaxationReport {
        iterations: 1,
        ..Default::default()
    };
    for &i in group_a {
        for &j in group_b {
            let (i, j) = (i as usize, j as usize);
            if i == j {
                continue;
            }
            let (a, b) = (&bodies[i], &bodies[j]);
            if let Some(info) = collide(&a.shape, a.pos, &b.shape, b.pos) {
                report.contacts += 1;
                report.deepest = report.deepest.max(info.depth);
                bodies[i].collided = true;
                bodies[j].collided = true;
            }
        }
    }
    report
}

/// How far a pair sank in past the surface, and its relative acceleration along the
/// normal: what its speed at the surface is reckoned from.
#[derive(Clone, Copy, Debug)]
pub struct Sunk {
    pub depth: f64,
    pub accel: f64,
}

/// Resolves one collision: positional correction, friction, then the restitution impulse
/// ("resolveCollision", steps A to F). `info.normal` points from `a` toward `b`. With
/// `sunk`, the bounce is of the speed at the surface (see [`RelaxationParams::impact`]).
pub fn resolve_collision(
    a: &mut Body,
    b: &mut Body,
    info: &CollisionInfo,
    correction_rate: f64,
    relaxation_offset: f64,
    sunk: Option<Sunk>,
) {
    let inv_sum = a.inv_mass + b.inv_mass;
    if inv_sum == 0.0 {
        return;
    }
    a.collided = true;
    b.collided = true;
    let n = info.normal;

    // Step B: project apart by a share of the depth, in inverse proportion to mass.
    let correction = n * (info.depth / inv_sum * correction_rate);
    a.pos -= correction * a.inv_mass;
    b.pos += correction * b.inv_mass;

    // Step C: friction, each body against its own tangential motion.
    apply_friction(n, &mut a.vel, a.friction, a.inv_mass, relaxation_offset);
    apply_friction(n, &mut b.vel, b.friction, b.inv_mass, relaxation_offset);

    // Steps D-E: only bodies moving toward each other get an impulse.
    let v_n = (b.vel - a.vel).dot(n);
    if v_n > 0.0 {
        return;
    }
    // Step F: impulse with the smaller restitution.
    let e = a.restitution.min(b.restitution);
    let j = match sunk {
        None => -(1.0 + e) * v_n / inv_sum,
        Some(Sunk { depth, accel }) => {
            let at_surface = (v_n * v_n + 2.0 * accel * depth).max(0.0).sqrt();
            (e * at_surface - v_n) / inv_sum
        }
    };
    a.vel -= n * (j * a.inv_mass);
    b.vel += n * (j * b.inv_mass);
}

/// Decelerates `vel` along the tangent of `normal` by `friction * inv_mass * offset`,
/// never past zero.
pub fn apply_friction(normal: DVec2, vel: &mut DVec2, friction: f64, inv_mass: f64, offset: f64) {
    let tangent = DVec2::new(normal.y, -normal.x);
    let t = vel.dot(tangent);
    if t.abs() < FRICTION_REST_SPEED {
        return;
    }
    let slow = (friction * inv_mass * offset).min(t.abs());
    *vel -= tangent * (slow * t.signum());
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Shape;

    fn body(shape: Shape, pos: DVec2, vel: DVec2, inv_mass: f64) -> Body {
        Body::for_test(shape, pos, vel, inv_mass)
    }

    #[test]
    fn head_on_collision_conserves_momentum_and_uses_the_smaller_restitution() {
        let mut a = body(
            Shape::circle(1.0),
            DVec2::new(0.0, 0.0),
            DVec2::new(4.0, 0.0),
            1.0 / 2.0,
        );
        let mut b = body(
            Shape::circle(1.0),
            DVec2::new(1.9, 0.0),
            DVec2::new(-2.0, 0.0),
            1.0 / 3.0,
        );
        a.restitution = 0.5;
        b.restitution = 0.9;
        let p0 = a.vel * a.mass() + b.vel * b.mass();
        let info = collide(&a.shape, a.pos, &b.shape, b.pos).unwrap();
        resolve_collision(&mut a, &mut b, &info, 0.8, 1.0 / 15.0, None);
        let p1 = a.vel * a.mass() + b.vel * b.mass();
        assert!((p1 - p0).length() < 1e-12, "momentum {p0} -> {p1}");
        // Separation speed = e * approach speed with e = min(0.5, 0.9).
        let approach = 6.0;
        let separation = (b.vel - a.vel).x;
        assert!(
            (separation - 0.5 * approach).abs() < 1e-12,
            "separation {separation}"
        );
        assert!(a.collided && b.collided);
    }

    #[test]
    fn positional_correction_is_split_by_inverse_mass() {
        let mut a = body(Shape::rect(2.0, 2.0), DVec2::ZERO, DVec2::ZERO, 1.0);
        let mut b = body(
            Shape::rect(2.0, 2.0),
            DVec2::new(1.5, 0.0),
            DVec2::ZERO,
            3.0,
        );
        let info = collide(&a.shape, a.pos, &b.shape, b.pos).unwrap();
        assert!((info.depth - 0.5).abs() < 1e-12);
        resolve_collision(&mut a, &mut b, &info, 0.8, 1.0, None);
        // 0.8 * 0.5 = 0.4 removed, a takes 1/4 of it and b 3/4.
        assert!((a.pos.x + 0.1).abs() < 1e-12);
        assert!((b.pos.x - (1.5 + 0.3)).abs() < 1e-12);
    }

    #[test]
    fn two_static_bodies_are_left_alone() {
        let mut bodies = vec![
            body(Shape::rect(2.0, 2.0), DVec2::ZERO, DVec2::ZERO, 0.0),
            body(
                Shape::rect(2.0, 2.0),
                DVec2::new(0.5, 0.0),
                DVec2::ZERO,
                0.0,
            ),
        ];
        let r = relax(
            &mut bodies,
            &[0],
            &[1],
            RelaxationParams {
                iterations: 15,
                correction_rate: 0.8,
                impact: None,
            },
        );
        assert_eq!(r.contacts, 0);
        assert!(bodies.iter().all(|b| b.pos.is_finite() && !b.collided));
        // Called directly, the resolution still refuses to divide by zero.
        let info = CollisionInfo {
            depth: 1.0,
            normal: DVec2::X,
        };
        let (a, b) = pair_mut(&mut bodies, 0, 1);
        resolve_collision(a, b, &info, 0.8, 1.0, None);
        assert!(a.pos.is_finite() && b.pos.is_finite());
    }

    #[test]
    fn friction_opposes_both_bodies_and_never_reverses_them() {
        // A box sliding right on a box sliding left: each must slow down, not speed up.
        let normal = DVec2::new(0.0, 1.0);
        let mut top = DVec2::new(3.0, 0.0);
        let mut bottom = DVec2::new(-3.0, 0.0);
        apply_friction(normal, &mut top, 0.3, 1.0, 1.0);
        apply_friction(normal, &mut bottom, 0.3, 1.0, 1.0);
        assert!((top.x - 2.7).abs() < 1e-12, "{top}");
        assert!((bottom.x + 2.7).abs() < 1e-12, "{bottom}");
        // Strong friction stops a slow body; it does not flip its direction.
        let mut slow = DVec2::new(0.05, -1.0);
        apply_friction(normal, &mut slow, 10.0, 1.0, 1.0);
        assert_eq!(slow.x, 0.0);
        assert_eq!(slow.y, -1.0);
    }

    #[test]
    fn second_body_of_a_pair_is_slowed_by_friction() {
        // The chapter's sign defect sped up the second body of a pair.
        let mut platform = body(Shape::rect(10.0, 1.0), DVec2::ZERO, DVec2::ZERO, 0.0);
        let mut slider = body(
            Shape::rect(1.0, 1.0),
            DVec2::new(0.0, 0.9),
            DVec2::new(5.0, -1.0),
            1.0,
        );
        let info = collide(&platform.shape, platform.pos, &slider.shape, slider.pos).unwrap();
        resolve_collision(&mut platform, &mut slider, &info, 0.8, 1.0 / 15.0, None);
        assert!(slider.vel.x < 5.0 && slider.vel.x > 0.0, "{}", slider.vel);
    }

    #[test]
    fn a_count_of_n_runs_exactly_n_passes() {
        // Deep overlap with a tiny correction rate never fully resolves, so every pass
        // finds a collision and the loop must run exactly N times.
        for n in [1u32, 2, 15] {
            let mut bodies = vec![
                body(Shape::rect(10.0, 10.0), DVec2::ZERO, DVec2::ZERO, 0.0),
                body(
                    Shape::rect(10.0, 10.0),
                    DVec2::new(0.0, 1.0),
                    DVec2::ZERO,
                    1.0,
                ),
            ];
            let r = relax(
                &mut bodies,
                &[0],
                &[1],
                RelaxationParams {
                    iterations: n,
                    correction_rate: 0.01,
                    impact: None,
                },
            );
            assert_eq!(r.iterations, n);
            assert_eq!(r.contacts, n as u64);
        }
    }

    #[test]
    fn relaxation_stops_after_a_clean_pass() {
        let mut bodies = vec![
            body(Shape::rect(10.0, 2.0), DVec2::ZERO, DVec2::ZERO, 0.0),
            body(
                Shape::rect(1.0, 1.0),
                DVec2::new(0.0, 1.6),
                DVec2::ZERO,
                1.0,
            ),
        ];
        let r = relax(
            &mut bodies,
            &[0],
            &[1],
            RelaxationParams {
                iterations: 15,
                correction_rate: 0.8,
                impact: None,
            },
        );
        assert_eq!(
            r,
            RelaxationReport {
                contacts: 0,
                iterations: 1,
                deepest: 0.0,
                residual: 0.0
            }
        );
    }
}
