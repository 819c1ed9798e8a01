//! Replies and events leave from a thread of their own.
//!
//! A reply travels with the congestion control its querier chose (zenoh's rule), so a
//! querier that asks with `Block` and then stops reading could hold whoever replies. The
//! stepping thread and zenoh's receive threads therefore never reply themselves: they hand
//! the reply to this thread through a bounded queue and go on; when the queue is full the
//! reply is dropped and counted (the querier then sees its query end unanswered). The
//! server's session also caps how long a blocked send may wait before zenoh closes that
//! peer's link (`wait_before_close`, set in [`super::server_config`]).
//!
//! The queue is a linked one (std's unbounded channel, bounded here by a count): its memory
//! follows what is waiting and is given back as it drains. An array ring of the same bound
//! would take 4096 slots (about 0.7 MiB) and, as its ends go round, keep every page of them
//! resident after the first few thousand messages.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{channel, Sender};
use std::sync::{Arc, Mutex};

use zenoh::pubsub::Publisher;
use zenoh::query::Query;
use zenoh::Wait;

/// Replies and events waiting to leave, at most.
pub const OUTBOX_CAPACITY: usize = 4096;

/// Bytes of replies and events waiting to leave, at most: 4096 answers to snapshot queries
/// of a large world would otherwise hold gigabytes. One larger than this alone is taken
/// when nothing else waits.
pub const OUTBOX_BYTES: usize = 64 << 20;

/// What waits in the outbox: replies and events, and their bytes.
#[derive(Default)]
struct Waiting {
    count: usize,
    bytes: usize,
}

enum Out {
    Reply(Query, Vec<u8>),
    Event(Vec<u8>),
}

/// The sending end, cheap to clone into zenoh's callbacks.
#[derive(Clone)]
pub struct Outbox {
    tx: Sender<Out>,
    /// Replies and events queued and not yet sent by the sending thread.
    waiting: Arc<Mutex<Waiting>>,
    /// Replies and events dropped: the queue was full, or zenoh refused them.
    pub unsent: Arc<AtomicU64>,
}

impl Outbox {
    /// Starts the sending thread; it ends when every [`Outbox`] is dropped.
    pub fn start(events: Publisher<'static>) -> Outbox {
        let (tx, rx) = channel::<Out>();
        let unsent = Arc::new(AtomicU64::new(0));
        let waiting = Arc::new(Mutex::new(Waiting::default()));
        let (failed, taken) = (unsent.clone(), waiting.clone());
        std::thread::Builder::new()
            .name("ricochet-outbox".into())
            .spawn(move || {
                // Events name this session as their source (clients take them from the
                // holder of the world's token only), numbered in order.
                let mut sn = 0u32;
                for out in rx {
                    let len = out.len();
                    let sent = match out {
                        Out::Reply(query, body) => {
                            query.reply(query.key_expr().clone(), body).wait()
                        }
                        Out::Event(body) => {
                            sn = sn.wrapping_add(1);
                            let source = zenoh::sample::SourceInfo::new(events.id(), sn);
                            events.put(body).source_info(source).wait()
                        }
                    };
                    release(&taken, len);
                    if let Err(e) = sent {
                        failed.fetch_add(1, Ordering::Relaxed);
                        tracing::debug!("a reply or event was not sent: {e}");
                    }
                }
            })
            .expect("the outbox thread starts");
        Outbox {
            tx,
            waiting,
            unsent,
        }
    }

    /// An outbox whose thread never runs: everything sent to it counts as unsent (for
    /// tests of what feeds it).
    #[cfg(test)]
    pub fn detached() -> Outbox {
        let (tx, _) = channel::<Out>();
        Outbox {
            tx,
            waiting: Arc::default(),
            unsent: Arc::new(AtomicU64::new(0)),
        }
    }

    /// An outbox whose queue nobody drains, and its receiving end (for tests of the bound).
    #[cfg(test)]
    fn stalled() -> (Outbox, std::sync::mpsc::Receiver<Out>) {
        let (tx, rx) = channel::<Out>();
        let outbox = Outbox {
            tx,
            waiting: Arc::default(),
            unsent: Arc::new(AtomicU64::new(0)),
        };
        (outbox, rx)
    }

    /// Queues a reply to `query`; never blocks.
    /// Bytes of replies and events waiting to leave.
    pub fn waiting_bytes(&self) -> usize {
        self.waiting.lock().unwrap_or_else(|e| e.into_inner()).bytes
    }

