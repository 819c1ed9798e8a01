//! What zenoh's receive threads hand to the stepping thread.
//!
//! zenoh calls the callbacks below on its own threads; they never block, or a flood would
//! stall every peer's traffic. Each one only checks and queues:
//!
//! - a command larger than the server's `command_bytes` limit is refused at once;
//! - each sender has a token bucket (`rate` a second, `burst` at once): over it, the
//!   command is dropped and counted;
//! - each sender has a queue of its own, commands and requests together in the order they
//!   came; queues are bounded each in count, and all together in count and bytes: a
//!   command that finds them full is dropped and counted. Queries (state, snapshot, info)
//!   have a bounded queue of their own.
//!
//! A refused or dropped request is answered so, through the [`Outbox`]. The stepping thread
//! takes one command from each sender in turn (round robin), so a sender's commands keep
//! their order, and a flood from one sender, of commands or of requests, delays only that
//! sender's own.
//!
//! A sender is the zenoh id its session declares in zenoh's source info, which Ricochet's
//! clients set; commands without one share a bucket. The id is the sender's own claim, so
//! a claim keeps buckets of its own only when it names a session connected to the server
//! and the message's signature proves it is from that session ([`Peers::bucket`]); any
//! other claim shares the anonymous sender's. The buckets share capacity fairly among
//! honest clients, while the queue bounds and the per-frame bounds keep the step safe from
//! any.

use std::collections::{HashMap, VecDeque};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;

use ricochet_protocol::command::Reply;
use zenoh::query::Query;
use zenoh::sample::Sample;

use super::limiter::SenderLimiter;
use super::outbox::Outbox;
use super::peers::{Claim, Peers};

/// Who sent a command: the zenoh id its session declares, if any.
pub type Sender = Option<String>;

/// A command or request waiting for the frame boundary.
pub struct Incoming {
    pub payload: Vec<u8>,
    /// The sender the message claims: its answers are remembered under it.
    pub sender: Sender,
    /// The sender its buckets and budget are charged to ([`Peers::bucket`]).
    pub key: Sender,
    /// The request to answer; none for a fire-and-forget command.
    pub query: Option<Query>,
}

/// A query answered from what the server already has.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Ask {
    /// The state of the stream of one frame in this many steps.
    State(u64),
    Snapshot,
    Info,
}

/// How much the inbox holds and takes.
#[derive(Clone, Copy, Debug)]
pub struct InboxLimits {
    /// Commands (and requests) waiting at most, per sender; four times this in all.
    pub queue: usize,
    /// Bytes of commands waiting at most, in all.
    pub queue_bytes: usize,
    /// Commands a second each sender may send, over time.
    pub rate: f64,
    /// Commands a sender may send at once above its rate.
    pub burst: f64,
    /// Queries (state, snapshot, info) waiting at most.
    pub queries: usize,
    /// Queries a second each sender may make, over time (an answer may be the whole
    /// world's state or statics: a flood of them is a flood of the server's bytes).
    pub query_rate: f64,
    /// Queries a sender may make at once above its rate.
    pub query_burst: f64,
    /// The largest command taken, in bytes.
    pub command_bytes: usize,
}

impl Default for InboxLimits {
    fn default() -> Self {
        InboxLimits {
            queue: 4096,
            queue_bytes: 16 << 20,
            rate: 1000.0,
            burst: 500.0,
            queries: 1024,
            query_rate: 50.0,
            query_burst: 100.0,
            command_bytes: 65_536,
        }
    }
}

/// What the inbox turned away since the server started.
#[derive(Default)]
pub struct Turned {
    pub rate_limited: AtomicU64,
    pub queue_full: AtomicU64,
    pub too_large: AtomicU64,
    pub queries_dropped: AtomicU64,
    /// Of those, the commands sent without a way to answer them (a put, not a query), by
    /// reason: nobody was told; the host sums them up in an event now and then.
    pub unanswered: Unanswered,
}

/// Fire-and-forget commands the inbox dropped, by reason.
#[derive(Default)]
pub struct Unanswered {
    pub too_large: AtomicU64,
    pub rate_limited: AtomicU64,
    pub queue_full: AtomicU64,
}

impl Unanswered {
    /// (too large, over the rate, queue full) so far.
    pub fn counts(&self) -> [u64; 3] {
        [&self.too_large, &self.rate_limited, &self.queue_full].map(|a| a.load(Ordering::Relaxed))
    }
}

#[derive(Default)]
struct Queues {
    /// Each sender's commands, in the order they came.
    waiting: HashMap<Sender, VecDeque<Incoming>>,
    /// The senders with commands waiting, in the order they are served.
    turns: VecDeque<Sender>,
    /// Commands and bytes waiting in all.
    count: usize,
    bytes: usize,
    queries: VecDeque<(Ask, Query)>,
    /// `info` queries, answered before the others: an answer of a few hundred bytes never
    /// waits behind whole snapshots and states.
    infos: VecDeque<Query>,
}

