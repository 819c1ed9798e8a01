//! The sequential-impulse contact solver (`solver = "impulses"`).
//!
//! Contacts are speculative: a pair still apart by a gap `s` gets the constraint "approach
//! at most `s / dt`", so bodies meet exactly instead of sinking in and being pushed back.
//!
//! Contacts of every resolving interaction are solved together: each velocity iteration
//! visits every contact once and applies the normal impulse that brings the bodies'
//! normal velocity to its target, accumulating it and clamping the sum at zero (contacts
//! push, never pull), then a Coulomb friction impulse clamped by `friction x normal
//! impulse`. The target is the restitution bounce for an approach faster than
//! [`RESTITUTION_SPEED`], plus a Baumgarte bias that removes `baumgarte` of the
//! penetration beyond the slop per sub-step. Impulses are kept between steps (keyed by the
//! pair of bodies) and applied first next step: warm starting, which lets stacks and
//! pyramids settle in a few iterations. Positions move only by velocity, after each
//! sub-step's solve.
//!
//! Shapes do not rotate, so one contact per pair carries all of it.

use std::collections::HashMap;

use glam::DVec2;

use super::body::{Body, BodyKey};
use crate::geometry::separation;

/// The fastest the position bias pushes overlapping bodies apart, in body sizes per
/// second: a deep overlap (a spawn on top of another body, coincident centres) is undone
/// over a few frames instead of launching the bodies.
pub const MAX_PUSH_OUT: f64 = 2.0;

/// A contact found with a larger gap than this (in body sizes) may close it and no more
/// (a falling body lands instead of stopping short); a nearer one holds, which keeps
/// stacks of touching bodies still.
pub const SPECULATIVE_GAP: f64 = 0.02;

/// Approaches slower than this (units/s) do not bounce: resting contacts stay at rest.
pub const RESTITUTION_SPEED: f64 = 1.0;

/// The solver's settings for one sub-step.
#[derive(Clone, Copy, Debug)]
pub struct ImpulseParams {
    pub iterations: u32,
    pub warm_starting: bool,
    pub baumgarte: f64,
    pub slop: f64,
    pub dt: f64,
}

/// One contact, as the inner loop reads it.
#[derive(Clone, Copy, Debug)]
struct Contact {
    a: u32,
    b: u32,
    normal: DVec2,
    inv_a: f64,
    inv_b: f64,
    /// 1 / (inv_a + inv_b).
    mass: f64,
    friction: f64,
    /// Separation at the start of the frame (negative: penetration).
    gap: f64,
    /// Penetration left alone.
    slop: f64,
    /// Normal velocity of the restitution bounce (0 for a resting contact).
    bounce: f64,
    start_a: DVec2,
    start_b: DVec2,
    /// Cap of the position bias velocity.
    max_push: f64,
    /// Found apart (beyond the slop): the bodies may close the gap, no more.
    speculative: bool,
    normal_impulse: f64,
    tangent_impulse: f64,
}

/// A fast hash of small integer keys (the multiply-rotate of rustc's FxHasher). Only
/// lookups use it, never iteration order, so results stay deterministic.
#[derive(Clone, Copy, Debug, Default)]
pub struct KeyHasher(u64);

impl std::hash::Hasher for KeyHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(b as u64);
        }
    }
    fn write_u32(&mut self, n: u32) {
        self.write_u64(n as u64);
    }
    fn write_u64(&mut self, n: u64) {
        self.0 = (self.0.rotate_left(5) ^ n).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
    }
}

type KeyMap<K, V> = HashMap<K, V, std::hash::BuildHasherDefault<KeyHasher>>;

/// Impulses of the last step, for warm starting.
#[derive(Clone, Debug, Default)]
pub struct ContactCache {
    impulses: KeyMap<(BodyKey, BodyKey), (DVec2, f64, f64)>,
}

impl ContactCache {
    pub fn clear(&mut self) {
        self.impulses.clear();
    }
}

