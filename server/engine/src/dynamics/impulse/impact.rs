//! Impact propagation (`impact_propagation`): a heavy body's push carried down a file of
//! light bodies at once, without gravity.
//!
//! A heavy body driven into light ones (a circle of mass 250 at 18 u/s into a block of
//! boxes of mass 0.25) must move the whole file of boxes ahead of it at once. Sequential
//! impulses carry its push down such a file one contact a pass, halving it at each: after
//! a sub-step's passes the box it touches moves at its speed, the next at two thirds of
//! it, the one after at a half, and so on down the file. Each box then runs into the next
//! a twentieth of a box a step, until the two lie one on the other; axis-aligned boxes
//! that coincide have no side to be pushed out of, and stay so. Sub-steps and passes
//! shorten the file that lags but do not end it (the impacts family fails 1 seed in 10 to
//! 20 either way).
//!
//! After the passes, the bodies reached from a heavy body (at least [`HEAVY_RATIO`] times
//! a body it touches, and pulled by no force) through contacts still approaching (the
//! outer body running into the inner one, or closing a gap faster than the sub-step
//! allows) move on as one: each takes the cluster's speed along the cluster's momentum,
//! as a perfectly plastic blow between them would leave them, and keeps its motion across
//! it. Momentum is kept, and the merge makes no kinetic energy (it takes out the spread
//! of speeds along the momentum). A pair that bounced (the collision
//! stage parts it first) or slides past another (its contact does not approach) is not
//! joined. Under gravity the support sweep holds piles (`support.rs`), and this sweep
//! starts from no body gravity pulls.

use glam::DVec2;

use super::{Contact, SolverBody};

/// A body starts a cluster when it is at least this many times heavier than a body it
/// touches. At 10, circles a body of 10 to 30 times their mass drove into a crowd of
/// circles were made to move as one where they should have scattered: the impacts family
/// gained 1% of its kinetic energy back on 4 seeds of 400, and held fewer than at 100.
pub(super) const HEAVY_RATIO: f64 = 10.0;

const NONE: u32 = u32::MAX;

/// One contact as the sweep reads it.
#[derive(Clone, Copy, Debug)]
struct Edge {
    a: u32,
    b: u32,
    normal: DVec2,
    /// Separation now, if the contact was found apart (speculative): the bodies may
    /// close it within the sub-step.
    apart: f64,
    /// The passes left it pushing its bodies apart.
    pressed: bool,
}

impl Edge {
    /// Whether the outer body `v` runs into the inner one `u` (faster than closing a
    /// gap within the sub-step `h`).
    fn approaches(&self, u: u32, sb: &[SolverBody], h: f64) -> bool {
        let v = if self.a == u { self.b } else { self.a };
        let normal = if self.a == u {
            self.normal
        } else {
            -self.normal
        };
        let vn = (sb[v as usize].vel - sb[u as usize].vel).dot(normal);
        vn < -self.apart.max(0.0) / h
    }
}

/// The sweep's buffers, kept from sub-step to sub-step.
#[derive(Clone, Debug, Default)]
pub(super) struct Sweep {
    edges: Vec<Edge>,
    /// Per solver body: where its contacts start in `links` (then one past the end).
    start: Vec<u32>,
    /// Each contact twice, once from each body: (contact, other body).
    links: Vec<(u32, u32)>,
    /// Per solver body: the heavy body whose cluster it joined (NONE: none).
    root: Vec<u32>,
    /// The bodies in the order they joined.
    order: Vec<u32>,
    /// Per heavy body: its cluster's mass and momentum.
    mass: Vec<f64>,
    momentum: Vec<DVec2>,
}

/// The heavy body of contact `c` when it starts a cluster: at least [`HEAVY_RATIO`] times
/// the other, pulled by nothing (`gain`).
fn heavy_of(c: &Contact, sb: &[SolverBody], gain: &[DVec2]) -> Option<u32> {
    let (ia, ib) = (sb[c.a as usize].inv_mass, sb[c.b as usize].inv_mass);
    let heavy = if ia > 0.0 && ib >= HEAVY_RATIO * ia {
        c.a
    } else if ib > 0.0 && ia >= HEAVY_RATIO * ib {
        c.b
    } else {
        return None;
    };
    gain.get(heavy as usize)
        .is_some_and(|g| *g == DVec2::ZERO)
        .then_some(heavy)
}

