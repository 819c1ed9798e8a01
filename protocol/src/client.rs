//! A typed zenoh client of a Ricochet world, for the command-line client, the viewer and
//! tests. Blocking calls (zenoh's `Wait`); no async runtime is needed by the caller.
//!
//! Replies are taken only from the world's server: the zenoh instance whose id the world's
//! liveliness token `ricochet/<world>/alive/<zid>` names. A reply from any other peer (a
//! stray or hostile queryable on the world's keys) is ignored and counted. When more than
//! one peer holds the token, the holder that alone answers is taken as the server (the
//! others hold spare tokens; frames are then taken from it too), and a world two holders
//! answer for is refused, since the client cannot tell which is the server. The id a reply carries is the one its sender's zenoh session declares, so on an
//! open network this guards against mistakes and naive impostors; against a peer that
//! forges its id, the secured deployment (docs/security.md) is what holds, where only the
//! server's credentials may declare the token and the queryables.
//!
//! Frames, snapshots and events are taken the same way: each publication the server makes
//! carries its session's id as its source ([`FrameStream`] drops and counts any other).

use std::collections::BTreeSet;
use std::sync::atomic::{AtomicU32, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::{anyhow, Context, Result};
use zenoh::handlers::{RingChannel, RingChannelHandler};
use zenoh::pubsub::{Publisher, Subscriber};
use zenoh::query::ConsolidationMode;
use zenoh::sample::{Sample, SourceInfo};
use zenoh::{Session, Wait};

use crate::command::{Command, Event, Reply};
use crate::identity::Identity;
use crate::keys::{self, WorldKeys};
use crate::net::Network;

/// The world's publications (frames, snapshots or events) as they arrive, in order, in a
/// ring: a reader that falls more than the ring behind loses the oldest (a frame decoder
/// then resyncs) instead of holding up zenoh's receive thread, and with it every reply
/// this session waits for. Only samples whose source is the session holding the world's
/// liveliness token come out; any other (no source, another peer's, or a world claimed by
/// several) is dropped and counted ([`FrameStream::ignored`]).
pub struct FrameStream {
    inner: Subscriber<RingChannelHandler<Sample>>,
    trust: Arc<Trust>,
    ignored: AtomicU64,
}

/// Who the world's server is, shared by a client and its streams.
struct Trust {
    session: Session,
    alive: String,
    /// The zenoh ids holding the world's liveliness token, as last read.
    servers: Mutex<Vec<String>>,
    /// When a stream last read the holders again (at most once a [`Trust::REFRESH`]).
    refreshed: Mutex<Option<Instant>>,
    /// Among several holders, the one that alone answered a request: the server, the
    /// others holding spare tokens without serving the world.
    pinned: Mutex<Option<String>>,
}

/// A reply's payload: `Ok` for a reply, `Err` for an error reply.
type Answered = Result<Vec<u8>, Vec<u8>>;

/// Who a replier is to the world, as far as the client knows.
enum Holder {
    /// The world's server: the only holder of its token, or the holder that alone
    /// answered among several.
    Server,
    /// Not a holder of the world's token.
    Other,
    /// One of several holders, none yet told apart.
    Among(Vec<String>),
}

impl Trust {
    /// How often an unknown source may make a stream read the token's holders again.
    const REFRESH: Duration = Duration::from_secs(1);

    /// What `zid` is among `holders`, given the holder pinned as the server if any.
    fn judge(&self, zid: &str, holders: &[String]) -> Holder {
        if !holders.iter().any(|s| s == zid) {
            return Holder::Other;
        }
        if holders.len() == 1 {
            return Holder::Server;
        }
        let pinned = self.pinned.lock().unwrap_or_else(|e| e.into_inner());
        match pinned.as_deref() {
            Some(p) if holders.iter().any(|s| s == p) => {
                if p == zid {
                    Holder::Server
                } else {
                    Holder::Other
                }
            }
            _ => Holder::Among(holders.to_vec()),
        }
    }

    /// Whether `zid` holds the world's token, and alone; an unknown `zid` rereads the
    /// holders, at most once a [`Trust::REFRESH`].
    fn holds_alone(&self, zid: &str) -> bool {
        let known = {
            let servers = self.servers.lock().unwrap_or_else(|e| e.into_inner());
            match self.judge(zid, &servers) {
                Holder::Server => Some(true),
                Holder::Among(_) => Some(false),
                Holder::Other => None,
            }
        };
        if let Some(alone) = known {
            return alone;
        }
        {
            let mut last = self.refreshed.lock().unwrap_or_else(|e| e.into_inner());
            if last.is_some_and(|t| t.elapsed() < Self::REFRESH) {
                return false;
            }
            *last = Some(Instant::now());
        }
        let Ok(tokens) = alive_tokens(&self.session, &self.alive, Self::REFRESH) else {
            return false;
        };
        let holders: Vec<String> = tokens.into_iter().map(|(_, z)| z).collect();
        let alone = matches!(self.judge(zid, &holders), Holder::Server);
        *self.servers.lock().unwrap_or_else(|e| e.into_inner()) = holders;
        alone
    }
}

impl FrameStream {
    /// The next sample from the world's server within `timeout` (`None`: none came).
    pub fn recv_timeout(&self, timeout: Duration) -> zenoh::Result<Option<Sample>> {
        let deadline = Instant::now() + timeout;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match self.inner.recv_timeout(left)? {
                Some(sample) if self.is_from_server(&sample) => return Ok(Some(sample)),
                Some(_) => continue,
                None => return Ok(None),
            }
        }
    }

    /// The next sample from the world's server already received (`None`: none is).
    pub fn try_recv(&self) -> zenoh::Result<Option<Sample>> {
        loop {
            match self.inner.try_recv()? {
                Some(sample) if self.is_from_server(&sample) => return Ok(Some(sample)),
                Some(_) => continue,
                None => return Ok(None),
            }
        }
    }

    /// Samples dropped so far because they did not come from the world's server.
    pub fn ignored(&self) -> u64 {
        self.ignored.load(Ordering::Relaxed)
    }

    fn is_from_server(&self, sample: &Sample) -> bool {
        let trusted = sample
            .source_info()
            .is_some_and(|s| self.trust.holds_alone(&s.source_id().zid().to_string()));
        if !trusted {
            let n = self.ignored.fetch_add(1, Ordering::Relaxed) + 1;
            // A note on the first, then at every power of two: a forger cannot flood the log.
            if n.is_power_of_two() {
                tracing::warn!(
                    key = %sample.key_expr(),
                    ignored = n,
                    "ignored a publication from a peer that is not the world's server"
                );
            }
        }
        trusted
    }
}

