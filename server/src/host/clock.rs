//! The host's clock: when the next step is due in wall time, in one place.
//!
//! Steps are due at `anchor + due x interval`: the clock never drifts with how long a
//! step or a pass of the loop took. A pause, a change of `dt` (or of the interval it
//! gives) re-anchors it at now; a loop more than [`MAX_CATCH_UP`] steps late re-anchors
//! it too, and says how many steps it dropped.

use std::time::{Duration, Instant};

use super::MAX_CATCH_UP;

/// What the host's loop does next.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Tick {
    /// Nothing is due before this long (at most [`Clock::MAX_SLEEP`], so the loop keeps
    /// serving queries and commands).
    Wait(Duration),
    /// The world is paused: nothing is due, the clock restarts from now.
    Paused,
    /// A step is due. `late` whole intervals after it was due (1 or more: an overrun);
    /// `dropped` steps were given up and the clock re-anchored (0: none).
    Step { late: u64, dropped: u64 },
}

/// When the host's steps are due.
#[derive(Clone, Debug)]
pub(super) struct Clock {
    interval: Duration,
    anchor: Instant,
    /// Steps since the anchor, the next one included.
    due: u64,
}

impl Clock {
    /// The longest the loop sleeps at once.
    pub const MAX_SLEEP: Duration = Duration::from_millis(20);

    /// A clock whose first step is due one `interval` from now.
    pub fn new(interval: Duration) -> Clock {
        Clock {
            interval,
            anchor: Instant::now(),
            due: 1,
        }
    }

    pub fn interval(&self) -> Duration {
        self.interval
    }

    /// Restarts the clock from now at `interval` (a new `dt`, or the end of a pause).
    pub fn restart(&mut self, interval: Duration) {
        self.interval = interval;
        self.anchor = Instant::now();
        self.due = 1;
    }

    /// What is due at `now`.
    pub fn tick(&mut self, now: Instant, paused: bool) -> Tick {
        let deadline = self.anchor
            + self
                .interval
                .saturating_mul(self.due.min(u32::MAX as u64) as u32);
        if now < deadline {
            return Tick::Wait((deadline - now).min(Self::MAX_SLEEP));
        }
        if paused {
            self.anchor = now;
            self.due = 1;
            return Tick::Paused;
        }
        let late = ((now - deadline).as_nanos() / self.interval.as_nanos().max(1)) as u64;
        let mut dropped = 0;
        if late > MAX_CATCH_UP {
            dropped = late;
            self.anchor = now;
            self.due = 0;
        }
        Tick::Step { late, dropped }
    }

    /// The due step was taken.
    pub fn stepped(&mut self) {
        self.due += 1;
    }
}

/// A hosted world's clock: its interval is the world's `dt`, or longer where that would
/// step faster than `max_rate`; a new `dt` or the end of a pause restarts it from now.
pub(super) struct WorldClock {
    clock: Clock,
    dt: f64,
    max_rate: f64,
}

impl WorldClock {
    pub fn new(dt: f64, max_rate: f64) -> WorldClock {
        WorldClock {
            clock: Clock::new(step_interval(dt, max_rate)),
            dt,
            max_rate,
        }
    }

    pub fn interval(&self) -> Duration {
        self.clock.interval()
    }

    /// Follows the world after a frame boundary: a new `dt`, or a world no longer paused
    /// (`resumed`), restarts the clock from now at the interval it gives.
    pub fn follow(&mut self, dt: f64, resumed: bool) {
        let interval = if dt != self.dt {
            self.dt = dt;
            step_interval(dt, self.max_rate)
        } else {
            self.clock.interval()
        };
        if interval != self.clock.interval() || resumed {
            self.clock.restart(interval);
        }
    }

    pub fn tick(&mut self, now: Instant, paused: bool) -> Tick {
        self.clock.tick(now, paused)
    }

    pub fn stepped(&mut self) {
        self.clock.stepped();
    }
}

/// The wall time between steps: `dt`, or `1 / max_rate` where that is longer (said in the
/// log: the world then runs slower than real time).
fn step_interval(dt: f64, max_rate: f64) -> Duration {
    let min_interval_ns = (1e9 / max_rate).round() as u64;
    let dt_ns = (dt * 1e9).round() as u64;
    if dt_ns < min_interval_ns {
        tracing::warn!(
            dt,
            max_rate,
            "dt is shorter than 1/max-rate: the world runs slower than real time"
        );
    }
    Duration::from_nanos(dt_ns.max(min_interval_ns))
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: Duration = Duration::from_millis(1);

    #[test]
    fn steps_fall_due_one_interval_apart_from_the_anchor() {
        let mut c = Clock::new(10 * MS);
        let t0 = c.anchor;
        assert_eq!(c.tick(t0 + 4 * MS, false), Tick::Wait(6 * MS));
        assert_eq!(
            c.tick(t0 + 10 * MS, false),
            Tick::Step {
                late: 0,
                dropped: 0
            }
        );
        c.stepped();
        // The next is due at 20 ms whatever the step cost.
        assert_eq!(c.tick(t0 + 19 * MS, false), Tick::Wait(MS));
        assert_eq!(
            c.tick(t0 + 31 * MS, false),
            Tick::Step {
                late: 1,
                dropped: 0
            }
        );
    }

    #[test]
    fn a_loop_far_behind_drops_the_lost_steps_and_re_anchors() {
        let mut c = Clock::new(10 * MS);
        let t0 = c.anchor;
        let late = t0 + 10 * MS + 10 * MS * (MAX_CATCH_UP as u32 + 2);
        match c.tick(late, false) {
            Tick::Step { dropped, .. } => assert_eq!(dropped, MAX_CATCH_UP + 2),
            other => panic!("{other:?}"),
        }
        c.stepped();
        // Re-anchored at `late`: the next step is one interval after it.
        assert_eq!(c.tick(late + 5 * MS, false), Tick::Wait(5 * MS));
    }

    #[test]
    fn a_paused_world_keeps_restarting_the_clock_and_a_wait_is_bounded() {
        let mut c = Clock::new(Duration::from_secs(1));
        let t0 = c.anchor;
        assert_eq!(c.tick(t0, false), Tick::Wait(Clock::MAX_SLEEP));
        assert_eq!(c.tick(t0 + Duration::from_secs(5), true), Tick::Paused);
        assert_eq!(
            c.tick(t0 + Duration::from_secs(5) + 999 * MS, false),
            Tick::Wait(MS)
        );
    }
}
