//! Shapes and narrow-phase collision detection.

pub mod collision;
pub mod shape;

pub use collision::{collide, separation, CollisionInfo};
pub use shape::{Aabb, Shape};