/// A request id no other peer can predict: 128 bits from the operating system's generator
/// (through a thread's generator seeded from it). The server applies a command once per
/// sender and id and answers a repeat with the first answer, so an id a peer could guess
/// (a counter) would let a peer that claims this client's sender id send its next id
/// first: the client's real command would then be "answered" and never applied.
pub fn request_id() -> String {
    format!("r{:032x}", rand::random::<u128>())
}

/// Frames a client holds unread at most before the oldest are dropped.
pub const FRAME_RING: usize = 4096;

/// A client of one world.
pub struct Client {
    session: Session,
    keys: WorldKeys,
    /// The world's server, as its streams and replies are checked against.
    trust: Arc<Trust>,
    /// Commands leave through this publisher; its id names this client as their sender.
    commands: Publisher<'static>,
    /// Numbers this client's messages (zenoh's source sequence number).
    sequence: AtomicU32,
    /// Signs every message when the session's id is this identity's: the server then
    /// keeps this client's rate and turns its own ([`crate::identity`]).
    identity: Option<Arc<Identity>>,
    /// The frame stream this client watches: one frame in this many steps.
    every: u64,
}

impl Client {
    /// Opens a session under a new identity and addresses `world`: every message it sends
    /// is signed.
    pub fn open(network: &Network, world: &str) -> Result<Self> {
        let identity = Arc::new(Identity::generate());
        let session = network.open_as(&identity)?;
        Self::with_identity(session, world, Some(identity))
    }