impl Sweep {
    /// Runs the sweep over `buckets` after a sub-step's passes. `gain` is what each mover
    /// gains per second; `h` the sub-step.
    pub(super) fn sweep(
        &mut self,
        sb: &mut [SolverBody],
        buckets: &[Vec<Contact>],
        gain: &[DVec2],
        h: f64,
    ) {
        // Only a body nothing pulls starts a cluster: where gravity pulls every body (a
        // pile, a rain), one look at their gains, not at every contact.
        if gain.iter().all(|g| *g != DVec2::ZERO) {
            return;
        }
        // The heavy bodies that start clusters, in the order of the contacts (so the bits
        // depend on nothing else). Most sub-steps have none: one look at each contact,
        // and the per-body marks are laid out only once one is found.
        let n = sb.len();
        self.order.clear();
        for c in buckets.iter().flatten() {
            let Some(heavy) = heavy_of(c, sb, gain) else {
                continue;
            };
            if self.order.is_empty() {
                self.root.clear();
                self.root.resize(n, NONE);
            }
            if self.root[heavy as usize] == NONE {
                self.root[heavy as usize] = heavy;
                self.order.push(heavy);
            }
        }
        if self.order.is_empty() {
            return;
        }
        // Most sub-steps after a blow, no heavy body presses or runs into any body: the
        // clusters are the heavy bodies alone, and the contacts are not laid out by body
        // (on a struck block of boxes, 19 sub-steps of 20).
        let edge = |c: &Contact| {
            let (ba, bb) = (&sb[c.a as usize], &sb[c.b as usize]);
            let apart = if c.speculative {
                c.gap + (bb.delta - ba.delta).dot(c.normal)
            } else {
                0.0
            };
            Edge {
                a: c.a,
                b: c.b,
                normal: c.normal,
                apart,
                pressed: c.normal_impulse > 0.0,
            }
        };
        let root = &self.root;
        let joined = buckets.iter().flatten().any(|c| {
            (root[c.a as usize] != NONE || root[c.b as usize] != NONE) && {
                let e = edge(c);
                e.pressed || e.approaches(c.a, sb, h)
            }
        });
        if joined {
            self.join(sb, buckets, edge, h);
        }
        self.merge_clusters(sb);
    }

    /// The clusters, breadth first from the heavy bodies in `order`, through the contacts
    /// that may join one (`edge` reads a contact as the sweep does).
    fn join(
        &mut self,
        sb: &[SolverBody],
        buckets: &[Vec<Contact>],
        edge: impl Fn(&Contact) -> Edge,
        h: f64,
    ) {
        let n = sb.len();
        // The contacts that may join a cluster, by body: those still approaching
        // (whichever body the cluster reaches first: the test is the same from either
        // side), and those a heavy body presses. A crowd at rest adds none.
        self.edges.clear();
        self.start.clear();
        self.start.resize(n + 1, 0);
        for c in buckets.iter().flatten() {
            let edge = edge(c);
            let by_root = edge.pressed
                && (self.root[c.a as usize] != NONE || self.root[c.b as usize] != NONE);
            if !by_root && !edge.approaches(c.a, sb, h) {
                continue;
            }
            self.edges.push(edge);
            self.start[c.a as usize] += 1;
            self.start[c.b as usize] += 1;
        }
        let mut total = 0;
        for s in self.start.iter_mut() {
            let k = *s;
            *s = total;
            total += k;
        }
        self.links.clear();
        self.links.resize(total as usize, (0, 0));
        for (k, e) in self.edges.iter().enumerate() {
            for (from, to) in [(e.a, e.b), (e.b, e.a)] {
                let at = &mut self.start[from as usize];
                self.links[*at as usize] = (k as u32, to);
                *at += 1;
            }
        }
        // `start` now holds where each body's contacts end: shifted back by one body.
        self.start.rotate_right(1);
        self.start[0] = 0;
        // The clusters, breadth first from the heavy bodies.
        let mut next = 0;
        while next < self.order.len() {
            let u = self.order[next];
            next += 1;
            let root = self.root[u as usize];
            let (from, to) = (self.start[u as usize], self.start[u as usize + 1]);
            for l in from..to {
                let (e, v) = self.links[l as usize];
                // The bodies the heavy body pushes join, then those that run into them.
                let e = &self.edges[e as usize];
                let joins = if u == root {
                    e.pressed || e.approaches(u, sb, h)
                } else {
                    e.approaches(u, sb, h)
                };
                if sb[v as usize].inv_mass == 0.0 || self.root[v as usize] != NONE || !joins {
                    continue;
                }
                self.root[v as usize] = root;
                self.order.push(v);
            }
        }
    }

    /// Each cluster moves on as one along its momentum.
    fn merge_clusters(&mut self, sb: &mut [SolverBody]) {
        let n = sb.len();
        self.mass.clear();
        self.mass.resize(n, 0.0);
        self.momentum.clear();
        self.momentum.resize(n, DVec2::ZERO);
        for &u in &self.order {
            let r = self.root[u as usize] as usize;
            let m = 1.0 / sb[u as usize].inv_mass;
            self.mass[r] += m;
            self.momentum[r] += sb[u as usize].vel * m;
        }
        for &u in &self.order {
            let r = self.root[u as usize] as usize;
            let (mass, p) = (self.mass[r], self.momentum[r]);
            // A heavy body nothing joined keeps its velocity to the bit.
            if mass * sb[r].inv_mass == 1.0 {
                continue;
            }
            let Some(along) = p.try_normalize() else {
                continue;
            };
            let b = &mut sb[u as usize];
            b.vel += along * (p.length() / mass - b.vel.dot(along));
        }
    }
}
