//! The persistent broad phase (`broad_phase = "grid"`): candidate pairs kept from step to
//! step.
//!
//! Every body of a group that a resolving interaction names gets a *fat box*: its bounding
//! box grown by a margin. Fat boxes live in an index of two tiers ([`Tiered`]): a uniform
//! grid for those that cover a few of its cells, a dynamic tree for the others (a large
//! body among small ones, a small one thrown fast), where a body costs what it overlaps,
//! not the area it covers. The candidate pairs are the pairs of eligible bodies whose fat
//! boxes overlap. A step looks only at the bodies that move: one whose box (grown by how
//! far it may travel this step) still fits in its fat box changes nothing; one that left
//! it gets a new fat box, is moved in the index and looks for new neighbours there. A
//! resting pile of thousands of bodies costs one containment test per body; static
//! bodies cost nothing at all until the layout changes (bodies added, removed or moved by
//! hand, interactions declared), which rebuilds the set.
//!
//! Pairs are kept sorted by body index (`a < b`), so the order, and with it every result,
//! is deterministic: the pairs are exactly the eligible pairs whose fat boxes overlap,
//! whatever a body's tier or the tree's shape. They live in [`Contacts`], the one home of
//! the solver's pairs and their warm starts whatever the broad phase: the pair set keeps
//! them up to date in place, the other broad phases refill them each step
//! ([`Contacts::refill`]).

use glam::DVec2;

use super::body::{Body, GroupId};
use super::impulse::KeyMap;
use crate::geometry::tiered::Tiered;
use crate::geometry::Aabb;

/// A candidate pair of bodies (indices, `a < b`) with the impulses of its last contact.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Pair {
    pub a: u32,
    pub b: u32,
    /// The normal of the last contact (from `a` to `b`).
    pub normal: DVec2,
    pub normal_impulse: f64,
    pub tangent_impulse: f64,
}

impl Pair {
    pub fn new(a: u32, b: u32) -> Pair {
        Pair {
            a,
            b,
            normal: DVec2::ZERO,
            normal_impulse: 0.0,
            tangent_impulse: 0.0,
        }
    }
}

/// The candidate pairs the solver works through, each carrying the impulses the solver
/// left on it last step (warm starting without a lookup): kept from step to step
/// whichever broad phase found them, sorted by `(a, b)`, renumbered when bodies are
/// removed.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct Contacts {
    pub pairs: Vec<Pair>,
}

impl Contacts {
    /// Replaces the pairs by `candidates` (either way round, repeats allowed: each pair
    /// counts once); a pair kept from last step keeps its impulses if it had any.
    /// `kept` is scratch space.
    pub fn refill(&mut self, candidates: &mut Vec<(u32, u32)>, kept: &mut Vec<Pair>) {
        for p in candidates.iter_mut() {
            if p.0 > p.1 {
                *p = (p.1, p.0);
            }
        }
        candidates.sort_unstable();
        candidates.dedup();
        std::mem::swap(&mut self.pairs, kept);
        self.pairs.clear();
        // Both lists are sorted: one walk matches them.
        let mut last = kept.iter().peekable();
        self.pairs.extend(candidates.iter().map(|&(a, b)| {
            let mut p = Pair::new(a, b);
            while last.next_if(|o| (o.a, o.b) < (a, b)).is_some() {}
            if let Some(o) = last.next_if(|o| (o.a, o.b) == (a, b)) {
                if o.normal_impulse != 0.0 || o.tangent_impulse != 0.0 {
                    p.normal = o.normal;
                    p.normal_impulse = o.normal_impulse;
                    p.tangent_impulse = o.tangent_impulse;
                }
            }
            p
        }));
    }

    /// Drops the pairs of the bodies `removed` marks and renumbers the others as the
    /// bodies left close up (in order).
    pub fn remove_bodies(&mut self, removed: &[bool]) {
        let mut index = Vec::with_capacity(removed.len());
        let mut next = 0u32;
        for &r in removed {
            index.push(next);
            next += u32::from(!r);
        }
        self.pairs
            .retain(|p| !removed[p.a as usize] && !removed[p.b as usize]);
        for p in &mut self.pairs {
            p.a = index[p.a as usize];
            p.b = index[p.b as usize];
        }
    }
}