    /// Addresses `world` over an existing session, unsigned: the server charges its
    /// messages to the anonymous sender, shared by every peer that does not sign.
    pub fn with_session(session: Session, world: &str) -> Result<Self> {
        Self::with_identity(session, world, None)
    }

    /// Addresses `world` over this client's session, under its identity.
    pub fn alongside(&self, world: &str) -> Result<Self> {
        Self::with_identity(self.session.clone(), world, self.identity.clone())
    }

    /// Addresses `world` over `session`, signing with `identity` (whose zenoh id the
    /// session must have, or the server takes its messages as unsigned).
    pub fn with_identity(
        session: Session,
        world: &str,
        identity: Option<Arc<Identity>>,
    ) -> Result<Self> {
        let keys = WorldKeys::new(world).map_err(|e| anyhow!(e))?;
        let commands = session
            .declare_publisher(keys.cmd.clone())
            .wait()
            .map_err(|e| anyhow!("declare the command publisher: {e}"))?;
        let trust = Arc::new(Trust {
            session: session.clone(),
            alive: keys.alive_tokens(),
            servers: Mutex::new(Vec::new()),
            refreshed: Mutex::new(None),
            pinned: Mutex::new(None),
        });
        Ok(Client {
            session,
            keys,
            commands,
            trust,
            sequence: AtomicU32::new(0),
            identity,
            every: 1,
        })
    }

    /// Watches the stream of one frame in `every` steps (1, the default: every step; the
    /// server's streams are `keys::STREAMS`): `frames`, `state`, `join` and `catch_up`
    /// follow it.
    pub fn watch_every(&mut self, every: u64) {
        self.every = every;
    }

    /// The stream this client watches.
    pub fn every(&self) -> u64 {
        self.every
    }

    /// Watches the fullest stream whose rate fits `bits_per_second`, by the server's
    /// info; returns the steps a frame of it stands for.
    pub fn watch_within(&mut self, bits_per_second: f64, timeout: Duration) -> Result<u64> {
        let info = self.info(timeout)?;
        let every = info.stream_for(bits_per_second);
        self.every = every;
        Ok(every)
    }

    pub fn session(&self) -> &Session {
        &self.session
    }

    pub fn keys(&self) -> &WorldKeys {
        &self.keys
    }

    /// Sends a command without waiting: it is applied at the next frame boundary; a
    /// refusal is published as an event.
    pub fn send(&self, command: &Command) -> Result<()> {
        self.send_raw(command.to_json().into_bytes())
    }

    /// What this client says of itself on each message: its session's zenoh id (the
    /// server's rate limit and request ids are per sender) and a sequence number.
    fn source(&self) -> SourceInfo {
        let sn = self.sequence.fetch_add(1, Ordering::Relaxed);
        SourceInfo::new(self.commands.id(), sn)
    }

    /// The signed attachment of a message with `payload` on `key`, if this client signs.
    fn attachment(&self, key: &str, payload: &[u8]) -> Option<Vec<u8>> {
        self.identity.as_ref().map(|me| me.sign(key, payload))
    }

    /// The identity this client signs with, if any.
    pub fn identity(&self) -> Option<&Arc<Identity>> {
        self.identity.as_ref()
    }

    /// Sends raw bytes as a command (tests send malformed ones).
    pub fn send_raw(&self, bytes: Vec<u8>) -> Result<()> {
        let attachment = self.attachment(&self.keys.cmd, &bytes);
        let mut put = self.commands.put(bytes).source_info(self.source());
        if let Some(attachment) = attachment {
            put = put.attachment(attachment);
        }
        put.wait().map_err(|e| anyhow!("send: {e}"))
    }

