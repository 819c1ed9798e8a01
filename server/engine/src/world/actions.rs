//! Actions applied between steps ([`World::apply`]): every argument checked, and a
//! refused action changes nothing.

use glam::DVec2;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::action::{Action, ActionError, ActionOutcome, BodySpec, MinionShape, Point};
use crate::behavior::{self, Behavior};
use crate::dynamics::body::BodyDef;
use crate::dynamics::config::WorldConfig;
use crate::dynamics::setting::Setting;
use crate::geometry::Shape;
use crate::particles::Emitter;

use super::{short, LimitError, World};

impl World {
    /// Applies an action between steps. A refused action changes nothing: every check
    /// runs first ([`World::check`]), and only an accepted action wakes sleeping bodies.
    pub fn apply(&mut self, action: &Action) -> Result<ActionOutcome, ActionError> {
        self.check(action)?;
        // The pairs the islands found after the last step are looked at again.
        self.scratch.fresh_pairs = None;
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
        self.execute(action)
    }

    /// Whether `action` would be accepted now, and if not why; changes nothing.
    pub fn check(&self, action: &Action) -> Result<(), ActionError> {
        let group = |name: &str| {
            self.group(name)
                .ok_or_else(|| ActionError::UnknownGroup(short(name, MAX_ECHO)))
        };
        let preset = |name: &str| {
            self.presets
                .get(name)
                .map(|_| ())
                .ok_or_else(|| self.unknown_preset(name))
        };
        let spawn = |group: &str| -> Result<(), ActionError> {
            self.check_new_bodies(1)?;
            self.check_new_group(group)?;
            Ok(())
        };
        match action {
            Action::Press { .. } | Action::Release { .. } => {
                self.hero().ok_or(ActionError::NoHero)?;
            }
            Action::FireDyePack { at } => {
                point("at", *at)?;
                spawn("dye_packs")?;
            }
            Action::SpawnMinion { at, .. } => {
                point("at", *at)?;
                spawn("minions")?;
            }
            Action::SpawnDumbMinion { at } => {
                point("at", *at)?;
                spawn("dumb_minions")?;
            }
            Action::Select { at, group: g } => {
                point("at", *at)?;
                if let Some(name) = g {
                    group(name)?;
                }
            }
            Action::Drag { to } => {
                point("to", *to)?;
                let key = self.selected.ok_or(ActionError::NothingSelected)?;
                self.by_key.get(&key).ok_or(ActionError::NothingSelected)?;
            }
            Action::Deselect => {}
            Action::Agitate { strength } => {
                let s = strength.unwrap_or(behavior::DEFAULT_AGITATION);
                if !(0.0..=crate::dynamics::body::MAX_COORDINATE).contains(&s) {
                    return Err(ActionError::BadArgument {
                        field: "strength",
                        reason: format!(
                            "{s} must be a number from 0 to {}",
                            crate::dynamics::body::MAX_COORDINATE
                        ),
                    });
                }
            }
            Action::Clear { group: g } => {
                group(g)?;
            }
            Action::SpawnParticles {
                preset: p,
                at,
                count,
            } => {
                point("at", *at)?;
                preset(p)?;
                self.check_new_particles(*count as u64)
                    .map_err(count_error)?;
            }
            Action::StartEmitter {
                preset: p,
                count,
                at,
            } => {
                point("at", *at)?;
                preset(p)?;
                self.check_new_emitter(*count).map_err(count_error)?;
            }
            Action::Remove { body: id } => {
                self.body_index(id)?;
            }
            Action::Impulse { body: id, impulse } => {
                let i = self.body_index(id)?;
                point("impulse", *impulse)?;
                if self.bodies[i].is_static() {
                    return Err(ActionError::BadArgument {
                        field: "body",
                        reason: format!(
                            "`{}` is static: an impulse moves only a dynamic body",
                            short(id, MAX_ECHO)
                        ),
                    });
                }
            }
            Action::SetBody { body: id, pos, vel } => {
                let i = self.body_index(id)?;
                if pos.is_none() && vel.is_none() {
                    return Err(ActionError::BadArgument {
                        field: "pos",
                        reason: "or `vel` is needed: there is nothing to set".into(),
                    });
                }
                if let Some(pos) = pos {
                    point("pos", *pos)?;
                }
                if let Some(vel) = vel {
                    point("vel", *vel)?;
                    if self.bodies[i].is_static() && *vel != [0.0, 0.0] {
                        return Err(ActionError::BadArgument {
                            field: "vel",
                            reason: format!(
                                "`{}` is static: it has no velocity",
                                short(id, MAX_ECHO)
                            ),
                        });
                    }
                }
            }
            Action::Spawn {
                body,
                template,
                at,
                vel,
            } => {
                self.spawn_def(body.as_deref(), template.as_deref(), *at, *vel)?;
            }
            Action::Set(setting) => {
                self.config_after(setting)?;
            }
        }
        Ok(())
    }

