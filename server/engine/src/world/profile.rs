//! What each stage of the last step took by the wall clock, as Box2D's `b2Profile`: for
//! finding where a step's time goes. It is not one of the step's figures
//! ([`super::StepStats`], written to deterministic outputs) and nothing simulated reads
//! it.

use std::time::{Duration, Instant};

/// The wall-clock time of each stage of the last [`super::World::step`]. A stage with
/// nothing to do (no behaviours, no particles, sleeping off, the relaxation's broad
/// phase) reads zero.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StepProfile {
    /// The whole step.
    pub step: Duration,
    /// The game rules before the motion (the demo's behaviours).
    pub hooks: Duration,
    /// The broad phase of the impulse solver (zero under the relaxation, which finds each
    /// interaction's pairs inside the rigid stage); on the first frame, the settling of
    /// the resting load too.
    pub broad_phase: Duration,
    /// The rigid stage: motion and resolution, the game rules after the motion included.
    pub rigid: Duration,
    /// Particles moved, expired ones removed, emitters emitting.
    pub particles_move: Duration,
    /// Particles projected out of the shapes of their interactions.
    pub particle_interactions: Duration,
    /// Sleepers frozen before the step and thawed after, islands put to sleep, collided
    /// flags cleared.
    pub sleep: Duration,
    /// The energies of the step's figures.
    pub energy: Duration,
}

/// A stopwatch handing out the time since its last reading: one clock reading a stage.
pub(super) struct Laps {
    start: Instant,
    last: Instant,
}

impl Laps {
    pub(super) fn start() -> Laps {
        let now = Instant::now();
        Laps {
            start: now,
            last: now,
        }
    }

    /// The time since the last lap (or the start).
    pub(super) fn lap(&mut self) -> Duration {
        let now = Instant::now();
        let lap = now - self.last;
        self.last = now;
        lap
    }

    /// [`Laps::lap`] for a stage that had work; a stage that had none is not timed (zero)
    /// and its few nanoseconds go to the next: a clock reading costs as much as an idle
    /// stage, and a small world's step is a few microseconds.
    pub(super) fn lap_if(&mut self, had_work: bool) -> Duration {
        if had_work {
            self.lap()
        } else {
            Duration::ZERO
        }
    }

    /// The time from the start to the last lap.
    pub(super) fn total(&self) -> Duration {
        self.last - self.start
    }
}
