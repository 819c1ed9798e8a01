//! The world: bodies in groups, particles, emitters, the declared interactions, one
//! seeded random generator, and the step that ties them together.
//!
//! A step runs in the chapter's order: move every body (demo behaviours, then
//! integration), then every particle (removing the expired, then emitting), then the
//! declared interactions in their order, each rigid pair of groups with its own
//! relaxation loop and each particle pair by projection. Nothing is computed for what
//! no interaction names.

use glam::{DVec2, Vec2};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::action::{Action, ActionError, ActionOutcome, MAX_PARTICLES_PER_ACTION};
use crate::behavior::{self, Behavior};
use crate::dynamics::body::{Body, BodyDef, BodyKey, GroupId};
use crate::dynamics::broad_phase::{
    grid_pairs, sweep_pairs, BroadPhase, StaticGrid, SweepBuffers, STATIC_GRID_MIN_MEMBERS,
};
use crate::dynamics::ccd;
use crate::dynamics::config::Solver;
use crate::dynamics::config::WorldConfig;
use crate::dynamics::impulse::{self, ContactCache, ImpulseParams, SolverBuffers};
use crate::dynamics::integrate::{self, integrate_bodies};
use crate::dynamics::pairs::{Pair, PairSet};
use crate::dynamics::relaxation::{self, RelaxationParams};
use crate::dynamics::sleep;
use crate::geometry::{collide, Shape};
use crate::particles::system::{ParticleShape, ShapeGrid};
use crate::particles::{Emitter, ParticleDef, Particles, PresetLibrary};

/// Particle interactions with at least this many shapes bin them in a grid.
pub const PARTICLE_GRID_MIN_SHAPES: usize = 8;

/// One side of an interaction: a group of bodies or the particle system.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Side {
    Group(GroupId),
    Particles,
}

/// A declared interaction, tested every step in declaration order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Interaction {
    pub a: Side,
    pub b: Side,
    /// false: collisions are only flagged (the bounds demo), nothing moves.
    pub resolve: bool,
}

/// The name a scene uses for the particle side of an interaction.
pub const PARTICLES: &str = "particles";

/// A named group and its members (indices into the body array, in body order).
#[derive(Clone, Debug, Default)]
struct Group {
    name: String,
    members: Vec<u32>,
}

/// What one step did: the figures a frame reports.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StepStats {
    /// Rigid pair resolutions (or detections, in detect-only interactions).
    pub contacts: u64,
    /// Relaxation passes run, summed over interactions.
    pub relaxation_iterations: u64,
    /// Deepest rigid penetration detected.
    pub deepest_penetration: f64,
    /// Particles projected out of shapes.
    pub particle_contacts: u64,
    /// Kinetic energy of the rigid bodies after the step.
    pub kinetic_energy: f64,
    /// Bodies asleep after the step.
    pub sleeping: u64,
}

/// Why a body or particle could not be added.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum WorldError {
    #[error("body `{id}`: {source}")]
    Body {
        id: String,
        #[source]
        source: crate::dynamics::body::BodyError,
    },
    #[error("a body with id `{0}` already exists")]
    DuplicateId(String),
    #[error("particle: {0}")]
    Particle(#[from] crate::particles::system::ParticleError),
    #[error("unknown particle preset `{0}`")]
    UnknownPreset(String),
    #[error("interaction: {0}")]
    Interaction(String),
}

/// A simulated world.
#[derive(Clone, Debug)]
pub struct World {
    pub config: WorldConfig,
    bodies: Vec<Body>,
    groups: Vec<Group>,
    interactions: Vec<Interaction>,
    particles: Particles,
    emitters: Vec<Emitter>,
    presets: PresetLibrary,
    rng: ChaCha8Rng,
    frame: u64,
    next_key: u32,
    spawned: u64,
    selected: Option<BodyKey>,
    stats: StepStats,
    statics_revision: u64,
    // Scratch space of the broad phase and the impulse solver, kept between steps.
    sweep: SweepBuffers,
    /// Per group: the layout revision it was last looked at for, and its static grid if
    /// it is all static and large.
    static_grids: Vec<(u64, Option<StaticGrid>)>,
    /// Changes whenever bodies are added or removed or a static body is moved.
    layout_revision: u64,
    pairs: Vec<(u32, u32)>,
    sweep_out: Vec<(u32, u32)>,
    /// Indices of the dynamic bodies, and of the bodies with a behaviour: what a step
    /// walks, so static bodies cost nothing unless something touches them.
    movers: Vec<u32>,
    behaving: Vec<u32>,
    /// Bodies flagged collided in the last step, to clear at the next.
    flagged: Vec<u32>,
    contact_cache: ContactCache,
    /// The persistent pairs of the grid broad phase.
    pair_set: PairSet,
    /// Pairs handed to the impulse solver by the other broad phases.
    solver_pairs: Vec<Pair>,
    solver_buffers: SolverBuffers,
    /// Every body's id, to refuse duplicates without a scan.
    ids: std::collections::HashSet<String>,
    /// Bodies asleep after the last step.
    sleeping: u64,
}

