//! The controls of the chapter's demos and the engine's knobs, as one API.
//!
//! An [`Action`] is applied between steps by [`crate::world::World::apply`]; the network
//! layer stamps each with the frame it takes effect in. In JSON an action is an object
//! whose `do` field names it: `{"do": "fire_dye_pack", "at": [50, 60]}`.

use serde::{Deserialize, Serialize};

pub use ricochet_protocol::command::{Action, Direction, Point};

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
