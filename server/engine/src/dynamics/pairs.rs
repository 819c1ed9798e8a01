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
//! **A frame of reference of its own.** A fat box is swept along its body's travel (two
//! steps of it under gravity, eight without: `SWEPT_STEPS`; and grown by a quarter of that
//! every way, for a body turned aside within a step), so a crowd moving together (a heavy
//! body pushing hundreds ahead of it, a rain falling) would have every box grown by the
//! crowd's speed and overlapping hundreds of others, though the bodies hardly move
//! against each other. Whether two bodies can meet within
//! a step depends only on how they move against each other, so the set keeps its boxes in
//! a frame moving at a velocity of its own (`PairSet::frame_velocity`): a box is swept
//! along its body's travel in that frame, and any frame finds every pair that can meet.
//! Sweeping along the travel rather than growing the box by it every way keeps a spray of
//! bodies flying apart from overlapping each other's boxes; a crowded body flying straight
//! gets a box that moves with it instead ([`fat`]), and two such boxes are a pair only if
//! they meet at one time, not wherever their sweeps cross (impacts seed 5, a block of 289
//! circles struck apart, kept 9 600 pairs for 400 contacts with every box standing, 3 700
//! with every box fit to fly moving, and a third of the pairs later in the run). The frame
//! is the median velocity of the bodies in play, taken when that halves the travel summed
//! over them (at a rebuild, or in a step that moved a quarter of the boxes); most worlds
//! keep the frame at rest. In a moving frame the static bodies move
//! too, and are looked at every step. Under gravity a body may also be stopped within a
//! step by a third one (a falling box landing on a pile, its neighbour still falling), so
//! the box of a body gravity pulls is swept back to where it would stop as well. A rain
//! falls freely, gaining speed every step, and would leave a frame of fixed velocity
//! behind within a few steps: when the median velocity has gained what gravity gives since
//! the frame was chosen, the frame falls too (`PairSet::falls`), as the solver's sub-steps
//! move a body, and each box is swept over what its body's acceleration and the frame's
//! may differ by.
//!
//! Pairs are kept sorted by body index (`a < b`), so the order, and with it every result,
//! is deterministic: the pairs are exactly the eligible pairs whose fat boxes meet,
//! whatever a body's tier or the tree's shape. They live in [`Contacts`], the one home of
//! the solver's pairs and their warm starts whatever the broad phase: the pair set keeps
//! them up to date in place, the other broad phases refill them each step
//! ([`Contacts::refill`]).

use glam::DVec2;

use super::body::{Body, GroupId};
use super::impulse::KeyMap;
use crate::geometry::tiered::Tiered;
use crate::geometry::Aabb;
use fat::{cross, encloses, meet, meet_crossing, Fat};
use frame::{fixed, pulled, reach, sideways, swept_steps, velocity, CROWDED, MOVING_STEPS};

/// A candidate pair of bodies (indices, `a < b`) with the impulses of its last contact.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Pair {
    pub a: u32,
    pub b: u32,
    /// The normal of the last contact (from `a` to `b`).
    pub normal: DVec2,
    pub normal_impulse: f64,
    pub tangent_impulse: f64,
    /// The split impulse the solver pushed the pair apart with last step.
    #[serde(default)]
    pub pseudo_impulse: f64,
}

impl Pair {
    pub fn new(a: u32, b: u32) -> Pair {
        Pair {
            a,
            b,
            normal: DVec2::ZERO,
            normal_impulse: 0.0,
            tangent_impulse: 0.0,
            pseudo_impulse: 0.0,
        }
    }

    /// Whether the pair has an impulse left to start its next contact from (a normal,
    /// friction or split impulse).
    fn carries_impulses(&self) -> bool {
        self.normal_impulse != 0.0 || self.tangent_impulse != 0.0 || self.pseudo_impulse != 0.0
    }