impl World {
    /// An empty world with the given parameters and the built-in presets.
    pub fn new(config: WorldConfig) -> Self {
        let rng = ChaCha8Rng::seed_from_u64(config.seed);
        World {
            config,
            bodies: Vec::new(),
            groups: Vec::new(),
            interactions: Vec::new(),
            particles: Particles::default(),
            emitters: Vec::new(),
            presets: PresetLibrary::built_in(),
            rng,
            frame: 0,
            next_key: 0,
            spawned: 0,
            selected: None,
            stats: StepStats::default(),
            statics_revision: 0,
            sweep: SweepBuffers::default(),
            static_grids: Vec::new(),
            layout_revision: 1,
            pairs: Vec::new(),
            sweep_out: Vec::new(),
            movers: Vec::new(),
            behaving: Vec::new(),
            flagged: Vec::new(),
            contact_cache: ContactCache::default(),
            pair_set: PairSet::default(),
            solver_pairs: Vec::new(),
            solver_buffers: SolverBuffers::default(),
            ids: Default::default(),
            sleeping: 0,
        }
    }

    // ---- reading -------------------------------------------------------------------

    /// Steps taken so far.
    pub fn frame(&self) -> u64 {
        self.frame
    }

    /// Simulated seconds so far.
    pub fn time(&self) -> f64 {
        self.frame as f64 * self.config.dt
    }

    pub fn bodies(&self) -> &[Body] {
        &self.bodies
    }

    pub fn particles(&self) -> &Particles {
        &self.particles
    }

    pub fn emitters(&self) -> &[Emitter] {
        &self.emitters
    }

    pub fn interactions(&self) -> &[Interaction] {
        &self.interactions
    }

    pub fn presets(&self) -> &PresetLibrary {
        &self.presets
    }

    pub fn presets_mut(&mut self) -> &mut PresetLibrary {
        &mut self.presets
    }

    /// The figures of the last step.
    pub fn stats(&self) -> StepStats {
        self.stats
    }

    pub fn body(&self, id: &str) -> Option<&Body> {
        self.bodies.iter().find(|b| b.id == id)
    }

    pub fn group_name(&self, group: GroupId) -> &str {
        &self.groups[group as usize].name
    }

    /// The group's id, if any body or interaction has named it.
    /// The group names by index.
    pub fn group_names(&self) -> impl Iterator<Item = &str> {
        self.groups.iter().map(|g| g.name.as_str())
    }

    pub fn group(&self, name: &str) -> Option<GroupId> {
        self.groups
            .iter()
            .position(|g| g.name == name)
            .map(|i| i as GroupId)
    }

    /// Changes whenever a static body is added, moved or removed: when to re-send them.
    pub fn statics_revision(&self) -> u64 {
        self.statics_revision
    }

    /// The selected body's id.
    pub fn selected(&self) -> Option<&str> {
        let key = self.selected?;
        self.bodies
            .iter()
            .find(|b| b.key == key)
            .map(|b| b.id.as_str())
    }

    /// Total kinetic energy of the rigid bodies.
    pub fn kinetic_energy(&self) -> f64 {
        self.movers
            .iter()
            .map(|&i| self.bodies[i as usize].kinetic_energy())
            .sum()
    }

    // ---- building ------------------------------------------------------------------

    /// The group's id, creating the group if needed.
    pub fn group_or_insert(&mut self, name: &str) -> GroupId {
        if let Some(g) = self.group(name) {
            return g;
        }
        self.groups.push(Group {
            name: name.to_string(),
            members: Vec::new(),
        });
        (self.groups.len() - 1) as GroupId
    }

    /// Adds a body. Its id must be unique; every number is checked.
    pub fn add_body(&mut self, def: BodyDef) -> Result<BodyKey, WorldError> {
        def.validate().map_err(|source| WorldError::Body {
            id: def.id.clone(),
            source,
        })?;
        if self.ids.contains(&def.id) {
            return Err(WorldError::DuplicateId(def.id));
        }
        self.ids.insert(def.id.clone());
        let group = self.group_or_insert(&def.group);
        let key = BodyKey(self.next_key);
        self.next_key += 1;
        let index = self.bodies.len() as u32;
        if def.mass == 0.0 {
            self.statics_revision += 1;
        }
        self.layout_revision += 1;
        self.bodies.push(Body {
            pos: def.pos,
            vel: def.vel,
            shape: def.shape,
            inv_mass: def.inv_mass(),
            restitution: def.restitution,
            friction: def.friction,
            collided: false,
            gravity: def.gravity,
            group,
            key,
            behavior: def.behavior,
            id: def.id,
            rest_time: 0.0,
            asleep: None,
        });
        self.groups[group as usize].members.push(index);
        let body = &self.bodies[index as usize];
        if !body.is_static() {
            self.movers.push(index);
        }
        if body.behavior != Behavior::None {
            self.behaving.push(index);
        }
        Ok(key)
    }