pub struct Inbox {
    queues: Mutex<Queues>,
    limits: InboxLimits,
    /// Each sender's rate of commands, and of queries.
    commands: SenderLimiter,
    queries: SenderLimiter,
    pub turned: Turned,
    outbox: Outbox,
    /// The frame commands now take effect in, for refusals sent from here.
    frame: AtomicU64,
    /// Which claimed senders are connected sessions (their buckets are their own).
    peers: Peers,
}

impl Inbox {
    pub fn new(limits: InboxLimits, outbox: Outbox, peers: Peers) -> Inbox {
        Inbox {
            peers,
            queues: Mutex::new(Queues::default()),
            commands: SenderLimiter::new(limits.rate, limits.burst),
            queries: SenderLimiter::new(limits.query_rate, limits.query_burst),
            limits,
            turned: Turned::default(),
            outbox,
            frame: AtomicU64::new(0),
        }
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Queues> {
        self.queues.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// The frame refusals from the callbacks name.
    pub fn set_frame(&self, frame: u64) {
        self.frame.store(frame, Ordering::Relaxed);
    }

    /// A fire-and-forget command (zenoh's subscriber callback).
    pub fn offer_command(&self, sample: Sample) {
        let sender = sample
            .source_info()
            .map(|s| s.source_id().zid().to_string());
        let payload = sample.payload().to_bytes().into_owned();
        let attachment = sample.attachment().map(|a| a.to_bytes());
        let claim = Claim {
            sender: &sender,
            attachment: attachment.as_deref(),
            key: sample.key_expr().as_str(),
            payload: &payload,
        };
        let key = self.bucket(&claim);
        self.offer(payload, sender, key, None);
    }

    /// A request (zenoh's queryable callback).
    pub fn offer_request(&self, query: Query) {
        let sender = query.source_info().map(|s| s.source_id().zid().to_string());
        let payload = query
            .payload()
            .map(|p| p.to_bytes().into_owned())
            .unwrap_or_default();
        let attachment = query.attachment().map(|a| a.to_bytes());
        let claim = Claim {
            sender: &sender,
            attachment: attachment.as_deref(),
            key: query.key_expr().as_str(),
            payload: &payload,
        };
        let key = self.bucket(&claim);
        self.offer(payload, sender, key, Some(query));
    }

    /// Whose buckets a claim is charged to; a message larger than the command bound is
    /// not verified (it is refused whoever sent it).
    fn bucket(&self, claim: &Claim) -> Sender {
        if claim.payload.len() > self.limits.command_bytes {
            return None;
        }
        self.peers.bucket(claim)
    }

    fn offer(&self, payload: Vec<u8>, sender: Sender, key: Sender, query: Option<Query>) {
        tracing::trace!(
            ?sender,
            request = query.is_some(),
            bytes = payload.len(),
            "offered"
        );
        let frame = self.frame.load(Ordering::Relaxed);
        if payload.len() > self.limits.command_bytes {
            self.turned.too_large.fetch_add(1, Ordering::Relaxed);
            let error = format!(
                "command of {} bytes is larger than the limit of {}",
                payload.len(),
                self.limits.command_bytes
            );
            return self.refuse(query, frame, error, &self.turned.unanswered.too_large);
        }
        if !self.commands.take(&key) {
            self.turned.rate_limited.fetch_add(1, Ordering::Relaxed);
            let error = format!(
                "rate limit: a sender may send {} commands a second ({} at once); this one was dropped",
                self.limits.rate, self.limits.burst
            );
            return self.refuse(query, frame, error, &self.turned.unanswered.rate_limited);
        }
        let limits = self.limits;
        let mut q = self.lock();
        let queued = q.waiting.get(&key).map_or(0, VecDeque::len);
        if queued >= limits.queue
            || q.count >= limits.queue.saturating_mul(4)
            || q.bytes + payload.len() > limits.queue_bytes
        {
            let waiting = q.count;
            drop(q);
            self.turned.queue_full.fetch_add(1, Ordering::Relaxed);
            let error = format!(
                "server busy: {waiting} commands are waiting ({queued} of this sender's); this one was dropped"
            );
            return self.refuse(query, frame, error, &self.turned.unanswered.queue_full);
        }
        q.count += 1;
        q.bytes += payload.len();
        if queued == 0 {
            q.turns.push_back(key.clone());
        }
        q.waiting
            .entry(key.clone())
            .or_default()
            .push_back(Incoming {
                payload,
                sender,
                key,
                query,
            });
    }

    /// Answers a refused request at once (through the outbox); a refused fire-and-forget
    /// command is counted in `unanswered` (the host tells event subscribers how many, at
    /// most once a second: a flood of them is not echoed) and logged.
    fn refuse(&self, query: Option<Query>, frame: u64, error: String, unanswered: &AtomicU64) {
        match query {
            Some(query) => {
                let reply = Reply::refused(frame, error);
                self.outbox.reply(
                    query,
                    serde_json::to_vec(&reply).expect("replies serialise"),
                );
            }
            None => {
                unanswered.fetch_add(1, Ordering::Relaxed);
                tracing::debug!(frame, "command dropped: {error}");
            }
        }
    }

    /// A query for what the server already has (zenoh's queryable callback).
    pub fn offer_query(&self, ask: Ask, query: Query) {
        let claimed = query.source_info().map(|s| s.source_id().zid().to_string());
        let attachment = query.attachment().map(|a| a.to_bytes());
        let payload = query.payload().map(|p| p.to_bytes());
        let sender = self.bucket(&Claim {
            sender: &claimed,
            attachment: attachment.as_deref(),
            key: query.key_expr().as_str(),
            payload: payload.as_deref().unwrap_or_default(),
        });
        let mut q = self.lock();
        let waiting = match ask {
            Ask::Info => q.infos.len(),
            _ => q.queries.len(),
        };
        if waiting >= self.limits.queries || !self.queries.take(&sender) {
            drop(q);
            // Dropping the query ends it for the querier: no answer.
            self.turned.queries_dropped.fetch_add(1, Ordering::Relaxed);
            return;
        }
        match ask {
            Ask::Info => q.infos.push_back(query),
            _ => q.queries.push_back((ask, query)),
        }
    }

    /// The next command or request: the oldest of the sender whose turn it is.
    pub fn next(&self) -> Option<Incoming> {
        let mut q = self.lock();
        let sender = q.turns.pop_front()?;
        let queue = q.waiting.get_mut(&sender)?;
        let incoming = queue.pop_front()?;
        if queue.is_empty() {
            q.waiting.remove(&sender);
        } else {
            q.turns.push_back(sender);
        }
        q.count -= 1;
        q.bytes -= incoming.payload.len();
        Some(incoming)
    }

    /// The next query, if any.
    pub fn next_query(&self, heavy: bool) -> Option<(Ask, Query)> {
        let mut q = self.lock();
        match q.infos.pop_front() {
            Some(query) => Some((Ask::Info, query)),
            None if heavy => q.queries.pop_front(),
            None => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn inbox(queue: usize) -> Inbox {
        let limits = InboxLimits {
            queue,
            ..InboxLimits::default()
        };
        Inbox::new(limits, Outbox::detached(), Peers::trusting())
    }

    /// A command whose claim is taken as it is.
    fn offer(inbox: &Inbox, payload: Vec<u8>, sender: Sender) {
        inbox.offer(payload, sender.clone(), sender, None);
    }

    fn take_all(inbox: &Inbox) -> Vec<(Sender, u8)> {
        std::iter::from_fn(|| inbox.next())
            .map(|i| (i.sender, i.payload[0]))
            .collect()
    }

    #[test]
    fn senders_are_served_in_turn_each_in_its_own_order() {
        let inbox = inbox(100);
        let (a, b) = (Some("a".to_string()), Some("b".to_string()));
        for n in 0..5 {
            offer(&inbox, vec![n], a.clone());
        }
        offer(&inbox, vec![10], b.clone());
        offer(&inbox, vec![11], b.clone());
        offer(&inbox, vec![20], None);
        let order = take_all(&inbox);
        assert_eq!(
            order,
            vec![
                (a.clone(), 0),
                (b.clone(), 10),
                (None, 20),
                (a.clone(), 1),
                (b.clone(), 11),
                (a.clone(), 2),
                (a.clone(), 3),
                (a.clone(), 4),
            ]
        );
        assert!(inbox.next().is_none());
    }

    #[test]
    fn a_full_queue_drops_and_counts_and_others_still_get_in() {
        let inbox = inbox(3);
        let a = Some("a".to_string());
        for n in 0..10 {
            offer(&inbox, vec![n], a.clone());
        }
        offer(&inbox, vec![99], Some("b".into()));
        assert_eq!(inbox.turned.queue_full.load(Ordering::Relaxed), 7);
        let order = take_all(&inbox);
        assert_eq!(order.len(), 4, "{order:?}");
        assert!(order.contains(&(Some("b".into()), 99)));
        // Too large for the command limit: refused before queueing.
        offer(&inbox, vec![0; 70_000], a.clone());
        assert_eq!(inbox.turned.too_large.load(Ordering::Relaxed), 1);
        assert!(inbox.next().is_none());
    }
}
