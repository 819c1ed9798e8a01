//! Rigid bodies, the world's parameters, and what moves them: integration, broad phases
//! and the solvers (the chapter's relaxation, sequential impulses).
//!
//! In: bodies, candidate pairs and the world's parameters ([`WorldConfig`], changed one
//! typed [`Setting`] at a time). Out: bodies moved and resolved for one step, with the
//! figures of the solve (contacts, passes run, deepest penetration).

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
