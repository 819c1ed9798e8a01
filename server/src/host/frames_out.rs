//! Frames and snapshots leave from a thread of their own.
//!
//! The stepping thread encodes each stream's frame (an encoder follows the world step by
//! step) and hands the bytes to this thread through a queue; it never waits for zenoh.
//! Writing a frame into zenoh's queues is a copy per peer: a key frame of a busy world is
//! megabytes, written once for every viewer connected directly, which took longer than a
//! step has (docs/network.md, "Fan-out, measured"). Frames still leave in the order they
//! were made, with zenoh's `Drop` congestion control; snapshots go through the same queue,
//! so none overtakes the frames before it.
//!
//! The queue is bounded by its bytes: a frame that would pass the bound is dropped and
//! counted, and its receivers resync (the next key frame, or the state query), as when
//! zenoh drops a frame for a slow peer. Whether each publisher has subscribers comes from
//! zenoh's matching listeners as it changes (and is asked twice a second besides): the
//! stepping thread reads it every frame and no longer asks zenoh itself.

use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::mpsc::{channel, RecvTimeoutError, Sender};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use zenoh::pubsub::Publisher;
use zenoh::sample::SourceInfo;
use zenoh::Wait;

/// Bytes of frames and snapshots waiting to leave, at most (one larger than this alone is
/// taken when nothing else waits).
pub const FRAMES_OUT_BYTES: usize = 64 << 20;

/// How often the sending thread asks each publisher whether anyone subscribes.
const MATCHING_EVERY: Duration = Duration::from_millis(500);

struct Out {
    publisher: usize,
    /// The sequence number the payload is sent under (its frame).
    sn: u32,
    bytes: Vec<u8>,
}

/// Asks each publisher whether anyone subscribes (yes, when zenoh cannot tell).
fn ask(publishers: &[Publisher<'static>], watched: &[AtomicBool]) {
    for (p, w) in publishers.iter().zip(watched) {
        let matching = p.matching_status().wait().map(|m| m.matching());
        w.store(matching.unwrap_or(true), Ordering::Relaxed);
    }
}

/// The stepping thread's end of the queue.
pub struct FramesOut {
    tx: Option<Sender<Out>>,
    waiting: Arc<AtomicUsize>,
    /// Payloads dropped because the queue was full, or refused by zenoh.
    pub dropped: Arc<AtomicU64>,
    /// Whether each publisher had subscribers when last asked.
    watched: Arc<Vec<AtomicBool>>,
    thread: Option<JoinHandle<()>>,
}

impl FramesOut {
    /// Starts the sending thread for `publishers` (payloads name them by index); it
    /// ends, once what waits has left, when the [`FramesOut`] is dropped.
    pub fn start(publishers: Vec<Publisher<'static>>) -> FramesOut {
        let (tx, rx) = channel::<Out>();
        let waiting = Arc::new(AtomicUsize::new(0));
        let dropped = Arc::new(AtomicU64::new(0));
        let watched: Arc<Vec<AtomicBool>> =
            Arc::new(publishers.iter().map(|_| AtomicBool::new(false)).collect());
        // zenoh says when a publisher gains its first subscriber or loses its last; the
        // asking twice a second below is the fallback.
        for (i, p) in publishers.iter().enumerate() {
            let flags = watched.clone();
            let listened = p
                .matching_listener()
                .callback(move |m| flags[i].store(m.matching(), Ordering::Relaxed))
                .background()
                .wait();
            if let Err(e) = listened {
                tracing::warn!("no matching listener on {}: {e}", p.key_expr());
            }
        }
        // Known before the first frame is made.
        ask(&publishers, &watched);
        let (taken, failed, seen) = (waiting.clone(), dropped.clone(), watched.clone());
        let thread = std::thread::Builder::new()
            .name("ricochet-frames".into())
            .spawn(move || {
                let mut asked = Instant::now();
                loop {
                    match rx.recv_timeout(MATCHING_EVERY) {
                        Ok(out) => {
                            let p = &publishers[out.publisher];
                            let len = out.bytes.len();
                            let source = SourceInfo::new(p.id(), out.sn);
                            if let Err(e) = p.put(out.bytes).source_info(source).wait() {
                                failed.fetch_add(1, Ordering::Relaxed);
                                tracing::warn!("publishing on {} failed: {e}", p.key_expr());
                            }
                            taken.fetch_sub(len, Ordering::Relaxed);
                        }
                        Err(RecvTimeoutError::Timeout) => {}
                        Err(RecvTimeoutError::Disconnected) => break,
                    }
                    if asked.elapsed() >= MATCHING_EVERY {
                        ask(&publishers, &seen);
                        asked = Instant::now();
                    }
                }
            })
            .expect("the frames thread starts");
        FramesOut {
            tx: Some(tx),
            waiting,
            dropped,
            watched,
            thread: Some(thread),
        }
    }

    /// Queues `bytes` for the publisher of index `publisher`, under sequence number `sn`;
    /// never blocks. Returns false when the payload was dropped (the queue is full).
    pub fn send(&self, publisher: usize, sn: u32, bytes: Vec<u8>) -> bool {
        let len = bytes.len();
        let before = self.waiting.fetch_add(len, Ordering::Relaxed);
        let sent = (before == 0 || before + len <= FRAMES_OUT_BYTES)
            && self.tx.as_ref().is_some_and(|tx| {
                tx.send(Out {
                    publisher,
                    sn,
                    bytes,
                })
                .is_ok()
            });
        if !sent {
            self.waiting.fetch_sub(len, Ordering::Relaxed);
            self.dropped.fetch_add(1, Ordering::Relaxed);
        }
        sent
    }

    /// Whether the publisher of index `publisher` had subscribers when last asked.
    pub fn watched(&self, publisher: usize) -> bool {
        self.watched
            .get(publisher)
            .is_some_and(|w| w.load(Ordering::Relaxed))
    }
}

impl Drop for FramesOut {
    /// What waits leaves before the thread ends (each `put` drops rather than blocks, so
    /// this is bounded by the bytes queued).
    fn drop(&mut self) {
        self.tx = None;
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}