/// What the solver did in one sub-step.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ImpulseReport {
    pub contacts: u64,
    pub deepest: f64,
}

/// One frame of the impulse solver: finds the contacts among `pairs` once (body indices;
/// a pair listed in both orders counts once), then runs `substeps` sub-steps of
/// `dt / substeps`: `integrate_velocities(h)`, warm start, velocity iterations, and
/// `p += v h` for the dynamic bodies listed in `movers`. Within the frame a contact's separation is tracked from how far its two
/// bodies moved along its normal, so detection runs once per frame however many sub-steps
/// there are (in the manner of Box2D v3's soft step).
pub fn solve_frame(
    bodies: &mut [Body],
    pairs: &mut Vec<(u32, u32)>,
    params: ImpulseParams,
    substeps: u32,
    cache: &mut ContactCache,
    movers: &[u32],
    mut integrate_velocities: impl FnMut(&mut [Body], f64),
) -> ImpulseReport {
    // One contact per unordered pair, in a deterministic order.
    for p in pairs.iter_mut() {
        if p.0 > p.1 {
            *p = (p.1, p.0);
        }
    }
    pairs.sort_unstable();
    pairs.dedup();

    let frame_dt = params.dt;
    let substeps = substeps.max(1);
    let h = frame_dt / substeps as f64;
    let inv_h = 1.0 / h;
    let mut report = ImpulseReport::default();
    let mut contacts = Vec::with_capacity(pairs.len());
    for &(i, j) in pairs.iter() {
        let (a, b) = (&bodies[i as usize], &bodies[j as usize]);
        if a.inv_mass + b.inv_mass == 0.0 {
            continue;
        }
        let (gap, n) = separation(&a.shape, a.pos, &b.shape, b.pos);
        let approach = (b.vel - a.vel).dot(n);
        let size = a
            .shape
            .half_extents()
            .min_element()
            .min(b.shape.half_extents().min_element())
            * 2.0;
        // Too far apart to meet within the frame: no contact.
        if gap > (b.vel - a.vel).length() * frame_dt + 0.1 * size {
            continue;
        }
        if gap <= 0.0 {
            report.contacts += 1;
            report.deepest = report.deepest.max(-gap);
        }
        let bounce = if approach < -RESTITUTION_SPEED {
            -a.restitution.min(b.restitution) * approach
        } else {
            0.0
        };
        let mut c = Contact {
            a: i,
            b: j,
            normal: n,
            inv_a: a.inv_mass,
            inv_b: b.inv_mass,
            mass: 1.0 / (a.inv_mass + b.inv_mass),
            friction: (a.friction * b.friction).sqrt(),
            gap,
            slop: params.slop * size,
            bounce,
            start_a: a.pos,
            start_b: b.pos,
            max_push: MAX_PUSH_OUT * size,
            speculative: gap > SPECULATIVE_GAP * size,
            normal_impulse: 0.0,
            tangent_impulse: 0.0,
        };
        // Only contacts that touch start from their last impulses.
        if params.warm_starting && gap <= c.slop {
            if let Some(&(old_n, jn, jt)) = cache.impulses.get(&(a.key, b.key)) {
                if old_n.dot(n) > 0.99 {
                    c.normal_impulse = jn;
                    c.tangent_impulse = jt;
                }
            }
        }
        contacts.push(c);
    }

    for step in 0..substeps {
        integrate_velocities(bodies, h);
        // Warm start: the impulses of the last sub-step (or frame) once more.
        if params.warm_starting || step > 0 {
            for c in &contacts {
                if c.normal_impulse != 0.0 || c.tangent_impulse != 0.0 {
                    let t = DVec2::new(-c.normal.y, c.normal.x);
                    apply(
                        bodies,
                        c,
                        c.normal * c.normal_impulse + t * c.tangent_impulse,
                    );
                }
            }
        }
        for _ in 0..params.iterations {
            for c in contacts.iter_mut() {
                let (a, b) = (c.a as usize, c.b as usize);
                let dv = bodies[b].vel - bodies[a].vel;
                // Separation now: the frame's start plus how far the bodies moved since.
                let gap = c.gap
                    + ((bodies[b].pos - c.start_b) - (bodies[a].pos - c.start_a)).dot(c.normal);
                let target = if c.speculative && gap > 0.0 {
                    // Apart when found: close the gap within this sub-step, no further.
                    -gap * inv_h
                } else {
                    // Touching: hold, push out what exceeds the slop.
                    (params.baumgarte * inv_h * (-gap - c.slop).max(0.0)).min(c.max_push)
                };
                // Normal: drive the normal velocity to its target, never pulling.
                let vn = dv.dot(c.normal);
                let total = (c.normal_impulse + c.mass * (target - vn)).max(0.0);
                let dn = total - c.normal_impulse;
                c.normal_impulse = total;
                // Friction: stop the sliding, within the Coulomb cone of the normal impulse.
                // (The normal impulse does not change the tangential velocity.)
                let t = DVec2::new(-c.normal.y, c.normal.x);
                let vt = dv.dot(t);
                let limit = c.friction * c.normal_impulse;
                let total_t = (c.tangent_impulse - c.mass * vt).clamp(-limit, limit);
                let dt_imp = total_t - c.tangent_impulse;
                c.tangent_impulse = total_t;
                apply(bodies, c, c.normal * dn + t * dt_imp);
            }
        }
        for &i in movers {
            let body = &mut bodies[i as usize];
            body.pos += body.vel * h;
        }
        // Restitution, once, for contacts that pushed: after the move, the normal velocity
        // becomes the bounce of the approach speed the contact was found with (as Box2D
        // applies it), so a contact that caught a body early still bounces it fully.
        for c in contacts.iter_mut() {
            if c.bounce > 0.0 && c.normal_impulse > 0.0 {
                let (a, b) = (c.a as usize, c.b as usize);
                let vn = (bodies[b].vel - bodies[a].vel).dot(c.normal);
                let total = (c.normal_impulse + c.mass * (c.bounce - vn)).max(0.0);
                let p = c.normal * (total - c.normal_impulse);
                c.normal_impulse = total;
                apply(bodies, c, p);
                c.bounce = 0.0;
            }
        }
    }

    cache.impulses.clear();
    for c in &contacts {
        if c.normal_impulse > 0.0 {
            bodies[c.a as usize].collided = true;
            bodies[c.b as usize].collided = true;
        }
        let key = (bodies[c.a as usize].key, bodies[c.b as usize].key);
        cache
            .impulses
            .insert(key, (c.normal, c.normal_impulse, c.tangent_impulse));
    }
    report
}

