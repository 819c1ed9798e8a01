//! The controls of the chapter's demos and the engine's knobs, as one API.
//!
//! An [`Action`] is applied between steps by [`crate::world::World::apply`]; the network
//! layer stamps each with the frame it takes effect in. In JSON an action is an object
//! whose `do` field names it: `{"do": "fire_dye_pack", "at": [50, 60]}`.

use serde::{Deserialize, Serialize};

use crate::behavior::Direction;

/// A point `[x, y]` in world units.
pub type Point = [f64; 2];

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "do", rename_all = "snake_case", deny_unknown_fields)]
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
        #[serde(default)]
        shape: Option<String>,
    },
    /// Spawns a dumb minion (the stability demo's test body) at `at`.
    SpawnDumbMinion { at: Point },
    /// Selects the body under `at` (among `group`, or any dynamic body).
    Select {
        at: Point,
        #[serde(default)]
        group: Option<String>,
    },
    /// Moves the selected body to `to`, its velocity zeroed.
    Drag { to: Point },
    /// Forgets the selection.
    Deselect,
    /// Adds a random velocity to every dumb minion.
    Agitate {
        #[serde(default)]
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
    /// Sets a world parameter by name (see [`crate::dynamics::WorldConfig::set`]).
    Set { name: String, value: toml::Value },
}

fn one() -> u32 {
    1
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
    #[error(transparent)]
    Config(#[from] crate::dynamics::config::ConfigError),
}

/// The largest particle count one action may ask for.
pub const MAX_PARTICLES_PER_ACTION: u32 = 1_000_000;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn actions_read_as_json_a_person_can_type() {
        let a: Action = serde_json::from_str(r#"{"do":"fire_dye_pack","at":[50,60.5]}"#).unwrap();
        assert_eq!(a, Action::FireDyePack { at: [50.0, 60.5] });
        let a: Action = serde_json::from_str(r#"{"do":"press","dir":"left"}"#).unwrap();
        assert_eq!(
            a,
            Action::Press {
                dir: Direction::Left
            }
        );
        let a: Action =
            serde_json::from_str(r#"{"do":"set","name":"gravity","value":[0,-10]}"#).unwrap();
        assert!(matches!(a, Action::Set { .. }));
        let a: Action =
            serde_json::from_str(r#"{"do":"spawn_particles","preset":"fire","at":[1,2]}"#).unwrap();
        assert_eq!(
            a,
            Action::SpawnParticles {
                preset: "fire".into(),
                at: [1.0, 2.0],
                count: 1
            }
        );
    }

    #[test]
    fn malformed_actions_are_refused_with_the_reason() {
        for (text, needle) in [
            (r#"{"do":"fly"}"#, "fly"),
            (r#"{"do":"fire_dye_pack"}"#, "at"),
            (r#"{"do":"press","dir":"sideways"}"#, "sideways"),
            (r#"{"do":"drag","to":[1,2],"speed":3}"#, "speed"),
        ] {
            let e = serde_json::from_str::<Action>(text)
                .unwrap_err()
                .to_string();
            assert!(e.contains(needle), "{text}: {e}");
        }
    }
}