    /// Sends a command and waits for the reply. The request carries an id, so
    /// [`Client::request_retrying`] may send it again without its being applied twice.
    pub fn request(&self, command: &Command, timeout: Duration) -> Result<Reply> {
        self.request_retrying(command, timeout, 1)
    }

    /// Sends a command and waits for the reply, sending it again (same id: the server
    /// applies it once and answers every copy) up to `attempts` times in all while no
    /// answer comes, each attempt waiting `timeout`.
    pub fn request_retrying(
        &self,
        command: &Command,
        timeout: Duration,
        attempts: u32,
    ) -> Result<Reply> {
        let id = request_id();
        let mut body = serde_json::to_value(command).expect("commands serialise");
        body.as_object_mut()
            .expect("a command is a JSON object")
            .insert("id".into(), serde_json::Value::String(id.clone()));
        let bytes = body.to_string().into_bytes();
        let mut last = None;
        for attempt in 1..=attempts.max(1) {
            let began = Instant::now();
            match self.request_raw(bytes.clone(), timeout) {
                Ok(reply) => return Ok(reply),
                Err(e) => {
                    if attempt < attempts {
                        tracing::warn!(attempt, id, "no answer, sending again: {e:#}");
                        // A query nobody could take ends at once (the server is down, say):
                        // back off before the next, up to the attempt's timeout.
                        let backoff = Duration::from_millis(100 << (attempt - 1).min(6));
                        std::thread::sleep(backoff.min(timeout.saturating_sub(began.elapsed())));
                    }
                    last = Some(e);
                }
            }
        }
        Err(last.expect("at least one attempt"))
    }

    /// Sends raw bytes as a request and waits for the reply.
    pub fn request_raw(&self, bytes: Vec<u8>, timeout: Duration) -> Result<Reply> {
        let payload = match self.first_reply(&self.keys.rpc, Some(bytes), timeout)? {
            Ok(payload) | Err(payload) => payload,
        };
        serde_json::from_slice(&payload)
            .with_context(|| format!("unreadable reply: {}", String::from_utf8_lossy(&payload)))
    }

    /// The zenoh ids of the peers holding the world's liveliness token now: one when the
    /// world is served, none when it is not.
    pub fn servers(&self, timeout: Duration) -> Result<Vec<String>> {
        let tokens = alive_tokens(&self.session, &self.keys.alive_tokens(), timeout)?;
        Ok(tokens.into_iter().map(|(_, zid)| zid).collect())
    }

    /// What `zid` is to the world: read from the last list of holders, refreshed once
    /// (`refreshed`) when `zid` is not on it.
    fn holder(&self, zid: &str, refreshed: &mut bool, timeout: Duration) -> Result<Holder> {
        let mut servers = self.trust.servers.lock().unwrap_or_else(|e| e.into_inner());
        if !servers.iter().any(|s| s == zid) && !*refreshed {
            *refreshed = true;
            *servers = self.servers(timeout)?;
        }
        Ok(self.trust.judge(zid, &servers))
    }