fn apply(bodies: &mut [Body], c: &Contact, impulse: DVec2) {
    bodies[c.a as usize].vel -= impulse * c.inv_a;
    bodies[c.b as usize].vel += impulse * c.inv_b;
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Shape;

    fn body(key: u32, pos: DVec2, vel: DVec2, inv_mass: f64) -> Body {
        Body {
            key: BodyKey(key),
            restitution: 0.5,
            friction: 0.5,
            ..Body::for_test(Shape::rect(1.0, 1.0), pos, vel, inv_mass)
        }
    }

    /// One frame of one sub-step, without gravity.
    fn solve(
        bodies: &mut [Body],
        pairs: &mut Vec<(u32, u32)>,
        params: ImpulseParams,
        cache: &mut ContactCache,
    ) -> ImpulseReport {
        solve_frame(bodies, pairs, params, 1, cache, &[0, 1], |_, _| {})
    }

    fn params() -> ImpulseParams {
        ImpulseParams {
            iterations: 8,
            warm_starting: true,
            baumgarte: 0.2,
            slop: 0.01,
            dt: 1.0 / 60.0,
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
            &mut ContactCache::default(),
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
            &mut ContactCache::default(),
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
            &mut ContactCache::default(),
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
            &mut ContactCache::default(),
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
            &mut ContactCache::default(),
        );
        assert_eq!(r.contacts, 1);
    }
}
