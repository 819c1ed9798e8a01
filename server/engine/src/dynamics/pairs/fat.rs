//! A body's fat box, standing or moving with its body (see the parent module's notes).
//!
//! A box *standing* in the set's frame holds its body for as long as the body stays in
//! it: the body's bounding box swept along a few steps of its travel and grown by a
//! margin. A box *moving* with its body is the body's bounding box grown by the margin
//! alone, carried at the body's velocity (in the frame) from the time it was placed
//! (`since`) until it expires (`until`): it holds a body that flies straight, not one
//! that stops or turns. Two moving boxes are a pair only if they overlap at one time
//! within both their lives, not merely somewhere along their two sweeps: bodies flying
//! apart side by side or away from each other (a block struck apart) sweep over each
//! other's paths but never meet. The index (`Tiered`) keeps each box's hull over its
//! life, and a query's finds are then tested in time too.

use glam::DVec2;

use crate::geometry::Aabb;

#[derive(Clone, Copy, Debug, serde::Serialize, serde::Deserialize)]
pub(super) struct Fat {
    /// The box swept over its whole life (a standing box: the box): what the index holds.
    pub min: DVec2,
    pub max: DVec2,
    /// Whether the body is in the index (in a resolving interaction).
    pub placed: bool,
    /// The box's velocity in the set's frame (zero: it stands).
    #[serde(default)]
    pub vel: DVec2,
    /// The set's time when the box was placed.
    #[serde(default)]
    pub since: f64,
    /// The set's time the box must be left by (`f64::MAX` for a standing box).
    #[serde(default = "forever")]
    pub until: f64,
}

/// The `until` of a standing box (finite: every format writes it).
fn forever() -> f64 {
    f64::MAX
}

impl Fat {
    /// A box standing at `min..max`.
    pub fn standing(min: DVec2, max: DVec2) -> Fat {
        Fat {
            min,
            max,
            placed: true,
            vel: DVec2::ZERO,
            since: 0.0,
            until: forever(),
        }
    }

    /// A box `min..max` when placed at the set's time `since`, moving at `vel` until
    /// `until`.
    pub fn moving(min: DVec2, max: DVec2, vel: DVec2, since: f64, until: f64) -> Fat {
        let d = vel * (until - since);
        Fat {
            min: min + d.min(DVec2::ZERO),
            max: max + d.max(DVec2::ZERO),
            placed: true,
            vel,
            since,
            until,
        }
    }

    /// Whether the box moves.
    #[inline]
    pub fn moves(&self) -> bool {
        self.vel != DVec2::ZERO
    }

    /// The box swept over its whole life: what the index holds.
    #[inline]
    pub fn hull(&self) -> Aabb {
        Aabb {
            min: self.min,
            max: self.max,
        }
    }

    /// The box at the set's time `t`.
    pub fn at(&self, t: f64) -> Aabb {
        let d = self.vel * (self.until - self.since);
        let e = self.vel * (t - self.since);
        Aabb {
            min: self.min - d.min(DVec2::ZERO) + e,
            max: self.max - d.max(DVec2::ZERO) + e,
        }
    }

    /// Whether a body whose box is `min..max` at time `now` and moves by `step` over the
    /// next `dt`, grown every way by `reach`, stays inside this moving box over that step,
    /// before the box expires. Both move straight over the step, so its ends decide.
    pub fn holds(
        &self,
        min: DVec2,
        max: DVec2,
        step: DVec2,
        reach: f64,
        now: f64,
        dt: f64,
    ) -> bool {
        now + dt <= self.until
            && encloses(self.at(now), min, max, reach)
            && encloses(self.at(now + dt), min + step, max + step, reach)
    }
}

/// Whether the box `f` holds the box `min..max` grown every way by `reach`.
#[inline]
pub(super) fn encloses(f: Aabb, min: DVec2, max: DVec2, reach: f64) -> bool {
    min.x - reach >= f.min.x
        && min.y - reach >= f.min.y
        && max.x + reach <= f.max.x
        && max.y + reach <= f.max.y
}

/// Whether two fat boxes meet: their hulls overlap, and, where one moves, the two boxes
/// overlap at one time within both their lives.
#[inline]
pub(super) fn meet(p: &Fat, q: &Fat) -> bool {
    cross(p, q) && meet_crossing(p, q)
}

/// Whether two fat boxes whose hulls overlap meet ([`meet`]).
#[inline]
pub(super) fn meet_crossing(p: &Fat, q: &Fat) -> bool {
    !(p.moves() || q.moves()) || meet_in_time(p, q)
}

/// Whether two fat boxes' hulls overlap (what the index finds, before any test in time).
#[inline]
pub(super) fn cross(p: &Fat, q: &Fat) -> bool {
    p.min.x <= q.max.x && q.min.x <= p.max.x && p.min.y <= q.max.y && q.min.y <= p.max.y
}

