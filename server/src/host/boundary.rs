//! The frame boundary: the commands and requests that arrived since the last pass, applied
//! up to a bound in count and in wall time; the steps `step` commands asked for, in
//! slices; and the replies those steps made due.

use std::time::Instant;

use super::apply::{self, apply_incoming};
use super::serve::Serving;
use super::{boundary_budget, MAX_COMMANDS_PER_FRAME, STEP_SLICE};

impl Serving {
    /// Applies what arrived, [`MAX_COMMANDS_PER_FRAME`] at most and for at most
    /// [`boundary_budget`] of wall time; a new world's frame 0 goes out at once.
    pub(super) fn frame_boundary(&mut self) {
        let (boundary, budget) = (Instant::now(), boundary_budget(self.clock.interval()));
        for _ in 0..MAX_COMMANDS_PER_FRAME {
            if boundary.elapsed() >= budget {
                break;
            }
            let Some(incoming) = self.wiring.inbox.next() else {
                break;
            };
            apply_incoming(
                &mut self.host,
                incoming,
                apply::Boundary {
                    answered: &mut self.answered,
                    budgets: &mut self.budgets,
                    deferred: &mut self.deferred,
                    journal: &mut self.journal,
                    outbox: &self.wiring.outbox,
                    slot: self.slot.as_ref(),
                },
            );
            if self.host.stepping.fresh {
                self.publisher.frame(&mut self.host);
            }
        }
    }

    /// Runs the steps `step` commands asked for, for at most [`STEP_SLICE`].
    pub(super) fn run_asked_steps(&mut self) {
        let began = Instant::now();
        while self.host.stepping.pending_steps > 0 && began.elapsed() < STEP_SLICE {
            self.advance();
        }
    }

    /// Sends the replies to `step` commands whose steps have all run.
    pub(super) fn reply_due(&mut self) {
        if self.deferred.is_empty() {
            return;
        }
        let steps_run = self.host.stepping.steps_run;
        let (ready, waiting): (Vec<_>, Vec<_>) = self
            .deferred
            .drain(..)
            .partition(|d| d.due_at_step <= steps_run);
        self.deferred = waiting;
        for d in ready {
            self.wiring.outbox.reply(d.query, d.reply.into_vec());
        }
    }
}
