//! Shapes and narrow-phase collision detection.
//!
//! In: two shapes and their positions. Out: whether they overlap, and by how much along
//! which normal (or their separation, for speculative contacts). And what the broad phases
//! keep boxes in: the uniform grid of a large all-static group ([`grid::Grid`]), and the
//! persistent pair set's two tiers ([`tiered::Tiered`]: that grid for small boxes, a
//! dynamic tree, [`tree::Tree`], for large or fast ones).

pub mod collision;
pub mod grid;
pub mod shape;
pub mod tiered;
pub mod tree;

pub use collision::{collide, separation, CollisionInfo};
pub use shape::{Aabb, Shape};
