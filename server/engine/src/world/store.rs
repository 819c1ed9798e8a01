//! The body store: adding bodies (checked), particles, emitters and interactions;
//! removing bodies; the indices a step walks (movers, behaving, flagged) kept in step.

use glam::Vec2;

use crate::behavior::Behavior;
use crate::dynamics::body::{Body, BodyDef, BodyKey, GroupId};
use crate::particles::{Emitter, ParticleDef, ParticlePreset};

use super::{BodyInfo, Group, Interaction, LimitError, Side, World, WorldError, PARTICLES};

impl World {
    /// The group's id, creating the group if needed (within the `groups` limit).
    pub fn group_or_insert(&mut self, name: &str) -> Result<GroupId, WorldError> {
        if let Some(g) = self.group(name) {
            return Ok(g);
        }
        self.check_new_group(name)?;
        self.groups.push(Group {
            name: name.to_string(),
            members: Vec::new(),
        });
        Ok((self.groups.len() - 1) as GroupId)
    }

    /// Refuses a group that would be one too many.
    pub(super) fn check_new_group(&self, name: &str) -> Result<(), LimitError> {
        if self.group(name).is_none() && self.groups.len() as u64 >= self.limits.groups as u64 {
            return Err(LimitError::exceeded("groups", "groups", self.limits.groups));
        }
        Ok(())
    }

    /// Refuses `n` more bodies if they would be too many.
    pub(super) fn check_new_bodies(&self, n: u64) -> Result<(), LimitError> {
        if self.bodies.len() as u64 + n > self.limits.bodies as u64 {
            return Err(LimitError::exceeded("bodies", "bodies", self.limits.bodies));
        }
        Ok(())
    }

    /// Refuses `n` more particles (alive or to come) if they would be too many.
    pub(super) fn check_new_particles(&self, n: u64) -> Result<(), LimitError> {
        if n > self.limits.particles_per_action as u64 {
            return Err(LimitError::exceeded(
                "particles_per_action",
                "particles at once",
                self.limits.particles_per_action,
            ));
        }
        if self.particles_committed() + n > self.limits.particles as u64 {
            return Err(LimitError::exceeded(
                "particles",
                "particles (alive and to come from emitters)",
                self.limits.particles,
            ));
        }
        self.check_work_with(&self.config, n)
    }

    /// Refuses one more emitter of `count` particles if it would exceed a limit.
    pub(super) fn check_new_emitter(&self, count: u32) -> Result<(), LimitError> {
        if self.emitters.len() as u64 >= self.limits.emitters as u64 {
            return Err(LimitError::exceeded(
                "emitters",
                "emitters",
                self.limits.emitters,
            ));
        }
        self.check_new_particles(count as u64)
    }

    /// Adds or replaces a particle preset, within the `presets` and `rand_terms` limits.
    pub fn add_preset(&mut self, name: &str, preset: ParticlePreset) -> Result<(), WorldError> {
        if self.presets.get(name).is_none()
            && self.presets.len() as u64 >= self.limits.presets as u64
        {
            return Err(LimitError::exceeded("presets", "presets", self.limits.presets).into());
        }
        if let Some((field, n)) = preset.too_many_rand_terms(self.limits.rand_terms as usize) {
            return Err(LimitError::Invalid {
                name: "rand_terms".into(),
                reason: format!(
                    "`{field}` draws {n} random terms, over the world's limit of {}",
                    self.limits.rand_terms
                ),
            }
            .into());
        }
        self.presets.insert(name, preset);
        Ok(())
    }

    /// Adds a body driven by physics alone. Its id must be unique; every number is
    /// checked.
    pub fn add_body(&mut self, def: BodyDef) -> Result<BodyKey, WorldError> {
        self.add_actor(def, Behavior::None)
    }

