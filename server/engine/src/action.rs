//! What clients may do to a world, as typed values: the controls of the chapter's demos
//! and the engine's knobs.
//!
//! An [`Action`] is applied between steps by [`crate::world::World::apply`], which checks
//! every argument and changes nothing when it refuses one. The network layer stamps each
//! action with the frame it takes effect in. Actions read and write as JSON objects whose
//! `do` field names them (`{"do": "fire_dye_pack", "at": [50, 60]}`): the form clients
//! send and input logs keep.

use serde::{Deserialize, Serialize};

use crate::dynamics::config::ConfigError;
use crate::dynamics::setting::Setting;

pub use crate::behavior::Direction;

/// A point `[x, y]` in world units.
pub type Point = [f64; 2];

/// The shape of a spawned minion: the chapter's circle, or the bounds demo's rectangle.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MinionShape {
    #[default]
    Circle,
    Rect,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, strum::VariantNames)]
#[serde(tag = "do", rename_all = "snake_case", deny_unknown_fields)]
#[strum(serialize_all = "snake_case")]
pub enum Action {
    /// Starts holding a direction of the hero's controls.
    Press { dir: Direction },
    /// Stops holding a direction.
    Release { dir: Direction },
    /// Sends a dye pack from `at`, homing on the hero.
    FireDyePack { at: Point },
    /// Spawns a patrolling minion at `at` (a circle unless `shape` is "rect").
    SpawnMinion {
        at: Point,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        shape: Option<MinionShape>,
    },
    /// Spawns a dumb minion (the stability demo's test body) at `at`.
    SpawnDumbMinion { at: Point },
    /// Selects the body under `at` (among `group`, or any dynamic body).
    Select {
        at: Point,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        group: Option<String>,
    },
    /// Moves the selected body to `to`, its velocity zeroed.
    Drag { to: Point },
    /// Forgets the selection.
    Deselect,
    /// Adds a random velocity to every dumb minion.
    Agitate {
        #[serde(default, skip_serializing_if = "Option::is_none")]
        strength: Option<f64>,
    },
    /// Removes every body of a group.
    Clear { group: String },
    /// Spawns `count` particles of a preset at `at`.
    SpawnParticles {
        preset: String,
        at: Point,
        #[serde(default = "one")]
        count: u32,
    },
    /// Starts an emitter of `count` particles of a preset at `at`.
    StartEmitter {
        preset: String,
        count: u32,
        at: Point,
    },
    /// Removes the body whose id is `body` (any body of any scene, static or not). A
    /// body is named by `body` in these commands: `id` is a request's own id.
    Remove { body: String },
    /// Adds `impulse` [x, y] to the momentum of the dynamic body `body`: its velocity
    /// changes by the impulse over its mass.
    Impulse { body: String, impulse: Point },
    /// Moves the body `body` to `pos`, sets its velocity to `vel`, or both (a static body
    /// only moves).
    SetBody {
        body: String,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        pos: Option<Point>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        vel: Option<Point>,
    },
    /// Adds a body: `body`, a table with the fields of a scene's `[[body]]` (its `pos`,
    /// or `at`), or `template`, a body the scene names in a `[[template]]`, put at `at`
    /// (with `vel` if given). The reply names the new body's id.
    Spawn {
        #[serde(default, skip_serializing_if = "Option::is_none")]
        body: Option<Box<BodySpec>>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        template: Option<String>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        at: Option<Point>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        vel: Option<Point>,
    },
    /// Sets one world parameter, named and typed by [`Setting`]:
    /// `{"do": "set", "name": "gravity", "value": [0, -9.8]}`.
    Set(Setting),
}

fn one() -> u32 {
    1
}

/// A body's shape kind, as scenes and `spawn` name it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum ShapeKind {
    Rect,
    Circle,
}

/// A body as a `spawn` or a scene's `[[template]]` gives it: the fields of a scene's
/// `[[body]]` but its behaviour, each optional but `shape` (and `size` or `radius`),
/// with a scene's defaults (group `default`, mass 1, restitution 0.8, friction 0.3).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct BodySpec {
    /// The body's name, unique in the world (a spawn without one gets a fresh id; a
    /// template has none).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub id: Option<String>,
    /// The group it joins (default `default`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub group: Option<String>,
    /// `rect` (with `size`) or `circle` (with `radius`).
    pub shape: ShapeKind,
    /// Width and height of a rect, units.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub size: Option<Point>,
    /// Radius of a circle, units.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub radius: Option<f64>,
    /// Centre, units (a spawn's `at` stands for it; a template has none).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pos: Option<Point>,
    /// Velocity, units per second (default at rest).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub vel: Option<Point>,
    /// Mass (default 1; 0 makes it static).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mass: Option<f64>,
    /// Bounce, 0 to 1 (default 0.8).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub restitution: Option<f64>,
    /// Coulomb friction coefficient (default 0.3).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub friction: Option<f64>,
    /// Its own gravity, units per second squared (default the world's).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gravity: Option<Point>,
}

