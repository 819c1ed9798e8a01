//! Continuous collision for the relaxation solver (`ccd = true`): sweeps fast bodies.
//!
//! After integration, a body that moved more than half its smallest extent is swept from
//! where it was to where it is against the bodies of the groups it interacts with: the
//! path of its centre against each other box grown by its own half extents (slab test).
//! At the first hit it is put back just before the contact and its velocity into the
//! surface is reflected with the pair's smaller restitution, so the relaxation that
//! follows sees a touching pair instead of one already past the wall.

use glam::DVec2;

use super::body::Body;
use crate::geometry::Aabb;

/// The earliest hit of a centre moving from `from` by `delta` against `target` grown by
/// `grow`: the fraction of the move and the surface normal.
fn sweep(from: DVec2, delta: DVec2, target: &Aabb, grow: DVec2) -> Option<(f64, DVec2)> {
    let (min, max) = (target.min - grow, target.max + grow);
    let (mut t_in, mut t_out) = (0.0f64, 1.0f64);
    let mut normal = DVec2::ZERO;
    for axis in 0..2 {
        let (p, d, lo, hi) = (from[axis], delta[axis], min[axis], max[axis]);
        if d == 0.0 {
            if p <= lo || p >= hi {
                return None;
            }
            continue;
        }
        let (mut t0, mut t1) = ((lo - p) / d, (hi - p) / d);
        let mut n = DVec2::ZERO;
        n[axis] = -d.signum();
        if t0 > t1 {
            std::mem::swap(&mut t0, &mut t1);
        }
        if t0 > t_in {
            t_in = t0;
            normal = n;
        }
        t_out = t_out.min(t1);
        if t_in > t_out {
            return None;
        }
    }
    // Starting inside (t_in = 0 with no entering face) is the solver's business.
    (normal != DVec2::ZERO && t_in > 0.0 && t_in <= 1.0).then_some((t_in, normal))
}

/// Sweeps the fast bodies among `movers` against the bodies of their partner groups.
/// `partners(i)` lists the bodies body `i` interacts with. Returns the bodies stopped.
pub fn sweep_fast_bodies(
    bodies: &mut [Body],
    movers: &[u32],
    dt: f64,
    partners: impl Fn(u32) -> Vec<u32>,
) -> u64 {
    let mut stopped = 0;
    for &i in movers {
        let b = &bodies[i as usize];
        let delta = b.vel * dt;
        let half = b.shape.half_extents();
        if b.is_static() || delta.abs().max_element() <= half.min_element() {
            continue;
        }
        let from = b.pos - delta;
        let mut first: Option<(f64, DVec2, f64)> = None;
        for j in partners(i) {
            if j == i {
                continue;
            }
            let o = &bodies[j as usize];
            if let Some((t, n)) = sweep(from, delta, &Aabb::of(&o.shape, o.pos), half) {
                if first.is_none_or(|(best, _, _)| t < best) {
                    first = Some((t, n, b.restitution.min(o.restitution)));
                }
            }
        }
        if let Some((t, n, e)) = first {
            let b = &mut bodies[i as usize];
            // Just short of the surface, so the pair starts the relaxation touching.
            b.pos = from + delta * t + n * (1e-9 * (1.0 + half.max_element()));
            let into = b.vel.dot(n);
            if into < 0.0 {
                b.vel -= n * ((1.0 + e) * into);
            }
            b.collided = true;
            stopped += 1;
        }
    }
    stopped
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Shape;

    #[test]
    fn a_bullet_is_stopped_at_the_face_of_a_thin_wall() {
        let mut bodies = vec![
            Body::for_test(
                Shape::rect(0.05, 10.0),
                DVec2::new(10.0, 0.0),
                DVec2::ZERO,
                0.0,
            ),
            Body::for_test(
                Shape::circle(0.05),
                DVec2::new(13.0, 0.0),
                DVec2::new(300.0, 0.0),
                100.0,
            ),
        ];
        bodies[1].restitution = 0.5;
        // It moved from x = 8 to x = 13 this step: through the wall.
        let n = sweep_fast_bodies(&mut bodies, &[1], 5.0 / 300.0, |_| vec![0]);
        assert_eq!(n, 1);
        let b = &bodies[1];
        assert!(
            (b.pos.x - (10.0 - 0.025 - 0.05)).abs() < 1e-6,
            "stopped at {}",
            b.pos.x
        );
        assert!(
            (b.vel.x + 0.5 * 300.0).abs() < 1e-9,
            "bounced at {}",
            b.vel.x
        );
    }

    #[test]
    fn slow_bodies_and_misses_are_left_alone() {
        let mut bodies = vec![
            Body::for_test(
                Shape::rect(0.05, 10.0),
                DVec2::new(10.0, 0.0),
                DVec2::ZERO,
                0.0,
            ),
            Body::for_test(
                Shape::circle(0.05),
                DVec2::new(13.0, 20.0),
                DVec2::new(300.0, 0.0),
                100.0,
            ),
            Body::for_test(
                Shape::circle(1.0),
                DVec2::new(9.0, 0.0),
                DVec2::new(30.0, 0.0),
                1.0,
            ),
        ];
        let n = sweep_fast_bodies(&mut bodies, &[1, 2], 1.0 / 60.0, |_| vec![0]);
        assert_eq!(n, 0);
        assert_eq!(bodies[1].pos, DVec2::new(13.0, 20.0));
    }
}
