//! The scene file as read: TOML tables into these types (serde, unknown fields refused),
//! each kept with its span so errors point at the line. Checked and turned into a world
//! by the parent module.

use std::collections::BTreeMap;

use serde::Deserialize;
use toml::Spanned;

use crate::dynamics::config::WorldConfig;
use crate::particles::ParticlePreset;

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct SceneFile {
    /// Groups that bodies join only at run time (spawned by the world's rules or by
    /// commands), so that an interaction may name them before any body belongs to them.
    #[serde(default)]
    pub(super) groups: Vec<Spanned<String>>,
    #[serde(default)]
    pub(super) world: Option<Spanned<WorldConfig>>,
    /// Read over the ceiling's values (see [`crate::world::Limits`]).
    #[serde(default)]
    pub(super) limits: Option<Spanned<toml::Table>>,
    #[serde(default)]
    pub(super) preset: BTreeMap<String, Spanned<ParticlePreset>>,
    #[serde(default)]
    pub(super) body: Vec<Spanned<RawBody>>,
    #[serde(default)]
    pub(super) generate: Vec<Spanned<RawGenerator>>,
    #[serde(default)]
    pub(super) particle: Vec<Spanned<RawParticle>>,
    #[serde(default)]
    pub(super) emitter: Vec<Spanned<RawEmitter>>,
    #[serde(default)]
    pub(super) interact: Vec<Spanned<RawInteraction>>,
    /// What a run of the scene is expected to hold (see [`crate::criteria`]).
    #[serde(default)]
    pub(super) criteria: Option<Spanned<crate::criteria::Criteria>>,
}

#[derive(Debug, Clone, Copy, Deserialize, PartialEq)]
#[serde(rename_all = "snake_case")]
pub(super) enum ShapeKind {
    Rect,
    Circle,
}

#[derive(Debug, Clone, Copy, Deserialize, PartialEq)]
#[serde(rename_all = "snake_case")]
pub(super) enum BehaviorKind {
    None,
    Hero,
    Minion,
    DumbMinion,
}

/// The body fields shared by `[[body]]` and `[[generate]]`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawBody {
    #[serde(default)]
    pub(super) id: Option<String>,
    #[serde(default = "default_group")]
    pub(super) group: String,
    pub(super) shape: ShapeKind,
    #[serde(default)]
    pub(super) size: Option<[f64; 2]>,
    #[serde(default)]
    pub(super) radius: Option<f64>,
    #[serde(default)]
    pub(super) pos: [f64; 2],
    #[serde(default)]
    pub(super) vel: [f64; 2],
    #[serde(default = "default_mass")]
    pub(super) mass: f64,
    #[serde(default = "default_restitution")]
    pub(super) restitution: f64,
    #[serde(default = "default_friction")]
    pub(super) friction: f64,
    #[serde(default)]
    pub(super) gravity: Option<[f64; 2]>,
    #[serde(default)]
    pub(super) behavior: Option<BehaviorKind>,
}

pub(super) fn default_group() -> String {
    "default".into()
}
pub(super) fn default_mass() -> f64 {
    1.0
}
pub(super) fn default_restitution() -> f64 {
    0.8
}
pub(super) fn default_friction() -> f64 {
    0.3
}

#[derive(Debug, Clone, Copy, Deserialize, PartialEq)]
#[serde(rename_all = "snake_case")]
pub(super) enum GeneratorKind {
    /// `count` bodies from `start`, each `step` from the previous.
    Row,
    /// `cols` x `rows` bodies from `start`, `step[0]` apart on x and `step[1]` on y.
    Grid,
    /// `count` bodies stacked upward, the lowest resting its bottom on `base`.
    Stack,
    /// `levels` rows, `levels` bodies wide at the bottom and one at the top, centred on
    /// `base` with their bottom on it.
    Pyramid,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawGenerator {
    pub(super) kind: GeneratorKind,
    pub(super) id: String,
    #[serde(default = "default_group")]
    pub(super) group: String,
    pub(super) shape: ShapeKind,
    #[serde(default)]
    pub(super) size: Option<[f64; 2]>,
    #[serde(default)]
    pub(super) radius: Option<f64>,
    #[serde(default)]
    pub(super) start: [f64; 2],
    #[serde(default)]
    pub(super) step: Option<[f64; 2]>,
    #[serde(default)]
    pub(super) base: [f64; 2],
    #[serde(default)]
    pub(super) count: Option<u32>,
    #[serde(default)]
    pub(super) cols: Option<u32>,
    #[serde(default)]
    pub(super) rows: Option<u32>,
    #[serde(default)]
    pub(super) levels: Option<u32>,
    /// Space between neighbours of a stack or pyramid.
    #[serde(default)]
    pub(super) gap: f64,
    #[serde(default)]
    pub(super) vel: [f64; 2],
    #[serde(default = "default_mass")]
    pub(super) mass: f64,
    #[serde(default = "default_restitution")]
    pub(super) restitution: f64,
    #[serde(default = "default_friction")]
    pub(super) friction: f64,
    #[serde(default)]
    pub(super) gravity: Option<[f64; 2]>,
    #[serde(default)]
    pub(super) behavior: Option<BehaviorKind>,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawParticle {
    pub(super) pos: [f32; 2],
    #[serde(default)]
    pub(super) vel: [f32; 2],
    pub(super) life: f32,
    #[serde(default = "default_particle_size")]
    pub(super) size: f32,
    #[serde(default = "default_color")]
    pub(super) color: [f32; 4],
    #[serde(default)]
    pub(super) final_color: Option<[f32; 4]>,
    #[serde(default = "default_size_delta")]
    pub(super) size_delta: f32,
    #[serde(default = "default_drag")]
    pub(super) drag: f32,
    #[serde(default)]
    pub(super) gravity: Option<[f32; 2]>,
}

pub(super) fn default_particle_size() -> f32 {
    1.0
}
pub(super) fn default_color() -> [f32; 4] {
    [1.0, 1.0, 1.0, 1.0]
}
pub(super) fn default_size_delta() -> f32 {
    1.0
}
pub(super) fn default_drag() -> f32 {
    0.95
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawEmitter {
    pub(super) preset: String,
    pub(super) count: u32,
    pub(super) pos: [f32; 2],
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawInteraction {
    pub(super) a: Spanned<String>,
    pub(super) b: Spanned<String>,
    #[serde(default = "default_true")]
    pub(super) resolve: bool,
}

pub(super) fn default_true() -> bool {
    true
}
