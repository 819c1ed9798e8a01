//! Shapes and narrow-phase collision detection.
//!
//! In: two shapes and their positions. Out: whether they overlap, and by how much along
//! which normal (or their separation, for speculative contacts). And the uniform grid
//! broad phases bin boxes in ([`grid::Grid`]).

pub mod collision;
pub mod grid;
pub mod shape;

pub use collision::{collide, separation, CollisionInfo};
pub use shape::{Aabb, Shape};
