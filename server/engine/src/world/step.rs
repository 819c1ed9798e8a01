//! The step pipeline: behaviours, integration, the rigid solver over the declared
//! interactions, particles and emitters, sleeping, in that order (see [`World::step`]).

use crate::behavior::Behavior;
use crate::dynamics::body::GroupId;
use crate::dynamics::broad_phase::BroadPhase;
use crate::dynamics::ccd;
use crate::dynamics::config::{Integrator, Solver};
use crate::dynamics::impulse::{self, ImpulseParams};
use crate::dynamics::integrate::{self, integrate_bodies};
use crate::dynamics::relaxation::{self, Gravity, RelaxationParams};
use crate::dynamics::sleep;
use crate::geometry::Shape;
use crate::particles::system::{ParticleShape, ShapeGrid};

use super::{Side, StepStats, World, PARTICLE_GRID_MIN_SHAPES};

impl World {
    /// Advances the world by one fixed step.
    ///
    /// With the chapter's relaxation and one sub-step this is the chapter's order: move
    /// bodies, move particles, then the rigid interactions in declaration order, then the
    /// particle interactions in declaration order (the chapter's demos declare theirs
    /// last). With sub-steps or the impulse solver, the rigid bodies take their sub-steps
    /// first (move and resolve), then the particles move and meet the shapes where they
    /// ended.
    pub fn step(&mut self) {
        let mut stats = StepStats::default();
        let energy_before = match self.last_energy {
            Some(e) => e,
            None => self.mechanical_energy(),
        };
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
        if self.config.sleeping {
            let bodies = &self.bodies;
            self.scratch.step_start.clear();
            self.scratch
                .step_start
                .extend(self.movers.iter().map(|&i| (i, bodies[i as usize].pos)));
        }
        self.run_behaviors();
        let dt = self.config.dt;
        let chapter_order = self.config.solver == Solver::Relaxation && self.config.substeps == 1;
        if chapter_order {
            integrate_bodies(&mut self.bodies, &self.movers, &self.config, dt);
            self.sweep_fast_bodies(dt);
            self.explode_dye_packs_on_hero();
            self.move_particles();
            self.relax_interactions(&mut stats, dt);
            self.particle_interactions(&mut stats);
        } else {
            let n = self.config.substeps.max(1);
            match self.config.solver {
                Solver::Relaxation => {
                    let h = dt / n as f64;
                    for _ in 0..n {
                        integrate_bodies(&mut self.bodies, &self.movers, &self.config, h);
                        self.sweep_fast_bodies(h);
                        self.relax_interactions(&mut stats, h);
                    }
                }
                Solver::Impulses => {
                    if self.frame == 0 && self.config.settle_iterations > 0 {
                        self.settle_impulses(dt);
                    }
                    self.solve_impulses(&mut stats, dt)
                }
            }
            self.explode_dye_packs_on_hero();
            self.move_particles();
            self.particle_interactions(&mut stats);
        }
        if self.sleeping > 0 {
            sleep::thaw(&mut self.bodies, &self.movers);
        }
        if self.config.sleeping {
            self.update_sleep();
        }
        stats.sleeping = self.sleeping;
        (stats.kinetic_energy, stats.energy) = self.energies();
        stats.energy_change = stats.energy - energy_before;
        self.last_energy = Some(stats.energy);
        self.stats = stats;
        self.frame += 1;
    }

    /// With `ccd`, stops fast bodies at the first shape of their interactions they would
    /// have passed through this step.
    pub(super) fn sweep_fast_bodies(&mut self, dt: f64) {
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
    pub(super) fn update_sleep(&mut self) {
        let dt = self.config.dt;
        // Where the bodies are after the step: islands join bodies touching now.
        self.broad_phase(dt);
        let pairs: Vec<(u32, u32)> = self.found_pairs().collect();
        let (speed, delay) = (self.config.sleep_speed, self.config.sleep_delay);
        let infos = &self.infos;
        let may_sleep =
            |i: usize| matches!(infos[i].behavior, Behavior::None | Behavior::DumbMinion);
        self.sleeping = sleep::update(
            &mut self.bodies,
            &self.movers,
            may_sleep,
            &pairs,
            &self.scratch.step_start,
            dt,
            speed,
            delay,
        );
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
    pub(super) fn move_particles(&mut self) {
        if !self.particles.is_empty() {
            self.particles
                .update_on(self.config.dt as f32, self.config.threads);
        }
        self.run_emitters();
    }

    /// The rigid interactions in declaration order, each by the chapter's relaxation over
    /// `dt` (or only flagged, when it does not resolve).
    pub(super) fn relax_interactions(&mut self, stats: &mut StepStats, dt: f64) {
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
            stats.contacts += report.contacts;
            stats.relaxation_iterations += report.iterations as u64;
            stats.deepest_penetration = stats.deepest_penetration.max(report.deepest);
            stats.residual = stats.residual.max(report.residual);
        }
    }

    /// The particle interactions in declaration order: every particle inside a shape of
    /// the group is projected out to its boundary, where the rigid bodies are now.
    pub(super) fn particle_interactions(&mut self, stats: &mut StepStats) {
        if self.particles.is_empty() {
            return;
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
            stats.particle_contacts += match grid {
                Some(grid) => self.particles.project_out_of_grid_on(&grid, threads),
                None => self.particles.project_out_of_shapes_on(&shapes, threads),
            };
        }
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
        self.solve_impulses(&mut StepStats::default(), dt);
        self.config = config;
        self.bodies = bodies;
        self.flagged = flagged;
    }

    /// One frame of the impulse solver (all its sub-steps) over the contacts of every rigid
    /// interaction.
    pub(super) fn solve_impulses(&mut self, stats: &mut StepStats, h: f64) {
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
                stats.contacts += report.contacts;
            }
        }
        self.broad_phase(h);
        let mut all = std::mem::take(&mut self.scratch.candidates);
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
        };
        if config.broad_phase != BroadPhase::Grid {
            self.contacts
                .refill(&mut all, &mut self.scratch.last_contacts);
            self.pair_set.forget();
        }
        let config = &self.config;
        let report = impulse::solve_frame(
            &mut self.bodies,
            &mut self.contacts.pairs,
            params,
            &mut self.solver_buffers,
            &self.movers,
            |b| integrate::acceleration(b, config),
            &mut self.flagged,
        );
        stats.contacts += report.contacts;
        stats.relaxation_iterations += report.passes;
        stats.deepest_penetration = stats.deepest_penetration.max(report.deepest);
        stats.residual = stats.residual.max(report.residual);
        self.scratch.candidates = all;
    }

    /// Runs `n` steps.
    pub fn step_n(&mut self, n: u64) {
        for _ in 0..n {
            self.step();
        }
    }

    pub(super) fn run_emitters(&mut self) {
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
