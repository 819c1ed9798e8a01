//! The serving loop: one pass answers queries, applies the commands that arrived at the
//! frame boundary, runs the steps `step` commands asked for, does the upkeep, and steps
//! the world when the clock says a step is due. Each part is a method in a file of its
//! own: [`super::queries`], [`super::boundary`], [`super::upkeep`], [`super::clock`].

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::Instant;

use anyhow::Result;

use super::answered::Answered;
use super::apply::Deferred;
use super::budget::Budgets;
use super::clock::{Tick, WorldClock};
use super::hosted::Hosted;
use super::journal::Journal;
use super::publish::Publisher;
use super::queries::StateCache;
use super::start::Started;
use super::upkeep::Upkeep;
use super::wiring::Wiring;
use super::worlds::Slot;
use super::HostOptions;

/// A world being served, and everything the loop keeps between passes.
pub(super) struct Serving {
    pub host: Hosted,
    pub answered: Answered,
    pub journal: Option<Journal>,
    pub opts: HostOptions,
    pub wiring: Wiring,
    pub publisher: Publisher,
    pub clock: WorldClock,
    /// Replies to `step` commands, due once their steps have run.
    pub deferred: Vec<Deferred>,
    pub budgets: Budgets,
    pub state: StateCache,
    pub upkeep: Upkeep,
    /// Its place among the worlds this server serves (`fork`, `close`).
    pub slot: Option<Slot>,
    /// The signal that asked the server to stop (SIGTERM, SIGINT), 0 until one has.
    pub stop: Arc<AtomicUsize>,
}

impl Serving {
    /// Serves `started` on `wiring`, its frames through `publisher`.
    pub fn new(
        started: Started,
        wiring: Wiring,
        publisher: Publisher,
        stop: Arc<AtomicUsize>,
    ) -> Serving {
        let Started {
            host,
            answered,
            journal,
            opts,
        } = started;
        Serving {
            clock: WorldClock::new(host.world.config.dt, opts.max_rate),
            budgets: Budgets::new(opts.budget, Instant::now()),
            host,
            answered,
            journal,
            opts,
            wiring,
            publisher,
            deferred: Vec::new(),
            state: StateCache::default(),
            upkeep: Upkeep::new(),
            slot: None,
            stop,
        }
    }

    /// Served in `slot`, among the worlds of its server.
    pub fn in_slot(mut self, slot: Slot) -> Serving {
        self.slot = Some(slot);
        self
    }

    /// Serves until `max_frames`, or until a signal asks it to stop, or `close` does (or
    /// forever).
    pub fn run(mut self) -> Result<()> {
        // Frame 0: the state before the first step.
        self.publisher.frame(&mut self.host);
        loop {
            self.wiring.inbox.set_frame(self.host.world.frame());
            // A change of the statics held back by their rate goes out once it is due.
            self.publisher.statics(&mut self.host);
            self.answer_queries();
            let was_paused = self.host.stepping.paused;
            self.frame_boundary();
            self.run_asked_steps();
            self.reply_due();
            self.answered.forget();
            let Wiring { inbox, outbox, .. } = &self.wiring;
            self.upkeep
                .run(&self.host, inbox, outbox, &mut self.budgets);
            self.clock.follow(
                self.host.world.config.dt,
                was_paused && !self.host.stepping.paused,
            );
            if self.slot.as_ref().is_some_and(Slot::stopping) {
                return Ok(());
            }
            if self
                .opts
                .max_frames
                .is_some_and(|m| self.host.world.frame() >= m)
            {
                tracing::info!(
                    frame = self.host.world.frame(),
                    overruns = self.host.stepping.overruns,
                    "stopping after the last frame"
                );
                return Ok(());
            }
            let signal = self.stop.load(Ordering::Relaxed);
            if signal != 0 {
                self.stop(signal);
                return Ok(());
            }
            if self.host.stepping.pending_steps > 0 {
                // More steps to run: serve the others, then the next slice, without sleeping.
                continue;
            }
            if self.step_due() {
                self.advance();
                self.clock.stepped();
                self.checkpoint_if_due();
            }
        }
    }

    /// Whether the clock has a step due now (after sleeping until it is, at most
    /// [`super::clock::Clock::MAX_SLEEP`]); late steps are counted.
    fn step_due(&mut self) -> bool {
        match self.clock.tick(Instant::now(), self.host.stepping.paused) {
            Tick::Wait(wait) => {
                std::thread::sleep(wait);
                false
            }
            Tick::Paused => false,
            Tick::Step { late, dropped } => {
                let host = &mut self.host;
                if late >= 1 {
                    host.stepping.overruns = host.stepping.overruns.saturating_add(1);
                }
                if dropped > 0 {
                    tracing::warn!(
                        late_steps = dropped,
                        frame = host.world.frame(),
                        "the world cannot keep real time; the clock re-anchors"
                    );
                    host.stepping.overruns = host
                        .stepping
                        .overruns
                        .saturating_add(dropped.min(u32::MAX as u64) as u32);
                }
                true
            }
        }
    }

    /// One step of the world, as the clock or a `step` command takes it: stepped (counted
    /// against pending `step`s), published, and journalled.
    pub fn advance(&mut self) {
        self.host.advance();
        self.publisher.frame(&mut self.host);
        if let Some(journal) = self.journal.as_mut() {
            journal.stepped(
                self.host.world.frame(),
                f64::from(self.host.stepping.last_step_ms),
            );
        }
    }

    /// Stops on `signal` (a `systemctl stop`, a `docker stop`, a Ctrl-C): a journaled
    /// world is checkpointed as it is, so the same command line resumes it from this frame
    /// with nothing to replay; said in the log either way.
    fn stop(&mut self, signal: usize) {
        let signal = match signal as i32 {
            libc::SIGTERM => "SIGTERM",
            libc::SIGINT => "SIGINT",
            _ => "a signal",
        };
        let frame = self.host.world.frame();
        let Some(journal) = self.journal.as_mut() else {
            tracing::info!(frame, "stopping on {signal}");
            return;
        };
        if self.host.stepping.pending_steps > 0 || !self.deferred.is_empty() {
            // A checkpoint never holds steps still to run: the journal's lines do.
            tracing::info!(
                frame,
                pending_steps = self.host.stepping.pending_steps,
                "stopping on {signal}; `step` commands in flight, so no checkpoint: the journal's lines resume them"
            );
            return;
        }
        match journal.checkpoint_now(&self.host, &self.answered, &self.opts.world, &self.opts) {
            Ok(file) => tracing::info!(
                frame,
                checkpoint = %file.display(),
                "stopping on {signal}; the world is checkpointed beside its journal"
            ),
            Err(e) => tracing::error!(
                frame,
                "stopping on {signal}: {e:#}; a resume replays the journal"
            ),
        }
    }

    /// The journal's bound: a checkpoint, once no `step` command is in flight (a resume
    /// finds its remaining steps in the journal's lines, never in a checkpoint).
    fn checkpoint_if_due(&mut self) {
        if let Some(j) = self.journal.as_mut() {
            j.poll(false);
            if j.checkpoint_due()
                && self.host.stepping.pending_steps == 0
                && self.deferred.is_empty()
            {
                j.checkpoint(&self.host, &self.answered, &self.opts.world, &self.opts);
            }
        }
    }
}