    /// Adds a particle.
    pub fn add_particle(&mut self, def: &ParticleDef) -> Result<(), WorldError> {
        def.validate()?;
        self.particles
            .push(def, self.config.particle_gravity.as_vec2());
        Ok(())
    }

    /// Starts an emitter of `count` particles of `preset` at `pos`.
    pub fn add_emitter(&mut self, preset: &str, count: u32, pos: Vec2) -> Result<(), WorldError> {
        if self.presets.get(preset).is_none() {
            return Err(WorldError::UnknownPreset(preset.to_string()));
        }
        if !pos.is_finite() {
            return Err(WorldError::Interaction(format!(
                "emitter position {pos} is not finite"
            )));
        }
        self.emitters.push(Emitter {
            pos,
            remaining: count,
            preset: preset.to_string(),
        });
        Ok(())
    }

    /// Declares an interaction between two groups, or a group and [`PARTICLES`].
    pub fn add_interaction(&mut self, a: &str, b: &str, resolve: bool) -> Result<(), WorldError> {
        let side = |w: &mut World, name: &str| {
            if name == PARTICLES {
                Side::Particles
            } else {
                Side::Group(w.group_or_insert(name))
            }
        };
        let (sa, sb) = (side(self, a), side(self, b));
        if sa == Side::Particles && sb == Side::Particles {
            return Err(WorldError::Interaction(
                "particles do not collide with each other; pair `particles` with a group of bodies"
                    .into(),
            ));
        }
        self.interactions.push(Interaction {
            a: sa,
            b: sb,
            resolve,
        });
        // The grid broad phase keeps pairs of the groups that resolve: look again.
        self.layout_revision += 1;
        Ok(())
    }

    /// A fresh id `<prefix>-<n>` that no body uses.
    fn fresh_id(&mut self, prefix: &str) -> String {
        loop {
            self.spawned += 1;
            let id = format!("{prefix}-{}", self.spawned);
            if !self.ids.contains(&id) {
                return id;
            }
        }
    }

    /// Removes the bodies for which `remove` is true, keeping the order of the rest (and
    /// wakes the world: a removed body may have held others up).
    fn remove_bodies(&mut self, remove: impl Fn(&Body) -> bool) {
        if self.bodies.iter().any(&remove) {
            self.wake_all();
        }
        if self.bodies.iter().any(|b| b.is_static() && remove(b)) {
            self.statics_revision += 1;
        }
        let before = self.bodies.len();
        for b in self.bodies.iter().filter(|b| remove(b)) {
            self.ids.remove(&b.id);
        }
        self.bodies.retain(|b| !remove(b));
        if self.bodies.len() != before {
            self.layout_revision += 1;
            self.rebuild_groups();
        }
    }

    fn rebuild_groups(&mut self) {
        for g in &mut self.groups {
            g.members.clear();
        }
        self.movers.clear();
        self.behaving.clear();
        self.flagged.clear();
        for (i, b) in self.bodies.iter().enumerate() {
            self.groups[b.group as usize].members.push(i as u32);
            if !b.is_static() {
                self.movers.push(i as u32);
            }
            if b.behavior != Behavior::None {
                self.behaving.push(i as u32);
            }
            if b.collided {
                self.flagged.push(i as u32);
            }
        }
    }

    // ---- stepping ------------------------------------------------------------------

    /// Advances the world by one fixed step.
    ///
    /// With the chapter's relaxation and one sub-step this is the chapter's order: move
    /// bodies, move particles, then every interaction in declaration order. With sub-steps
    /// or the impulse solver, the rigid bodies take their sub-steps first (move and
    /// resolve), then the particles move and meet the shapes where they ended.
    pub fn step(&mut self) {
        let mut stats = StepStats::default();
        for &i in &self.flagged {
            self.bodies[i as usize].collided = false;
        }
        self.flagged.clear();
        if !self.config.sleeping {
            self.wake_all();
        }
        if self.sleeping > 0 {
            sleep::freeze(&mut self.bodies, &self.movers);
        }
        self.run_behaviors();
        let dt = self.config.dt;
        let chapter_order = self.config.solver == Solver::Relaxation && self.config.substeps == 1;
        if chapter_order {
            integrate_bodies(&mut self.bodies, &self.movers, &self.config, dt);
            self.sweep_fast_bodies(dt);
            self.explode_dye_packs_on_hero();
            self.move_particles();
            self.run_interactions(&mut stats, true, true, dt);
        } else {
            let n = self.config.substeps.max(1);
            match self.config.solver {
                Solver::Relaxation => {
                    let h = dt / n as f64;
                    for _ in 0..n {
                        integrate_bodies(&mut self.bodies, &self.movers, &self.config, h);
                        self.sweep_fast_bodies(h);
                        self.run_interactions(&mut stats, true, false, h);
                    }
                }
                Solver::Impulses => self.solve_impulses(&mut stats, dt),
            }
            self.explode_dye_packs_on_hero();
            self.move_particles();
            self.run_interactions(&mut stats, false, true, dt);
        }
        if self.sleeping > 0 {
            sleep::thaw(&mut self.bodies, &self.movers);
        }
        if self.config.sleeping {
            self.update_sleep();
        }
        stats.sleeping = self.sleeping;
        stats.kinetic_energy = self.kinetic_energy();
        self.stats = stats;
        self.frame += 1;
    }

