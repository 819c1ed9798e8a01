//! Ricochet's simulation engine: the physics and particles of the book chapter
//! "Integrating Physics and Particles", as a fixed-step 2D world driven by scene files
//! and actions.
//!
//! The module tree follows the data flow of a step:
//! - [`geometry`]: shapes and narrow-phase detection (depth and normal of a pair);
//! - [`dynamics`]: bodies, world parameters, integration and the relaxation solver;
//! - [`particles`]: the particle system, presets and emitters;
//! - [`behavior`]: the demo objects (hero, minions, dye packs, dumb minions);
//! - [`world`]: the step that ties them together, and [`action`]: what clients may do;
//! - [`scene`]: scene files; [`dump`]: the JSON Lines frames of headless runs;
//! - [`host`]: the authoritative server on zenoh.

pub mod action;
pub mod behavior;
pub mod bench;
pub mod dump;
pub mod dynamics;
pub mod geometry;
pub mod host;
pub mod particles;
pub mod scene;
pub mod tradeoff;
pub mod wire;
pub mod world;

/// The names most users need.
pub mod prelude {
    pub use crate::action::{Action, ActionError, ActionOutcome};
    pub use crate::dynamics::{BodyDef, Integrator, WorldConfig};
    pub use crate::geometry::Shape;
    pub use crate::world::{StepStats, World};
}
