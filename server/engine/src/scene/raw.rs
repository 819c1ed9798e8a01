//! The scene file as read: TOML tables into these types (serde, unknown fields refused),
//! each kept with its span so errors point at the line. Checked and turned into a world
//! by the parent module.

use std::collections::BTreeMap;

use schemars::JsonSchema;
use serde::Deserialize;
use toml::Spanned;

use crate::dynamics::config::WorldConfig;
use crate::particles::ParticlePreset;

/// A scene file. Every table is optional; `groups`, a top-level key, comes before the
/// first table.
#[derive(Debug, Default, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
#[schemars(title = "Ricochet scene")]
pub(super) struct SceneFile {
    /// Groups that bodies join only at run time (spawned by the world's rules or by
    /// commands), so that an interaction may name them before any body belongs to them.
    #[serde(default)]
    #[schemars(with = "Vec<String>")]
    pub(super) groups: Vec<Spanned<String>>,
    /// The world's parameters: gravity, time step, solver and its knobs.
    #[serde(default)]
    #[schemars(with = "Option<WorldConfig>")]
    pub(super) world: Option<Spanned<WorldConfig>>,
    /// Lower limits for this world than the server's (never higher): bodies, particles,
    /// the estimated work of a step.
    #[serde(default)]
    #[schemars(with = "Option<crate::world::Limits>")]
    pub(super) limits: Option<Spanned<toml::Table>>,
    /// Particle presets by name (`[preset.NAME]`), added to the built-in ones, for
    /// `[[emitter]]` and the `spawn_particles` command.
    #[serde(default)]
    #[schemars(with = "BTreeMap<String, ParticlePreset>")]
    pub(super) preset: BTreeMap<String, Spanned<ParticlePreset>>,
    /// A rigid body, one a table.
    #[serde(default)]
    #[schemars(with = "Vec<RawBody>")]
    pub(super) body: Vec<Spanned<RawBody>>,
    /// Rows, grids, stacks and pyramids of one shape: bodies `ID/0`, `ID/1`, ...
    #[serde(default)]
    #[schemars(with = "Vec<RawGenerator>")]
    pub(super) generate: Vec<Spanned<RawGenerator>>,
    /// A particle placed by hand, one a table.
    #[serde(default)]
    #[schemars(with = "Vec<RawParticle>")]
    pub(super) particle: Vec<Spanned<RawParticle>>,
    /// Particles of a preset released over the first frames.
    #[serde(default)]
    #[schemars(with = "Vec<RawEmitter>")]
    pub(super) emitter: Vec<Spanned<RawEmitter>>,
    /// Which groups collide: only the pairs named here do.
    #[serde(default)]
    #[schemars(with = "Vec<RawInteraction>")]
    pub(super) interact: Vec<Spanned<RawInteraction>>,
    /// A body the `spawn` command may name (`{"do": "spawn", "template": NAME, "at": [x,
    /// y]}`): a `name` and a body's fields but `id` and `pos` (each spawn gets a fresh id
    /// `NAME-<n>` and its own place). At most 256.
    #[serde(default)]
    #[schemars(with = "Vec<RawTemplate>")]
    pub(super) template: Vec<Spanned<toml::Table>>,
    /// What a run of the scene must hold (`ricochet-lab suite` judges it); a criterion
    /// left out is not judged.
    #[serde(default)]
    #[schemars(with = "Option<crate::criteria::Criteria>")]
    pub(super) criteria: Option<Spanned<crate::criteria::Criteria>>,
}

#[derive(Debug, Clone, Copy, Deserialize, PartialEq, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub(super) enum ShapeKind {
    Rect,
    Circle,
}

#[derive(Debug, Clone, Copy, Deserialize, PartialEq, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub(super) enum BehaviorKind {
    None,
    Hero,
    Minion,
    DumbMinion,
}

/// A rigid body: `[[body]]`.
#[derive(Debug, Clone, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub(super) struct RawBody {
    /// The body's name in commands and replies (`body/N`, N its index, when left out).
    #[serde(default)]
    pub(super) id: Option<String>,
    /// The group it belongs to; `[[interact]]` names groups.
    #[serde(default = "default_group")]
    pub(super) group: String,
    /// `rect` (with `size`) or `circle` (with `radius`).
    pub(super) shape: ShapeKind,
    /// A rect's width and height (units, each above 0).
    #[serde(default)]
    pub(super) size: Option<[f64; 2]>,
    /// A circle's radius (units, above 0).
    #[serde(default)]
    pub(super) radius: Option<f64>,
    /// Where its centre is (units, within ±1e12).
    #[serde(default)]
    pub(super) pos: [f64; 2],
    /// Its velocity at the start (units/s); a minion's patrol speed is its x.
    #[serde(default)]
    pub(super) vel: [f64; 2],
    /// 0 for a static body (it never moves), else from 1e-9 to 1e12.
    #[serde(default = "default_mass")]
    pub(super) mass: f64,
    /// Bounciness, from 0 (none) to 1 (a bounce keeps its speed).
    #[serde(default = "default_restitution")]
    pub(super) restitution: f64,
    /// Coulomb friction coefficient, from 0 to 100.
    #[serde(default = "default_friction")]
    pub(super) friction: f64,
    /// Its own gravity (units/s²) instead of the world's.
    #[serde(default)]
    pub(super) gravity: Option<[f64; 2]>,
    /// A game behaviour: `hero` (steered by `press`), `minion` (patrols), `dumb_minion`, or `none`.
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

#[derive(Debug, Clone, Copy, Deserialize, PartialEq, JsonSchema)]
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