#[derive(Clone, Copy, Debug, serde::Serialize, serde::Deserialize)]
struct Fat {
    min: DVec2,
    max: DVec2,
    /// Whether the body is in the index (in a resolving interaction).
    placed: bool,
}

/// The index of fat boxes that keeps the candidate pairs of every resolving interaction (in
/// [`Contacts`]) from step to step.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct PairSet {
    /// The world layout revision the set was built for.
    revision: Option<u64>,
    fat: Vec<Fat>,
    /// The side of the grid's cells (twice the typical moving body).
    cell: f64,
    /// The fat boxes of the placed bodies: a grid of cells of side `cell` for those that
    /// cover a few of them, a tree for the others. Not saved: a restored set builds it
    /// again from `fat` (what a query finds does not depend on the tree's shape).
    #[serde(skip)]
    index: Tiered,
    /// Which group pairs resolve (row-major, `groups x groups`).
    resolves: Vec<bool>,
    groups: usize,
    moved: Vec<u32>,
    /// New pairs found by a search, as `a << 32 | b` (sorted, they are in pair order).
    found: Vec<u64>,
    merged: Vec<Pair>,
    /// The bodies whose neighbours this round searches: a pair of two of them is taken
    /// from the smaller's search only.
    searching: Vec<bool>,
    /// Bodies re-inserted over the set's life (a figure for tests and benchmarks).
    pub reinserted: u64,
}

/// How far a body may travel during a step of `dt` plus a tenth of its size: its box
/// grown by this must stay inside its fat box.
fn reach(body: &Body, dt: f64) -> f64 {
    body.vel.length() * dt + 0.1 * body.shape.half_extents().max_element()
}

/// A body that is static for good (a sleeper is only frozen for the step).
fn fixed(body: &Body) -> bool {
    body.is_static() && body.asleep.is_none()
}

/// Whether bodies `i` and `j` make a candidate pair: two bodies, not both static for
/// good, of groups that resolve (`resolves`, row-major, `groups x groups`).
fn eligible(resolves: &[bool], groups: usize, bodies: &[Body], i: u32, j: u32) -> bool {
    let (p, q) = (&bodies[i as usize], &bodies[j as usize]);
    i != j && !(fixed(p) && fixed(q)) && resolves[p.group as usize * groups + q.group as usize]
}

fn overlap(p: &Fat, q: &Fat) -> bool {
    p.min.x <= q.max.x && q.min.x <= p.max.x && p.min.y <= q.max.y && q.min.y <= p.max.y
}

impl PairSet {
    /// Brings the pairs in `contacts` up to date for a step of `dt`. `revision` is the
    /// world's layout revision (a new one rebuilds everything), `resolving` the group
    /// pairs of the resolving interactions, `movers` the bodies that may have moved since
    /// last time.
    pub fn update(
        &mut self,
        contacts: &mut Contacts,
        bodies: &[Body],
        revision: u64,
        resolving: &[(GroupId, GroupId)],
        movers: &[u32],
        dt: f64,
    ) {
        let pairs = &mut contacts.pairs;
        if self.revision != Some(revision) || self.fat.len() != bodies.len() {
            self.rebuild(pairs, bodies, revision, resolving, dt);
            return;
        }
        if self.index.capacity() != self.fat.len() {
            self.reindex();
        }
        self.moved.clear();
        for &i in movers {
            let body = &bodies[i as usize];
            let f = self.fat[i as usize];
            if !f.placed {
                continue;
            }
            let r = reach(body, dt);
            let Aabb { min, max } = Aabb::of(&body.shape, body.pos);
            if min.x - r >= f.min.x
                && min.y - r >= f.min.y
                && max.x + r <= f.max.x
                && max.y + r <= f.max.y
            {
                continue;
            }
            self.index.remove(i, f.min, f.max);
            self.place(bodies, i, dt);
            let Fat { min, max, .. } = self.fat[i as usize];
            self.index.insert(i, min, max);
            self.moved.push(i);
        }
        if self.moved.is_empty() {
            return;
        }
        self.index.flush();
        self.reinserted += self.moved.len() as u64;
        let fat = &self.fat;
        pairs.retain(|p| overlap(&fat[p.a as usize], &fat[p.b as usize]));
        self.found.clear();
        let moved = std::mem::take(&mut self.moved);
        self.searching.clear();
        self.searching.resize(bodies.len(), false);
        for &i in &moved {
            self.searching[i as usize] = true;
        }
        for &i in &moved {
            self.neighbours(bodies, i);
        }
        self.moved = moved;
        self.merge_found(pairs);
    }

