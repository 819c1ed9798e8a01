//! The world: bodies in groups, particles, emitters, the declared interactions, one
//! seeded random generator, and the step that ties them together.
//!
//! A step is one list of stages (see [`World::step`]): sleepers frozen, the game rules
//! before the motion, the broad phase (when the solver takes all pairs at once), the
//! rigid stage (bodies move and their contacts are resolved, the game rules after the
//! motion at the point the solver's order puts them), particles and emitters, the
//! particle interactions, sleeping, the energies. The solver decides what the rigid
//! stage does inside, never the order. Nothing is computed for what no interaction names.
//!
//! In: scene definitions (bodies, particles, emitters, interactions) and typed actions
//! between steps. Out: the state after each step, the step's figures ([`StepStats`]) and
//! what its stages took ([`StepProfile`]). The files split it by concept: `store` (adding
//! and removing bodies, groups, ids), `step` (the stages), `candidates` (which broad phase
//! yields a group pair's candidates), `demo` (the chapter demo's game rules, at the
//! step's hook points), `actions` (what clients do), `checkpoint` (the state as bytes),
//! `profile` (the stages' wall-clock times).

use crate::geometry::grid::KeyMap;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use crate::behavior::Behavior;
use crate::dynamics::body::{Body, BodyKey, GroupId};
use crate::dynamics::broad_phase::{StaticGrid, SweepBuffers};
use crate::dynamics::config::WorldConfig;
use crate::dynamics::impulse::SolverBuffers;
use crate::dynamics::pairs::{Contacts, Pair, PairSet};
use crate::particles::{Emitter, Particles, PresetLibrary};

mod actions;
mod candidates;
mod checkpoint;
mod demo;
mod limits;
mod profile;
mod step;
mod store;
mod validate;

pub use checkpoint::{CheckpointError, CHECKPOINT_VERSION};
pub use limits::{short, LimitError, Limits, REAL_TIME_STEP_WORK};
pub use profile::StepProfile;

/// Particle interactions with at least this many shapes bin them in a grid.
pub const PARTICLE_GRID_MIN_SHAPES: usize = 8;

/// One side of an interaction: a group of bodies or the particle system.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Side {
    Group(GroupId),
    Particles,
}

/// A declared interaction, tested every step in declaration order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Interaction {
    pub a: Side,
    pub b: Side,
    /// false: collisions are only flagged (the bounds demo), nothing moves.
    pub resolve: bool,
}

/// The name a scene uses for the particle side of an interaction.
pub const PARTICLES: &str = "particles";

/// A named group and its members (indices into the body array, in body order).
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
struct Group {
    name: String,
    members: Vec<u32>,
}

/// What users and the demo know a body by, read rarely: kept apart from the solver's
/// [`Body`] (at the same index in [`World::infos`]) so the step streams through hot data
/// only.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct BodyInfo {
    /// The name reported in frames and dumps; unique in a world.
    pub id: String,
    pub behavior: Behavior,
}

/// What one step did: the figures a frame reports.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct StepStats {
    /// Rigid pair resolutions (or detections, in detect-only interactions).
    pub contacts: u64,
    /// Solver passes run, counted as they run: the relaxation solver's passes summed over
    /// interactions (it stops early once a pass finds no overlap), or the impulse
    /// solver's velocity passes over all sub-steps.
    pub solver_passes: u64,
    /// Deepest rigid penetration detected.
    pub deepest_penetration: f64,
    /// Particles projected out of shapes.
    pub particle_contacts: u64,
    /// Kinetic energy of the rigid bodies after the step.
    pub kinetic_energy: f64,
    /// Bodies asleep after the step.
    pub sleeping: u64,
    /// Mechanical energy of the dynamic bodies after the step: kinetic plus the potential
    /// of their constant acceleration (`-m a·p`).
    pub energy: f64,
    /// `energy` minus its value after the previous step (or at the world's start), actions
    /// between the steps included: what the step (and the solver) gained or lost.
    pub energy_change: f64,
    /// What the last solver pass of the step still corrected, as a distance: under the
    /// relaxation solver the deepest overlap its last pass found (0 when it stopped because
    /// none was left), under the impulse solver the largest normal velocity change of its
    /// last velocity pass times the sub-step. Near 0: the passes converged.
    pub residual: f64,
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
    #[error(transparent)]
    Limit(#[from] LimitError),
}