    /// The body a `spawn` adds, checked whole (shape, numbers, the world's bounds, its
    /// limits, a free id); with the prefix of a fresh id to give it when it names none.
    fn spawn_def(
        &self,
        body: Option<&BodySpec>,
        template: Option<&str>,
        at: Option<Point>,
        vel: Option<Point>,
    ) -> Result<(crate::dynamics::body::BodyDef, Option<String>), ActionError> {
        let bad = |field: &'static str, reason: String| ActionError::BadArgument { field, reason };
        let (mut spec, prefix) = match (body, template) {
            (Some(b), None) => (b.clone(), "body".to_string()),
            (None, Some(name)) => match self.templates.get(name) {
                Some(t) => (t.clone(), name.to_string()),
                None => {
                    return Err(ActionError::UnknownTemplate {
                        name: short(name, MAX_ECHO),
                        known: short(
                            &self
                                .templates
                                .keys()
                                .cloned()
                                .collect::<Vec<_>>()
                                .join(", "),
                            4 * MAX_ECHO,
                        ),
                    })
                }
            },
            (Some(_), Some(_)) => {
                return Err(bad(
                    "template",
                    "is given with `body`: spawn one or the other".into(),
                ))
            }
            (None, None) => {
                return Err(bad("body", "or `template` is needed: what to spawn".into()))
            }
        };
        if let Some(at) = at {
            point("at", at)?;
            if spec.pos.is_some() && body.is_some() {
                return Err(bad(
                    "at",
                    "is given with the body's own `pos`: give one of the two".into(),
                ));
            }
            spec.pos = Some(at);
        } else if template.is_some() {
            return Err(bad(
                "at",
                "is needed: where to put the template's body".into(),
            ));
        }
        if let Some(vel) = vel {
            point("vel", vel)?;
            spec.vel = Some(vel);
        }
        let fresh = match &spec.id {
            Some(id) if self.by_id.contains_key(id) => {
                return Err(bad(
                    "id",
                    format!("a body `{}` is in the world already", short(id, MAX_ECHO)),
                ))
            }
            Some(_) => None,
            None => Some(prefix),
        };
        let def = spec.def(spec.id.clone().unwrap_or_default())?;
        let [lo, hi] = self.config.bounds;
        if !(def.pos.cmpge(lo).all() && def.pos.cmple(hi).all()) {
            return Err(bad(
                if at.is_some() { "at" } else { "pos" },
                format!(
                    "{} is outside the world's bounds, [{}, {}] to [{}, {}]",
                    def.pos, lo.x, lo.y, hi.x, hi.y
                ),
            ));
        }
        self.check_new_bodies(1)?;
        self.check_new_group(&def.group)?;
        Ok((def, fresh))
    }

    /// Adds a body the scene names `name` for `spawn` (a `[[template]]`): its numbers
    /// checked as a spawned body's, at most [`MAX_TEMPLATES`] templates.
    pub fn add_template(&mut self, name: &str, spec: BodySpec) -> Result<(), ActionError> {
        let bad = |field: &'static str, reason: String| ActionError::BadArgument { field, reason };
        if name.is_empty() || name.len() > MAX_ECHO {
            return Err(bad("name", format!("must be 1 to {MAX_ECHO} bytes")));
        }
        if self.templates.contains_key(name) {
            return Err(bad("name", format!("`{name}` names two templates")));
        }
        if self.templates.len() >= MAX_TEMPLATES {
            return Err(bad("name", format!("more than {MAX_TEMPLATES} templates")));
        }
        if spec.id.is_some() || spec.pos.is_some() {
            return Err(bad(
                if spec.id.is_some() { "id" } else { "pos" },
                "a template has none: each spawn gives a fresh id and its own `at`".into(),
            ));
        }
        spec.def(name.to_string())?;
        self.templates.insert(name.to_string(), spec);
        Ok(())
    }

    /// The names of the templates `spawn` may name, in order.
    pub fn template_names(&self) -> impl Iterator<Item = &str> {
        self.templates.keys().map(String::as_str)
    }