    /// Queries `key` (with `payload`) and waits for the first reply from the world's
    /// server: `Ok` with its payload, or `Err` with the payload of an error reply. Replies
    /// from peers that do not hold the world's token are ignored.
    fn first_reply(
        &self,
        key: &str,
        payload: Option<Vec<u8>>,
        timeout: Duration,
    ) -> Result<Answered> {
        // Every reply, unconsolidated: consolidation keeps one reply per key, which could be
        // an impostor's.
        let ask = || {
            let mut get = self
                .session
                .get(key)
                .consolidation(ConsolidationMode::None)
                .source_info(self.source())
                .timeout(timeout);
            if let Some(bytes) = &payload {
                get = get.payload(bytes.clone());
            }
            if let Some(attachment) = self.attachment(key, payload.as_deref().unwrap_or_default()) {
                get = get.attachment(attachment);
            }
            get.wait().map_err(|e| anyhow!("{key}: {e}"))
        };
        // The holders are read before asking when none were read yet: a world that stops
        // as it answers (a fork's `close`) no longer holds its token when its reply
        // arrives, and a reply from a peer that held it when asked is the server's.
        {
            let mut servers = self.trust.servers.lock().unwrap_or_else(|e| e.into_inner());
            if servers.is_empty() {
                if let Ok(now) = self.servers(timeout) {
                    *servers = now;
                }
            }
        }
        let deadline = Instant::now() + timeout + Duration::from_millis(500);
        let mut ignored = 0usize;
        // Replies from holders of the world's token when several hold it: the one that
        // alone answers is the server (the others hold spare tokens); two that answer
        // cannot be told apart.
        let mut among: Vec<(String, Answered)> = Vec::new();
        let mut claimed: Vec<String> = Vec::new();
        let mut refreshed = false;
        let mut backoff = Duration::from_millis(50);
        'asking: loop {
            let replies = ask()?;
            let mut heard = false;
            loop {
                let left = deadline.saturating_duration_since(Instant::now());
                match replies.recv_timeout(left) {
                    Ok(Some(reply)) => {
                        heard = true;
                        let from = reply.replier_id().map(|id| id.zid().to_string());
                        let result = || match reply.result() {
                            Ok(sample) => Ok(sample.payload().to_bytes().into_owned()),
                            Err(err) => Err(err.payload().to_bytes().into_owned()),
                        };
                        let holder = match &from {
                            Some(zid) => self.holder(zid, &mut refreshed, timeout)?,
                            None => Holder::Other,
                        };
                        match (holder, from.clone()) {
                            (Holder::Server, _) => return Ok(result()),
                            (Holder::Among(holders), Some(zid)) => {
                                claimed = holders;
                                if !among.iter().any(|(z, _)| *z == zid) {
                                    among.push((zid, result()));
                                }
                            }
                            _ => {
                                ignored += 1;
                                tracing::warn!(
                                    key,
                                    replier = from.as_deref().unwrap_or("unknown"),
                                    "ignored a reply from a peer that does not hold the world's token"
                                );
                            }
                        }
                    }
                    // The deadline passed.
                    Ok(None) => break 'asking,
                    // Every replier is done, and holders of several tokens answered.
                    Err(_) if !among.is_empty() => break 'asking,
                    // Every replier is done. With no reply at all, nobody took the query (a
                    // queryable not yet known along the route, a server restarting): ask
                    // again, backing off, while the time lasts. A request carries its id,
                    // so the server applies it once however often it is asked.
                    Err(_) => {
                        if heard || Instant::now() + backoff >= deadline {
                            break 'asking;
                        }
                        std::thread::sleep(backoff);
                        backoff = (backoff * 2).min(Duration::from_secs(1));
                        continue 'asking;
                    }
                }
            }
        }
        match among.len() {
            0 => {}
            1 => {
                let (zid, result) = among.pop().expect("one");
                tracing::info!(
                    server = %zid,
                    holders = claimed.len(),
                    "the world's token is held by several peers; only this one answers: taken as the server"
                );
                *self.trust.pinned.lock().unwrap_or_else(|e| e.into_inner()) = Some(zid);
                return Ok(result);
            }
            _ => return Err(anyhow!(claimed_twice(&self.keys.world, &claimed))),
        }
        let ignored = match ignored {
            0 => String::new(),
            n => format!(
                " ({n} {} from peers not holding the world's liveliness token ignored)",
                if n == 1 { "reply" } else { "replies" }
            ),
        };
        Err(anyhow!(
            "no answer on {key} from the server within {timeout:?}{ignored}: is the server of world `{}` up?",
            self.keys.world
        ))
    }

    /// Every frame from now on, in order, in a ring of [`FRAME_RING`].
    pub fn frames(&self) -> Result<FrameStream> {
        self.latest_frames(FRAME_RING)
    }

    /// The latest `capacity` frames: for viewers, which must never hold anything back.
    pub fn latest_frames(&self, capacity: usize) -> Result<FrameStream> {
        self.subscribe(&self.keys.frame_every(self.every), capacity)
    }

    fn subscribe(&self, key: &str, capacity: usize) -> Result<FrameStream> {
        let inner = self
            .session
            .declare_subscriber(key.to_string())
            .with(RingChannel::new(capacity.max(1)))
            .wait()
            .map_err(|e| anyhow!("subscribe to {key}: {e}"))?;
        Ok(FrameStream {
            inner,
            trust: Arc::clone(&self.trust),
            ignored: AtomicU64::new(0),
        })
    }

    /// Statics snapshots re-published when static bodies change.
    pub fn snapshots(&self) -> Result<FrameStream> {
        self.subscribe(&self.keys.snapshot, 64)
    }

    /// Events: one per command the server handled.
    pub fn events(&self) -> Result<FrameStream> {
        self.subscribe(&self.keys.event, 4096)
    }

    /// Fetches the statics snapshot (what a late joiner needs besides the frames).
    pub fn snapshot(&self, timeout: Duration) -> Result<Vec<u8>> {
        self.fetch(&self.keys.snapshot, timeout)
    }

    /// Fetches a key frame of the dynamic state now: a late joiner applies it, then the
    /// frames that follow it, instead of waiting for the next key frame.
    pub fn state(&self, timeout: Duration) -> Result<Vec<u8>> {
        self.fetch(&self.keys.state_every(self.every), timeout)
    }

    /// The world's scene name, bounds, step and groups.
    pub fn info(&self, timeout: Duration) -> Result<crate::command::WorldInfo> {
        let bytes = self.fetch(&self.keys.info, timeout)?;
        serde_json::from_slice(&bytes).context("unreadable world info")
    }

    /// Subscribes to frames and brings a decoder up to date: statics from the snapshot,
    /// dynamic state from a resync key frame. Frames the subscription already holds that
    /// are not newer are skipped by the decoder.
    pub fn join(&self, timeout: Duration) -> Result<(FrameStream, crate::frame::FrameDecoder)> {
        let stream = self.frames()?;
        Ok((stream, self.catch_up(timeout)?))
    }

    /// A decoder brought up to date from scratch: statics from the snapshot, dynamic state
    /// from a resync key frame (for a late joiner, or after the server changed). On a
    /// reduced-rate stream (`watch_every`), meant for slow links, the state (all of the
    /// world's particles at once) is not asked for: the decoder is whole at the stream's
    /// next key frame, which the server sends when a stream gains its first watcher.
    pub fn catch_up(&self, timeout: Duration) -> Result<crate::frame::FrameDecoder> {
        let mut decoder = crate::frame::FrameDecoder::new();
        decoder
            .apply(&self.snapshot(timeout)?)
            .map_err(|e| anyhow!("snapshot: {e}"))?;
        if self.every == 1 {
            decoder
                .apply(&self.state(timeout)?)
                .map_err(|e| anyhow!("state: {e}"))?;
        }
        Ok(decoder)
    }

    fn fetch(&self, key: &str, timeout: Duration) -> Result<Vec<u8>> {
        self.first_reply(key, None, timeout)?
            .map_err(|err| anyhow!("{key} refused: {}", String::from_utf8_lossy(&err)))
    }
}

