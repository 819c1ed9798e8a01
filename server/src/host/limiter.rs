//! Each sender's rate of commands or queries, on `governor`'s keyed limiter: a bucket a
//! sender (GCRA, which lets a burst through at once and then the rate), its memory bounded
//! by forgetting the senders whose buckets are full again and, past [`MAX_SENDERS`], by
//! newcomers sharing the anonymous sender's bucket.
//!
//! Which senders get a key of their own is [`super::peers::Peers::bucket`]'s to say: by
//! default only connected sessions, so the cap is reached only by a server that trusts
//! every claimed id (`--sender-ids claimed`).

use std::num::NonZeroU32;
use std::time::Duration;

use governor::clock::{Clock, DefaultClock};
use governor::middleware::NoOpMiddleware;
use governor::state::keyed::HashMapStateStore;
use governor::{Quota, RateLimiter};

use super::inbox::Sender;

/// Senders with a bucket of their own at most; others share the anonymous one.
pub const MAX_SENDERS: usize = 4096;

/// Buckets of `rate` a second and `burst` at once, one a sender.
pub struct SenderLimiter<C: Clock = DefaultClock> {
    limiter: RateLimiter<Sender, HashMapStateStore<Sender>, C, NoOpMiddleware<C::Instant>>,
}

/// `rate` a second over time, `burst` at once (both at least 1, as the flags require).
fn quota(rate: f64, burst: f64) -> Quota {
    let period = Duration::try_from_secs_f64(1.0 / rate.max(f64::MIN_POSITIVE))
        .unwrap_or(Duration::MAX)
        .max(Duration::from_nanos(1));
    let burst = NonZeroU32::new(burst.round().clamp(1.0, f64::from(u32::MAX)) as u32)
        .unwrap_or(NonZeroU32::MIN);
    Quota::with_period(period)
        .expect("a period of at least a nanosecond")
        .allow_burst(burst)
}

impl SenderLimiter {
    pub fn new(rate: f64, burst: f64) -> SenderLimiter {
        SenderLimiter::with_clock(rate, burst, DefaultClock::default())
    }
}

impl<C: Clock> SenderLimiter<C> {
    /// Buckets read on `clock` (a test's clock moves when the test says).
    pub fn with_clock(rate: f64, burst: f64, clock: C) -> SenderLimiter<C> {
        SenderLimiter {
            limiter: RateLimiter::hashmap_with_clock(quota(rate, burst), clock),
        }
    }

    /// Takes one of `sender`'s turns: whether it may go now.
    pub fn take(&self, sender: &Sender) -> bool {
        let shared: Sender = None;
        let key = if self.limiter.len() < MAX_SENDERS {
            sender
        } else {
            // Forget the senders whose buckets are full again (idle ones); else share.
            self.limiter.retain_recent();
            if self.limiter.len() < MAX_SENDERS {
                sender
            } else {
                &shared
            }
        };
        self.limiter.check_key(key).is_ok()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use governor::clock::FakeRelativeClock;

    #[test]
    fn a_bucket_gives_its_burst_then_its_rate() {
        let clock = FakeRelativeClock::default();
        let limiter = SenderLimiter::with_clock(10.0, 5.0, clock.clone());
        let alice = Some("a".to_string());
        let taken = (0..20).filter(|_| limiter.take(&alice)).count();
        assert_eq!(taken, 5, "the burst, then nothing at once");
        // Another sender has a bucket of its own.
        assert!(limiter.take(&Some("b".to_string())));
        clock.advance(Duration::from_millis(350));
        let later = (0..20).filter(|_| limiter.take(&alice)).count();
        assert_eq!(later, 3, "0.35 s at 10 a second");
        clock.advance(Duration::from_secs(60));
        let rested = (0..20).filter(|_| limiter.take(&alice)).count();
        assert_eq!(rested, 5, "a rested bucket holds its burst, no more");
    }

    #[test]
    fn past_the_sender_cap_newcomers_share_one_bucket_until_others_rest() {
        let clock = FakeRelativeClock::default();
        let limiter = SenderLimiter::with_clock(1.0, 1.0, clock.clone());
        for i in 0..MAX_SENDERS {
            assert!(limiter.take(&Some(i.to_string())));
        }
        // Every bucket is empty, so none is forgotten: newcomers share the anonymous one.
        assert!(limiter.take(&Some("new-1".into())));
        assert!(!limiter.take(&Some("new-2".into())));
        assert!(limiter.limiter.len() <= MAX_SENDERS + 1);
        // Once the others' buckets are full again they are forgotten, and a newcomer has
        // its own.
        clock.advance(Duration::from_secs(2));
        assert!(limiter.take(&Some("new-3".into())));
        assert!(
            limiter.limiter.len() < 10,
            "{} senders kept",
            limiter.limiter.len()
        );
    }

    #[test]
    fn extreme_flags_make_a_quota() {
        let limiter = SenderLimiter::new(1e300, 1e300);
        assert!((0..1000).all(|_| limiter.take(&None)));
        let limiter = SenderLimiter::new(1.0, 1.0);
        assert!(limiter.take(&None));
        assert!(!limiter.take(&None));
    }
}
