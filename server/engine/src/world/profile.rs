//! What each stage of the last step took by the wall clock, as Box2D's `b2Profile`: for
//! finding where a step's time goes. It is not one of the step's figures
//! ([`super::StepStats`], written to deterministic outputs) and nothing simulated reads
//! it. Only a profiled world ([`super::World::set_profiling`]) reads the clock: the rest
//! pay nothing for it.

use std::time::{Duration, Instant};

pub use crate::dynamics::impulse::SolveTimes;

/// The wall-clock time of each stage of the last [`super::World::step`] of a profiled
/// world (all zero otherwise). A stage with nothing to do (no behaviours, no particles,
/// sleeping off, the relaxation's broad phase) reads zero.
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
    /// The impulse solver's stages inside `rigid` (zero under the relaxation).
    pub solve: SolveTimes,
}

/// A stopwatch handing out the time since its last reading: one clock reading a stage, or
/// none at all when the world is not profiled.
pub(super) struct Laps {
    /// The start and the last reading; `None`: off, every lap is zero.
    readings: Option<(Instant, Instant)>,
}

impl Laps {
    /// A stopwatch that reads the clock only when `on`.
    pub(super) fn start(on: bool) -> Laps {
        Laps {
            readings: on.then(|| {
                let now = Instant::now();
                (now, now)
            }),
        }
    }

    /// The time since the last lap (or the start).
    pub(super) fn lap(&mut self) -> Duration {
        let Some((_, last)) = self.readings.as_mut() else {
            return Duration::ZERO;
        };
        let now = Instant::now();
        let lap = now - *last;
        *last = now;
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
        self.readings
            .map_or(Duration::ZERO, |(start, last)| last - start)
    }
}
