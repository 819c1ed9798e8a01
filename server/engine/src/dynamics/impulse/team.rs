//! The threads of one frame's passes: started once a frame, then handed each pass's
//! blocks through a spinning barrier, not a thread pool's sleep and wake-up.
//!
//! A pass over a large pile lasts about a tenth of a millisecond; a pool's worker that has
//! gone to sleep between two passes takes longer than that to wake on a virtual machine (the
//! pool's hand-over made two threads slower than one on every scene of the suite). A team
//! starts its helpers once for the frame's sub-steps; between passes they spin, so a pass
//! starts on every thread within a few hundred nanoseconds. What runs where is the same as
//! with the pool (the blocks of [`super::blocks`], group `k` on thread `k`), so the bits are
//! the same for any thread count.

use std::cell::UnsafeCell;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};

/// A pass's work: group `k`'s largest measure.
type Job<'a> = dyn Fn(usize) -> f64 + Sync + 'a;

/// Spins before a waiting helper yields its core (a few microseconds of spinning; a power
/// of two).
const SPINS_BEFORE_YIELD: u32 = 1 << 12;

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
}

// SAFETY: `job` is written only by the caller, before the `epoch` bump that publishes it
// (release) and while no helper runs a job (all of the last one's are done, acquired);
// helpers read it only after seeing the bump (acquire). The closure it points to is `Sync`
// and outlives the job: `Team::run` returns only once every helper is done with it.
unsafe impl Sync for Team {}

impl Team {
    fn new(size: usize) -> Team {
        Team {
            size,
            epoch: AtomicU64::new(0),
            done: AtomicUsize::new(0),
            stop: AtomicBool::new(false),
            poisoned: AtomicBool::new(false),
            results: (0..size).map(|_| AtomicU64::new(0)).collect(),
            job: UnsafeCell::new(None),
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
        self.epoch.fetch_add(1, Ordering::Release);
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
        self.epoch.fetch_add(1, Ordering::Release);
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

/// Runs `body` with a team of `size` members (at least 1): the helpers start before it
/// and stop after it, however it ends.
pub(super) fn with_team<R>(size: usize, body: impl FnOnce(&Team) -> R) -> R {
    let team = Team::new(size.max(1));
    if team.size == 1 {
        return body(&team);
    }
    struct Finish<'a>(&'a Team);
    impl Drop for Finish<'_> {
        fn drop(&mut self) {
            self.0.finish();
        }
    }
    std::thread::scope(|scope| {
        for k in 1..team.size {
            let team = &team;
            std::thread::Builder::new()
                .name(format!("ricochet-pass-{k}"))
                .spawn_scoped(scope, move || team.help(k))
                .expect("a thread for the solver's passes");
        }
        let _finish = Finish(&team);
        body(&team)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_member_runs_each_job_once_and_the_largest_result_comes_back() {
        for size in 1..=4 {
            with_team(size, |team| {
                for round in 0..100u32 {
                    let ran: Vec<AtomicUsize> = (0..size).map(|_| AtomicUsize::new(0)).collect();
                    let largest = team.run(&|k| {
                        ran[k].fetch_add(1, Ordering::Relaxed);
                        (k as u32 * 10 + round) as f64
                    });
                    assert!(ran.iter().all(|r| r.load(Ordering::Relaxed) == 1));
                    assert_eq!(largest, ((size as u32 - 1) * 10 + round) as f64);
                }
            });
        }
    }

    #[test]
    #[should_panic(expected = "panicked")]
    fn a_helper_that_panics_makes_the_caller_panic_instead_of_waiting() {
        with_team(2, |team| {
            team.run(&|k| if k == 1 { panic!("boom") } else { 0.0 });
        });
    }
}