/// Decodes an event payload.
pub fn parse_event(sample: &Sample) -> Result<Event> {
    serde_json::from_slice(&sample.payload().to_bytes()).context("unreadable event")
}

/// The worlds whose servers are up, by their liveliness tokens.
pub fn list_worlds(session: &Session, timeout: Duration) -> Result<Vec<String>> {
    let mut worlds: Vec<String> = alive_tokens(session, keys::ALL_ALIVE, timeout)?
        .into_iter()
        .map(|(world, _)| world)
        .collect();
    worlds.dedup();
    Ok(worlds)
}

/// The liveliness tokens matching `key` now, as (world, server's zenoh id), sorted, each
/// once.
fn alive_tokens(session: &Session, key: &str, timeout: Duration) -> Result<Vec<(String, String)>> {
    // A callback, not a channel: zenoh hands the tokens it already knows to the query's
    // handler before the query returns, so a bounded channel nobody reads yet (the default
    // holds 256) would block for good under a peer holding more tokens than it holds.
    // The (world, zid) pairs kept, and how many more there were.
    type Found = (BTreeSet<(String, String)>, usize);
    let found: Arc<Mutex<Found>> = Arc::default();
    let (finished, done) = std::sync::mpsc::channel::<()>();
    let collect = {
        let found = Arc::clone(&found);
        // Dropped with the callback when the query ends: the receiver then disconnects.
        move |reply: zenoh::query::Reply| {
            let _alive = &finished;
            if let Ok(sample) = reply.result() {
                if let Some((world, zid)) = keys::parse_alive(sample.key_expr().as_str()) {
                    let mut found = found.lock().unwrap_or_else(|e| e.into_inner());
                    let token = (world.to_string(), zid.to_string());
                    if found.0.len() < MAX_TOKENS || found.0.contains(&token) {
                        found.0.insert(token);
                    } else {
                        found.1 += 1;
                    }
                }
            }
        }
    };
    session
        .liveliness()
        .get(key)
        .callback(collect)
        .timeout(timeout)
        .wait()
        .map_err(|e| anyhow!("{key}: {e}"))?;
    // Bounded: the query ends by its timeout at the latest.
    let _ = done.recv_timeout(timeout + Duration::from_millis(500));
    let (tokens, more) = std::mem::take(&mut *found.lock().unwrap_or_else(|e| e.into_inner()));
    if more > 0 {
        tracing::warn!(
            key,
            kept = MAX_TOKENS,
            more,
            "more liveliness tokens than a query keeps: some holders were not read"
        );
    }
    Ok(tokens.into_iter().collect())
}

