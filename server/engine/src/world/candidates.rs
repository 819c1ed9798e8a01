//! The broad phase, the step's one stage that finds candidate pairs: the grid's
//! persistent pairs, a large all-static group's cached grid, or sweep and prune, always in
//! all-pairs order so every broad phase gives the same result. [`World::broad_phase`]
//! finds the pairs of every resolving interaction at once, for the impulse solver and
//! for sleeping; the chapter's relaxation asks interaction by interaction
//! ([`World::candidates`]), because each interaction moves bodies before the next one's
//! pairs are found.

use crate::dynamics::body::GroupId;
use crate::dynamics::broad_phase::{
    grid_pairs, sweep_pairs, BroadPhase, StaticGrid, STATIC_GRID_MIN_MEMBERS,
};

use super::{Side, World};

impl World {
    /// Finds the candidate pairs of every resolving interaction between groups for a step
    /// of `dt` from where the bodies are now: with the grid, its persistent pairs brought
    /// up to date (in `contacts.pairs`); otherwise each interaction's pairs
    /// in declaration order, into the scratch candidates (every pair of the two groups under
    /// `all_pairs`).
    pub(super) fn broad_phase(&mut self, dt: f64) {
        let mut all = std::mem::take(&mut self.scratch.candidates);
        all.clear();
        if self.config.broad_phase == BroadPhase::Grid {
            self.update_pair_set(dt);
            self.scratch.candidates = all;
            return;
        }
        let mut some = std::mem::take(&mut self.scratch.interaction_pairs);
        for (a, b) in self.resolving() {
            let (ga, gb) = (
                &self.groups[a as usize].members,
                &self.groups[b as usize].members,
            );
            if ga.is_empty() || gb.is_empty() {
                continue;
            }
            if self.config.broad_phase == BroadPhase::AllPairs {
                for &i in ga {
                    all.extend(gb.iter().filter(|&&j| j != i).map(|&j| (i, j)));
                }
            } else {
                self.candidates(a, b, dt, &mut some);
                all.extend_from_slice(&some);
            }
        }
        self.scratch.interaction_pairs = some;
        self.scratch.candidates = all;
    }

    /// Candidate pairs of the interaction between groups `a` and `b`, in all-pairs order:
    /// from the grid broad phase's kept pairs; or, with the sweep, against a large
    /// all-static group from its cached grid, otherwise by sweep and prune.
    pub(super) fn candidates(
        &mut self,
        a: GroupId,
        b: GroupId,
        dt: f64,
        out: &mut Vec<(u32, u32)>,
    ) {
        if self.config.broad_phase == BroadPhase::Grid {
            self.grid_candidates(a, b, dt, out);
            return;
        }
        if a != b {
            for (fixed, moving, static_first) in [(b, a, false), (a, b, true)] {
                if self.static_grid(fixed) {
                    let grid = self.scratch.static_grids[fixed as usize]
                        .1
                        .as_ref()
                        .expect("checked above");
                    let (ms, ss) = (
                        &self.groups[moving as usize].members,
                        &self.groups[fixed as usize].members,
                    );
                    grid_pairs(&self.bodies, ms, ss, grid, static_first, dt, out);
                    return;
                }
            }
        }
        let (ga, gb) = (
            &self.groups[a as usize].members,
            &self.groups[b as usize].members,
        );
        sweep_pairs(
            &self.bodies,
            ga,
            gb,
            a == b,
            dt,
            &mut self.scratch.sweep,
            out,
        );
    }

    /// Whether group `g` has a static grid now (building it if the layout changed).
    pub(super) fn static_grid(&mut self, g: GroupId) -> bool {
        let g = g as usize;
        if self.scratch.static_grids.len() <= g {
            self.scratch.static_grids.resize_with(g + 1, || (0, None));
        }
        if self.scratch.static_grids[g].0 != self.layout_revision {
            let members = &self.groups[g].members;
            let eligible = members.len() > STATIC_GRID_MIN_MEMBERS
                && members.iter().all(|&i| {
                    self.bodies[i as usize].is_static() && self.bodies[i as usize].asleep.is_none()
                });
            let grid =
                eligible.then(|| StaticGrid::build(&self.bodies, members, self.layout_revision));
            self.scratch.static_grids[g] = (self.layout_revision, grid);
        }
        self.scratch.static_grids[g].1.is_some()
    }