    /// Takes `other`'s normal and impulses (the same pair, found again).
    fn take_impulses(&mut self, other: &Pair) {
        self.normal = other.normal;
        self.normal_impulse = other.normal_impulse;
        self.tangent_impulse = other.tangent_impulse;
        self.pseudo_impulse = other.pseudo_impulse;
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
    /// counts once); a pair kept from last step keeps its impulses (split impulse too) if
    /// it had any.
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
                if o.carries_impulses() {
                    p.take_impulses(o);
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
    /// Each moved body's fat box before this update (scratch, read for the moved only): a
    /// pair whose boxes overlapped before is kept already.
    #[serde(skip)]
    prior: Vec<Fat>,
    /// New pairs found by a search, as `a << 32 | b` (sorted, they are in pair order).
    found: Vec<u64>,
    merged: Vec<Pair>,
    /// The bodies whose neighbours this round searches: a pair of two of them is taken
    /// from the smaller's search only.
    searching: Vec<bool>,
    /// Bodies re-inserted over the set's life (a figure for tests and benchmarks).
    pub reinserted: u64,
    /// Bodies placed by a search of every body (a rebuild, or a new frame), over the
    /// set's life (a figure for tests and benchmarks).
    #[serde(default)]
    pub placed_whole: u64,
    /// The velocity of the frame the fat boxes are kept in (see the module's notes).
    #[serde(default)]
    frame_velocity: DVec2,
    /// Where that frame is: a body's box at `pos` is at `pos - shift` in it.
    #[serde(default)]
    shift: DVec2,
    /// How long the bodies moved since the frame last moved ([`PairSet::advance`]): the
    /// next update moves the frame that long at its velocity. An update that follows no
    /// motion (the islands of sleeping, after the step's own broad phase) moves it not at
    /// all, or the frame would run ahead of the bodies and every box leave its fat box.
    #[serde(default)]
    elapsed: f64,
    /// Bodies in the index (set by a rebuild, the only place that places or unplaces).
    #[serde(default)]
    in_play: usize,
    /// The placed bodies static for good (looked at every step when the frame moves).
    #[serde(default)]
    statics: Vec<u32>,
    /// Scratch for the median velocity.
    #[serde(skip)]
    speeds: Vec<f64>,
    /// The world's gravity, set before each update: a body it accelerates may be stopped
    /// within a step (see [`PairSet::place`]).
    #[serde(skip)]
    gravity: DVec2,
    /// Whether a body's acceleration is its gravity (not scaled by its inverse mass, the
    /// chapter's rule): only then may the frame fall (see [`PairSet::falls`]).
    #[serde(skip)]
    plain_gravity: bool,
    /// The share of a step's gain in velocity a body gravity pulls moves by within the
    /// step: `(n + 1) / (2 n)` under symplectic Euler in `n` sub-steps (a falling frame
    /// falls so, and a body of a rain stays where it is in it).
    #[serde(skip)]
    fall_share: f64,
    /// Whether the frame falls: its velocity gains `gravity` as the bodies' do, so a rain
    /// in free fall stays at rest in it (see the module's notes).
    #[serde(default)]
    falls: bool,
    /// How long since the frame was chosen: the median velocity then followed free fall
    /// if it gained `gravity` times this.
    #[serde(default)]
    since: f64,
    /// How long the bodies moved since the set was made: the time a moving fat box is
    /// placed at and expires at.
    #[serde(default)]
    clock: f64,
    /// How many boxes each body's box crossed when placed (of a moving box, the share of
    /// them a standing one would have crossed): a crowded body gets a moving box.
    #[serde(default)]
    crowd: Vec<u16>,
}

/// Whether bodies `i` and `j` make a candidate pair: two bodies, not both static for
/// good, of groups that resolve (`resolves`, row-major, `groups x groups`).
fn eligible(resolves: &[bool], groups: usize, bodies: &[Body], i: u32, j: u32) -> bool {
    let (p, q) = (&bodies[i as usize], &bodies[j as usize]);
    i != j && !(fixed(p) && fixed(q)) && resolves[p.group as usize * groups + q.group as usize]
}

impl PairSet {
    /// The world's gravity, for the updates that follow.
    pub fn set_gravity(&mut self, gravity: DVec2) {
        self.set_acceleration(gravity, false, 1);
    }

    /// The world's gravity, whether a body's acceleration is scaled by its inverse mass
    /// (then the frame never falls) and the solver's sub-steps a step, for the updates
    /// that follow.
    pub fn set_acceleration(&mut self, gravity: DVec2, mass_scaled: bool, substeps: u32) {
        self.gravity = gravity;
        self.plain_gravity = !mass_scaled;
        let n = f64::from(substeps.max(1));
        self.fall_share = (n + 1.0) / (2.0 * n);
    }

    /// The bodies moved for `dt` since the last update (the world calls it after each
    /// integration): the frame follows them at the next update.
    pub fn advance(&mut self, dt: f64) {
        self.elapsed += dt;
    }

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
        // A set restored from an older checkpoint counts no crowds yet.
        self.crowd.resize(self.fat.len(), 0);
        self.shift += self.frame_velocity * self.elapsed;
        if self.falls {
            // Falling over the time the bodies moved as their sub-steps move them.
            self.shift += self.fall_share * self.gravity * self.elapsed * self.elapsed;
            self.frame_velocity += self.gravity * self.elapsed;
        }
        self.since += self.elapsed;
        self.clock += self.elapsed;
        self.elapsed = 0.0;
        self.moved.clear();
        let still = self.frame_velocity == DVec2::ZERO && !self.falls;
        let statics = std::mem::take(&mut self.statics);
        for &i in movers
            .iter()
            .chain(if still { &[][..] } else { &statics[..] })
        {
            let body = &bodies[i as usize];
            let f = self.fat[i as usize];
            if !f.placed {
                continue;
            }
            let r = reach(body, self.frame_velocity, dt);
            let Aabb { min, max } = Aabb::of(&body.shape, body.pos - self.shift);
            let held = if f.moves() {
                let step = (velocity(body) - self.frame_velocity) * dt;
                f.holds(min, max, step, r, self.clock, dt)
            } else {
                let (min, max) = self.swept(body, min, max, 1.0, dt);
                encloses(f.hull(), min, max, r)
            };
            if !held {
                self.moved.push(i);
            }
        }
        self.statics = statics;
        if self.moved.is_empty() {
            return;
        }
        // A new frame places every body again: the ones that left their boxes are not
        // placed in the old one first.
        if self.moved.len() * 4 >= self.in_play {
            if let Some(frame) = self.better_frame(bodies) {
                self.falls = self.free_fall(frame);
                self.frame_velocity = frame;
                self.shift = DVec2::ZERO;
                self.since = 0.0;
                self.search_all(pairs, bodies, dt);
                return;
            }
        }
        if self.prior.len() != self.fat.len() {
            self.prior
                .resize(self.fat.len(), Fat::standing(DVec2::ZERO, DVec2::ZERO));
        }
        let moved = std::mem::take(&mut self.moved);
        for &i in &moved {
            let f = self.fat[i as usize];
            self.prior[i as usize] = f;
            self.place(bodies, i, dt);
            let (old, new) = (f.hull(), self.fat[i as usize].hull());
            self.index.relocate(i, (old.min, old.max), new.min, new.max);
        }
        self.moved = moved;
        self.index.flush();
        self.reinserted += self.moved.len() as u64;
        self.found.clear();
        let moved = std::mem::take(&mut self.moved);
        self.searching.clear();
        self.searching.resize(bodies.len(), false);
        for &i in &moved {
            self.searching[i as usize] = true;
        }
        for &i in &moved {
            self.neighbours(bodies, i, true, dt);
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
        if !(self.frame_velocity.is_finite()
            && self.shift.is_finite()
            && self.elapsed.is_finite()
            && self.since.is_finite()
            && self.clock.is_finite())
        {
            return bad(
                "frame_velocity",
                "the set's frame of reference is not finite".into(),
            );
        }
        if let Some(&i) = self.statics.iter().find(|&&i| i as usize >= n) {
            return bad("statics", format!("body {i} of a world of {n} bodies"));
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
            if !(f.min.is_finite()
                && f.max.is_finite()
                && f.min.cmple(f.max).all()
                && f.vel.is_finite()
                && f.since.is_finite()
                && f.until.is_finite())
            {
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
                let hull = f.hull();
                self.index.insert(i as u32, hull.min, hull.max);
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
            .filter(|p| p.carries_impulses())
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
        self.crowd.clear();
        self.crowd.resize(bodies.len(), 0);
        self.fat
            .resize(bodies.len(), Fat::standing(DVec2::ZERO, DVec2::ZERO));
        for (f, &p) in self.fat.iter_mut().zip(&play) {
            f.placed = p;
        }
        self.in_play = play.iter().filter(|&&p| p).count();
        self.statics.clear();
        self.statics.extend(
            (0..bodies.len() as u32).filter(|&i| play[i as usize] && fixed(&bodies[i as usize])),
        );
        self.frame_velocity = DVec2::ZERO;
        self.falls = false;
        self.frame_velocity = self.better_frame(bodies).unwrap_or(DVec2::ZERO);
        self.shift = DVec2::ZERO;
        self.since = 0.0;
        pairs.clear();
        self.search_all(pairs, bodies, dt);
        if !old.is_empty() {
            for p in pairs.iter_mut() {
                let (ka, kb) = (bodies[p.a as usize].key.0, bodies[p.b as usize].key.0);
                if let Some(o) = old.get(&(ka.min(kb), ka.max(kb))) {
                    p.take_impulses(o);
                }
            }
        }
    }

    /// Places every body in play again in the set's frame and finds all its pairs; the
    /// pairs found again keep their impulses.
    fn search_all(&mut self, pairs: &mut Vec<Pair>, bodies: &[Body], dt: f64) {
        self.elapsed = 0.0;
        self.placed_whole += self.in_play as u64;
        for i in 0..self.fat.len() as u32 {
            if self.fat[i as usize].placed {
                self.place(bodies, i, dt);
            }
        }
        self.reindex();
        self.found.clear();
        self.searching.clear();
        self.searching.extend(self.fat.iter().map(|f| f.placed));
        for i in 0..self.fat.len() as u32 {
            if self.fat[i as usize].placed {
                self.neighbours(bodies, i, false, dt);
            }
        }
        self.merge_found(pairs);
    }

    /// Gives body `i` a fat box around where it is now in the set's frame (the caller puts
    /// it in the index).
    fn place(&mut self, bodies: &[Body], i: u32, dt: f64) {
        let body = &bodies[i as usize];
        let Aabb { min, max } = Aabb::of(&body.shape, body.pos - self.shift);
        // Swept along a few steps of travel in the frame ([`SWEPT_STEPS`]), grown every
        // way by a share of that travel ([`sideways`]) and a quarter of the body's size (a
        // body static for good in a frame at rest needs none).
        let steps = swept_steps(body, self.gravity);
        let rel = velocity(body) - self.frame_velocity;
        let travel = rel.length();
        let half = body.shape.half_extents().max_element();
        let m = if fixed(body) && travel == 0.0 {
            0.0
        } else {
            sideways(body, steps, travel * dt) + 0.25 * half
        };
        // A body that flies straight (nothing accelerates it) and far over its steps, in
        // a frame that does not fall, gets a box moving with it ([`fat`]).
        let flies = self.crowd.get(i as usize).is_some_and(|&c| c >= CROWDED)
            && !self.falls
            && !fixed(body)
            && !pulled(body, self.gravity)
            && travel * steps * dt > 2.0 * half;
        // Its box lasts twice as long as the last one did, up to [`MOVING_STEPS`].
        let last = self.fat[i as usize];
        let lasted = if last.moves() {
            (self.clock - last.since) / dt
        } else {
            0.0
        };
        let life = (2.0 * lasted).clamp(steps, MOVING_STEPS);
        self.fat[i as usize] = if flies {
            Fat::moving(min - m, max + m, rel, self.clock, self.clock + life * dt)
        } else {
            let (min, max) = self.swept(body, min, max, steps, dt);
            Fat::standing(min - m, max + m)
        };
    }

    /// Pushes to `found` every eligible pair of `i` whose fat boxes meet, each once: a pair
    /// of two searched bodies from the smaller's search. Counts in `crowd` the boxes it
    /// crossed. With `new_only`, after `i`
    /// and the other searched bodies moved (their boxes before in `prior`), only the pairs
    /// whose boxes did not meet before: the others are kept already (the pairs are exactly
    /// the eligible pairs whose boxes meet).
    fn neighbours(&mut self, bodies: &[Body], i: u32, new_only: bool, dt: f64) {
        let fi = self.fat[i as usize];
        if !fi.placed {
            return;
        }
        let hull = fi.hull();
        let (fat, prior, searching, found) =
            (&self.fat, &self.prior, &self.searching, &mut self.found);
        let (resolves, groups) = (&self.resolves, self.groups);
        let was = |j: u32| {
            if searching[j as usize] {
                &prior[j as usize]
            } else {
                &fat[j as usize]
            }
        };
        let mut crossed = 0u32;
        self.index.query(hull.min, hull.max, |j| {
            let fj = &fat[j as usize];
            if j == i || !cross(&fi, fj) {
                return;
            }
            crossed += 1;
            if (j < i && searching[j as usize])
                || !meet_crossing(&fi, fj)
                || (new_only && meet(was(i), was(j)))
                || !eligible(resolves, groups, bodies, i, j)
            {
                return;
            }
            let (a, b) = (i.min(j), i.max(j));
            found.push(u64::from(a) << 32 | u64::from(b));
        });
        // What a box of the sweep a standing one has would cross.
        let share = if fi.moves() {
            (swept_steps(&bodies[i as usize], self.gravity) * dt / (fi.until - fi.since)).min(1.0)
        } else {
            1.0
        };
        if let Some(c) = self.crowd.get_mut(i as usize) {
            *c = (f64::from(crossed) * share).min(f64::from(u16::MAX)) as u16;
        }
    }

    /// Drops the pairs whose boxes no longer meet and adds those in `found` that are not
    /// kept yet, keeping `pairs` sorted, in one pass. Only a searched body's box changed: a
    /// pair of two others still meets. A pair is looked at alone only when a searched
    /// body is in it or a new pair goes before it; the runs between are copied whole (on a
    /// struck block, a few dozen new pairs among thousands kept, the pass took a tenth of
    /// the step copying pair by pair).
    fn merge_found(&mut self, pairs: &mut Vec<Pair>) {
        let (fat, searching) = (&self.fat, &self.searching);
        let touched = |p: &Pair| searching[p.a as usize] || searching[p.b as usize];
        let keep = |p: &Pair| !touched(p) || meet(&fat[p.a as usize], &fat[p.b as usize]);
        if self.found.is_empty() {
            pairs.retain(keep);
            return;
        }
        self.found.sort_unstable();
        self.found.dedup();
        self.merged.clear();
        self.merged.reserve(pairs.len() + self.found.len());
        let new_pair = |k: u64| Pair::new((k >> 32) as u32, k as u32);
        // Keys in pair order; none is `u64::MAX` (a pair has `a < b`).
        let key = |p: &Pair| u64::from(p.a) << 32 | u64::from(p.b);
        let mut new = self.found.iter().copied();
        let mut next = new.next().unwrap_or(u64::MAX);
        let mut run = 0;
        for (k, p) in pairs.iter().enumerate() {
            let at = key(p);
            if at < next && !touched(p) {
                continue;
            }
            self.merged.extend_from_slice(&pairs[run..k]);
            run = k + 1;
            // The new pairs before this one; one found again is kept as it is.
            while next <= at {
                if next < at {
                    self.merged.push(new_pair(next));
                }
                next = new.next().unwrap_or(u64::MAX);
            }
            if keep(p) {
                self.merged.push(*p);
            }
        }
        self.merged.extend_from_slice(&pairs[run..]);
        if next != u64::MAX {
            self.merged.push(new_pair(next));
            self.merged.extend(new.map(new_pair));
        }
        std::mem::swap(pairs, &mut self.merged);
    }
}

mod fat;
mod frame;
#[cfg(test)]
mod tests;
