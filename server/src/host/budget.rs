//! What commands may cost the stepping thread, in its own wall time: a budget per sender
//! and one in all, refilled with real time.
//!
//! Counting commands does not bound what they cost: a `reset`, `select` or `agitate` of a
//! large world costs as much as thousands of cheap ones. So each command is priced before
//! it runs ([`super::hosted::Hosted::price`]: by the size of what it touches), refused with
//! a reply that says why if its sender's budget or the budget in all does not hold that
//! price, and charged what it really took once it ran. The charge is the measured time,
//! not the price, so a command priced too low still pays in full: a sender that overdrew
//! waits until its budget is back above zero.
//!
//! The budget in all is what keeps the world's clock: commands may take at most
//! [`BudgetLimits::share`] of real time over any stretch longer than a burst, whoever
//! sends them, under however many sender ids. The per-sender budget shares that among
//! honest clients, whose ids zenoh gives them (a hostile peer may claim many ids: it then
//! competes for the budget in all, never beyond it).
//!
//! Refusals here are not journaled and not remembered as answers: the command never ran,
//! and the same request id sent again once the budget refilled is tried again.

use std::collections::HashMap;
use std::time::{Duration, Instant};

use super::inbox::Sender;
use super::limiter::MAX_SENDERS;

/// How much of the stepping thread's time commands may take.
#[derive(Clone, Copy, Debug)]
pub struct BudgetLimits {
    /// Fraction of real time the commands of all senders may take, over time.
    pub share: f64,
    /// Fraction of real time one sender's commands may take, over time.
    pub sender_share: f64,
    /// Time commands may take at once above their share: each budget's depth. A command
    /// priced above it is refused whatever the budgets hold.
    pub burst: Duration,
}

impl Default for BudgetLimits {
    /// A fifth of real time in all, a tenth per sender, 100 ms at once: with steps within
    /// their work limit, the world keeps its clock under any mix of accepted commands.
    fn default() -> Self {
        BudgetLimits {
            share: 0.2,
            sender_share: 0.1,
            burst: Duration::from_millis(100),
        }
    }
}

impl BudgetLimits {
    /// No budget: for trusted local runs that measure, never for a world peers can reach.
    pub fn unbounded() -> Self {
        BudgetLimits {
            share: f64::INFINITY,
            sender_share: f64::INFINITY,
            burst: Duration::MAX,
        }
    }
}

/// Seconds of the stepping thread's time left to spend; below zero after an overdraw.
#[derive(Clone, Copy, Debug)]
struct Bucket {
    left: f64,
    at: Instant,
}

impl Bucket {
    fn full(depth: f64, now: Instant) -> Self {
        Bucket {
            left: depth,
            at: now,
        }
    }

    fn refill(&mut self, now: Instant, rate: f64, depth: f64) {
        let elapsed = now.saturating_duration_since(self.at).as_secs_f64();
        if elapsed > 0.0 {
            self.left = (self.left + rate * elapsed).min(depth);
            self.at = now;
        }
    }
}

/// Why a command was not run.
#[derive(Debug, Clone, PartialEq)]
pub enum OverBudget {
    /// Priced above what any budget holds at once.
    TooCostly { price: Duration, burst: Duration },
    /// The sender's budget does not hold the price now.
    Sender { price: Duration, wait: Duration },
    /// The budget in all does not hold the price now.
    All { price: Duration, wait: Duration },
}

impl std::fmt::Display for OverBudget {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let ms = |d: &Duration| d.as_secs_f64() * 1e3;
        match self {
            OverBudget::TooCostly { price, burst } => write!(
                f,
                "this command would take about {:.1} ms of the server's time, more than the {:.0} ms any command may take at once",
                ms(price),
                ms(burst)
            ),
            OverBudget::Sender { price, wait } => write!(
                f,
                "over this sender's budget of the server's time: the command would take about {:.1} ms; retry in {:.0} ms",
                ms(price),
                ms(wait).ceil()
            ),
            OverBudget::All { price, wait } => write!(
                f,
                "over the server's budget for commands (all senders): the command would take about {:.1} ms; retry in {:.0} ms",
                ms(price),
                ms(wait).ceil()
            ),
        }
    }
}

/// The budgets of all senders.
pub struct Budgets {
    limits: BudgetLimits,
    all: Bucket,
    senders: HashMap<Sender, Bucket>,
}

impl Budgets {
    pub fn new(limits: BudgetLimits, now: Instant) -> Self {
        Budgets {
            limits,
            all: Bucket::full(limits.burst.as_secs_f64(), now),
            senders: HashMap::new(),
        }
    }

    fn depth(&self) -> f64 {
        self.limits.burst.as_secs_f64()
    }

    /// The key a sender's budget is kept under: its own while there is room, the shared
    /// anonymous one beyond [`MAX_SENDERS`].
    fn key(&self, sender: &Sender) -> Sender {
        if self.senders.contains_key(sender) || self.senders.len() < MAX_SENDERS {
            sender.clone()
        } else {
            None
        }
    }

