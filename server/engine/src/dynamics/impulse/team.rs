//! The threads of the solver's passes: a world's crew of helpers, kept from frame to
//! frame, handed each pass's blocks through a spinning barrier, not a thread pool's sleep
//! and wake-up.
//!
//! A pass over a large pile lasts about a tenth of a millisecond; a pool's worker that has
//! gone to sleep between two passes takes longer than that to wake on a virtual machine (the
//! pool's hand-over made two threads slower than one on every scene of the suite), and so
//! does starting a thread each frame. A crew's helpers spin between passes, so a pass
//! starts on every thread within a few hundred nanoseconds, and between frames for a while
//! (steps run back to back find them awake); then they park until the next frame wakes
//! them (a server stepping at 60 Hz pays one wake-up a frame). What runs where is the same as
//! with the pool (the blocks of [`super::blocks`], group `k` on thread `k`), so the bits are
//! the same for any thread count.

use std::cell::UnsafeCell;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::Arc;
use std::thread::{JoinHandle, Thread};

/// A pass's work: group `k`'s largest measure.
type Job<'a> = dyn Fn(usize) -> f64 + Sync + 'a;

/// Spins before a waiting helper yields its core (a few microseconds of spinning; a power
/// of two).
const SPINS_BEFORE_YIELD: u32 = 1 << 12;

/// Yields (of [`SPINS_BEFORE_YIELD`] spins each) before an idle helper parks: a
/// millisecond or two awake after the last job.
const YIELDS_BEFORE_PARK: u32 = 8;

/// The threads of one frame: the caller (member 0) and `size - 1` helpers.
pub(super) struct Team {
    size: usize,
    /// Bumped once per job (and once to stop); helpers start a job when it changes.
    epoch: AtomicU64,
    /// Helpers done with the current job.
    done: AtomicUsize,
    stop: AtomicBool,
    /// A helper's job panicked: the caller panics too, instead of waiting for ever.
    poisoned: AtomicBool,
    /// Each member's result, as bits.
    results: Vec<AtomicU64>,
    /// The current job, set by the caller before it bumps `epoch`.
    job: UnsafeCell<Option<*const Job<'static>>>,
    /// Each helper's thread (set once started) and whether it is parked or about to.
    threads: std::sync::OnceLock<Vec<Thread>>,
    parked: Vec<AtomicBool>,
}

// SAFETY: `job` is written only by the caller, before the `epoch` bump that publishes it
// (release) and while no helper runs a job (all of the last one's are done, acquired);
// helpers read it only after seeing the bump (acquire). The closure it points to is `Sync`
// and outlives the job: `Team::run` returns only once every helper is done with it.
unsafe impl Sync for Team {}

// SAFETY: the job pointer is the only field that is not `Send`; it is only read under the
// protocol above, whichever thread holds the team.
unsafe impl Send for Team {}

impl Team {
    /// The team of the caller alone (`run` calls the job and returns), shared by every
    /// world: it has no helpers and no state a run changes.
    pub(super) fn alone() -> &'static Team {
        static ALONE: std::sync::OnceLock<Team> = std::sync::OnceLock::new();
        ALONE.get_or_init(|| Team::new(1))
    }

    fn new(size: usize) -> Team {
        Team {
            size,
            epoch: AtomicU64::new(0),
            done: AtomicUsize::new(0),
            stop: AtomicBool::new(false),
            poisoned: AtomicBool::new(false),
            results: (0..size).map(|_| AtomicU64::new(0)).collect(),
            job: UnsafeCell::new(None),
            threads: std::sync::OnceLock::new(),
            parked: (0..size).map(|_| AtomicBool::new(false)).collect(),
        }
    }

    /// Bumps the epoch (publishing a job or the stop) and wakes the parked helpers.
    fn wake(&self) {
        self.epoch.fetch_add(1, Ordering::SeqCst);
        if let Some(threads) = self.threads.get() {
            for (k, t) in threads.iter().enumerate() {
                if self.parked[k + 1].load(Ordering::SeqCst) {
                    t.unpark();
                }
            }
        }
    }

    /// Members, the caller included.
    pub(super) fn size(&self) -> usize {
        self.size
    }

    /// Runs `job(k)` on member `k` for every member (the caller takes 0) and returns the
    /// largest result, once every member is done.
    pub(super) fn run(&self, job: &Job<'_>) -> f64 {
        if self.size == 1 {
            return job(0);
        }
        // SAFETY: the lifetime is erased only for the helpers' reads, which all end before
        // this function returns (see the `Sync` impl).
        let erased: *const Job<'static> = unsafe { std::mem::transmute(job as *const Job<'_>) };
        unsafe { *self.job.get() = Some(erased) };
        self.done.store(0, Ordering::Relaxed);
        self.wake();
        // The caller's share may panic: the helpers must be done with `job` before it
        // unwinds past the closure they read.
        let mine = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| job(0)));
        let mut spins = 0u32;
        while self.done.load(Ordering::Acquire) < self.size - 1 {
            spin(&mut spins);
        }
        let mine = mine.unwrap_or_else(|e| std::panic::resume_unwind(e));
        if self.poisoned.load(Ordering::Relaxed) {
            panic!("a thread of the solver's passes panicked");
        }
        self.results[1..]
            .iter()
            .map(|r| f64::from_bits(r.load(Ordering::Relaxed)))
            .fold(mine, f64::max)
    }

    /// Member `k`'s loop: each new job once, until stopped.
    fn help(&self, k: usize) {
        let mut seen = 0u64;
        loop {
            let mut spins = 0u32;
            let epoch = loop {
                let e = self.epoch.load(Ordering::Acquire);
                if e != seen {
                    break e;
                }
                if spins >= SPINS_BEFORE_YIELD * YIELDS_BEFORE_PARK {
                    // Idle for a while: park, telling the caller first, then looking once
                    // more (a job published in between is not missed: the caller wakes a
                    // parked helper after publishing, and an early unpark is kept).
                    self.parked[k].store(true, Ordering::SeqCst);
                    if self.epoch.load(Ordering::SeqCst) == seen {
                        std::thread::park();
                    }
                    self.parked[k].store(false, Ordering::SeqCst);
                    spins = 0;
                    continue;
                }
                spin(&mut spins);
            };
            seen = epoch;
            if self.stop.load(Ordering::Acquire) {
                return;
            }
            // SAFETY: published before the epoch bump just seen (see the `Sync` impl).
            let job = unsafe { (*self.job.get()).map(|j| &*j) };
            let result = match job {
                Some(job) => std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| job(k)))
                    .unwrap_or_else(|_| {
                        self.poisoned.store(true, Ordering::Relaxed);
                        0.0
                    }),
                None => 0.0,
            };
            self.results[k].store(result.to_bits(), Ordering::Relaxed);
            self.done.fetch_add(1, Ordering::Release);
        }
    }

    fn finish(&self) {
        self.stop.store(true, Ordering::Release);
        self.wake();
    }
}