    /// With `ccd`, stops fast bodies at the first shape of their interactions they would
    /// have passed through this step.
    fn sweep_fast_bodies(&mut self, dt: f64) {
        if !self.config.ccd {
            return;
        }
        let (groups, interactions, bodies) = (&self.groups, &self.interactions, &mut self.bodies);
        let group_of: Vec<GroupId> = self
            .movers
            .iter()
            .map(|&i| bodies[i as usize].group)
            .collect();
        let movers = &self.movers;
        let stopped = ccd::sweep_fast_bodies(bodies, movers, dt, |i| {
            let g = group_of[movers.iter().position(|&m| m == i).expect("a mover")];
            let mut out = Vec::new();
            for inter in interactions.iter().filter(|it| it.resolve) {
                match (inter.a, inter.b) {
                    (Side::Group(a), Side::Group(b)) if a == g => {
                        out.extend_from_slice(&groups[b as usize].members)
                    }
                    (Side::Group(a), Side::Group(b)) if b == g => {
                        out.extend_from_slice(&groups[a as usize].members)
                    }
                    _ => {}
                }
            }
            out
        });
        if stopped > 0 {
            let bodies = &self.bodies;
            self.flagged
                .extend(self.movers.iter().filter(|&&i| bodies[i as usize].collided));
        }
    }

    /// Joins touching bodies into islands and puts resting islands to sleep.
    fn update_sleep(&mut self) {
        let dt = self.config.dt;
        let mut pairs = Vec::new();
        let mut some = Vec::new();
        for k in 0..self.interactions.len() {
            let inter = self.interactions[k];
            if let (Side::Group(a), Side::Group(b), true) = (inter.a, inter.b, inter.resolve) {
                self.candidates(a, b, dt, &mut some);
                pairs.extend_from_slice(&some);
            }
        }
        let (speed, delay) = (self.config.sleep_speed, self.config.sleep_delay);
        self.sleeping = sleep::update(&mut self.bodies, &self.movers, &pairs, dt, speed, delay);
    }

    /// Wakes every sleeping body.
    fn wake_all(&mut self) {
        if self.sleeping == 0 {
            return;
        }
        for &i in &self.movers {
            sleep::wake(&mut self.bodies[i as usize]);
        }
        self.sleeping = 0;
    }

    /// Moves every particle, removing the expired, then emits.
    fn move_particles(&mut self) {
        if !self.particles.is_empty() {
            self.particles.update(self.config.dt as f32);
        }
        self.run_emitters();
    }

