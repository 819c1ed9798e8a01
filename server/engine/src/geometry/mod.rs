//! Shapes and narrow-phase collision detection.
//!
//! In: two shapes and their positions. Out: whether they overlap, and by how much along
//! which normal (or their separation, for speculative contacts). And what the broad phases
//! keep boxes in: the uniform grid of a large all-static group ([`grid::Grid`]) and the
//! dynamic tree of the persistent pair set ([`tree::Tree`]).

pub mod collision;
pub mod grid;
pub mod shape;
pub mod tree;

pub use collision::{collide, separation, CollisionInfo};
pub use shape::{Aabb, Shape};