/// Waits a little: spins, then yields the core now and then (a helper whose caller does
/// serial work must not starve it on a loaded machine).
#[inline]
fn spin(spins: &mut u32) {
    *spins += 1;
    if *spins & (SPINS_BEFORE_YIELD - 1) == 0 {
        std::thread::yield_now();
    } else {
        std::hint::spin_loop();
    }
}

/// A world's helpers for the solver's passes, started when a frame first asks for a team
/// of their size and kept for the frames after (a clone of the world starts its own).
#[derive(Default)]
pub struct Crew {
    team: Option<(Arc<Team>, Vec<JoinHandle<()>>)>,
}

impl Clone for Crew {
    fn clone(&self) -> Self {
        Crew::default()
    }
}

impl std::fmt::Debug for Crew {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let size = self.team.as_ref().map_or(1, |(t, _)| t.size);
        write!(f, "Crew {{ size: {size} }}")
    }
}

impl Crew {
    /// The team of `size` members (at least 1; the caller is member 0), its helpers
    /// started if the crew had another size.
    pub(super) fn team(&mut self, size: usize) -> Arc<Team> {
        let size = size.max(1);
        match &self.team {
            Some((team, _)) if team.size == size => return Arc::clone(team),
            _ => {}
        }
        self.stop();
        let team = Arc::new(Team::new(size));
        let helpers: Vec<JoinHandle<()>> = (1..size)
            .map(|k| {
                let team = Arc::clone(&team);
                std::thread::Builder::new()
                    .name(format!("ricochet-pass-{k}"))
                    .spawn(move || team.help(k))
                    .expect("a thread for the solver's passes")
            })
            .collect();
        let _ = team
            .threads
            .set(helpers.iter().map(|h| h.thread().clone()).collect());
        self.team = Some((Arc::clone(&team), helpers));
        team
    }

    fn stop(&mut self) {
        if let Some((team, helpers)) = self.team.take() {
            team.finish();
            for h in helpers {
                let _ = h.join();
            }
        }
    }
}

impl Drop for Crew {
    fn drop(&mut self) {
        self.stop();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_member_runs_each_job_once_and_the_largest_result_comes_back() {
        let mut crew = Crew::default();
        for size in [1, 2, 3, 4, 2] {
            let team = crew.team(size);
            {
                for round in 0..100u32 {
                    let ran: Vec<AtomicUsize> = (0..size).map(|_| AtomicUsize::new(0)).collect();
                    let largest = team.run(&|k| {
                        ran[k].fetch_add(1, Ordering::Relaxed);
                        (k as u32 * 10 + round) as f64
                    });
                    assert!(ran.iter().all(|r| r.load(Ordering::Relaxed) == 1));
                    assert_eq!(largest, ((size as u32 - 1) * 10 + round) as f64);
                }
            }
            // Idle long enough to park, then woken by the next job.
            std::thread::sleep(std::time::Duration::from_millis(20));
            assert_eq!(team.run(&|k| k as f64), (size - 1) as f64);
        }
    }

    #[test]
    #[should_panic(expected = "panicked")]
    fn a_helper_that_panics_makes_the_caller_panic_instead_of_waiting() {
        let mut crew = Crew::default();
        let team = crew.team(2);
        team.run(&|k| if k == 1 { panic!("boom") } else { 0.0 });
    }
}