/// A simulated world.
/// A checkpoint ([`World::save`]) holds every field but the scratch space the next step
/// rebuilds.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct World {
    pub config: WorldConfig,
    /// What the world may hold and a step may cost.
    limits: Limits,
    /// The bodies' hot data, and their ids and behaviours at the same indices.
    bodies: Vec<Body>,
    infos: Vec<BodyInfo>,
    groups: Vec<Group>,
    interactions: Vec<Interaction>,
    particles: Particles,
    emitters: Vec<Emitter>,
    presets: PresetLibrary,
    /// Bodies the scene names for `spawn` (its `[[template]]` tables), by name.
    #[serde(default)]
    templates: std::collections::BTreeMap<String, crate::action::BodySpec>,
    rng: ChaCha8Rng,
    frame: u64,
    next_key: u32,
    spawned: u64,
    selected: Option<BodyKey>,
    stats: StepStats,
    statics_revision: u64,
    /// Changes whenever bodies are added or removed or a static body is moved.
    layout_revision: u64,
    /// Indices of the dynamic bodies, and of the bodies with a behaviour: what a step
    /// walks, so static bodies cost nothing unless something touches them.
    movers: Vec<u32>,
    behaving: Vec<u32>,
    /// Bodies flagged collided in the last step, to clear at the next.
    flagged: Vec<u32>,
    /// The solver's pairs and their warm starts, whatever the broad phase.
    contacts: Contacts,
    /// The grid broad phase's fat boxes, which keep `contacts` from step to step.
    pair_set: PairSet,
    /// The impulse solver's blocks (state: when they are cut again depends on the frames
    /// since the last cut) and its buffers (scratch, left out of checkpoints).
    solver_buffers: SolverBuffers,
    /// Where each body is in `bodies`, by id and by key: O(1) handles, rebuilt when
    /// bodies are removed (which moves the ones after them).
    by_id: KeyMap<String, u32>,
    by_key: KeyMap<BodyKey, u32>,
    /// Bodies asleep after the last step.
    sleeping: u64,
    /// The mechanical energy after the last step (`None` before the first).
    last_energy: Option<f64>,
    #[serde(skip)]
    scratch: Scratch,
    /// What the last step's stages took by the wall clock (not state: measured, never
    /// read by the simulation).
    #[serde(skip)]
    profile: StepProfile,
    /// Whether steps time their stages ([`World::set_profiling`]).
    #[serde(skip)]
    profiling: bool,
}

/// What a step fills and reads again, kept between steps only to spare allocations or as
/// caches rebuilt on demand: not state, left out of checkpoints (a restored world
/// rebuilds it and continues with the same bits).
#[derive(Clone, Debug, Default)]
struct Scratch {
    /// The sweep and prune's buffers.
    sweep: SweepBuffers,
    /// Per group: the layout revision it was last looked at for, and its static grid if
    /// it is all static and large.
    static_grids: Vec<(u64, Option<StaticGrid>)>,
    /// The candidate pairs the last [`World::broad_phase`] found (sweep and all pairs).
    candidates: Vec<(u32, u32)>,
    /// One interaction's candidate pairs.
    interaction_pairs: Vec<(u32, u32)>,
    /// The group pairs of the resolving interactions, for the grid.
    resolving: Vec<(GroupId, GroupId)>,
    /// Last step's contacts while sweep or all pairs refill the contacts.
    last_contacts: Vec<Pair>,
    /// Each moving body's place at the start of the step (kept only with sleeping on).
    step_start: Vec<(u32, glam::DVec2)>,
    /// The energies (kinetic, mechanical) of a world that rested whole at the last step
    /// (see [`World::dormant`]): nothing moved since, so they are the same.
    dormant_energies: Option<(f64, f64)>,
    /// What the islands of sleeping brought the pair set up to date for after the last
    /// step, when the next step's own broad phase would find nothing to change: while it
    /// still matches, that broad phase is skipped (see [`World::find_contacts`]).
    fresh_pairs: Option<step::FreshPairs>,
}