    /// Adds a body that `behavior` also drives (the chapter demo's hero, minions and dye
    /// packs), as [`World::add_body`] checks it.
    pub fn add_actor(&mut self, def: BodyDef, behavior: Behavior) -> Result<BodyKey, WorldError> {
        def.validate().map_err(|source| WorldError::Body {
            id: def.id.clone(),
            source,
        })?;
        if self.by_id.contains_key(&def.id) {
            return Err(WorldError::DuplicateId(def.id));
        }
        self.check_new_bodies(1)?;
        let group = self.group_or_insert(&def.group)?;
        let key = BodyKey(self.next_key);
        self.next_key += 1;
        let index = self.bodies.len() as u32;
        self.by_id.insert(def.id.clone(), index);
        self.by_key.insert(key, index);
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
            rest_time: 0.0,
            rest_anchor: def.pos,
            rest_depth: 0.0,
            asleep: None,
        });
        self.groups[group as usize].members.push(index);
        if !self.bodies[index as usize].is_static() {
            self.movers.push(index);
        }
        if behavior != Behavior::None {
            self.behaving.push(index);
        }
        self.infos.push(BodyInfo {
            id: def.id,
            behavior,
        });
        Ok(key)
    }

    /// Adds a particle.
    pub fn add_particle(&mut self, def: &ParticleDef) -> Result<(), WorldError> {
        def.validate()?;
        self.check_new_particles(1)?;
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
        self.check_new_emitter(count)?;
        self.emitters.push(Emitter {
            pos,
            remaining: count,
            preset: preset.to_string(),
        });
        Ok(())
    }

    /// Declares an interaction between two groups, or a group and [`PARTICLES`].
    pub fn add_interaction(&mut self, a: &str, b: &str, resolve: bool) -> Result<(), WorldError> {
        if self.interactions.len() as u64 >= self.limits.interactions as u64 {
            return Err(LimitError::exceeded(
                "interactions",
                "interactions",
                self.limits.interactions,
            )
            .into());
        }
        let side = |w: &mut World, name: &str| -> Result<Side, WorldError> {
            Ok(if name == PARTICLES {
                Side::Particles
            } else {
                Side::Group(w.group_or_insert(name)?)
            })
        };
        let (sa, sb) = (side(self, a)?, side(self, b)?);
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
    pub(super) fn fresh_id(&mut self, prefix: &str) -> String {
        loop {
            self.spawned += 1;
            let id = format!("{prefix}-{}", self.spawned);
            if !self.by_id.contains_key(&id) {
                return id;
            }
        }
    }

    /// Removes the bodies for which `remove` is true, keeping the order of the rest (and
    /// wakes the world: a removed body may have held others up).
    pub(super) fn remove_bodies(&mut self, remove: impl Fn(&Body, &BodyInfo) -> bool) {
        let doomed: Vec<bool> = self
            .bodies
            .iter()
            .zip(&self.infos)
            .map(|(b, info)| remove(b, info))
            .collect();
        if !doomed.contains(&true) {
            return;
        }
        self.wake_all();
        if self
            .bodies
            .iter()
            .zip(&doomed)
            .any(|(b, &d)| d && b.is_static())
        {
            self.statics_revision += 1;
        }
        let mut keep = doomed.iter().map(|&d| !d);
        self.bodies.retain(|_| keep.next().unwrap_or(true));
        let mut keep = doomed.iter().map(|&d| !d);
        self.infos.retain(|_| keep.next().unwrap_or(true));
        self.contacts.remove_bodies(&doomed);
        self.layout_revision += 1;
        self.rebuild_groups();
    }

    /// Rebuilds every index into `bodies`: groups, the lists a step walks, and the
    /// handles by id and by key.
    pub(super) fn rebuild_groups(&mut self) {
        for g in &mut self.groups {
            g.members.clear();
        }
        self.by_id.clear();
        self.by_key.clear();
        self.movers.clear();
        self.behaving.clear();
        self.flagged.clear();
        for (i, (b, info)) in self.bodies.iter().zip(&self.infos).enumerate() {
            self.by_id.insert(info.id.clone(), i as u32);
            self.by_key.insert(b.key, i as u32);
            self.groups[b.group as usize].members.push(i as u32);
            if !b.is_static() {
                self.movers.push(i as u32);
            }
            if info.behavior != Behavior::None {
                self.behaving.push(i as u32);
            }
            if b.collided {
                self.flagged.push(i as u32);
            }
        }
    }
}
