//! World actions as they travel: what a client may ask of a world, in the JSON form clients
//! send and input logs keep (`{"do": "fire_dye_pack", "at": [50, 60]}`).
//!
//! These are the wire's own types, so the codec and its clients link no physics. A server
//! turns each into the engine's action of the same shape before it applies it, and that is
//! where a `set`'s name and value are checked (the engine knows its settings; the wire
//! carries any name and value). Every engine action reads back as the same wire action and
//! back again: the server's tests hold the two to one shape.

use serde::{Deserialize, Serialize};

/// A point `[x, y]` in world units.
pub type Point = [f64; 2];

/// A direction of the hero's controls (the chapter's WASD keys).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Direction {
    Up,
    Down,
    Left,
    Right,
}

/// The shape of a spawned minion: the chapter's circle, or the bounds demo's rectangle.
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema,
)]
#[serde(rename_all = "snake_case")]
pub enum MinionShape {
    #[default]
    Circle,
    Rect,
}

/// One world action; the engine applies it between steps and refuses it, changing
/// nothing, when an argument is out of range.
#[derive(
    Clone, Debug, PartialEq, Serialize, Deserialize, strum::VariantNames, schemars::JsonSchema,
)]
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
    /// Sets one world parameter: `{"do": "set", "name": "gravity", "value": [0, -9.8]}`
    /// (the names and their values: docs/network.md; the server checks both).
    Set {
        name: String,
        value: serde_json::Value,
    },
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

/// A body as `spawn` gives it: the fields of a scene's `[[body]]` but its behaviour,
/// each optional but `shape` (and `size` for a rect, `radius` for a circle); the server
/// fills in a scene's defaults (group `default`, mass 1, restitution 0.8, friction 0.3,
/// a fresh id) and checks every number.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct BodySpec {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub id: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub group: Option<String>,
    pub shape: ShapeKind,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub size: Option<Point>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub radius: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pos: Option<Point>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub vel: Option<Point>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mass: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub restitution: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub friction: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gravity: Option<Point>,
}

/// The names a `set` may carry: the `[world]` fields of a scene, in the engine's order
/// (the server's tests hold the list to the engine's). A client refuses any other before
/// sending; the server checks the value's type and range.
pub const SETTING_NAMES: &[&str] = &[
    "gravity",
    "particle_gravity",
    "dt",
    "relaxation_iterations",
    "correction_rate",
    "seed",
    "integrator",
    "mass_scaled_acceleration",
    "bounds",
    "solver",
    "broad_phase",
    "substeps",
    "impulse_iterations",
    "adaptive_iterations",
    "warm_starting",
    "baumgarte",
    "slop",
    "relax_iterations",
    "settle_iterations",
    "start_iterations",
    "start_frames",
    "rest_load",
    "shock_propagation",
    "impact_propagation",
    "exact_sliding",
    "contact_hertz",
    "contact_damping",
    "split_impulses",
    "ccd",
    "sleeping",
    "sleep_speed",
    "sleep_delay",
    "threads",
];

impl Action {
    /// The names of every action, as the `do` field spells them (its variants').
    pub const NAMES: &'static [&'static str] = <Action as strum::VariantNames>::VARIANTS;
}
