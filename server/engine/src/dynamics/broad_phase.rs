//! Broad phase: which pairs of an interaction are worth an exact test.
//!
//! The chapter tests every pair of the two groups (`BroadPhase::AllPairs`), which costs
//! N x M per relaxation pass. `BroadPhase::Sweep` sorts the bodies' bounding boxes along x
//! once per step (sweep and prune), keeps the pairs whose boxes, grown by a margin,
//! overlap, and hands them to the solver in the order the all-pairs loop would have met
//! them, so both find the same contacts in the same order whenever the margin covers how
//! far bodies move while the solver runs. Pairs of two static bodies are never kept.

use crate::geometry::grid::Grid;
use serde::{Deserialize, Serialize};

use super::body::Body;
use crate::geometry::Aabb;

/// How an interaction finds its candidate pairs.
#[derive(
    Clone,
    Copy,
    Debug,
    Default,
    PartialEq,
    Eq,
    Serialize,
    Deserialize,
    strum::IntoStaticStr,
    schemars::JsonSchema,
)]
#[serde(rename_all = "snake_case")]
#[strum(serialize_all = "snake_case")]
pub enum BroadPhase {
    /// Every pair of the two groups, every pass (the chapter).
    AllPairs,
    /// Sweep and prune along x, once per step.
    #[default]
    Sweep,
    /// Fattened boxes whose pairs are kept between steps and looked at again only for
    /// bodies that left their fat box ([`super::pairs`]): small boxes in a uniform grid,
    /// large or fast ones in a dynamic tree.
    Grid,
}

impl BroadPhase {
    /// The name scenes and settings use (as serde spells it).
    pub fn name(self) -> &'static str {
        self.into()
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
    use crate::geometry::Shape;
    use glam::DVec2;
    use proptest::prelude::*;

    fn body(x: f64, y: f64, w: f64, h: f64, inv_mass: f64) -> Body {
        Body::for_test(Shape::rect(w, h), DVec2::new(x, y), DVec2::ZERO, inv_mass)
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

    proptest! {
        /// The static grid finds the same candidate pairs, in the same order, as the sweep
        /// (up to pairs the sweep keeps whose boxes only touch through its margins).
        #[test]
        fn the_static_grid_keeps_every_colliding_pair_in_all_pairs_order(
            statics in proptest::collection::vec((0.0f64..200.0, 0.0f64..100.0, 0.5f64..30.0, 0.5f64..5.0), 33..120),
            movers in proptest::collection::vec((0.0f64..200.0, 0.0f64..100.0, 0.5f64..20.0, 0.5f64..20.0), 1..10),
            static_first in prop::bool::ANY,
        ) {
            let mut bodies: Vec<Body> = statics.iter().map(|&(x, y, w, h)| body(x, y, w, h, 0.0)).collect();
            bodies.extend(movers.iter().map(|&(x, y, w, h)| body(x, y, w, h, 1.0)));
            let s: Vec<u32> = (0..statics.len() as u32).collect();
            let m: Vec<u32> = (statics.len() as u32..bodies.len() as u32).collect();
            let grid = StaticGrid::build(&bodies, &s, 0);
            let mut pairs = Vec::new();
            let (ga, gb) = if static_first { (&s, &m) } else { (&m, &s) };
            grid_pairs(&bodies, &m, &s, &grid, static_first, 1.0 / 60.0, &mut pairs);
            let colliding = colliding_all_pairs(&bodies, ga, gb);
            let kept: Vec<(u32, u32)> = pairs.iter().copied().filter(|p| colliding.contains(p)).collect();
            prop_assert_eq!(&kept, &colliding);
            let order = |p: &(u32, u32)| (ga.iter().position(|&x| x == p.0).unwrap(), gb.iter().position(|&x| x == p.1).unwrap());
            prop_assert!(pairs.windows(2).all(|w| order(&w[0]) < order(&w[1])));
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

/// A uniform grid over a group whose members are all static, built once and kept until
/// bodies are added, removed or moved by hand: an interaction between a few moving bodies
/// and many static ones costs what the moving bodies' neighbourhoods cost, not the size
/// of the static group.
#[derive(Clone, Debug)]
pub struct StaticGrid {
    /// Slots are positions in the group's member list.
    grid: Grid,
    /// The world's layout revision the grid was built for.
    pub revision: u64,
}

/// Groups with more members than this get a static grid when all are static.
pub const STATIC_GRID_MIN_MEMBERS: usize = 32;
const MAX_CELLS_PER_MEMBER: i64 = 64;

impl StaticGrid {
    /// A grid of `members` (slots are positions in `members`); cells twice the mean half
    /// extent of the members.
    pub fn build(bodies: &[Body], members: &[u32], revision: u64) -> Self {
        let mean_half = members
            .iter()
            .map(|&i| bodies[i as usize].shape.half_extents().max_element())
            .sum::<f64>()
            / members.len().max(1) as f64;
        let mut grid = Grid::new(2.0 * mean_half, MAX_CELLS_PER_MEMBER);
        for (slot, &i) in members.iter().enumerate() {
            let b = &bodies[i as usize];
            let Aabb { min, max } = Aabb::of(&b.shape, b.pos);
            grid.insert(slot as u32, min, max);
        }
        StaticGrid { grid, revision }
    }

    /// Slots of the members whose cells the box touches, in increasing order.
    fn query(&self, min: glam::DVec2, max: glam::DVec2, out: &mut Vec<u32>) {
        self.grid.query(min, max, out);
    }
}

/// Candidate pairs of a moving group against a static group held in `grid`, in all-pairs
/// order. `static_first` says whether the static group is the interaction's first side.
pub fn grid_pairs(
    bodies: &[Body],
    moving: &[u32],
    statics: &[u32],
    grid: &StaticGrid,
    static_first: bool,
    dt: f64,
    out: &mut Vec<(u32, u32)>,
) {
    out.clear();
    let mut slots = Vec::new();
    let mut pairs: Vec<(u32, u32)> = Vec::new();
    for (ms, &i) in moving.iter().enumerate() {
        let b = &bodies[i as usize];
        if b.is_static() {
            continue;
        }
        let m = margin(b, dt);
        let Aabb { min, max } = Aabb::of(&b.shape, b.pos);
        slots.clear();
        grid.query(min - m, max + m, &mut slots);
        for &ss in &slots {
            let j = statics[ss as usize];
            let o = &bodies[j as usize];
            let Aabb {
                min: omin,
                max: omax,
            } = Aabb::of(&o.shape, o.pos);
            if omin.x > max.x + m
                || min.x - m > omax.x
                || omin.y > max.y + m
                || min.y - m > omax.y
                || i == j
            {
                continue;
            }
            pairs.push(if static_first {
                (ss, ms as u32)
            } else {
                (ms as u32, ss)
            });
        }
    }
    pairs.sort_unstable();
    let (first, second) = if static_first {
        (statics, moving)
    } else {
        (moving, statics)
    };
    out.extend(
        pairs
            .iter()
            .map(|&(p, q)| (first[p as usize], second[q as usize])),
    );
}