    /// Checks a set read back from a checkpoint against the world's `bodies` and its
    /// `groups`: every index in range, every box of a placed body finite. A set the next update rebuilds anyway (another revision, another body
    /// count) is not read and passes. Names the field that is wrong.
    pub fn check(&self, bodies: &[Body], groups: usize) -> Result<(), (String, String)> {
        let bad = |field: &str, reason: String| Err((format!("pair_set.{field}"), reason));
        let n = bodies.len();
        if self.revision.is_none() || self.fat.len() != n {
            return Ok(());
        }
        if self.groups > groups || self.resolves.len() != self.groups * self.groups {
            return bad(
                "resolves",
                format!(
                    "{} entries for {} groups (the world has {groups})",
                    self.resolves.len(),
                    self.groups
                ),
            );
        }
        if !(self.cell.is_finite() && self.cell >= 1e-9) {
            return bad(
                "cell",
                format!("{} is not a finite size of at least 1e-9", self.cell),
            );
        }
        for (i, f) in self.fat.iter().enumerate() {
            if !f.placed {
                continue;
            }
            if !(f.min.is_finite() && f.max.is_finite() && f.min.cmple(f.max).all()) {
                return bad(
                    &format!("fat[{i}]"),
                    "a box not finite or upside down".into(),
                );
            }
            if bodies[i].group as usize >= self.groups {
                return bad(
                    &format!("fat[{i}]"),
                    format!(
                        "body {i} of group {} is in a set of {} groups",
                        bodies[i].group, self.groups
                    ),
                );
            }
        }
        Ok(())
    }

    /// The first body in the index (for tests).
    #[cfg(test)]
    pub(crate) fn first_placed(&self) -> Option<usize> {
        self.fat.iter().position(|f| f.placed)
    }

    /// Builds the index again from the fat boxes (after a rebuild, or in a set restored
    /// from a checkpoint).
    fn reindex(&mut self) {
        self.index.reset(self.cell, self.fat.len());
        for (i, f) in self.fat.iter().enumerate() {
            if f.placed {
                self.index.insert(i as u32, f.min, f.max);
            }
        }
        self.index.flush();
    }

    /// Makes the next update rebuild the set: `Contacts` were filled by another broad
    /// phase.
    pub fn forget(&mut self) {
        self.revision = None;
    }

    fn rebuild(
        &mut self,
        pairs: &mut Vec<Pair>,
        bodies: &[Body],
        revision: u64,
        resolving: &[(GroupId, GroupId)],
        dt: f64,
    ) {
        // Warm-starting impulses survive a rebuild, found again by the bodies' keys.
        let old: KeyMap<(u32, u32), Pair> = pairs
            .iter()
            .filter(|p| p.normal_impulse != 0.0 || p.tangent_impulse != 0.0)
            .map(|p| {
                let (ka, kb) = (bodies[p.a as usize].key.0, bodies[p.b as usize].key.0);
                ((ka.min(kb), ka.max(kb)), *p)
            })
            .collect();
        self.revision = Some(revision);
        self.groups = resolving
            .iter()
            .map(|&(a, b)| a.max(b) as usize + 1)
            .max()
            .unwrap_or(0);
        self.resolves = vec![false; self.groups * self.groups];
        for &(a, b) in resolving {
            let (a, b) = (a as usize, b as usize);
            self.resolves[a * self.groups + b] = true;
            self.resolves[b * self.groups + a] = true;
        }
        let in_play = |b: &Body| {
            let g = b.group as usize;
            g < self.groups && (0..self.groups).any(|h| self.resolves[g * self.groups + h])
        };
        // Cells about twice the typical moving body (static ones may be huge floors).
        let mean_half = |keep: &dyn Fn(&Body) -> bool| {
            let halves: Vec<f64> = bodies
                .iter()
                .filter(|b| in_play(b) && keep(b))
                .map(|b| b.shape.half_extents().max_element())
                .collect();
            (!halves.is_empty()).then(|| halves.iter().sum::<f64>() / halves.len() as f64)
        };
        self.cell = mean_half(&|b| !fixed(b))
            .or_else(|| mean_half(&|_| true))
            .map_or(1.0, |h| (4.0 * h).max(1e-9));
        let play: Vec<bool> = bodies.iter().map(in_play).collect();
        self.fat.clear();
        self.fat.resize(
            bodies.len(),
            Fat {
                min: DVec2::ZERO,
                max: DVec2::ZERO,
                placed: false,
            },
        );
        for (i, &p) in play.iter().enumerate() {
            if p {
                self.place(bodies, i as u32, dt);
            }
        }
        self.reindex();
        self.found.clear();
        self.searching.clear();
        self.searching.extend_from_slice(&play);
        for (i, &p) in play.iter().enumerate() {
            if p {
                self.neighbours(bodies, i as u32);
            }
        }
        pairs.clear();
        self.merge_found(pairs);
        if !old.is_empty() {
            for p in pairs.iter_mut() {
                let (ka, kb) = (bodies[p.a as usize].key.0, bodies[p.b as usize].key.0);
                if let Some(o) = old.get(&(ka.min(kb), ka.max(kb))) {
                    p.normal = o.normal;
                    p.normal_impulse = o.normal_impulse;
                    p.tangent_impulse = o.tangent_impulse;
                }
            }
        }
    }