    /// Whether a command priced `price` may run now for `sender`; if not, why.
    pub fn admit(
        &mut self,
        sender: &Sender,
        price: Duration,
        now: Instant,
    ) -> Result<(), OverBudget> {
        let (limits, depth) = (self.limits, self.depth());
        if price > limits.burst {
            return Err(OverBudget::TooCostly {
                price,
                burst: limits.burst,
            });
        }
        let need = price.as_secs_f64();
        let wait = |left: f64, rate: f64| {
            Duration::try_from_secs_f64(((need - left) / rate).max(0.0)).unwrap_or(Duration::MAX)
        };
        self.all.refill(now, limits.share, depth);
        let key = self.key(sender);
        let mine = self
            .senders
            .entry(key)
            .or_insert_with(|| Bucket::full(depth, now));
        mine.refill(now, limits.sender_share, depth);
        // A budget overdrawn by a command that took longer than its price holds the next
        // command back until it is above zero again, whatever that one's price.
        if mine.left < need || mine.left <= 0.0 && need == 0.0 {
            return Err(OverBudget::Sender {
                price,
                wait: wait(mine.left, limits.sender_share),
            });
        }
        if self.all.left < need || self.all.left <= 0.0 && need == 0.0 {
            return Err(OverBudget::All {
                price,
                wait: wait(self.all.left, limits.share),
            });
        }
        Ok(())
    }

    /// Charges `took` (the measured time of a command [`Budgets::admit`] let run) to
    /// `sender` and to the budget in all.
    pub fn charge(&mut self, sender: &Sender, took: Duration) {
        let took = took.as_secs_f64();
        self.all.left -= took;
        let key = self.key(sender);
        if let Some(mine) = self.senders.get_mut(&key) {
            mine.left -= took;
        }
    }

    /// Forgets the budgets that refilled to full: a full budget is what a new sender
    /// gets, so nothing is lost, and the map stays as small as the senders still paying.
    pub fn forget_full(&mut self, now: Instant) {
        let (rate, depth) = (self.limits.sender_share, self.depth());
        self.senders.retain(|_, b| {
            b.refill(now, rate, depth);
            b.left < depth
        });
    }

    /// Senders with a budget of their own now.
    pub fn senders(&self) -> usize {
        self.senders.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn limits() -> BudgetLimits {
        BudgetLimits {
            share: 0.2,
            sender_share: 0.1,
            burst: Duration::from_millis(100),
        }
    }

    #[test]
    fn a_sender_spends_its_burst_then_its_share_of_real_time() {
        let t0 = Instant::now();
        let mut b = Budgets::new(limits(), t0);
        let me = Some("a".to_string());
        let ms = Duration::from_millis;
        // Ten commands of 10 ms each fit the 100 ms burst; the eleventh does not.
        for _ in 0..10 {
            b.admit(&me, ms(10), t0).unwrap();
            b.charge(&me, ms(10));
        }
        let e = b.admit(&me, ms(10), t0).unwrap_err();
        let OverBudget::Sender { wait, .. } = e else {
            panic!("{e:?}")
        };
        assert!(wait > ms(99) && wait < ms(101), "{wait:?}");
        assert!(e.to_string().contains("retry in 10"), "{e}");
        // At a tenth of real time, 10 ms more are there 100 ms later.
        b.admit(&me, ms(10), t0 + ms(101)).unwrap();
    }

    #[test]
    fn many_senders_share_the_budget_in_all() {
        let t0 = Instant::now();
        let mut b = Budgets::new(limits(), t0);
        let ms = Duration::from_millis;
        let mut admitted = Duration::ZERO;
        for k in 0..100 {
            let who = Some(format!("forged-{k}"));
            if b.admit(&who, ms(10), t0).is_ok() {
                b.charge(&who, ms(10));
                admitted += ms(10);
            }
        }
        assert_eq!(
            admitted,
            ms(100),
            "the burst in all, whatever the number of ids"
        );
        let e = b.admit(&Some("honest".into()), ms(10), t0).unwrap_err();
        assert!(matches!(e, OverBudget::All { .. }), "{e:?}");
    }

    #[test]
    fn an_overdraw_is_paid_back_before_the_next_command() {
        let t0 = Instant::now();
        let mut b = Budgets::new(limits(), t0);
        let me = Some("a".to_string());
        let ms = Duration::from_millis;
        // Priced at 1 ms, took 300.
        b.admit(&me, ms(1), t0).unwrap();
        b.charge(&me, ms(300));
        // Even a free command waits until the budget is above zero: 2 s at 10%.
        assert!(b.admit(&me, Duration::ZERO, t0 + ms(1900)).is_err());
        b.admit(&me, Duration::ZERO, t0 + ms(2100)).unwrap();
    }

    #[test]
    fn a_command_priced_above_the_burst_is_refused_outright() {
        let t0 = Instant::now();
        let mut b = Budgets::new(limits(), t0);
        let e = b.admit(&None, Duration::from_millis(150), t0).unwrap_err();
        assert!(matches!(e, OverBudget::TooCostly { .. }));
        assert!(e.to_string().contains("150.0 ms"), "{e}");
    }

    #[test]
    fn full_budgets_are_forgotten_and_the_map_is_bounded() {
        let t0 = Instant::now();
        let mut b = Budgets::new(BudgetLimits::unbounded(), t0);
        for k in 0..MAX_SENDERS + 10 {
            let who = Some(k.to_string());
            b.admit(&who, Duration::from_micros(1), t0).unwrap();
            b.charge(&who, Duration::from_micros(1));
        }
        assert_eq!(
            b.senders(),
            MAX_SENDERS + 1,
            "the rest share the anonymous budget"
        );
        let mut b = Budgets::new(limits(), t0);
        let who = Some("a".to_string());
        b.admit(&who, Duration::from_millis(1), t0).unwrap();
        b.charge(&who, Duration::from_millis(1));
        b.forget_full(t0);
        assert_eq!(b.senders(), 1, "still paying back");
        b.forget_full(t0 + Duration::from_millis(20));
        assert_eq!(b.senders(), 0);
    }
}
