//! Queries (snapshot, state, info) answered from what the server has, a bounded number
//! per pass of the loop.

use super::inbox::Ask;
use super::serve::Serving;
use super::upkeep::health;
use super::MAX_QUERIES_PER_PASS;

/// Bytes of replies waiting in the outbox past which snapshot and state queries wait their
/// turn in the inbox (info queries are answered whatever waits).
pub const HEAVY_REPLIES_WAITING: usize = 4 << 20;

/// The state query's answer, kept for the (generation, frame, stream) it was made at.
#[derive(Default)]
pub(super) struct StateCache(Option<((u64, u64, u64), Vec<u8>)>);

impl Serving {
    /// Answers the queries waiting, [`MAX_QUERIES_PER_PASS`] at most.
    pub(super) fn answer_queries(&mut self) {
        let Serving {
            host,
            wiring,
            state,
            ..
        } = self;
        for _ in 0..MAX_QUERIES_PER_PASS {
            // Snapshots and states wait in the inbox while the outbox holds a bound of
            // bytes: a flood of them cannot queue minutes of bytes ahead of the next
            // `info` or command reply.
            let heavy = wiring.outbox.waiting_bytes() < HEAVY_REPLIES_WAITING;
            let Some((ask, query)) = wiring.inbox.next_query(heavy) else {
                break;
            };
            let body = match ask {
                Ask::Snapshot => {
                    host.refresh_snapshot();
                    host.wire.snapshot.clone()
                }
                Ask::State(every) => {
                    let at = (host.wire.generation, host.world.frame(), every);
                    match &state.0 {
                        Some((made, bytes)) if *made == at => bytes.clone(),
                        _ => {
                            // Before a tier's first frame, the full stream's state: the
                            // tier's first frame is a key frame.
                            let bytes = host
                                .wire
                                .streams
                                .resync(every)
                                .or_else(|| host.wire.streams.resync(1))
                                .expect("frame 0 was encoded");
                            state.0 = Some((at, bytes.clone()));
                            bytes
                        }
                    }
                }
                Ask::Info => {
                    let mut info = host.info();
                    info.health = Some(health(host, &wiring.inbox, &wiring.outbox));
                    serde_json::to_vec(&info).expect("world info serialises")
                }
            };
            host.accounts.health.queries += 1;
            wiring.outbox.reply(query, body);
        }
    }
}
