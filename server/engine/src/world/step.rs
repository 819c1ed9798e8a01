//! The step: one list of named stages (see [`World::step`]), in the manner of Box2D's
//! `b2World_Step`. The solver chosen decides what the rigid stage does inside, never the
//! order of the stages; the chapter demo's game rules run at two named points of it
//! ([`HookPoint`]).

use crate::behavior::Behavior;
use crate::dynamics::body::GroupId;
use crate::dynamics::broad_phase::BroadPhase;
use crate::dynamics::ccd;
use crate::dynamics::config::{Integrator, Solver};
use crate::dynamics::impulse::{self, ImpulseParams, ImpulseReport};
use crate::dynamics::integrate::{self, integrate_bodies};
use crate::dynamics::relaxation::{self, Gravity, RelaxationParams, RelaxationReport};
use crate::dynamics::sleep;
use crate::geometry::Shape;
use crate::particles::system::{ParticleShape, ShapeGrid};

use super::demo::HookPoint;
use super::profile::{Laps, StepProfile};
use super::{Side, StepStats, World, PARTICLE_GRID_MIN_SHAPES};

/// What a rigid solver did, as the step's figures count it.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct SolverReport {
    contacts: u64,
    passes: u64,
    deepest: f64,
    residual: f64,
}

impl From<RelaxationReport> for SolverReport {
    fn from(r: RelaxationReport) -> Self {
        SolverReport {
            contacts: r.contacts,
            passes: r.iterations as u64,
            deepest: r.deepest,
            residual: r.residual,
        }
    }
}

impl From<ImpulseReport> for SolverReport {
    fn from(r: ImpulseReport) -> Self {
        SolverReport {
            contacts: r.contacts,
            passes: r.passes,
            deepest: r.deepest,
            residual: r.residual,
        }
    }
}

impl StepStats {
    /// Adds what a rigid solver did to the step's figures.
    pub(super) fn fold(&mut self, report: impl Into<SolverReport>) {
        let r = report.into();
        self.contacts += r.contacts;
        self.solver_passes += r.passes;
        self.deepest_penetration = self.deepest_penetration.max(r.deepest);
        self.residual = self.residual.max(r.residual);
    }
}

/// What the pair set was brought up to date for by the islands of sleeping after a step:
/// the frame of the next step, and what of the world the update reads besides the bodies.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct FreshPairs {
    frame: u64,
    layout_revision: u64,
    dt: f64,
    gravity: glam::DVec2,
    substeps: u32,
    mass_scaled: bool,
    grid: bool,
}