    pub fn reply(&self, query: Query, body: Vec<u8>) {
        self.send(Out::Reply(query, body));
    }

    /// Queues an event's bytes; never blocks.
    pub fn event(&self, body: Vec<u8>) {
        self.send(Out::Event(body));
    }

    /// Queues an event for subscribers; never blocks.
    pub fn publish_event(&self, event: &ricochet_protocol::command::Event) {
        self.event(serde_json::to_vec(event).expect("events serialise"));
    }

    fn send(&self, out: Out) {
        // Take a place first: the bounds are never passed, whoever sends at once.
        let len = out.len();
        let placed = {
            let mut w = self.waiting.lock().unwrap_or_else(|e| e.into_inner());
            let fits = w.count < OUTBOX_CAPACITY
                && (w.count == 0 || w.bytes.saturating_add(len) <= OUTBOX_BYTES);
            if fits {
                w.count += 1;
                w.bytes += len;
            }
            fits
        };
        if !placed {
            self.unsent.fetch_add(1, Ordering::Relaxed);
        } else if self.tx.send(out).is_err() {
            release(&self.waiting, len);
            self.unsent.fetch_add(1, Ordering::Relaxed);
        }
    }
}

impl Out {
    fn len(&self) -> usize {
        match self {
            Out::Reply(_, body) | Out::Event(body) => body.len(),
        }
    }
}

/// Gives back the place of a reply or event of `len` bytes.
fn release(waiting: &Mutex<Waiting>, len: usize) {
    let mut w = waiting.lock().unwrap_or_else(|e| e.into_inner());
    w.count = w.count.saturating_sub(1);
    w.bytes = w.bytes.saturating_sub(len);
}

#[cfg(test)]
mod tests {
    use super::*;

    fn waiting(outbox: &Outbox) -> (usize, usize) {
        let w = outbox.waiting.lock().unwrap();
        (w.count, w.bytes)
    }

    #[test]
    fn a_full_outbox_drops_and_counts_and_takes_again_as_it_drains() {
        let (outbox, rx) = Outbox::stalled();
        for _ in 0..OUTBOX_CAPACITY + 3 {
            outbox.event(vec![1]);
        }
        assert_eq!(outbox.unsent.load(Ordering::Relaxed), 3);
        assert_eq!(waiting(&outbox), (OUTBOX_CAPACITY, OUTBOX_CAPACITY));
        // The sending thread sends one (as its loop does), and one more fits.
        assert!(rx.try_recv().is_ok());
        release(&outbox.waiting, 1);
        outbox.event(vec![2]);
        outbox.event(vec![3]);
        assert_eq!(outbox.unsent.load(Ordering::Relaxed), 4);
        assert_eq!(rx.try_iter().count(), OUTBOX_CAPACITY);
    }

    #[test]
    fn large_replies_wait_within_a_byte_budget() {
        // Answers to snapshot queries of a large world: half a MiB each.
        let (outbox, rx) = Outbox::stalled();
        let big = 512 << 10;
        for _ in 0..1000 {
            outbox.event(vec![0; big]);
        }
        let (count, bytes) = waiting(&outbox);
        assert!(bytes <= OUTBOX_BYTES, "{bytes} bytes waiting");
        assert_eq!(count, OUTBOX_BYTES / big);
        assert_eq!(outbox.unsent.load(Ordering::Relaxed), (1000 - count) as u64);
        // Small events still fit beside them only as the big ones leave.
        outbox.event(vec![1]);
        assert_eq!(waiting(&outbox).0, count);
        assert!(rx.try_recv().is_ok());
        release(&outbox.waiting, big);
        outbox.event(vec![1]);
        assert_eq!(waiting(&outbox), (count, bytes - big + 1));
        // One larger than the whole budget goes when nothing else waits.
        let (alone, _rx) = Outbox::stalled();
        alone.event(vec![0; OUTBOX_BYTES + 1]);
        assert_eq!(waiting(&alone), (1, OUTBOX_BYTES + 1));
        alone.event(vec![1]);
        assert_eq!(alone.unsent.load(Ordering::Relaxed), 1);
    }

    #[test]
    fn an_outbox_whose_thread_is_gone_counts_everything_unsent() {
        let outbox = Outbox::detached();
        outbox.event(vec![1]);
        outbox.event(vec![2]);
        assert_eq!(outbox.unsent.load(Ordering::Relaxed), 2);
        assert_eq!(waiting(&outbox), (0, 0));
    }
}