    /// The declared interactions in order: the rigid ones by relaxation (if `rigid`), the
    /// particle ones by projection (if `particles`).
    fn run_interactions(&mut self, stats: &mut StepStats, rigid: bool, particles: bool, dt: f64) {
        let params = RelaxationParams {
            iterations: self.config.relaxation_iterations,
            correction_rate: self.config.correction_rate,
        };
        for k in 0..self.interactions.len() {
            let inter = self.interactions[k];
            match (inter.a, inter.b) {
                (Side::Group(a), Side::Group(b)) if rigid => {
                    if self.groups[a as usize].members.is_empty()
                        || self.groups[b as usize].members.is_empty()
                    {
                        continue;
                    }
                    let report = if !inter.resolve {
                        let (ga, gb) = (
                            &self.groups[a as usize].members,
                            &self.groups[b as usize].members,
                        );
                        relaxation::detect_only(&mut self.bodies, ga, gb)
                    } else {
                        match self.config.broad_phase {
                            BroadPhase::AllPairs => {
                                let (ga, gb) = (
                                    &self.groups[a as usize].members,
                                    &self.groups[b as usize].members,
                                );
                                relaxation::relax(&mut self.bodies, ga, gb, params)
                            }
                            BroadPhase::Sweep | BroadPhase::Grid => {
                                let mut pairs = std::mem::take(&mut self.pairs);
                                self.candidates(a, b, dt, &mut pairs);
                                let report =
                                    relaxation::relax_pairs(&mut self.bodies, &pairs, params);
                                self.pairs = pairs;
                                report
                            }
                        }
                    };
                    stats.contacts += report.contacts;
                    stats.relaxation_iterations += report.iterations as u64;
                    stats.deepest_penetration = stats.deepest_penetration.max(report.deepest);
                }
                (Side::Group(g), Side::Particles) | (Side::Particles, Side::Group(g))
                    if particles =>
                {
                    if self.particles.is_empty() || !inter.resolve {
                        continue;
                    }
                    let members = &self.groups[g as usize].members;
                    let shapes: Vec<ParticleShape> = members
                        .iter()
                        .map(|&i| {
                            let body = &self.bodies[i as usize];
                            let centre = body.pos.as_vec2();
                            match body.shape {
                                Shape::Rect { half } => ParticleShape::Rect {
                                    centre,
                                    half: half.as_vec2(),
                                },
                                Shape::Circle { radius } => ParticleShape::Circle {
                                    centre,
                                    radius: radius as f32,
                                },
                            }
                        })
                        .collect();
                    // Many shapes: bin them so each particle meets only its neighbours
                    // (same result as shape after shape, tested); a few: shape after shape.
                    let grid = if shapes.len() >= PARTICLE_GRID_MIN_SHAPES {
                        ShapeGrid::build(shapes.clone())
                    } else {
                        None
                    };
                    stats.particle_contacts += match grid {
                        Some(grid) => self.particles.project_out_of_grid(&grid),
                        None => shapes
                            .iter()
                            .map(|s| match *s {
                                ParticleShape::Rect { centre, half } => {
                                    self.particles.project_out_of_rect(centre, half)
                                }
                                ParticleShape::Circle { centre, radius } => {
                                    self.particles.project_out_of_circle(centre, radius)
                                }
                            })
                            .sum(),
                    };
                }
                _ => {}
            }
        }
    }