impl World {
    /// Advances the world by one fixed step, stage after stage:
    ///
    /// 1. sleepers are frozen (static to the solvers) and last step's collided flags
    ///    cleared;
    /// 2. the game rules before the motion (the demo's behaviours steer bodies);
    /// 3. the broad phase, when the solver takes every interaction's pairs at once (the
    ///    impulse solver; the relaxation finds each interaction's pairs in the rigid
    ///    stage, after the interactions before it moved bodies);
    /// 4. the rigid stage: bodies move and their contacts are resolved, with the game
    ///    rules after the motion at the point the solver's order puts them (under the
    ///    relaxation at one sub-step, the chapter's order, between the motion and the
    ///    resolution; otherwise once the stage is done);
    /// 5. particles move and emitters emit (they read no body);
    /// 6. the particle interactions, against the shapes where the rigid stage left them;
    /// 7. sleeping: islands of resting bodies go to sleep;
    /// 8. the energies the step's figures report.
    ///
    /// In a profiled world ([`World::set_profiling`]) each stage's wall-clock time is
    /// kept in [`World::profile`]; nothing simulated reads it.
    pub fn step(&mut self) {
        let (mut laps, mut took) = (Laps::start(self.profiling), StepProfile::default());
        let mut stats = StepStats::default();
        let energy_before = self.last_energy.unwrap_or_else(|| self.mechanical_energy());
        // Every body asleep and no rule steering any: nothing rigid can move this step, so
        // neither the broad phase, the rigid stage nor the islands are computed, and no
        // per-body pass runs: the sleepers need no freezing, their energies are those of
        // the last step (an action that moves a body or changes the world wakes them all
        // first; a spawned body is awake).
        let dormant = self.dormant();
        if dormant {
            self.clear_collided();
        } else {
            self.freeze_sleepers();
        }
        took.sleep = laps.lap_if(self.config.sleeping);
        self.game_rules(HookPoint::BeforeMotion);
        took.hooks = laps.lap_if(!self.behaving.is_empty());
        if !dormant {
            self.rigid_broad_phase();
        }
        took.broad_phase = laps.lap_if(self.config.solver == Solver::Impulses && !dormant);
        if !dormant {
            self.rigid_stage(&mut stats);
        }
        took.rigid = laps.lap();
        self.move_particles();
        took.particles_move = laps.lap_if(!self.particles.is_empty() || !self.emitters.is_empty());
        stats.particle_contacts = self.particle_interactions();
        took.particle_interactions = laps.lap_if(!self.particles.is_empty());
        stats.sleeping = if dormant {
            self.sleeping
        } else {
            self.update_sleep()
        };
        took.sleep += laps.lap_if(self.config.sleeping);
        self.energy_stage(&mut stats, energy_before, dormant);
        took.energy = laps.lap();
        took.step = laps.total();
        took.solve = self.solver_buffers.times.take().unwrap_or_default();
        self.stats = stats;
        self.profile = took;
        self.frame += 1;
    }

    /// Runs `n` steps.
    pub fn step_n(&mut self, n: u64) {
        for _ in 0..n {
            self.step();
        }
    }

    /// The step's energies: kinetic and mechanical after it, and the change since the
    /// last step (or the world's start).
    /// A dormant step computes them once for the whole rest: nothing moves in it.
    fn energy_stage(&mut self, stats: &mut StepStats, energy_before: f64, dormant: bool) {
        (stats.kinetic_energy, stats.energy) = match self.scratch.dormant_energies {
            Some(e) if dormant => e,
            _ => self.energies(),
        };
        self.scratch.dormant_energies = dormant.then_some((stats.kinetic_energy, stats.energy));
        stats.energy_change = stats.energy - energy_before;
        self.last_energy = Some(stats.energy);
    }

    /// Whether the world rests whole: sleeping on, every dynamic body asleep, no body
    /// steered by a rule.
    fn dormant(&self) -> bool {
        self.config.sleeping
            && self.behaving.is_empty()
            && !self.movers.is_empty()
            // The count the last step left (0 after anything woke the world): the bodies
            // are read only when it says every one may sleep, and not again while the
            // world stays dormant (whatever wakes a body sets the count to 0).
            && self.sleeping as usize >= self.movers.len()
            && (self.scratch.dormant_energies.is_some()
                || self
                    .movers
                    .iter()
                    .all(|&i| self.bodies[i as usize].asleep.is_some()))
    }

    /// Before the step: last step's collided flags cleared; with sleeping on, sleepers
    /// frozen for the step and each mover's place noted (rest is judged from it after),
    /// with it off, everyone awake.
    fn freeze_sleepers(&mut self) {
        self.clear_collided();
        if !self.config.sleeping {
            self.wake_all();
            return;
        }
        if self.sleeping > 0 {
            sleep::freeze(&mut self.bodies, &self.movers);
        }
        let bodies = &self.bodies;
        self.scratch.step_start.clear();
        self.scratch
            .step_start
            .extend(self.movers.iter().map(|&i| (i, bodies[i as usize].pos)));
    }

    /// Last step's collided flags cleared.
    fn clear_collided(&mut self) {
        for &i in &self.flagged {
            self.bodies[i as usize].collided = false;
        }
        self.flagged.clear();
    }