/// The most tokens one liveliness query keeps: a peer may declare any number of them.
pub const MAX_TOKENS: usize = 4096;

/// The refusal of a world whose token several peers hold, naming a few of them: a peer
/// holding thousands of tokens must not make the error itself a flood.
fn claimed_twice(world: &str, claimed: &[String]) -> String {
    let named: Vec<String> = claimed
        .iter()
        .take(3)
        .map(|zid| crate::text::short(zid, 40))
        .collect();
    let more = match claimed.len().saturating_sub(named.len()) {
        0 => String::new(),
        n => format!(" and {n} more"),
    };
    format!(
        "world `{world}` is claimed by {} peers holding its liveliness token ({}{more}): \
         refusing their replies, as the server cannot be told apart (see docs/security.md)",
        claimed.len(),
        named.join(", "),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_world_claimed_by_thousands_is_refused_in_a_few_words() {
        let two = ["a1".to_string(), "b2".to_string()];
        let e = claimed_twice("w", &two);
        assert!(
            e.contains("claimed by 2 peers") && e.contains("(a1, b2)"),
            "{e}"
        );
        let many: Vec<String> = (0..5000).map(|k| format!("{k:032x}")).collect();
        let e = claimed_twice("w", &many);
        assert!(
            e.contains("claimed by 5000 peers") && e.contains("and 4997 more") && e.len() < 400,
            "{} bytes: {e}",
            e.len()
        );
        let hostile = ["\u{1b}[2J".repeat(100)];
        let e = claimed_twice("w", &[hostile[0].clone(), "x".into()]);
        assert!(!e.chars().any(char::is_control) && e.len() < 400, "{e}");
    }
}