    /// The parameters `setting` would give: checked, and within the work limit.
    fn config_after(&self, setting: &Setting) -> Result<WorldConfig, ActionError> {
        let mut next = self.config.clone();
        next.set(setting.clone())?;
        self.check_work(&next)
            .map_err(|e| ActionError::BadArgument {
                field: "value",
                reason: e.to_string(),
            })?;
        Ok(next)
    }

    /// Applies an action [`World::check`] accepted (its points are checked there).
    fn execute(&mut self, action: &Action) -> Result<ActionOutcome, ActionError> {
        let none = Ok(ActionOutcome::default());
        match action {
            Action::Press { dir } | Action::Release { dir } => {
                let pressed = matches!(action, Action::Press { .. });
                let hero = self
                    .infos
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
                let at = DVec2::from(*at);
                let id = self.fresh_id("dye_pack");
                self.spawn(
                    BodyDef {
                        id: id.clone(),
                        group: "dye_packs".into(),
                        shape: Shape::circle(behavior::DYE_PACK_RADIUS),
                        pos: at,
                        mass: behavior::DYE_PACK_MASS,
                        gravity: Some(DVec2::ZERO),
                        ..BodyDef::default()
                    },
                    Behavior::DyePack {
                        heading: DVec2::Y,
                        life: behavior::DYE_PACK_LIFE,
                    },
                )
            }
            Action::SpawnMinion { at, shape } => {
                let at = DVec2::from(*at);
                let shape = match shape.unwrap_or_default() {
                    MinionShape::Circle => Shape::circle(behavior::MINION_RADIUS),
                    MinionShape::Rect => {
                        Shape::rect(behavior::MINION_RECT.x, behavior::MINION_RECT.y)
                    }
                };
                let dir = if self.rng.random::<bool>() { 1.0 } else { -1.0 };
                let id = self.fresh_id("minion");
                self.spawn(
                    BodyDef {
                        id,
                        group: "minions".into(),
                        shape,
                        pos: at,
                        vel: DVec2::new(dir * behavior::MINION_SPEED, 0.0),
                        mass: behavior::MINION_MASS,
                        friction: 0.0,
                        gravity: Some(DVec2::ZERO),
                        ..BodyDef::default()
                    },
                    Behavior::Patrol {
                        speed: behavior::MINION_SPEED,
                        dir,
                    },
                )
            }
            Action::SpawnDumbMinion { at } => {
                let at = DVec2::from(*at);
                let shape = if self.rng.random::<bool>() {
                    Shape::circle(behavior::MINION_RADIUS)
                } else {
                    Shape::rect(behavior::MINION_RECT.x, behavior::MINION_RECT.y)
                };
                let id = self.fresh_id("dumb_minion");
                self.spawn(
                    BodyDef {
                        id,
                        group: "dumb_minions".into(),
                        shape,
                        pos: at,
                        ..BodyDef::default()
                    },
                    Behavior::DumbMinion,
                )
            }
            Action::Select { at, group } => {
                let at = DVec2::from(*at);
                let group = match group {
                    Some(name) => Some(
                        self.group(name)
                            .ok_or_else(|| ActionError::UnknownGroup(short(name, MAX_ECHO)))?,
                    ),
                    None => None,
                };
                // The last body drawn over the point wins: the one on top.
                let hit = self.bodies.iter().rposition(|b| {
                    group.map_or(!b.is_static(), |g| b.group == g)
                        && (b.shape.contains(b.pos, at) || b.pos == at)
                });
                self.selected = hit.map(|i| self.bodies[i].key);
                Ok(ActionOutcome {
                    ids: hit
                        .map(|i| vec![self.infos[i].id.clone()])
                        .unwrap_or_default(),
                })
            }
            Action::Drag { to } => {
                let to = DVec2::from(*to);
                let key = self.selected.ok_or(ActionError::NothingSelected)?;
                let &i = self.by_key.get(&key).ok_or(ActionError::NothingSelected)?;
                let body = &mut self.bodies[i as usize];
                body.pos = to;
                body.vel = DVec2::ZERO;
                if body.is_static() && body.asleep.is_none() {
                    self.layout_revision += 1;
                    self.statics_revision += 1;
                }
                Ok(ActionOutcome {
                    ids: vec![self.infos[i as usize].id.clone()],
                })
            }
            Action::Deselect => {
                self.selected = None;
                none
            }
            Action::Agitate { strength } => {
                let s = strength.unwrap_or(behavior::DEFAULT_AGITATION);
                let mut ids = Vec::new();
                for (b, info) in self.bodies.iter_mut().zip(&self.infos) {
                    if matches!(info.behavior, Behavior::DumbMinion) && !b.is_static() {
                        let kick = DVec2::new(
                            self.rng.random_range(-1.0..=1.0),
                            self.rng.random_range(-1.0..=1.0),
                        );
                        b.vel += kick * s;
                        ids.push(info.id.clone());
                    }
                }
                Ok(ActionOutcome { ids })
            }
            Action::Remove { body: id } => {
                self.remove_bodies(|_, info| info.id == *id);
                Ok(ActionOutcome {
                    ids: vec![id.clone()],
                })
            }
            Action::Impulse { body: id, impulse } => {
                let i = self.body_index(id)?;
                let body = &mut self.bodies[i];
                body.vel += DVec2::from(*impulse) * body.inv_mass;
                Ok(ActionOutcome {
                    ids: vec![id.clone()],
                })
            }
            Action::SetBody { body: id, pos, vel } => {
                let i = self.body_index(id)?;
                let body = &mut self.bodies[i];
                if let Some(pos) = pos {
                    body.pos = DVec2::from(*pos);
                    if body.is_static() && body.asleep.is_none() {
                        self.layout_revision += 1;
                        self.statics_revision += 1;
                    }
                }
                if let Some(vel) = vel {
                    body.vel = DVec2::from(*vel);
                }
                Ok(ActionOutcome {
                    ids: vec![id.clone()],
                })
            }
            Action::Clear { group } => {
                let g = self
                    .group(group)
                    .ok_or_else(|| ActionError::UnknownGroup(short(group, MAX_ECHO)))?;
                let ids = self
                    .bodies
                    .iter()
                    .zip(&self.infos)
                    .filter(|(b, _)| b.group == g)
                    .map(|(_, info)| info.id.clone())
                    .collect();
                self.remove_bodies(|b, _| b.group == g);
                Ok(ActionOutcome { ids })
            }
            Action::SpawnParticles { preset, at, count } => {
                let at = DVec2::from(*at).as_vec2();
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
                let at = DVec2::from(*at).as_vec2();
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
            Action::Spawn {
                body,
                template,
                at,
                vel,
            } => {
                let (mut def, fresh) =
                    self.spawn_def(body.as_deref(), template.as_deref(), *at, *vel)?;
                if let Some(prefix) = fresh {
                    def.id = self.fresh_id(&prefix);
                }
                self.spawn(def, Behavior::None)
            }
            Action::Set(setting) => {
                let before = self.config.seed;
                self.config = self.config_after(setting)?;
                if self.config.seed != before {
                    self.rng = ChaCha8Rng::seed_from_u64(self.config.seed);
                }
                none
            }
        }
    }

    pub(super) fn spawn(
        &mut self,
        def: BodyDef,
        behavior: Behavior,
    ) -> Result<ActionOutcome, ActionError> {
        let id = def.id.clone();
        self.add_actor(def, behavior)
            .map_err(|e| ActionError::BadArgument {
                field: "at",
                reason: e.to_string(),
            })?;
        Ok(ActionOutcome { ids: vec![id] })
    }

    pub(super) fn unknown_preset(&self, name: &str) -> ActionError {
        ActionError::UnknownPreset {
            name: short(name, MAX_ECHO),
            known: short(
                &self.presets.names().collect::<Vec<_>>().join(", "),
                4 * MAX_ECHO,
            ),
        }
    }
}

/// Bytes of a client's text (a group or preset name) echoed in a refusal at most.
pub const MAX_ECHO: usize = 64;

/// Templates a scene may name at most.
pub const MAX_TEMPLATES: usize = 256;

/// A point argument: finite and within the engine's coordinates.
fn point(field: &'static str, p: [f64; 2]) -> Result<DVec2, ActionError> {
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
}

impl World {
    /// Where the body `id` is in `bodies`, or a refusal naming it.
    fn body_index(&self, id: &str) -> Result<usize, ActionError> {
        self.by_id
            .get(id)
            .map(|&i| i as usize)
            .ok_or_else(|| ActionError::UnknownBody(short(id, MAX_ECHO)))
    }
}

/// A limit on particles, refused as the action's `count`.
fn count_error(e: LimitError) -> ActionError {
    ActionError::BadArgument {
        field: "count",
        reason: e.to_string(),
    }
}