/// Bodies of one shape laid out by a rule: `[[generate]]`. The body fields are as in
/// `[[body]]`; a `row` needs `count` and `step`, a `stack` `count`, a `grid` `cols` and
/// `rows` (its `step` is the body's size when left out), a `pyramid` `levels`.
#[derive(Debug, Clone, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub(super) struct RawGenerator {
    /// `row`, `grid`, `stack` or `pyramid`.
    pub(super) kind: GeneratorKind,
    /// Its bodies are named `ID/0`, `ID/1`, ... in the order they are made.
    pub(super) id: String,
    /// The group it belongs to; `[[interact]]` names groups.
    #[serde(default = "default_group")]
    pub(super) group: String,
    /// `rect` (with `size`) or `circle` (with `radius`).
    pub(super) shape: ShapeKind,
    /// A rect's width and height (units, each above 0).
    #[serde(default)]
    pub(super) size: Option<[f64; 2]>,
    /// A circle's radius (units, above 0).
    #[serde(default)]
    pub(super) radius: Option<f64>,
    /// Centre of the first body of a row or grid (units).
    #[serde(default)]
    pub(super) start: [f64; 2],
    /// From one body's centre to the next: a row's step, or a grid's x and y spacing (units).
    #[serde(default)]
    pub(super) step: Option<[f64; 2]>,
    /// Where a stack's or pyramid's bottom centre rests (units).
    #[serde(default)]
    pub(super) base: [f64; 2],
    /// Bodies of a row or stack.
    #[serde(default)]
    pub(super) count: Option<u32>,
    /// Columns of a grid.
    #[serde(default)]
    pub(super) cols: Option<u32>,
    /// Rows of a grid.
    #[serde(default)]
    pub(super) rows: Option<u32>,
    /// Levels of a pyramid (the bottom one `levels` bodies wide).
    #[serde(default)]
    pub(super) levels: Option<u32>,
    /// Space between neighbours of a stack or pyramid.
    #[serde(default)]
    pub(super) gap: f64,
    /// Every body's velocity at the start (units/s).
    #[serde(default)]
    pub(super) vel: [f64; 2],
    /// 0 for a static body (it never moves), else from 1e-9 to 1e12.
    #[serde(default = "default_mass")]
    pub(super) mass: f64,
    /// Bounciness, from 0 (none) to 1 (a bounce keeps its speed).
    #[serde(default = "default_restitution")]
    pub(super) restitution: f64,
    /// Coulomb friction coefficient, from 0 to 100.
    #[serde(default = "default_friction")]
    pub(super) friction: f64,
    /// Its own gravity (units/s²) instead of the world's.
    #[serde(default)]
    pub(super) gravity: Option<[f64; 2]>,
    /// A game behaviour: `hero` (steered by `press`), `minion` (patrols), `dumb_minion`, or `none`.
    #[serde(default)]
    pub(super) behavior: Option<BehaviorKind>,
}

/// One particle: `[[particle]]`.
#[derive(Debug, Clone, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub(super) struct RawParticle {
    /// Where it starts (units).
    pub(super) pos: [f32; 2],
    /// Its velocity at the start (units/s).
    #[serde(default)]
    pub(super) vel: [f32; 2],
    /// Seconds it lives (0 or more).
    pub(super) life: f32,
    /// Its size (units, 0 or more), multiplied by `size_delta` each frame.
    #[serde(default = "default_particle_size")]
    pub(super) size: f32,
    /// Red, green, blue, alpha at birth, each from 0 to 1.
    #[serde(default = "default_color")]
    pub(super) color: [f32; 4],
    /// Colour at the end of its life (`color` when left out), blended over its life.
    #[serde(default)]
    pub(super) final_color: Option<[f32; 4]>,
    /// Factor on its size each frame (0 or more; 1 keeps it).
    #[serde(default = "default_size_delta")]
    pub(super) size_delta: f32,
    /// Factor on its velocity each frame (1: no drag).
    #[serde(default = "default_drag")]
    pub(super) drag: f32,
    /// Its own gravity (units/s²) instead of the world's `particle_gravity`.
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

/// Particles of a preset, released a few a frame: `[[emitter]]`.
#[derive(Debug, Clone, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub(super) struct RawEmitter {
    /// A built-in preset (`fire`, `smoke`, ...) or a `[preset.NAME]` of the scene.
    pub(super) preset: String,
    /// Particles it releases in all (at most the `particles_per_action` limit).
    pub(super) count: u32,
    /// Where they appear (units).
    pub(super) pos: [f32; 2],
}

/// Two groups that collide: `[[interact]]`. Each must be a group a body or generator of
/// the scene is in, or one the top-level `groups` list names.
#[derive(Debug, Clone, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub(super) struct RawInteraction {
    /// A group of bodies.
    #[schemars(with = "String")]
    pub(super) a: Spanned<String>,
    /// A group of bodies (the same as `a`: its bodies collide with each other), or
    /// `particles` for the particles.
    #[schemars(with = "String")]
    pub(super) b: Spanned<String>,
    /// Push the bodies apart (`false`: only detect the contacts).
    #[serde(default = "default_true")]
    pub(super) resolve: bool,
}

pub(super) fn default_true() -> bool {
    true
}

/// A `[[template]]` as the reference describes it (read as a table, its `name` taken out
/// and the rest read as a [`crate::action::BodySpec`]).
#[derive(JsonSchema)]
#[allow(dead_code)]
pub(super) struct RawTemplate {
    /// The name `spawn` gives as `template`.
    name: String,
    #[serde(flatten)]
    body: crate::action::BodySpec,
}
