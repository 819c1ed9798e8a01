//! Particles, particle presets and emitters.
//!
//! In: presets (recipes), emitters and the world's random generator, and the shapes
//! particles collide with. Out: particles moved, aged, coloured and projected out of
//! shapes, in flat arrays a frame encoder reads directly.

pub mod emitter;
pub mod preset;
pub mod shapes;
pub mod system;

pub use emitter::Emitter;
pub use preset::{ParticlePreset, PresetLibrary, Sample};
pub use system::{color_after, size_after, ParticleDef, Particles};
