//! A world read back from bytes, checked as a scene is: a checkpoint is input like any
//! other file, and a crafted one must be refused, naming the field, never stepped into a
//! panic, a hang or numbers that are not numbers.
//!
//! [`World::validate`] runs after [`World::restore`] decodes the bytes: the settings as
//! a scene's `[world]` is checked ([`WorldConfig::validate`]), the counts under the
//! operator's limits, every number finite and in the range a scene allows, and every
//! index the world keeps into its bodies (groups' members, the lists a step walks, the
//! handles by id and key, the contacts, the broad phase's grid, the solver's blocks) in
//! range and the same as the bodies give.

use crate::behavior::Behavior;
use crate::dynamics::body::{MAX_FRICTION, MIN_MASS};
use crate::geometry::Shape;
use crate::particles::PresetLibrary;

use super::{CheckpointError, Side, World};

/// A refusal naming `field`.
fn bad(field: impl Into<String>, reason: impl Into<String>) -> CheckpointError {
    CheckpointError::Invalid {
        field: field.into(),
        reason: reason.into(),
    }
}

fn finite2(v: glam::DVec2) -> bool {
    v.is_finite()
}

impl World {
    /// Checks a world read back from a checkpoint (see the module). The first field that
    /// is wrong is named.
    pub fn validate(&self) -> Result<(), CheckpointError> {
        // The settings, as a scene's `[world]`: on a copy, since validating applies the
        // chapter's clamps and a restored world keeps its bits.
        self.config
            .clone()
            .validate()
            .map_err(|e| bad("config", e.to_string()))?;
        self.check_counts()?;
        self.check_bodies()?;
        self.check_indices()?;
        self.check_particles()?;
        let n = self.bodies.len() as u32;
        for (k, p) in self.contacts.pairs.iter().enumerate() {
            if !(p.a < p.b && p.b < n) {
                return Err(bad(
                    format!("contacts[{k}]"),
                    format!("pair ({}, {}) of {n} bodies", p.a, p.b),
                ));
            }
            if !(finite2(p.normal)
                && p.normal_impulse.is_finite()
                && p.tangent_impulse.is_finite()
                && p.pseudo_impulse.is_finite())
            {
                return Err(bad(format!("contacts[{k}]"), "impulses not finite"));
            }
        }
        if let Some(k) = self
            .contacts
            .pairs
            .windows(2)
            .position(|w| (w[0].a, w[0].b) >= (w[1].a, w[1].b))
        {
            return Err(bad(
                format!("contacts[{}]", k + 1),
                "pairs out of order or repeated",
            ));
        }
        self.pair_set
            .check(&self.bodies, self.groups.len())
            .map_err(|(field, reason)| bad(field, reason))?;
        self.solver_buffers
            .check(&self.movers)
            .map_err(|(field, reason)| bad(field, reason))?;
        let s = &self.stats;
        let figures = [
            s.deepest_penetration,
            s.kinetic_energy,
            s.energy,
            s.energy_change,
            s.residual,
        ];
        if !figures.iter().all(|v| v.is_finite())
            || self.last_energy.is_some_and(|e| !e.is_finite())
        {
            return Err(bad("stats", "a figure of the last step is not finite"));
        }
        Ok(())
    }

    /// Counts within the operator's limits, and the step's estimated work.
    fn check_counts(&self) -> Result<(), CheckpointError> {
        let l = &self.limits;
        let over = |name: &str, have: u64, limit: u32| {
            Err(bad(
                name,
                format!("{have} is over this server's limit of {limit} (limits.{name})"),
            ))
        };
        if self.bodies.len() as u64 > u64::from(l.bodies) {
            return over("bodies", self.bodies.len() as u64, l.bodies);
        }
        if self.particles_committed() > u64::from(l.particles) {
            return over("particles", self.particles_committed(), l.particles);
        }
        if self.emitters.len() as u64 > u64::from(l.emitters) {
            return over("emitters", self.emitters.len() as u64, l.emitters);
        }
        if self.groups.len() as u64 > u64::from(l.groups) {
            return over("groups", self.groups.len() as u64, l.groups);
        }
        if self.interactions.len() as u64 > u64::from(l.interactions) {
            return over(
                "interactions",
                self.interactions.len() as u64,
                l.interactions,
            );
        }
        // The built-in presets come with every world, whatever the limit.
        let presets = self.presets.len() as u64;
        if presets > u64::from(l.presets).max(PresetLibrary::built_in().len() as u64) {
            return over("presets", presets, l.presets);
        }
        for name in self.presets.names() {
            let preset = self.presets.get(name).expect("a preset by its name");
            if let Some(field) = preset.non_finite_field() {
                return Err(bad(format!("presets.{name}.{field}"), "not finite"));
            }
            if let Some((field, n)) = preset.too_many_rand_terms(l.rand_terms as usize) {
                return Err(bad(
                    format!("presets.{name}.{field}"),
                    format!("{n} random terms, over the limit of {}", l.rand_terms),
                ));
            }
        }
        for (k, e) in self.emitters.iter().enumerate() {
            if !e.pos.is_finite() || e.remaining > l.particles_per_action {
                return Err(bad(
                    format!("emitters[{k}]"),
                    format!(
                        "at {} with {} particles to come (at most {})",
                        e.pos, e.remaining, l.particles_per_action
                    ),
                ));
            }
            if self.presets.get(&e.preset).is_none() {
                return Err(bad(
                    format!("emitters[{k}].preset"),
                    format!("unknown preset `{}`", super::short(&e.preset, 64)),
                ));
            }
        }
        for (k, i) in self.interactions.iter().enumerate() {
            for side in [i.a, i.b] {
                if let Side::Group(g) = side {
                    if g as usize >= self.groups.len() {
                        return Err(bad(
                            format!("interactions[{k}]"),
                            format!("group {g} of {}", self.groups.len()),
                        ));
                    }
                }
            }
        }
        self.check_work(&self.config)
            .map_err(|e| bad("step_work", e.to_string()))
    }