impl BodySpec {
    /// The body this gives, named `id`, at its `pos` (the origin if none), with a
    /// scene's defaults for what it leaves out; every number checked.
    pub fn def(&self, id: String) -> Result<crate::dynamics::body::BodyDef, ActionError> {
        use crate::geometry::Shape;
        use glam::DVec2;
        let bad = |field: &'static str, reason: &str| ActionError::BadArgument {
            field,
            reason: reason.to_string(),
        };
        let shape = match (self.shape, self.size, self.radius) {
            (ShapeKind::Rect, Some([w, h]), None) => Shape::rect(w, h),
            (ShapeKind::Circle, None, Some(r)) => Shape::circle(r),
            (ShapeKind::Rect, None, _) => {
                return Err(bad("size", "a rect needs size = [width, height]"))
            }
            (ShapeKind::Rect, Some(_), Some(_)) => {
                return Err(bad("radius", "a rect has a size, not a radius"))
            }
            (ShapeKind::Circle, _, None) => return Err(bad("radius", "a circle needs radius = r")),
            (ShapeKind::Circle, Some(_), Some(_)) => {
                return Err(bad("size", "a circle has a radius, not a size"))
            }
        };
        let base = crate::dynamics::body::BodyDef::default();
        let def = crate::dynamics::body::BodyDef {
            id,
            group: self.group.clone().unwrap_or(base.group),
            shape,
            pos: self.pos.map_or(DVec2::ZERO, DVec2::from),
            vel: self.vel.map_or(DVec2::ZERO, DVec2::from),
            mass: self.mass.unwrap_or(base.mass),
            restitution: self.restitution.unwrap_or(base.restitution),
            friction: self.friction.unwrap_or(base.friction),
            gravity: self.gravity.map(DVec2::from),
        };
        def.validate().map_err(|e| ActionError::BadArgument {
            field: e.field,
            reason: e.reason,
        })?;
        Ok(def)
    }
}

impl Action {
    /// The names of every action, as the `do` field spells them (its variants').
    pub const NAMES: &'static [&'static str] = <Action as strum::VariantNames>::VARIANTS;
}

/// What an applied action created or chose, by body id.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ActionOutcome {
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub ids: Vec<String>,
}

/// Why an action was refused; the world is unchanged.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ActionError {
    #[error("`{field}` {reason}")]
    BadArgument { field: &'static str, reason: String },
    #[error("there is no hero in this world")]
    NoHero,
    #[error("no body is selected")]
    NothingSelected,
    #[error("unknown particle preset `{name}` (known: {known})")]
    UnknownPreset { name: String, known: String },
    #[error("unknown group `{0}`")]
    UnknownGroup(String),
    #[error("no body `{0}` in this world")]
    UnknownBody(String),
    #[error("unknown template `{name}` (known: {known})")]
    UnknownTemplate { name: String, known: String },
    #[error(transparent)]
    Config(#[from] ConfigError),
    #[error(transparent)]
    Limit(#[from] crate::world::LimitError),
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read(json: &str) -> Action {
        serde_json::from_str(json).unwrap_or_else(|e| panic!("{json}: {e}"))
    }

    #[test]
    fn actions_read_as_json_a_person_can_type() {
        assert_eq!(
            read(r#"{"do":"fire_dye_pack","at":[50,60.5]}"#),
            Action::FireDyePack { at: [50.0, 60.5] }
        );
        assert_eq!(
            read(r#"{"do":"press","dir":"left"}"#),
            Action::Press {
                dir: Direction::Left
            }
        );
        assert_eq!(
            read(r#"{"do":"spawn_particles","preset":"fire","at":[1,2]}"#),
            Action::SpawnParticles {
                preset: "fire".into(),
                at: [1.0, 2.0],
                count: 1
            }
        );
        assert_eq!(
            read(r#"{"do":"spawn_minion","at":[1,2],"shape":"rect"}"#),
            Action::SpawnMinion {
                at: [1.0, 2.0],
                shape: Some(MinionShape::Rect)
            }
        );
    }

    #[test]
    fn set_reads_a_typed_setting_and_writes_the_same_text() {
        let a = read(r#"{"do":"set","name":"gravity","value":[0,-10]}"#);
        assert_eq!(
            a,
            Action::Set(Setting::Gravity(glam::DVec2::new(0.0, -10.0)))
        );
        let back = serde_json::to_string(&a).unwrap();
        assert_eq!(read(&back), a);
        assert_eq!(
            read(r#"{"do":"set","name":"solver","value":"impulses"}"#),
            Action::Set(Setting::Solver(crate::dynamics::Solver::Impulses))
        );
    }

    #[test]
    fn malformed_actions_name_what_is_wrong() {
        for (json, needle) in [
            (r#"{"do":"set","name":"nope","value":1}"#, "nope"),
            (r#"{"do":"set","name":"dt","value":"fast"}"#, "fast"),
            (r#"{"do":"set","name":"gravity","value":[1]}"#, "2"),
            (
                r#"{"do":"spawn_minion","at":[1,2],"shape":"hexagon"}"#,
                "hexagon",
            ),
            (r#"{"do":"drag","to":[1,2],"speed":3}"#, "speed"),
        ] {
            let e = serde_json::from_str::<Action>(json)
                .unwrap_err()
                .to_string();
            assert!(e.contains(needle), "{json}: {e}");
        }
    }
}