    /// The group pairs of the resolving interactions between groups.
    pub(super) fn resolving(&self) -> Vec<(GroupId, GroupId)> {
        self.resolving_pairs().collect()
    }

    fn resolving_pairs(&self) -> impl Iterator<Item = (GroupId, GroupId)> + '_ {
        self.interactions
            .iter()
            .filter_map(|it| match (it.a, it.b, it.resolve) {
                (Side::Group(a), Side::Group(b), true) => Some((a, b)),
                _ => None,
            })
    }

    /// Brings the grid broad phase's persistent pairs up to date.
    pub(super) fn update_pair_set(&mut self, dt: f64) {
        let mut resolving = std::mem::take(&mut self.scratch.resolving);
        resolving.clear();
        resolving.extend(self.resolving_pairs());
        self.pair_set.set_acceleration(
            self.config.gravity,
            self.config.mass_scaled_acceleration,
            self.config.substeps,
        );
        self.pair_set.update(
            &mut self.contacts,
            &self.bodies,
            self.layout_revision,
            &resolving,
            &self.movers,
            dt,
        );
        self.scratch.resolving = resolving;
    }

    /// Candidate pairs of the interaction between groups `a` and `b` from the grid broad
    /// phase, in all-pairs order (group members are in body order).
    pub(super) fn grid_candidates(
        &mut self,
        a: GroupId,
        b: GroupId,
        dt: f64,
        out: &mut Vec<(u32, u32)>,
    ) {
        self.update_pair_set(dt);
        out.clear();
        let bodies = &self.bodies;
        for p in &self.contacts.pairs {
            let (ga, gb) = (bodies[p.a as usize].group, bodies[p.b as usize].group);
            if (ga, gb) == (a, b) {
                out.push((p.a, p.b));
            }
            if (gb, ga) == (a, b) {
                out.push((p.b, p.a));
            }
        }
        out.sort_unstable();
    }
}

#[cfg(test)]
mod tests {
    use crate::action::Action;
    use crate::world::World;

    fn world(text: &str) -> World {
        crate::scene::parse(text, std::path::Path::new("scene.toml"), &[]).expect("the scene")
    }

    /// A scene's `[[body]]` table: `id` of `group`, the shape's fields, at `pos`, with
    /// `more` fields.
    fn body(id: &str, group: &str, shape: &str, pos: [f64; 2], more: &str) -> String {
        format!("[[body]]\nid = \"{id}\"\ngroup = \"{group}\"\n{shape}\npos = {pos:?}\n{more}\n")
    }

    /// A crowd packed into walls past what fits, without gravity: it is long in resting
    /// whole, but parts of it sleep, so the islands bring the pairs up to date after the
    /// steps.
    /// The step's own broad phase is skipped then, and the crowd runs to the bits of a
    /// world that runs it every step.
    #[test]
    fn a_jammed_crowd_skips_the_broad_phase_the_islands_did_with_the_same_bits() {
        let (across, up) = (
            "shape = \"rect\"\nsize = [12, 1]",
            "shape = \"rect\"\nsize = [1, 12]",
        );
        let walls: String = [
            ("floor", across, [0.0, -5.5]),
            ("roof", across, [0.0, 5.5]),
            ("left", up, [-5.5, 0.0]),
            ("right", up, [5.5, 0.0]),
        ]
        .iter()
        .map(|&(id, shape, pos)| body(id, "walls", shape, pos, "mass = 0"))
        .collect();
        let text = format!(
            r#"
            interact = [{{ a = "balls", b = "balls" }}, {{ a = "balls", b = "walls" }}]

            [world]
            gravity = [0, 0]
            bounds = [[-10, -10], [10, 10]]

            {walls}

            [[generate]]
            kind = "grid"
            id = "ball"
            group = "balls"
            shape = "circle"
            radius = 0.5
            start = [-4.55, -4.5]
            step = [0.91, 0.9]
            cols = 11
            rows = 11
            restitution = 0
            friction = 0.4
        "#
        );
        let text = text.as_str();
        let (mut skipping, mut full) = (world(text), world(text));
        let mut skipped = 0;
        for step in 0..240 {
            skipped += u32::from(skipping.scratch.fresh_pairs.is_some());
            // What any action does: the next broad phase looks at every body again.
            full.scratch.fresh_pairs = None;
            skipping.step();
            full.step();
            assert_eq!(
                skipping.state_hash(),
                full.state_hash(),
                "the worlds part at step {step}"
            );
        }
        assert!(
            skipped >= 50,
            "the islands' pairs stood for the step's broad phase {skipped} times of 240"
        );
    }