impl World {
    /// An empty world with the given parameters, the default [`Limits`] and the built-in
    /// presets.
    pub fn new(config: WorldConfig) -> Self {
        Self::with_limits(config, Limits::default())
    }

    /// An empty world with the given parameters and limits, and the built-in presets.
    pub fn with_limits(config: WorldConfig, limits: Limits) -> Self {
        let rng = ChaCha8Rng::seed_from_u64(config.seed);
        World {
            config,
            limits,
            bodies: Vec::new(),
            infos: Vec::new(),
            groups: Vec::new(),
            interactions: Vec::new(),
            particles: Particles::default(),
            emitters: Vec::new(),
            presets: PresetLibrary::built_in(),
            templates: Default::default(),
            rng,
            frame: 0,
            next_key: 0,
            spawned: 0,
            selected: None,
            stats: StepStats::default(),
            statics_revision: 0,
            layout_revision: 1,
            movers: Vec::new(),
            behaving: Vec::new(),
            flagged: Vec::new(),
            last_energy: None,
            contacts: Contacts::default(),
            pair_set: PairSet::default(),
            solver_buffers: SolverBuffers::default(),
            by_id: Default::default(),
            by_key: Default::default(),
            sleeping: 0,
            scratch: Scratch::default(),
            profile: StepProfile::default(),
            profiling: false,
        }
    }

    // ---- reading -------------------------------------------------------------------

    /// Steps taken so far.
    pub fn frame(&self) -> u64 {
        self.frame
    }

    /// A 64-bit hash (XXH3) of the world's state: the frame, every body's position,
    /// velocity and whether it sleeps, every particle's position, velocity, life and size,
    /// the number of contacts and the random generator's place. A restored or replayed run
    /// compares its hashes with the original's frame by frame: the same hashes, the same
    /// run (but for a collision, about one in 2^64). The contacts' warm starts are left
    /// out (hashing them cost a sixth of a step on a large pile): a difference in them
    /// moves the bodies, and shows in the next frame's hash. Costs a pass over the bodies
    /// and the particles' columns.
    pub fn state_hash(&self) -> u64 {
        let mut h = xxhash_rust::xxh3::Xxh3::new();
        h.update(&self.frame.to_le_bytes());
        h.update(&(self.bodies.len() as u64).to_le_bytes());
        // Gathered into one buffer and hashed at once: a call per number would cost a
        // third of a step on a large pile.
        let mut words: Vec<u64> = Vec::with_capacity(5 * self.bodies.len());
        for b in &self.bodies {
            words.extend([b.pos.x, b.pos.y, b.vel.x, b.vel.y].map(f64::to_bits));
            words.push(u64::from(b.asleep.is_some()));
        }
        h.update(bytemuck::cast_slice(&words));
        let p = &self.particles;
        h.update(&(p.x.len() as u64).to_le_bytes());
        for column in [&p.x, &p.y, &p.vx, &p.vy, &p.life, &p.size] {
            h.update(bytemuck::cast_slice::<f32, u8>(column));
        }
        h.update(&(self.contacts.pairs.len() as u64).to_le_bytes());
        h.update(&self.rng.get_word_pos().to_le_bytes());
        h.digest()
    }