    /// After the step, with sleeping on: sleepers get their mass back, touching bodies are
    /// joined into islands and resting islands put to sleep. Returns how many bodies
    /// sleep.
    fn update_sleep(&mut self) -> u64 {
        if !self.config.sleeping {
            return self.sleeping;
        }
        if self.sleeping > 0 {
            sleep::thaw(&mut self.bodies, &self.movers);
        }
        let dt = self.config.dt;
        let (speed, delay) = (self.config.sleep_speed, self.config.sleep_delay);
        let infos = &self.infos;
        let may_sleep =
            |i: usize| matches!(infos[i].behavior, Behavior::None | Behavior::DumbMinion);
        let start = &self.scratch.step_start;
        let config = &self.config;
        let accelerated = |b: &crate::dynamics::body::Body| {
            integrate::acceleration(b, config) != glam::DVec2::ZERO
        };
        let depths = if config.solver == Solver::Impulses {
            self.solver_buffers.depths()
        } else {
            &[]
        };
        if !sleep::rest(
            &mut self.bodies,
            &self.movers,
            may_sleep,
            start,
            depths,
            accelerated,
            dt,
            speed,
            delay,
        ) {
            // Nothing sleeps or can: no islands, and no broad phase to find them.
            self.sleeping = 0;
            return 0;
        }
        // Where the bodies are after the step: islands join bodies touching now.
        self.broad_phase(dt);
        let config = &self.config;
        let accelerated = |b: &crate::dynamics::body::Body| {
            integrate::acceleration(b, config) != glam::DVec2::ZERO
        };
        // The pairs the broad phase found, read where they are (no copy a step).
        let pairs = if config.broad_phase == BroadPhase::Grid {
            either::Left(self.contacts.pairs.iter().map(|p| (p.a, p.b)))
        } else {
            either::Right(self.scratch.candidates.iter().copied())
        };
        let slept = sleep::islands(
            &mut self.bodies,
            &self.movers,
            pairs,
            accelerated,
            speed,
            delay,
            dt,
        );
        self.sleeping = slept.sleeping;
        // The next step's own broad phase would look at the bodies as they are now, and
        // find every one inside its box, unless a body put to sleep stopped (its box was
        // placed for its velocity) or a sleeper is pulled (frozen for the step, it is
        // swept as a static body: see `pairs::frame`).
        if self.config.broad_phase == BroadPhase::Grid && !slept.stopped && !slept.pulled {
            self.scratch.fresh_pairs = Some(self.fresh_pairs(self.frame + 1));
        }
        self.sleeping
    }

    /// What a pair set brought up to date for frame `frame` depends on besides the bodies
    /// (which only the step and the world's methods move).
    fn fresh_pairs(&self, frame: u64) -> FreshPairs {
        let c = &self.config;
        FreshPairs {
            frame,
            layout_revision: self.layout_revision,
            dt: c.dt,
            gravity: c.gravity,
            substeps: c.substeps,
            mass_scaled: c.mass_scaled_acceleration,
            grid: c.broad_phase == BroadPhase::Grid,
        }
    }

    /// The broad phase of a solver that takes every interaction's pairs at once (the
    /// impulse solver): the contacts of the step, with their warm starts. On the first
    /// frame, the resting load is settled first (it runs a frame of its own).
    fn rigid_broad_phase(&mut self) {
        if self.config.solver != Solver::Impulses {
            return;
        }
        let dt = self.config.dt;
        if self.frame == 0 && self.config.settle_iterations > 0 {
            self.settle_impulses(dt);
        }
        self.find_contacts(dt);
    }

