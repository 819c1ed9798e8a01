//! Particles, particle presets and emitters.

pub mod emitter;
pub mod preset;
pub mod system;

pub use emitter::Emitter;
pub use preset::{ParticlePreset, PresetLibrary, Sample};
pub use system::{ParticleDef, Particles};
