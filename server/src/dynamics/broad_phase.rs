//! Broad phase: which pairs of an interaction are worth an exact test.
//!
//! The chapter tests every pair of the two groups (`BroadPhase::AllPairs`), which costs
//! N x M per relaxation pass. `BroadPhase::Sweep` sorts the bodies' bounding boxes along x
//! once per step (sweep and prune), keeps the pairs whose boxes, grown by a margin,
//! overlap, and hands them to the solver in the order the all-pairs loop would have met
//! them, so both find the same contacts in the same order whenever the margin covers how
//! far bodies move while the solver runs. Pairs of two static bodies are never kept.

use serde::{Deserialize, Serialize};

use super::body::Body;
use crate::geometry::Aabb;

/// How an interaction finds its candidate pairs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BroadPhase {
    /// Every pair of the two groups, every pass (the chapter).
    AllPairs,
    /// Sweep and prune along x, once per step.
    #[default]
    Sweep,
}

impl BroadPhase {
    pub fn name(self) -> &'static str {
        match self {
            BroadPhase::AllPairs => "all_pairs",
            BroadPhase::Sweep => "sweep",
        }
    }
}

/// One box of the sweep: its x extent, y extent, and where it came from.
#[derive(Clone, Copy, Debug)]
struct Entry {
    min_x: f64,
    max_x: f64,
    min_y: f64,
    max_y: f64,
    /// Position in its group's member list.
    slot: u32,
    /// 0: group A, 1: group B.
    side: u8,
}

/// Reusable buffers of the sweep.
#[derive(Clone, Debug, Default)]
pub struct SweepBuffers {
    entries: Vec<Entry>,
    active: Vec<Entry>,
    /// Pairs as (slot in A, slot in B), before sorting.
    slots: Vec<(u32, u32)>,
}

/// The margin a body's box grows by: how far it may move while the solver runs (its speed
/// over one step) plus a tenth of its size.
fn margin(body: &Body, dt: f64) -> f64 {
    body.vel.length() * dt + 0.1 * body.shape.half_extents().max_element()
}