    /// Gives body `i` a fat box around where it is now (the caller puts it in the index).
    fn place(&mut self, bodies: &[Body], i: u32, dt: f64) {
        let body = &bodies[i as usize];
        let Aabb { min, max } = Aabb::of(&body.shape, body.pos);
        // Room for two steps of travel and a quarter of the body's size.
        let m = if fixed(body) {
            0.0
        } else {
            2.0 * body.vel.length() * dt + 0.25 * body.shape.half_extents().max_element()
        };
        let (min, max) = (min - m, max + m);
        self.fat[i as usize] = Fat {
            min,
            max,
            placed: true,
        };
    }

    /// Pushes to `found` every eligible pair of `i` whose fat boxes overlap, each once: a
    /// pair of two searched bodies from the smaller's search.
    fn neighbours(&mut self, bodies: &[Body], i: u32) {
        let fi = self.fat[i as usize];
        if !fi.placed {
            return;
        }
        let (fat, searching, found) = (&self.fat, &self.searching, &mut self.found);
        let (resolves, groups) = (&self.resolves, self.groups);
        self.index.query(fi.min, fi.max, |j| {
            if (j < i && searching[j as usize])
                || !overlap(&fi, &fat[j as usize])
                || !eligible(resolves, groups, bodies, i, j)
            {
                return;
            }
            let (a, b) = (i.min(j), i.max(j));
            found.push(u64::from(a) << 32 | u64::from(b));
        });
    }

