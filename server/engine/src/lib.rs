//! Ricochet's simulation engine: the physics and particles of the book chapter
//! "Integrating Physics and Particles", as a fixed-step 2D world driven by scene files
//! and actions. It knows nothing of networks, plots or command lines: scene text and
//! typed [`action::Action`]s flow in; the world's state and each step's figures
//! ([`world::StepStats`]) flow out.
//!
//! The module tree follows the data flow of a step:
//! - [`geometry`]: shapes and narrow-phase detection (depth and normal of a pair);
//! - [`dynamics`]: bodies, the world's parameters and settings, broad phases,
//!   integration and the solvers (the chapter's relaxation, sequential impulses);
//! - [`particles`]: the particle system, presets and emitters;
//! - [`world`]: the body store, the step pipeline that ties the above together, the
//!   chapter demo's behaviours and the actions;
//! - [`scene`]: scene files, refused with file, line and field;
//! - [`criteria`]: what a scene's user expects of a run (`[criteria]`), and the monitor
//!   that measures a run against it.

pub mod action;
pub mod behavior;
pub mod criteria;
pub mod dynamics;
pub mod geometry;
pub mod parallel;
pub mod particles;
pub mod scene;
pub mod world;

/// The names most users need.
pub mod prelude {
    pub use crate::action::{Action, ActionError, ActionOutcome, Direction};
    pub use crate::dynamics::{BodyDef, Integrator, Setting, Solver, WorldConfig};
    pub use crate::geometry::Shape;
    pub use crate::world::{StepStats, World};
}
