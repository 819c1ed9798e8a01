//! Frames of a headless run, one JSON object per line (JSON Lines).
//!
//! Line 0 is the state before the first step, line k the state after k steps:
//!
//! ```json
//! {"frame":1,"t":0.016666666666666666,
//!  "bodies":[{"id":"hero","x":30.0,"y":29.98,"vx":0.0,"vy":-1.19,"collided":false}],
//!  "particles":[{"x":10.0,"y":5.0,"size":4.2,"color":[1.0,0.0,0.0,1.0]}],
//!  "emitters":1}
//! ```
//!
//! Bodies keep their scene ids (generated ones are `<generator id>/<index>`), in the
//! world's order. Body numbers are 64-bit floats, particle numbers 32-bit; both are
//! written in the shortest form that reads back to the same bits, so a dump compares
//! bit for bit.

use serde::{Deserialize, Serialize};

/// The state of a world after `frame` steps.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FrameRecord {
    /// Steps taken.
    pub frame: u64,
    /// Simulated seconds: `frame * dt`.
    pub t: f64,
    pub bodies: Vec<BodyRecord>,
    pub particles: Vec<ParticleRecord>,
    /// Emitters still releasing particles.
    pub emitters: usize,
}

/// One rigid body.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BodyRecord {
    pub id: String,
    pub x: f64,
    pub y: f64,
    pub vx: f64,
    pub vy: f64,
    /// Touched by a rigid collision during the step that produced this frame.
    pub collided: bool,
}

/// One particle.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ParticleRecord {
    pub x: f32,
    pub y: f32,
    pub size: f32,
    /// RGBA; components above 1 are oversaturated (drawn as bright).
    pub color: [f32; 4],
}

/// What one step did, as `simulate --stats` writes it: one JSON object per line, line k
/// for step k (1-based). Every figure is counted by the engine as the step runs; wall
/// times are left out, so the file is as deterministic as the dump.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StatsRecord {
    pub frame: u64,
    /// Rigid pair resolutions (or detections, in detect-only interactions).
    pub contacts: u64,
    /// Solver passes run (relaxation passes over interactions, or impulse velocity
    /// passes over sub-steps).
    pub passes: u64,
    /// Deepest rigid penetration detected during the step.
    pub deepest_penetration: f64,
    /// Kinetic energy of the rigid bodies after the step.
    pub kinetic_energy: f64,
    /// Particles projected out of shapes.
    pub particle_contacts: u64,
    /// Bodies asleep after the step.
    pub sleeping: u64,
    /// Mechanical energy change of the dynamic bodies over the step.
    #[serde(default)]
    pub energy_change: f64,
    /// What the solver's last pass still corrected, as a distance.
    #[serde(default)]
    pub residual: f64,
}

impl FrameRecord {
    /// The body with this id.
    pub fn body(&self, id: &str) -> Option<&BodyRecord> {
        self.bodies.iter().find(|b| b.id == id)
    }
}

/// Reads a whole dump. Each error names its line (0-based, the frame number).
pub fn read_dump(text: &str) -> Result<Vec<FrameRecord>, String> {
    text.lines()
        .enumerate()
        .map(|(i, line)| serde_json::from_str(line).map_err(|e| format!("dump line {i}: {e}")))
        .collect()
}