    /// About how many bytes of memory the world takes (its bodies, ids, particles,
    /// contacts and solver state by their counts): what a copy of it costs to keep.
    pub fn memory_estimate(&self) -> usize {
        use std::mem::size_of;
        let ids: usize = self.infos.iter().map(|i| i.id.len() + 64).sum();
        self.bodies.len() * (size_of::<crate::dynamics::Body>() + 24)
            + ids
            + self.particles.len() * 64
            + self.contacts.pairs.len() * (size_of::<crate::dynamics::pairs::Pair>() + 16)
            + 4096
    }

    /// Simulated seconds so far.
    pub fn time(&self) -> f64 {
        self.frame as f64 * self.config.dt
    }

    /// The bodies' solver data, in body order.
    pub fn bodies(&self) -> &[Body] {
        &self.bodies
    }

    /// The bodies' ids and behaviours, at the same indices as [`World::bodies`].
    pub fn infos(&self) -> &[BodyInfo] {
        &self.infos
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

    /// What the world may hold and a step may cost.
    pub fn limits(&self) -> &Limits {
        &self.limits
    }

    /// How many more bodies the `bodies` limit allows.
    pub fn room_for_bodies(&self) -> u64 {
        (self.limits.bodies as u64).saturating_sub(self.bodies.len() as u64)
    }

    /// Particles alive plus those still to come from running emitters: what the
    /// `particles` limit bounds.
    pub fn particles_committed(&self) -> u64 {
        self.particles.len() as u64
            + self
                .emitters
                .iter()
                .map(|e| e.remaining as u64)
                .sum::<u64>()
    }

    /// The figures of the last step.
    pub fn stats(&self) -> StepStats {
        self.stats
    }

    /// Times each stage of the steps from now on ([`World::profile`]), or stops: a
    /// world that is not profiled reads no clock in its step. Changes no simulated bit.
    pub fn set_profiling(&mut self, on: bool) {
        self.profiling = on;
        if !on {
            self.profile = StepProfile::default();
        }
    }

    /// What each stage of the last step took by the wall clock (all zero unless the
    /// world is profiled).
    pub fn profile(&self) -> &StepProfile {
        &self.profile
    }

    pub fn body(&self, id: &str) -> Option<&Body> {
        self.by_id.get(id).map(|&i| &self.bodies[i as usize])
    }

    /// The id and behaviour of the body with this id.
    pub fn info(&self, id: &str) -> Option<&BodyInfo> {
        self.by_id.get(id).map(|&i| &self.infos[i as usize])
    }

    /// The body with this key.
    pub fn body_by_key(&self, key: BodyKey) -> Option<&Body> {
        self.by_key.get(&key).map(|&i| &self.bodies[i as usize])
    }

    /// The id and behaviour of the body with this key.
    pub fn info_by_key(&self, key: BodyKey) -> Option<&BodyInfo> {
        self.by_key.get(&key).map(|&i| &self.infos[i as usize])
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
        self.info_by_key(self.selected?).map(|b| b.id.as_str())
    }

    /// Total kinetic energy of the rigid bodies.
    pub fn kinetic_energy(&self) -> f64 {
        self.movers
            .iter()
            .map(|&i| self.bodies[i as usize].kinetic_energy())
            .sum()
    }

    /// Kinetic plus potential energy of the dynamic bodies (see [`StepStats::energy`]).
    pub fn mechanical_energy(&self) -> f64 {
        self.energies().1
    }

    /// (kinetic, kinetic plus potential) energy of the dynamic bodies, in one pass.
    pub(super) fn energies(&self) -> (f64, f64) {
        let (g, scaled) = (self.config.gravity, self.config.mass_scaled_acceleration);
        let (mut kinetic, mut mechanical) = (0.0, 0.0);
        for &i in &self.movers {
            let b = &self.bodies[i as usize];
            let k = b.kinetic_energy();
            let a = crate::dynamics::integrate::acceleration_under(b, g, scaled);
            kinetic += k;
            mechanical += k - b.mass() * a.dot(b.pos);
        }
        (kinetic, mechanical)
    }
}