/// Candidate pairs `(index a, index b)` of bodies, a from `group_a` and b from `group_b`,
/// in all-pairs order (a's position in `group_a`, then b's in `group_b`). For a group
/// against itself (`same`), every ordered pair of distinct members is returned, as the
/// chapter tests them.
pub fn sweep_pairs(
    bodies: &[Body],
    group_a: &[u32],
    group_b: &[u32],
    same: bool,
    dt: f64,
    buffers: &mut SweepBuffers,
    out: &mut Vec<(u32, u32)>,
) {
    out.clear();
    let SweepBuffers {
        entries,
        active,
        slots,
    } = buffers;
    entries.clear();
    slots.clear();
    let mut push = |members: &[u32], side: u8| {
        for (slot, &i) in members.iter().enumerate() {
            let b = &bodies[i as usize];
            let m = margin(b, dt);
            let Aabb { min, max } = Aabb::of(&b.shape, b.pos);
            entries.push(Entry {
                min_x: min.x - m,
                max_x: max.x + m,
                min_y: min.y - m,
                max_y: max.y + m,
                slot: slot as u32,
                side,
            });
        }
    };
    push(group_a, 0);
    if !same {
        push(group_b, 1);
    }
    entries.sort_unstable_by(|p, q| {
        p.min_x
            .total_cmp(&q.min_x)
            .then(p.side.cmp(&q.side))
            .then(p.slot.cmp(&q.slot))
    });
    active.clear();
    for e in entries.iter() {
        active.retain(|a| a.max_x >= e.min_x);
        for a in active.iter() {
            if a.min_y > e.max_y || e.min_y > a.max_y {
                continue;
            }
            if same {
                slots.push((a.slot, e.slot));
                slots.push((e.slot, a.slot));
            } else if a.side != e.side {
                let (sa, sb) = if a.side == 0 {
                    (a.slot, e.slot)
                } else {
                    (e.slot, a.slot)
                };
                slots.push((sa, sb));
            }
        }
        active.push(*e);
    }
    slots.sort_unstable();
    let members_b = if same { group_a } else { group_b };
    out.extend(slots.iter().filter_map(|&(sa, sb)| {
        let (i, j) = (group_a[sa as usize], members_b[sb as usize]);
        let both_static = bodies[i as usize].is_static() && bodies[j as usize].is_static();
        (i != j && !both_static).then_some((i, j))
    }));
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::behavior::Behavior;
    use crate::dynamics::body::BodyKey;
    use crate::geometry::Shape;
    use glam::DVec2;
    use proptest::prelude::*;

    fn body(x: f64, y: f64, w: f64, h: f64, inv_mass: f64) -> Body {
        Body {
            pos: DVec2::new(x, y),
            vel: DVec2::ZERO,
            shape: Shape::rect(w, h),
            inv_mass,
            restitution: 0.8,
            friction: 0.3,
            collided: false,
            gravity: None,
            group: 0,
            key: BodyKey(0),
            behavior: Behavior::None,
            id: String::new(),
        }
    }

    /// The pairs the all-pairs loop would find colliding, in its order.
    fn colliding_all_pairs(bodies: &[Body], a: &[u32], b: &[u32]) -> Vec<(u32, u32)> {
        let mut out = Vec::new();
        for &i in a {
            for &j in b {
                let (p, q) = (&bodies[i as usize], &bodies[j as usize]);
                if i != j
                    && !(p.is_static() && q.is_static())
                    && crate::geometry::collide(&p.shape, p.pos, &q.shape, q.pos).is_some()
                {
                    out.push((i, j));
                }
            }
        }
        out
    }

    proptest! {
        /// Every colliding pair is a candidate, and candidates keep the all-pairs order.
        #[test]
        fn the_sweep_keeps_every_colliding_pair_in_all_pairs_order(
            boxes in proptest::collection::vec((0.0f64..50.0, 0.0f64..50.0, 0.5f64..8.0, 0.5f64..8.0, prop::bool::ANY), 2..40),
            split in 0usize..40,
        ) {
            let bodies: Vec<Body> = boxes.iter().map(|&(x, y, w, h, s)| body(x, y, w, h, if s { 0.0 } else { 1.0 })).collect();
            let n = bodies.len() as u32;
            let split = (split as u32).min(n);
            let (a, b): (Vec<u32>, Vec<u32>) = ((0..split).collect(), (split..n).collect());
            let mut buffers = SweepBuffers::default();
            let mut pairs = Vec::new();
            for (ga, gb, same) in [(&a, &b, false), (&a, &a, true), (&b, &b, true)] {
                sweep_pairs(&bodies, ga, gb, same, 1.0 / 60.0, &mut buffers, &mut pairs);
                let colliding = colliding_all_pairs(&bodies, ga, gb);
                let kept: Vec<(u32, u32)> = pairs.iter().copied().filter(|p| colliding.contains(p)).collect();
                prop_assert_eq!(&kept, &colliding);
                // Candidates are in all-pairs order.
                let order = |p: &(u32, u32)| (ga.iter().position(|&x| x == p.0).unwrap(), gb.iter().position(|&x| x == p.1).unwrap());
                prop_assert!(pairs.windows(2).all(|w| order(&w[0]) < order(&w[1])));
            }
        }
    }

    #[test]
    fn far_apart_and_static_pairs_are_dropped() {
        let bodies = vec![
            body(0.0, 0.0, 1.0, 1.0, 1.0),
            body(100.0, 0.0, 1.0, 1.0, 1.0),
            body(0.5, 0.0, 1.0, 1.0, 0.0),
            body(0.6, 0.0, 1.0, 1.0, 0.0),
        ];
        let mut pairs = Vec::new();
        sweep_pairs(
            &bodies,
            &[0, 1, 2, 3],
            &[0, 1, 2, 3],
            true,
            1.0 / 60.0,
            &mut SweepBuffers::default(),
            &mut pairs,
        );
        assert_eq!(pairs, vec![(0, 2), (0, 3), (2, 0), (3, 0)]);
    }
}
