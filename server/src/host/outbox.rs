//! Replies and events leave from a thread of their own.
//!
//! A reply travels with the congestion control its querier chose (zenoh's rule), so a
//! querier that asks with `Block` and then stops reading could hold whoever replies. The
//! stepping thread and zenoh's receive threads therefore never reply themselves: they hand
//! the reply to this thread through a bounded queue and go on; when the queue is full the
//! reply is dropped and counted (the querier then sees its query end unanswered). The
//! server's session also caps how long a blocked send may wait before zenoh closes that
//! peer's link (`wait_before_close`, set in [`super::server_config`]).

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{sync_channel, SyncSender, TrySendError};
use std::sync::Arc;

use zenoh::pubsub::Publisher;
use zenoh::query::Query;
use zenoh::Wait;

/// Replies and events waiting to leave, at most.
pub const OUTBOX_CAPACITY: usize = 4096;

enum Out {
    Reply(Query, Vec<u8>),
    Event(Vec<u8>),
}

/// The sending end, cheap to clone into zenoh's callbacks.
#[derive(Clone)]
pub struct Outbox {
    tx: SyncSender<Out>,
    /// Replies and events dropped: the queue was full, or zenoh refused them.
    pub unsent: Arc<AtomicU64>,
}

impl Outbox {
    /// Starts the sending thread; it ends when every [`Outbox`] is dropped.
    pub fn start(events: Publisher<'static>) -> Outbox {
        let (tx, rx) = sync_channel::<Out>(OUTBOX_CAPACITY);
        let unsent = Arc::new(AtomicU64::new(0));
        let failed = unsent.clone();
        std::thread::Builder::new()
            .name("ricochet-outbox".into())
            .spawn(move || {
                for out in rx {
                    let sent = match out {
                        Out::Reply(query, body) => {
                            query.reply(query.key_expr().clone(), body).wait()
                        }
                        Out::Event(body) => events.put(body).wait(),
                    };
                    if let Err(e) = sent {
                        failed.fetch_add(1, Ordering::Relaxed);
                        tracing::debug!("a reply or event was not sent: {e}");
                    }
                }
            })
            .expect("the outbox thread starts");
        Outbox { tx, unsent }
    }

    /// An outbox whose thread never runs: everything sent to it counts as unsent (for
    /// tests of what feeds it).
    #[cfg(test)]
    pub fn detached() -> Outbox {
        let (tx, _) = sync_channel::<Out>(1);
        Outbox {
            tx,
            unsent: Arc::new(AtomicU64::new(0)),
        }
    }

    /// Queues a reply to `query`; never blocks.
    pub fn reply(&self, query: Query, body: Vec<u8>) {
        self.send(Out::Reply(query, body));
    }

    /// Queues an event; never blocks.
    pub fn event(&self, body: Vec<u8>) {
        self.send(Out::Event(body));
    }

    fn send(&self, out: Out) {
        match self.tx.try_send(out) {
            Ok(()) => {}
            Err(TrySendError::Full(_)) | Err(TrySendError::Disconnected(_)) => {
                self.unsent.fetch_add(1, Ordering::Relaxed);
            }
        }
    }
}