    /// Every body's numbers as a scene allows them (positions and velocities finite), its
    /// group and key in range.
    fn check_bodies(&self) -> Result<(), CheckpointError> {
        if self.infos.len() != self.bodies.len() {
            return Err(bad(
                "infos",
                format!("{} ids for {} bodies", self.infos.len(), self.bodies.len()),
            ));
        }
        for (i, (b, info)) in self.bodies.iter().zip(&self.infos).enumerate() {
            let field = |name: &str| format!("bodies[{i}].{name}");
            let size_ok = match b.shape {
                Shape::Rect { half } => {
                    half.is_finite()
                        && half.min_element() > 0.0
                        && half.max_element() <= crate::dynamics::body::MAX_COORDINATE
                }
                Shape::Circle { radius } => {
                    radius.is_finite()
                        && radius > 0.0
                        && radius <= crate::dynamics::body::MAX_COORDINATE
                }
            };
            if !size_ok {
                return Err(bad(field("shape"), "not a finite size above 0"));
            }
            for (name, v) in [("pos", b.pos), ("vel", b.vel)] {
                if !finite2(v) {
                    return Err(bad(field(name), format!("{v} is not finite")));
                }
            }
            let inv_ok = |m: f64| m.is_finite() && (0.0..=1.0 / MIN_MASS).contains(&m);
            if !inv_ok(b.inv_mass) || b.asleep.is_some_and(|s| !inv_ok(s.inv_mass)) {
                return Err(bad(
                    field("inv_mass"),
                    format!(
                        "{} is not 0 or the inverse of a mass a scene allows",
                        b.inv_mass
                    ),
                ));
            }
            if !(0.0..=1.0).contains(&b.restitution) {
                return Err(bad(
                    field("restitution"),
                    format!("{} is not 0 to 1", b.restitution),
                ));
            }
            if !(0.0..=MAX_FRICTION).contains(&b.friction) {
                return Err(bad(
                    field("friction"),
                    format!("{} is not 0 to {MAX_FRICTION}", b.friction),
                ));
            }
            if b.gravity.is_some_and(|g| !finite2(g)) || !b.rest_time.is_finite() {
                return Err(bad(field("gravity"), "not finite"));
            }
            if b.group as usize >= self.groups.len() {
                return Err(bad(
                    field("group"),
                    format!("group {} of {}", b.group, self.groups.len()),
                ));
            }
            if b.key.0 >= self.next_key {
                return Err(bad(
                    field("key"),
                    format!("key {} not below the next key {}", b.key.0, self.next_key),
                ));
            }
            if info.id.chars().any(char::is_control) {
                return Err(bad(format!("infos[{i}].id"), "holds a control character"));
            }
            let behaviour_ok = match info.behavior {
                Behavior::Patrol { speed, dir } => speed.is_finite() && dir.is_finite(),
                Behavior::DyePack { heading, .. } => finite2(heading),
                _ => true,
            };
            if !behaviour_ok {
                return Err(bad(format!("infos[{i}].behavior"), "not finite"));
            }
        }
        Ok(())
    }

    /// The indices into the bodies the world keeps beside them: the same as the bodies
    /// give (what [`World::rebuild_groups`] would make), so none is out of range.
    fn check_indices(&self) -> Result<(), CheckpointError> {
        let n = self.bodies.len();
        let mut members = vec![Vec::new(); self.groups.len()];
        let (mut movers, mut behaving) = (Vec::new(), Vec::new());
        for (i, (b, info)) in self.bodies.iter().zip(&self.infos).enumerate() {
            members[b.group as usize].push(i as u32);
            if !b.is_static() {
                movers.push(i as u32);
            }
            if info.behavior != Behavior::None {
                behaving.push(i as u32);
            }
        }
        for (g, (group, expected)) in self.groups.iter().zip(&members).enumerate() {
            if &group.members != expected {
                return Err(bad(
                    format!("groups[{g}].members"),
                    "not the bodies of the group, in body order",
                ));
            }
            if let Some(c) = group.name.chars().find(|c| c.is_control()) {
                return Err(bad(
                    format!("groups[{g}].name"),
                    format!("holds the control character {:?}", c),
                ));
            }
        }
        if self.movers != movers {
            return Err(bad("movers", "not the dynamic bodies, in body order"));
        }
        if self.behaving != behaving {
            return Err(bad(
                "behaving",
                "not the bodies with a behaviour, in body order",
            ));
        }
        if let Some(&i) = self.flagged.iter().find(|&&i| i as usize >= n) {
            return Err(bad("flagged", format!("body {i} of {n}")));
        }
        let by_id_ok = self.by_id.len() == n
            && self
                .infos
                .iter()
                .enumerate()
                .all(|(i, info)| self.by_id.get(&info.id) == Some(&(i as u32)));
        if !by_id_ok {
            return Err(bad(
                "by_id",
                "not each body's id to its index (ids repeated?)",
            ));
        }
        let by_key_ok = self.by_key.len() == n
            && self
                .bodies
                .iter()
                .enumerate()
                .all(|(i, b)| self.by_key.get(&b.key) == Some(&(i as u32)));
        if !by_key_ok {
            return Err(bad(
                "by_key",
                "not each body's key to its index (keys repeated?)",
            ));
        }
        Ok(())
    }

    fn check_particles(&self) -> Result<(), CheckpointError> {
        self.particles
            .check()
            .map_err(|(field, reason)| bad(field, reason))
    }
}
