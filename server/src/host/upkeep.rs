//! The host's upkeep between steps: events for dropped commands, the heap's free pages
//! given back, and a log line for what was turned away.

use std::sync::atomic::Ordering;
use std::time::Instant;

use ricochet_protocol::command::{Event, Health};

use super::budget::Budgets;
use super::hosted::Hosted;
use super::inbox::Inbox;
use super::outbox::Outbox;
use super::{memory, DROPS_EVERY, TRIM_EVERY};

/// When upkeep last ran, and the counts it saw then.
pub(super) struct Upkeep {
    last_report: (Instant, Health),
    last_drops: (Instant, [u64; 3]),
}

impl Upkeep {
    pub fn new() -> Upkeep {
        Upkeep {
            last_report: (Instant::now(), Health::default()),
            last_drops: (Instant::now(), [0; 3]),
        }
    }

    /// Every [`DROPS_EVERY`]: the budgets' full senders forgotten and an event for the
    /// commands dropped since; every [`TRIM_EVERY`]: memory given back and a warning for
    /// what was turned away since.
    pub fn run(&mut self, host: &Hosted, inbox: &Inbox, outbox: &Outbox, budgets: &mut Budgets) {
        if self.last_drops.0.elapsed() >= DROPS_EVERY {
            budgets.forget_full(Instant::now());
            let now = inbox.turned.unanswered.counts();
            if let Some(event) = drops_event(host.world.frame(), self.last_drops.1, now) {
                outbox.publish_event(&event);
            }
            self.last_drops = (Instant::now(), now);
        }
        if self.last_report.0.elapsed() >= TRIM_EVERY {
            memory::give_back_memory();
            let now = health(host, inbox, outbox);
            let before = &self.last_report.1;
            let turned =
                |h: &Health| h.refused + h.rate_limited + h.queue_full + h.unsent + h.over_budget;
            if turned(&now) > turned(before) {
                tracing::warn!(
                    refused = now.refused - before.refused,
                    rate_limited = now.rate_limited - before.rate_limited,
                    queue_full = now.queue_full - before.queue_full,
                    unsent = now.unsent - before.unsent,
                    over_budget = now.over_budget - before.over_budget,
                    "turned away in the last 10 s"
                );
            }
            self.last_report = (Instant::now(), now);
        }
    }
}

/// The server's counts now.
pub(super) fn health(host: &Hosted, inbox: &Inbox, outbox: &Outbox) -> Health {
    let load = |a: &std::sync::atomic::AtomicU64| a.load(Ordering::Relaxed);
    Health {
        overruns: u64::from(host.stepping.overruns),
        rate_limited: load(&inbox.turned.rate_limited),
        queue_full: load(&inbox.turned.queue_full),
        refused: host.accounts.health.refused + load(&inbox.turned.too_large),
        unsent: load(&outbox.unsent) + load(&inbox.turned.queries_dropped),
        ..host.accounts.health.clone()
    }
}

/// The event telling subscribers that fire-and-forget commands were dropped since the
/// counts `before` (too large, over the rate, queue full), if any were: they had no reply
/// to carry the refusal.
fn drops_event(frame: u64, before: [u64; 3], now: [u64; 3]) -> Option<Event> {
    let [large, rate, full] = [0, 1, 2].map(|k| now[k].saturating_sub(before[k]));
    let total = large + rate + full;
    (total > 0).then(|| Event {
        frame,
        ok: false,
        command: None,
        ids: Vec::new(),
        error: Some(format!(
            "dropped {total} command(s) sent without a reply key since the last such event: \
             {large} over the size limit, {rate} over their sender's rate, {full} with the queue full"
        )),
    })
}