    /// Candidate pairs of the interaction between groups `a` and `b`, in all-pairs order:
    /// from the grid broad phase's kept pairs; or, with the sweep, against a large
    /// all-static group from its cached grid, otherwise by sweep and prune.
    fn candidates(&mut self, a: GroupId, b: GroupId, dt: f64, out: &mut Vec<(u32, u32)>) {
        if self.config.broad_phase == BroadPhase::Grid {
            self.grid_candidates(a, b, dt, out);
            return;
        }
        if a != b {
            for (fixed, moving, static_first) in [(b, a, false), (a, b, true)] {
                if self.static_grid(fixed) {
                    let grid = self.static_grids[fixed as usize]
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
        sweep_pairs(&self.bodies, ga, gb, a == b, dt, &mut self.sweep, out);
    }

    /// Whether group `g` has a static grid now (building it if the layout changed).
    fn static_grid(&mut self, g: GroupId) -> bool {
        let g = g as usize;
        if self.static_grids.len() <= g {
            self.static_grids.resize_with(g + 1, || (0, None));
        }
        if self.static_grids[g].0 != self.layout_revision {
            let members = &self.groups[g].members;
            let eligible = members.len() > STATIC_GRID_MIN_MEMBERS
                && members.iter().all(|&i| {
                    self.bodies[i as usize].is_static() && self.bodies[i as usize].asleep.is_none()
                });
            let grid =
                eligible.then(|| StaticGrid::build(&self.bodies, members, self.layout_revision));
            self.static_grids[g] = (self.layout_revision, grid);
        }
        self.static_grids[g].1.is_some()
    }

    /// The group pairs of the resolving interactions between groups.
    fn resolving(&self) -> Vec<(GroupId, GroupId)> {
        self.interactions
            .iter()
            .filter_map(|it| match (it.a, it.b, it.resolve) {
                (Side::Group(a), Side::Group(b), true) => Some((a, b)),
                _ => None,
            })
            .collect()
    }

    /// Brings the grid broad phase's persistent pairs up to date.
    fn update_pair_set(&mut self, dt: f64) {
        let resolving = self.resolving();
        self.pair_set.update(
            &self.bodies,
            self.layout_revision,
            &resolving,
            &self.movers,
            dt,
        );
    }

    /// Candidate pairs of the interaction between groups `a` and `b` from the grid broad
    /// phase, in all-pairs order (group members are in body order).
    fn grid_candidates(&mut self, a: GroupId, b: GroupId, dt: f64, out: &mut Vec<(u32, u32)>) {
        self.update_pair_set(dt);
        out.clear();
        let bodies = &self.bodies;
        for p in &self.pair_set.pairs {
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

    /// One frame of the impulse solver (all its sub-steps) over the contacts of every rigid
    /// interaction.
    fn solve_impulses(&mut self, stats: &mut StepStats, h: f64) {
        let mut all = std::mem::take(&mut self.pairs);
        let mut some = std::mem::take(&mut self.sweep_out);
        all.clear();
        for k in 0..self.interactions.len() {
            let inter = self.interactions[k];
            let (Side::Group(a), Side::Group(b)) = (inter.a, inter.b) else {
                continue;
            };
            let (ga, gb) = (
                &self.groups[a as usize].members,
                &self.groups[b as usize].members,
            );
            if ga.is_empty() || gb.is_empty() {
                continue;
            }
            if !inter.resolve {
                let report = relaxation::detect_only(&mut self.bodies, ga, gb);
                stats.contacts += report.contacts;
                continue;
            }
            match self.config.broad_phase {
                BroadPhase::AllPairs => {
                    for &i in ga {
                        all.extend(gb.iter().filter(|&&j| j != i).map(|&j| (i, j)));
                    }
                }
                BroadPhase::Sweep => {
                    self.candidates(a, b, h, &mut some);
                    all.extend_from_slice(&some);
                }
                BroadPhase::Grid => {}
            }
        }
        self.sweep_out = some;
        let config = &self.config;
        let params = ImpulseParams {
            iterations: config.impulse_iterations,
            relax_iterations: config.relax_iterations,
            warm_starting: config.warm_starting,
            baumgarte: config.baumgarte,
            slop: config.slop,
            contact_hertz: config.contact_hertz,
            contact_damping: config.contact_damping,
            split_impulses: config.split_impulses,
            dt: h,
            substeps: config.substeps,
        };
        let grid = config.broad_phase == BroadPhase::Grid;
        let mut pairs = if grid {
            self.update_pair_set(h);
            std::mem::take(&mut self.pair_set.pairs)
        } else {
            let mut pairs = std::mem::take(&mut self.solver_pairs);
            self.contact_cache.pairs(&self.bodies, &mut all, &mut pairs);
            pairs
        };
        let config = &self.config;
        let report = impulse::solve_frame(
            &mut self.bodies,
            &mut pairs,
            params,
            &mut self.solver_buffers,
            &self.movers,
            |b| integrate::acceleration(b, config),
            &mut self.flagged,
        );
        if grid {
            self.pair_set.pairs = pairs;
        } else {
            self.contact_cache.store(&self.bodies, &pairs);
            self.solver_pairs = pairs;
        }
        stats.contacts += report.contacts;
        stats.relaxation_iterations +=
            ((config.impulse_iterations + config.relax_iterations) * config.substeps) as u64;
        stats.deepest_penetration = stats.deepest_penetration.max(report.deepest);
        self.pairs = all;
    }

    /// Runs `n` steps.
    pub fn step_n(&mut self, n: u64) {
        for _ in 0..n {
            self.step();
        }
    }

    /// The first hero's index.
    fn hero(&self) -> Option<usize> {
        self.behaving
            .iter()
            .map(|&i| i as usize)
            .find(|&i| matches!(self.bodies[i].behavior, Behavior::Hero { .. }))
    }

    fn hero_pos(&self) -> Option<DVec2> {
        self.hero().map(|i| self.bodies[i].pos)
    }

    fn run_behaviors(&mut self) {
        let dt = self.config.dt;
        let hero = self.hero_pos();
        let mut expired_packs = false;
        for &i in &self.behaving {
            let b = &mut self.bodies[i as usize];
            let movable = !b.is_static();
            match &mut b.behavior {
                Behavior::None | Behavior::DumbMinion => {}
                Behavior::Hero { held } => {
                    if movable {
                        b.vel += held.push() * dt;
                    }
                }
                Behavior::Patrol { speed, dir } => {
                    // A collision that reversed the motion turns the patrol back.
                    if b.vel.x != 0.0 && b.vel.x.signum() != *dir {
                        *dir = b.vel.x.signum();
                    }
                    b.vel = DVec2::new(*dir * *speed, 0.0);
                }
                Behavior::DyePack { heading, life } => {
                    if let Some(target) = hero {
                        *heading = behavior::turn_toward(
                            *heading,
                            target - b.pos,
                            behavior::DYE_PACK_TURN_RATE,
                        );
                    }
                    b.pos += *heading * (behavior::DYE_PACK_SPEED * dt);
                    *life = life.saturating_sub(1);
                    expired_packs |= *life == 0;
                }
            }
        }
        if expired_packs {
            self.remove_bodies(|b| matches!(b.behavior, Behavior::DyePack { life: 0, .. }));
        }
    }

    /// Dye packs touching the hero are removed, each starting an explosion where it was.
    fn explode_dye_packs_on_hero(&mut self) {
        let Some(hero) = self.hero() else {
            return;
        };
        let (hero_shape, hero_pos) = (self.bodies[hero].shape, self.bodies[hero].pos);
        let hits: Vec<BodyKey> = self
            .behaving
            .iter()
            .map(|&i| &self.bodies[i as usize])
            .filter(|b| matches!(b.behavior, Behavior::DyePack { .. }))
            .filter(|b| collide(&hero_shape, hero_pos, &b.shape, b.pos).is_some())
            .map(|b| b.key)
            .collect();
        if hits.is_empty() {
            return;
        }
        for key in &hits {
            let pos = self
                .bodies
                .iter()
                .find(|b| b.key == *key)
                .expect("hit is alive")
                .pos;
            if self
                .presets
                .get(behavior::DYE_PACK_EXPLOSION_PRESET)
                .is_some()
            {
                self.emitters.push(Emitter {
                    pos: pos.as_vec2(),
                    remaining: behavior::DYE_PACK_EXPLOSION,
                    preset: behavior::DYE_PACK_EXPLOSION_PRESET.to_string(),
                });
            }
        }
        self.remove_bodies(|b| hits.contains(&b.key));
    }

    fn run_emitters(&mut self) {
        if self.emitters.is_empty() {
            return;
        }
        let gravity = self.config.particle_gravity.as_vec2();
        for e in &mut self.emitters {
            let n = e.take_batch(&mut self.rng);
            let preset = self
                .presets
                .get(&e.preset)
                .expect("emitter presets are checked when added");
            for _ in 0..n {
                let def = preset.spawn(e.pos, &mut self.rng);
                self.particles.push(&def, gravity);
            }
        }
        self.emitters.retain(|e| !e.expired());
    }

    // ---- actions -------------------------------------------------------------------

    /// Applies an action between steps. A refused action changes nothing.
    pub fn apply(&mut self, action: &Action) -> Result<ActionOutcome, ActionError> {
        // Anything that moves bodies or changes the world's parameters wakes it.
        if !matches!(
            action,
            Action::Press { .. }
                | Action::Release { .. }
                | Action::Select { .. }
                | Action::Deselect
        ) {
            self.wake_all();
        }
        let point = |field: &'static str, p: [f64; 2]| -> Result<DVec2, ActionError> {
            let v = DVec2::from(p);
            if v.is_finite() && v.abs().max_element() <= crate::dynamics::body::MAX_COORDINATE {
                Ok(v)
            } else {
                Err(ActionError::BadArgument {
                    field,
                    reason: format!(
                        "{v} must be finite and within ±{}",
                        crate::dynamics::body::MAX_COORDINATE
                    ),
                })
            }
        };
        let none = Ok(ActionOutcome::default());
        match action {
            Action::Press { dir } | Action::Release { dir } => {
                let pressed = matches!(action, Action::Press { .. });
                let hero = self
                    .bodies
                    .iter_mut()
                    .find_map(|b| match &mut b.behavior {
                        Behavior::Hero { held } => Some(held),
                        _ => None,
                    })
                    .ok_or(ActionError::NoHero)?;
                hero.set(*dir, pressed);
                none
            }
            Action::FireDyePack { at } => {
                let at = point("at", *at)?;
                let id = self.fresh_id("dye_pack");
                self.spawn(BodyDef {
                    id: id.clone(),
                    group: "dye_packs".into(),
                    shape: Shape::circle(behavior::DYE_PACK_RADIUS),
                    pos: at,
                    mass: behavior::DYE_PACK_MASS,
                    gravity: Some(DVec2::ZERO),
                    behavior: Behavior::DyePack {
                        heading: DVec2::Y,
                        life: behavior::DYE_PACK_LIFE,
                    },
                    ..BodyDef::default()
                })
            }
            Action::SpawnMinion { at, shape } => {
                let at = point("at", *at)?;
                let shape = match shape.as_deref() {
                    None | Some("circle") => Shape::circle(behavior::MINION_RADIUS),
                    Some("rect") => Shape::rect(behavior::MINION_RECT.x, behavior::MINION_RECT.y),
                    Some(other) => {
                        return Err(ActionError::BadArgument {
                            field: "shape",
                            reason: format!("`{other}` is not \"circle\" or \"rect\""),
                        })
                    }
                };
                let dir = if self.rng.random::<bool>() { 1.0 } else { -1.0 };
                let id = self.fresh_id("minion");
                self.spawn(BodyDef {
                    id,
                    group: "minions".into(),
                    shape,
                    pos: at,
                    vel: DVec2::new(dir * behavior::MINION_SPEED, 0.0),
                    mass: behavior::MINION_MASS,
                    friction: 0.0,
                    gravity: Some(DVec2::ZERO),
                    behavior: Behavior::Patrol {
                        speed: behavior::MINION_SPEED,
                        dir,
                    },
                    ..BodyDef::default()
                })
            }
            Action::SpawnDumbMinion { at } => {
                let at = point("at", *at)?;
                let shape = if self.rng.random::<bool>() {
                    Shape::circle(behavior::MINION_RADIUS)
                } else {
                    Shape::rect(behavior::MINION_RECT.x, behavior::MINION_RECT.y)
                };
                let id = self.fresh_id("dumb_minion");
                self.spawn(BodyDef {
                    id,
                    group: "dumb_minions".into(),
                    shape,
                    pos: at,
                    behavior: Behavior::DumbMinion,
                    ..BodyDef::default()
                })
            }
            Action::Select { at, group } => {
                let at = point("at", *at)?;
                let group = match group {
                    Some(name) => Some(
                        self.group(name)
                            .ok_or_else(|| ActionError::UnknownGroup(name.clone()))?,
                    ),
                    None => None,
                };
                // The last body drawn over the point wins: the one on top.
                let hit = self
                    .bodies
                    .iter()
                    .rev()
                    .filter(|b| group.map_or(!b.is_static(), |g| b.group == g))
                    .find(|b| b.shape.contains(b.pos, at) || b.pos == at);
                self.selected = hit.map(|b| b.key);
                Ok(ActionOutcome {
                    ids: hit.map(|b| vec![b.id.clone()]).unwrap_or_default(),
                })
            }
            Action::Drag { to } => {
                let to = point("to", *to)?;
                let key = self.selected.ok_or(ActionError::NothingSelected)?;
                let body = self
                    .bodies
                    .iter_mut()
                    .find(|b| b.key == key)
                    .ok_or(ActionError::NothingSelected)?;
                body.pos = to;
                body.vel = DVec2::ZERO;
                if body.is_static() && body.asleep.is_none() {
                    self.layout_revision += 1;
                    self.statics_revision += 1;
                }
                Ok(ActionOutcome {
                    ids: vec![body.id.clone()],
                })
            }
            Action::Deselect => {
                self.selected = None;
                none
            }
            Action::Agitate { strength } => {
                let s = strength.unwrap_or(behavior::DEFAULT_AGITATION);
                if !(0.0..=crate::dynamics::body::MAX_COORDINATE).contains(&s) {
                    return Err(ActionError::BadArgument {
                        field: "strength",
                        reason: format!("{s} must be a finite number, 0 or above"),
                    });
                }
                let mut ids = Vec::new();
                for b in &mut self.bodies {
                    if matches!(b.behavior, Behavior::DumbMinion) && !b.is_static() {
                        let kick = DVec2::new(
                            self.rng.random_range(-1.0..=1.0),
                            self.rng.random_range(-1.0..=1.0),
                        );
                        b.vel += kick * s;
                        ids.push(b.id.clone());
                    }
                }
                Ok(ActionOutcome { ids })
            }
            Action::Clear { group } => {
                let g = self
                    .group(group)
                    .ok_or_else(|| ActionError::UnknownGroup(group.clone()))?;
                let ids = self
                    .bodies
                    .iter()
                    .filter(|b| b.group == g)
                    .map(|b| b.id.clone())
                    .collect();
                self.remove_bodies(|b| b.group == g);
                Ok(ActionOutcome { ids })
            }
            Action::SpawnParticles { preset, at, count } => {
                let at = point("at", *at)?.as_vec2();
                check_count(*count)?;
                let gravity = self.config.particle_gravity.as_vec2();
                let recipe = self
                    .presets
                    .get(preset)
                    .ok_or_else(|| self.unknown_preset(preset))?;
                for _ in 0..*count {
                    let def = recipe.spawn(at, &mut self.rng);
                    self.particles.push(&def, gravity);
                }
                none
            }
            Action::StartEmitter { preset, count, at } => {
                let at = point("at", *at)?.as_vec2();
                check_count(*count)?;
                if self.presets.get(preset).is_none() {
                    return Err(self.unknown_preset(preset));
                }
                self.emitters.push(Emitter {
                    pos: at,
                    remaining: *count,
                    preset: preset.clone(),
                });
                none
            }
            Action::Set { name, value } => {
                let value: toml::Value = serde_json::from_value(value.clone()).map_err(|e| {
                    ActionError::BadArgument {
                        field: "value",
                        reason: format!("{value} is not a parameter value: {e}"),
                    }
                })?;
                let before = self.config.seed;
                self.config.set(name, &value)?;
                if self.config.seed != before {
                    self.rng = ChaCha8Rng::seed_from_u64(self.config.seed);
                }
                none
            }
        }
    }

    fn spawn(&mut self, def: BodyDef) -> Result<ActionOutcome, ActionError> {
        let id = def.id.clone();
        self.add_body(def).map_err(|e| ActionError::BadArgument {
            field: "at",
            reason: e.to_string(),
        })?;
        Ok(ActionOutcome { ids: vec![id] })
    }

    fn unknown_preset(&self, name: &str) -> ActionError {
        ActionError::UnknownPreset {
            name: name.to_string(),
            known: self.presets.names().collect::<Vec<_>>().join(", "),
        }
    }
}

fn check_count(count: u32) -> Result<(), ActionError> {
    if count > MAX_PARTICLES_PER_ACTION {
        return Err(ActionError::BadArgument {
            field: "count",
            reason: format!("{count} is more than {MAX_PARTICLES_PER_ACTION} particles at once"),
        });
    }
    Ok(())
}