    /// Two balls asleep apart while a third drifts: the islands' pairs stand for the
    /// steps' broad phases. A body put onto another by an action is seen by the next
    /// broad phase all the same, and pushed out.
    #[test]
    fn an_action_between_steps_makes_the_broad_phase_look_again() {
        let ball = |id: &str, pos: [f64; 2], vel: [f64; 2]| {
            body(
                id,
                "balls",
                "shape = \"circle\"\nradius = 0.5",
                pos,
                &format!("vel = {vel:?}"),
            )
        };
        let text = format!(
            "[world]\ngravity = [0, 0]\nbounds = [[-100, -100], [100, 100]]\n{}{}{}\n[[interact]]\na = \"balls\"\nb = \"balls\"\n",
            ball("a", [0.0, 0.0], [0.0, 0.0]),
            ball("b", [10.0, 0.0], [0.0, 0.0]),
            ball("drifter", [-50.0, 0.0], [1.0, 0.0]),
        );
        let text = text.as_str();
        let mut world = world(text);
        for _ in 0..120 {
            world.step();
        }
        assert_eq!(world.stats().sleeping, 2, "the two balls at rest sleep");
        assert!(
            world.scratch.fresh_pairs.is_some(),
            "the islands' pairs stand for the next broad phase"
        );
        world
            .apply(&Action::SetBody {
                body: "b".into(),
                pos: Some([0.6, 0.0]),
                vel: None,
            })
            .expect("b moves onto a");
        world.step();
        assert!(
            world.stats().contacts >= 1,
            "the first step after the action finds the contact"
        );
        for _ in 0..30 {
            world.step();
        }
        let (a, b) = (world.body("a").unwrap().pos, world.body("b").unwrap().pos);
        assert!(
            (b - a).length() > 0.99,
            "b put 0.6 from a is pushed out to {}",
            (b - a).length()
        );
    }

    /// A packed crowd thrown at 50 u/s beside a box at rest: once that box has rested long
    /// enough, the islands of sleeping bring the pairs up to date after every step as
    /// well as the step's own broad phase. The set's frame follows the crowd by the time
    /// the bodies moved, not by the updates made, so the crowd's boxes keep their fat
    /// boxes (a frame moved at every update ran at twice the crowd's speed and placed
    /// every box again every step).
    #[test]
    fn a_crowd_thrown_together_keeps_its_boxes_while_islands_are_found() {
        let text = r#"
            [world]
            gravity = [0, 0]
            bounds = [[-100, -100], [400, 100]]

            [[body]]
            id = "still"
            group = "boxes"
            shape = "rect"
            size = [1, 1]
            pos = [-50, 0]

            [[generate]]
            kind = "grid"
            id = "crowd"
            group = "boxes"
            shape = "rect"
            size = [1, 1]
            start = [0.5, 0.5]
            cols = 20
            rows = 20
            vel = [50, 0]

            [[interact]]
            a = "boxes"
            b = "boxes"
        "#;
        let mut world =
            crate::scene::parse(text, std::path::Path::new("crowd.toml"), &[]).expect("the scene");
        for _ in 0..40 {
            world.step();
        }
        assert!(world.stats().sleeping >= 1, "the box at rest sleeps");
        let before = world.pair_set.reinserted;
        for _ in 0..20 {
            world.step();
        }
        let placed = world.pair_set.reinserted - before;
        assert!(
            placed < 20 * 400 / 10,
            "{placed} boxes placed again in 20 steps of a crowd of 400 moving together"
        );
    }
}