/// Whether two boxes, one moving at least, overlap at one time within both their lives.
#[inline(never)]
fn meet_in_time(p: &Fat, q: &Fat) -> bool {
    let (from, to) = (p.since.max(q.since), p.until.min(q.until));
    if from > to || from.is_nan() || to.is_nan() {
        // Lives that do not meet (a box its body should have left): kept, as the hulls.
        return true;
    }
    let (a, b) = (p.at(from), q.at(from));
    // Over `s` in 0..=to-from, `b` moves by `w s` against `a`: they overlap on an axis
    // while `b.min + w s <= a.max` and `a.min <= b.max + w s`.
    let w = q.vel - p.vel;
    let (mut lo, mut hi) = (0.0f64, to - from);
    for k in 0..2 {
        let (ahead, behind) = (a.max[k] - b.min[k], a.min[k] - b.max[k]);
        let wk = w[k];
        if wk > 0.0 {
            hi = hi.min(ahead / wk);
            lo = lo.max(behind / wk);
        } else if wk < 0.0 {
            lo = lo.max(ahead / wk);
            hi = hi.min(behind / wk);
        } else if ahead < 0.0 || behind > 0.0 {
            return false;
        }
    }
    lo <= hi
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn overlap(p: &Aabb, q: &Aabb) -> bool {
        p.min.x <= q.max.x && q.min.x <= p.max.x && p.min.y <= q.max.y && q.min.y <= p.max.y
    }

    fn moving(x: f64, y: f64, half: f64, vel: DVec2, since: f64, until: f64) -> Fat {
        let h = DVec2::splat(half);
        Fat::moving(
            DVec2::new(x, y) - h,
            DVec2::new(x, y) + h,
            vel,
            since,
            until,
        )
    }

    #[test]
    fn bodies_flying_apart_side_by_side_do_not_meet_though_their_sweeps_overlap() {
        // Side by side, 0.8 apart, flying alike: their hulls overlap.
        let p = moving(0.0, 0.0, 0.3, DVec2::new(10.0, 1.0), 0.0, 1.0);
        let q = moving(0.0, 0.8, 0.3, DVec2::new(10.0, 1.0), 0.0, 1.0);
        assert!(overlap(&p.hull(), &q.hull()));
        assert!(!meet(&p, &q));
        // Heading into each other, they do.
        let r = moving(5.0, 0.0, 0.3, DVec2::new(-10.0, 0.0), 0.0, 1.0);
        assert!(meet(&p, &r) && meet(&r, &p));
        // A standing box on the path of a moving one meets it; one off its path does not.
        let s = Fat::standing(DVec2::new(4.0, -0.1), DVec2::new(4.2, 0.1));
        let t = Fat::standing(DVec2::new(4.0, 2.0), DVec2::new(4.2, 2.2));
        assert!(meet(&p, &s) && !meet(&p, &t));
        // Paths that cross, crossed at different times.
        let late = moving(0.0, 0.0, 0.3, DVec2::new(10.0, 0.0), 0.0, 1.0);
        let gone = moving(2.0, 0.0, 0.3, DVec2::new(0.0, 10.0), 0.0, 1.0);
        assert!(!meet(&late, &gone), "gone when the first gets there");
    }

    proptest! {
        /// Two boxes that overlap at a time sampled within both lives meet.
        #[test]
        fn boxes_overlapping_at_a_shared_time_meet(
            a in (-5.0f64..5.0, -5.0f64..5.0, 0.01f64..2.0, -20.0f64..20.0, -20.0f64..20.0, 0.0f64..1.0, 0.0f64..1.0),
            b in (-5.0f64..5.0, -5.0f64..5.0, 0.01f64..2.0, -20.0f64..20.0, -20.0f64..20.0, 0.0f64..1.0, 0.0f64..1.0),
            stand in 0u8..3,
            share in 0.0f64..=1.0,
        ) {
            let make = |(x, y, h, vx, vy, t0, life): (f64, f64, f64, f64, f64, f64, f64), still: bool| {
                if still {
                    Fat::standing(DVec2::new(x - h, y - h), DVec2::new(x + h, y + h))
                } else {
                    moving(x, y, h, DVec2::new(vx, vy), t0, t0 + life)
                }
            };
            let (p, q) = (make(a, stand == 1), make(b, stand == 2));
            let (from, to) = (p.since.max(q.since), p.until.min(q.until));
            prop_assume!(from <= to && to.is_finite());
            let t = from + share * (to - from);
            if overlap(&p.at(t), &q.at(t)) {
                prop_assert!(meet(&p, &q) && meet(&q, &p));
            }
        }
    }
}