    /// The rigid stage: bodies move and their contacts are resolved; the game rules after
    /// the motion run once the bodies moved.
    ///
    /// The relaxation runs `substeps` rounds of motion (integration, then `ccd`'s sweep)
    /// and resolution over `dt / substeps`. At one sub-step this is the chapter's order,
    /// and the game rules see the bodies moved but not yet resolved; with sub-steps they
    /// run after the last round. The impulse solver runs one frame of its sub-steps over
    /// the contacts the broad phase found (motion and resolution interleaved inside),
    /// then the game rules.
    fn rigid_stage(&mut self, stats: &mut StepStats) {
        let dt = self.config.dt;
        match self.config.solver {
            Solver::Relaxation => {
                let n = self.config.substeps.max(1);
                let h = dt / n as f64;
                let chapter_order = n == 1;
                for _ in 0..n {
                    self.move_bodies(h);
                    if chapter_order {
                        self.game_rules(HookPoint::AfterMotion);
                    }
                    self.relax_interactions(stats, h);
                }
                if !chapter_order {
                    self.game_rules(HookPoint::AfterMotion);
                }
            }
            Solver::Impulses => {
                self.solve_impulses(stats, dt);
                self.pair_set.advance(dt);
                self.game_rules(HookPoint::AfterMotion);
            }
        }
    }

    /// Integrates the moving bodies over `dt`, then stops the fast ones (`ccd`).
    fn move_bodies(&mut self, dt: f64) {
        integrate_bodies(&mut self.bodies, &self.movers, &self.config, dt);
        self.sweep_fast_bodies(dt);
        self.pair_set.advance(dt);
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

    /// Wakes every sleeping body.
    pub(super) fn wake_all(&mut self) {
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
            self.particles
                .update_on(self.config.dt as f32, self.config.threads);
        }
        self.run_emitters();
    }

