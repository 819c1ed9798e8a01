//! Rigid bodies, their movement and the relaxation solver.

pub mod body;
pub mod config;
pub mod integrate;
pub mod relaxation;

pub use body::{Body, BodyDef, BodyKey, GroupId};
pub use config::{Integrator, WorldConfig};
