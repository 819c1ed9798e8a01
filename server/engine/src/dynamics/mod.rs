//! Rigid bodies, their movement and the relaxation solver.

pub mod body;
pub mod broad_phase;
pub mod ccd;
pub mod config;
pub mod impulse;
pub mod integrate;
pub mod pairs;
pub mod relaxation;
pub mod setting;
pub mod sleep;

pub use body::{Body, BodyDef, BodyKey, GroupId};
pub use broad_phase::BroadPhase;
pub use config::{ConfigError, Integrator, Solver, WorldConfig};
pub use setting::Setting;