    /// Adds the pairs in `found` that are not kept yet, keeping `pairs` sorted.
    fn merge_found(&mut self, pairs: &mut Vec<Pair>) {
        if self.found.is_empty() {
            return;
        }
        self.found.sort_unstable();
        self.found.dedup();
        self.merged.clear();
        let split = |k: u64| ((k >> 32) as u32, k as u32);
        let mut new = self.found.iter().map(|&k| split(k)).peekable();
        for p in pairs.iter() {
            while let Some(&(a, b)) = new.peek() {
                if (a, b) < (p.a, p.b) {
                    self.merged.push(Pair::new(a, b));
                    new.next();
                } else {
                    if (a, b) == (p.a, p.b) {
                        new.next();
                    }
                    break;
                }
            }
            self.merged.push(*p);
        }
        self.merged.extend(new.map(|(a, b)| Pair::new(a, b)));
        std::mem::swap(pairs, &mut self.merged);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Shape;
    use proptest::prelude::*;

    fn body(i: u32, x: f64, y: f64, w: f64, h: f64, inv_mass: f64, group: GroupId) -> Body {
        Body {
            key: super::super::body::BodyKey(i),
            group,
            ..Body::for_test(Shape::rect(w, h), DVec2::new(x, y), DVec2::ZERO, inv_mass)
        }
    }

    /// Every pair whose bodies' boxes overlap and that must be resolved.
    fn touching(bodies: &[Body], resolving: &[(GroupId, GroupId)]) -> Vec<(u32, u32)> {
        let mut out = Vec::new();
        for i in 0..bodies.len() {
            for j in i + 1..bodies.len() {
                let (p, q) = (&bodies[i], &bodies[j]);
                let named = resolving
                    .iter()
                    .any(|&(a, b)| (a, b) == (p.group, q.group) || (b, a) == (p.group, q.group));
                let (bp, bq) = (Aabb::of(&p.shape, p.pos), Aabb::of(&q.shape, q.pos));
                let overlap = bp.min.x <= bq.max.x
                    && bq.min.x <= bp.max.x
                    && bp.min.y <= bq.max.y
                    && bq.min.y <= bp.max.y;
                if named && overlap && !(p.is_static() && q.is_static()) {
                    out.push((i as u32, j as u32));
                }
            }
        }
        out
    }

    proptest! {
        /// After any sequence of moves, every touching pair is a candidate, candidates are
        /// sorted and unique, and none joins two static bodies or groups no interaction
        /// names.
        #[test]
        fn kept_pairs_cover_every_touching_pair_after_moves(
            boxes in proptest::collection::vec(
                (0.0f64..60.0, 0.0f64..60.0, 0.2f64..6.0, 0.2f64..6.0, 0u8..4, 0u16..3), 2..60),
            moves in proptest::collection::vec((0usize..60, -8.0f64..8.0, -8.0f64..8.0), 0..40),
        ) {
            // A static floor far larger than the other bodies, too.
            let mut bodies = vec![body(0, 30.0, -1.0, 400.0, 2.0, 0.0, 0)];
            bodies.extend(boxes.iter().enumerate().map(|(k, &(x, y, w, h, s, g))| {
                body(k as u32 + 1, x, y, w, h, if s == 0 { 0.0 } else { 1.0 }, g)
            }));
            let resolving = [(0, 1), (1, 1)];
            let movers: Vec<u32> = (0..bodies.len() as u32)
                .filter(|&i| !bodies[i as usize].is_static())
                .collect();
            let (mut set, mut contacts) = (PairSet::default(), Contacts::default());
            let dt = 1.0 / 60.0;
            set.update(&mut contacts, &bodies, 1, &resolving, &movers, dt);
            for (k, dx, dy) in moves {
                if let Some(&i) = movers.get(k % movers.len().max(1)) {
                    let b = &mut bodies[i as usize];
                    b.vel = DVec2::new(dx, dy) * 30.0;
                    b.pos += DVec2::new(dx, dy);
                }
                set.update(&mut contacts, &bodies, 1, &resolving, &movers, dt);
                let kept: Vec<(u32, u32)> = contacts.pairs.iter().map(|p| (p.a, p.b)).collect();
                prop_assert!(kept.windows(2).all(|w| w[0] < w[1]), "sorted, unique");
                for p in &contacts.pairs {
                    let (a, b) = (&bodies[p.a as usize], &bodies[p.b as usize]);
                    prop_assert!(!(a.is_static() && b.is_static()));
                    prop_assert!(a.group != 2 && b.group != 2);
                }
                for t in touching(&bodies, &resolving) {
                    prop_assert!(kept.binary_search(&t).is_ok(), "missing {:?}", t);
                }
            }
        }
    }

    /// Every eligible pair whose fat boxes overlap, by brute force over every pair: what
    /// the set must hold, exactly.
    fn overlapping_fat_boxes(set: &PairSet, bodies: &[Body]) -> Vec<(u32, u32)> {
        let mut out = Vec::new();
        for i in 0..bodies.len() as u32 {
            for j in i + 1..bodies.len() as u32 {
                let (p, q) = (&set.fat[i as usize], &set.fat[j as usize]);
                if p.placed
                    && q.placed
                    && overlap(p, q)
                    && eligible(&set.resolves, set.groups, bodies, i, j)
                {
                    out.push((i, j));
                }
            }
        }
        out
    }

    proptest! {
        /// Boxes from 1e-2 to 1e2 across, moved, thrown fast, added and removed: the kept
        /// pairs are exactly the eligible pairs whose fat boxes overlap, and they hold
        /// every pair whose boxes touch.
        #[test]
        fn kept_pairs_are_exactly_the_overlapping_fat_boxes_whatever_the_sizes(
            boxes in proptest::collection::vec(
                (-60.0f64..60.0, -60.0f64..60.0, -2.0f64..2.0, -2.0f64..2.0, 0u8..5, 0u16..3),
                2..50),
            ops in proptest::collection::vec(
                (0u8..5, 0usize..64, -1.0f64..1.0, -1.0f64..1.0, -2.0f64..2.0), 1..40),
        ) {
            // Sides of 10^-2 to 10^2, even in the logarithm.
            let make = |key: u32, x: f64, y: f64, w: f64, h: f64, s: u8, g: GroupId| {
                let inv_mass = if s == 0 { 0.0 } else { 1.0 };
                body(key, x, y, 10f64.powf(w), 10f64.powf(h), inv_mass, g)
            };
            let mut bodies: Vec<Body> = boxes
                .iter()
                .enumerate()
                .map(|(k, &(x, y, w, h, s, g))| make(k as u32, x, y, w, h, s, g))
                .collect();
            let mut key = bodies.len() as u32;
            let resolving = [(0, 1), (1, 1)];
            let movers = |bodies: &[Body]| -> Vec<u32> {
                (0..bodies.len() as u32)
                    .filter(|&i| !bodies[i as usize].is_static())
                    .collect()
            };
            let (mut set, mut contacts) = (PairSet::default(), Contacts::default());
            let (dt, mut revision) = (1.0 / 60.0, 1);
            set.update(&mut contacts, &bodies, revision, &resolving, &movers(&bodies), dt);
            for (op, k, dx, dy, e) in ops {
                let n = bodies.len();
                match op {
                    // A move of up to 10^e, at the speed it takes in a step.
                    0..=2 => {
                        let b = &mut bodies[k % n];
                        if !b.is_static() {
                            let d = DVec2::new(dx, dy) * 10f64.powf(e);
                            b.vel = d / dt;
                            b.pos += d;
                        }
                    }
                    // A body added, of sides 10^e by 10^-e.
                    3 => {
                        bodies.push(make(key, dx * 60.0, dy * 60.0, e, -e, k as u8 % 5, k as u16 % 3));
                        key += 1;
                        revision += 1;
                    }
                    // A body removed.
                    _ => {
                        if n > 2 {
                            let mut removed = vec![false; n];
                            removed[k % n] = true;
                            bodies.remove(k % n);
                            contacts.remove_bodies(&removed);
                            revision += 1;
                        }
                    }
                }
                set.update(&mut contacts, &bodies, revision, &resolving, &movers(&bodies), dt);
                let kept: Vec<(u32, u32)> = contacts.pairs.iter().map(|p| (p.a, p.b)).collect();
                prop_assert_eq!(&kept, &overlapping_fat_boxes(&set, &bodies));
                for t in touching(&bodies, &resolving) {
                    prop_assert!(kept.binary_search(&t).is_ok(), "missing {:?}", t);
                }
            }
        }
    }

    #[test]
    fn a_restored_set_builds_its_tree_again_and_keeps_its_pairs() {
        let mut bodies: Vec<Body> = (0..30)
            .map(|k| body(k, (k % 6) as f64, (k / 6) as f64, 1.0, 1.0, 1.0, 1))
            .collect();
        bodies.push(body(30, 2.5, -40.0, 80.0, 78.0, 0.0, 0));
        let movers: Vec<u32> = (0..30).collect();
        let resolving = [(0, 1), (1, 1)];
        let (mut set, mut contacts) = (PairSet::default(), Contacts::default());
        let dt = 1.0 / 60.0;
        set.update(&mut contacts, &bodies, 1, &resolving, &movers, dt);
        let bytes = serde_json::to_vec(&set).unwrap();
        let mut restored: PairSet = serde_json::from_slice(&bytes).unwrap();
        let mut again = contacts.clone();
        for step in 0..20 {
            bodies[step % 30].pos += DVec2::new(3.0, 0.5);
            bodies[step % 30].vel = DVec2::new(180.0, 30.0);
            set.update(&mut contacts, &bodies, 1, &resolving, &movers, dt);
            restored.update(&mut again, &bodies, 1, &resolving, &movers, dt);
            assert_eq!(contacts.pairs, again.pairs);
        }
        assert_eq!(restored.index.capacity(), 31);
        // The floor and the thrown bodies cover more cells than the grid keeps.
        assert!(restored.index.in_tree() > 1);
    }

    #[test]
    fn bodies_at_rest_are_never_looked_at_again_and_impulses_survive_a_rebuild() {
        let mut bodies: Vec<Body> = (0..10)
            .map(|k| body(k, 0.0, 0.5 + k as f64, 1.0, 1.0, 1.0, 1))
            .collect();
        bodies.push(body(10, 0.0, -1.0, 100.0, 2.0, 0.0, 0));
        let movers: Vec<u32> = (0..10).collect();
        let resolving = [(0, 1), (1, 1)];
        let (mut set, mut contacts) = (PairSet::default(), Contacts::default());
        set.update(&mut contacts, &bodies, 1, &resolving, &movers, 1.0 / 60.0);
        // Nine box-on-box contacts and the bottom box on the floor.
        let kept: Vec<(u32, u32)> = contacts.pairs.iter().map(|p| (p.a, p.b)).collect();
        assert!(
            kept.contains(&(0, 10)) && kept.contains(&(8, 9)),
            "{kept:?}"
        );
        for _ in 0..100 {
            set.update(&mut contacts, &bodies, 1, &resolving, &movers, 1.0 / 60.0);
        }
        assert_eq!(set.reinserted, 0);
        // A new layout (a body removed in front) keeps the impulses by body key.
        contacts
            .pairs
            .iter_mut()
            .for_each(|p| p.normal_impulse = (p.a * 100 + p.b) as f64);
        let before: Vec<(u32, u32, f64)> = contacts
            .pairs
            .iter()
            .map(|p| {
                (
                    bodies[p.a as usize].key.0,
                    bodies[p.b as usize].key.0,
                    p.normal_impulse,
                )
            })
            .collect();
        bodies.remove(5);
        let mut removed = vec![false; 11];
        removed[5] = true;
        contacts.remove_bodies(&removed);
        set.update(
            &mut contacts,
            &bodies,
            2,
            &resolving,
            &(0..9).collect::<Vec<_>>(),
            1.0 / 60.0,
        );
        for p in &contacts.pairs {
            let (ka, kb) = (bodies[p.a as usize].key.0, bodies[p.b as usize].key.0);
            if let Some(&(_, _, j)) = before.iter().find(|&&(a, b, _)| (a, b) == (ka, kb)) {
                assert_eq!(p.normal_impulse, j);
            }
        }
        assert!(contacts.pairs.iter().any(|p| p.normal_impulse > 0.0));
    }

    #[test]
    fn a_refill_keeps_the_impulses_of_the_pairs_found_again_and_removal_renumbers() {
        let mut contacts = Contacts::default();
        let mut kept = Vec::new();
        contacts.refill(&mut vec![(2, 1), (0, 3), (1, 2), (3, 4)], &mut kept);
        let found: Vec<(u32, u32)> = contacts.pairs.iter().map(|p| (p.a, p.b)).collect();
        assert_eq!(found, [(0, 3), (1, 2), (3, 4)]);
        for p in &mut contacts.pairs {
            p.normal = DVec2::Y;
            p.normal_impulse = (p.a * 10 + p.b) as f64;
        }
        // (0, 3) has no impulse left: it comes back cold, normal and all.
        contacts.pairs[0].normal_impulse = 0.0;
        contacts.refill(&mut vec![(4, 3), (0, 3), (2, 5), (1, 2)], &mut kept);
        let found: Vec<(u32, u32, f64, DVec2)> = contacts
            .pairs
            .iter()
            .map(|p| (p.a, p.b, p.normal_impulse, p.normal))
            .collect();
        assert_eq!(
            found,
            [
                (0, 3, 0.0, DVec2::ZERO),
                (1, 2, 12.0, DVec2::Y),
                (2, 5, 0.0, DVec2::ZERO),
                (3, 4, 34.0, DVec2::Y)
            ]
        );
        contacts.remove_bodies(&[false, false, true, false, false, false]);
        let left: Vec<(u32, u32, f64)> = contacts
            .pairs
            .iter()
            .map(|p| (p.a, p.b, p.normal_impulse))
            .collect();
        assert_eq!(left, [(0, 2, 0.0), (2, 3, 34.0)]);
    }
}