    /// The rigid interactions in declaration order, each by the chapter's relaxation over
    /// `dt` (or only flagged, when it does not resolve).
    fn relax_interactions(&mut self, stats: &mut StepStats, dt: f64) {
        let params = RelaxationParams {
            iterations: self.config.relaxation_iterations,
            correction_rate: self.config.correction_rate,
            impact: (self.config.integrator == Integrator::Exact).then_some(Gravity {
                world: self.config.gravity,
                mass_scaled: self.config.mass_scaled_acceleration,
            }),
        };
        for k in 0..self.interactions.len() {
            let inter = self.interactions[k];
            let (Side::Group(a), Side::Group(b)) = (inter.a, inter.b) else {
                continue;
            };
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
                        let mut pairs = std::mem::take(&mut self.scratch.candidates);
                        self.candidates(a, b, dt, &mut pairs);
                        let report = relaxation::relax_pairs(&mut self.bodies, &pairs, params);
                        self.scratch.candidates = pairs;
                        report
                    }
                }
            };
            stats.fold(report);
        }
    }

    /// The particle interactions in declaration order: every particle inside a shape of
    /// the group is projected out to its boundary, where the rigid bodies are now.
    /// Returns how many particles were projected.
    fn particle_interactions(&mut self) -> u64 {
        let mut projected = 0;
        if self.particles.is_empty() {
            return projected;
        }
        for k in 0..self.interactions.len() {
            let inter = self.interactions[k];
            let g = match (inter.a, inter.b) {
                (Side::Group(g), Side::Particles) | (Side::Particles, Side::Group(g)) => g,
                _ => continue,
            };
            if !inter.resolve {
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
            // Many shapes: bin them so each particle meets only its neighbours (same
            // result as shape after shape, tested); a few: shape after shape.
            let grid = if shapes.len() >= PARTICLE_GRID_MIN_SHAPES {
                ShapeGrid::build(shapes.clone())
            } else {
                None
            };
            let threads = self.config.threads;
            projected += match grid {
                Some(grid) => self.particles.project_out_of_grid_on(&grid, threads),
                None => self.particles.project_out_of_shapes_on(&shapes, threads),
            };
        }
        projected
    }

    /// Solves the resting load before the first step: one frame of `settle_iterations`
    /// passes whose contact impulses are kept (the next frame warm-starts from them) and
    /// whose motion is dropped: positions, velocities and flags are as they were.
    fn settle_impulses(&mut self, dt: f64) {
        let bodies = self.bodies.clone();
        let flagged = self.flagged.clone();
        let config = self.config.clone();
        self.config.impulse_iterations = config.settle_iterations;
        self.config.adaptive_iterations = 0;
        self.config.start_iterations = 0;
        self.config.relax_iterations = 0;
        self.find_contacts(dt);
        self.solve_impulses(&mut StepStats::default(), dt);
        self.config = config;
        self.bodies = bodies;
        self.flagged = flagged;
    }

    /// The candidate pairs of every resolving interaction at once, in the contacts: the
    /// grid keeps them up to date itself; sweep and all pairs refill them, the pairs found
    /// again keeping their warm starts.
    fn find_contacts(&mut self, dt: f64) {
        // The islands of sleeping brought the pairs up to date after the last step, and
        // nothing moved a body since (no action, no rule steering one): each body is still
        // inside its box, and this broad phase would change nothing. In a crowd that never
        // rests, a check of every body a step.
        let fresh = self.scratch.fresh_pairs.take();
        if fresh.is_some()
            && fresh == Some(self.fresh_pairs(self.frame))
            && self.behaving.is_empty()
        {
            return;
        }
        self.broad_phase(dt);
        if self.config.broad_phase != BroadPhase::Grid {
            self.contacts.refill(
                &mut self.scratch.candidates,
                &mut self.scratch.last_contacts,
            );
            self.pair_set.forget();
        }
    }

    /// One frame of the impulse solver (all its sub-steps) over the contacts found, and
    /// the detect-only interactions flagged.
    fn solve_impulses(&mut self, stats: &mut StepStats, h: f64) {
        for k in 0..self.interactions.len() {
            let inter = self.interactions[k];
            let (Side::Group(a), Side::Group(b), false) = (inter.a, inter.b, inter.resolve) else {
                continue;
            };
            let (ga, gb) = (
                &self.groups[a as usize].members,
                &self.groups[b as usize].members,
            );
            if !ga.is_empty() && !gb.is_empty() {
                let report = relaxation::detect_only(&mut self.bodies, ga, gb);
                // Detections count as contacts; no pass ran, nothing was resolved.
                stats.fold(SolverReport {
                    contacts: report.contacts,
                    ..SolverReport::default()
                });
            }
        }
        let config = &self.config;
        let params = ImpulseParams {
            iterations: config.impulse_iterations_at(self.frame),
            adaptive_iterations: config.adaptive_iterations,
            relax_iterations: config.relax_iterations,
            warm_starting: config.warm_starting,
            baumgarte: config.baumgarte,
            slop: config.slop,
            contact_hertz: config.contact_hertz,
            contact_damping: config.contact_damping,
            split_impulses: config.split_impulses,
            dt: h,
            substeps: config.substeps,
            flight: config.integrator,
            threads: config.threads,
            rest_load: (config.rest_load && self.frame == 0)
                .then(|| (-config.gravity).try_normalize())
                .flatten(),
            support: config
                .shock_propagation
                .then(|| (-config.gravity).try_normalize())
                .flatten(),
            impact_propagation: config.impact_propagation,
            still_frames: true,
            exact_sliding: config
                .exact_sliding
                .then(|| (-config.gravity).try_normalize())
                .flatten(),
        };
        // A profiled world times the solver's stages too (summed over the frame's calls).
        if self.profiling {
            self.solver_buffers
                .times
                .get_or_insert_with(Default::default);
        }
        let report = impulse::solve_frame(
            &mut self.bodies,
            &mut self.contacts.pairs,
            params,
            &mut self.solver_buffers,
            &self.movers,
            |b| integrate::acceleration(b, config),
            &mut self.flagged,
        );
        stats.fold(report);
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
}
