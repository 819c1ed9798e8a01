//! A typed zenoh client of a Ricochet world, for the command-line client, the viewer and
//! tests. Blocking calls (zenoh's `Wait`); no async runtime is needed by the caller.

use std::time::Duration;

use anyhow::{anyhow, Context, Result};
use zenoh::handlers::{FifoChannelHandler, RingChannel, RingChannelHandler};
use zenoh::pubsub::Subscriber;
use zenoh::sample::Sample;
use zenoh::{Session, Wait};

use crate::command::{Command, Event, Reply};
use crate::keys::{self, WorldKeys};
use crate::net::Network;

/// Frames as they arrive, all of them, in order (up to a large backlog).
pub type FrameStream = Subscriber<FifoChannelHandler<Sample>>;
/// Only the latest frames: a slow reader drops the oldest instead of stalling anything.
pub type LatestFrames = Subscriber<RingChannelHandler<Sample>>;

/// A client of one world.
pub struct Client {
    session: Session,
    keys: WorldKeys,
}

impl Client {
    /// Opens a session and addresses `world`.
    pub fn open(network: &Network, world: &str) -> Result<Self> {
        let keys = WorldKeys::new(world).map_err(|e| anyhow!(e))?;
        Ok(Client {
            session: network.open()?,
            keys,
        })
    }

    /// Addresses `world` over an existing session.
    pub fn with_session(session: Session, world: &str) -> Result<Self> {
        let keys = WorldKeys::new(world).map_err(|e| anyhow!(e))?;
        Ok(Client { session, keys })
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

    /// Sends raw bytes as a command (tests send malformed ones).
    pub fn send_raw(&self, bytes: Vec<u8>) -> Result<()> {
        self.session
            .put(&self.keys.cmd, bytes)
            .wait()
            .map_err(|e| anyhow!("send: {e}"))
    }

    /// Sends a command and waits for the reply.
    pub fn request(&self, command: &Command, timeout: Duration) -> Result<Reply> {
        self.request_raw(command.to_json().into_bytes(), timeout)
    }

    /// Sends raw bytes as a request and waits for the reply.
    pub fn request_raw(&self, bytes: Vec<u8>, timeout: Duration) -> Result<Reply> {
        let payload = match self.first_reply(&self.keys.rpc, Some(bytes), timeout)? {
            Ok(payload) | Err(payload) => payload,
        };
        serde_json::from_slice(&payload)
            .with_context(|| format!("unreadable reply: {}", String::from_utf8_lossy(&payload)))
    }

    /// Queries `key` (with `payload`) and waits for the first reply: `Ok` with its payload,
    /// or `Err` with the payload of an error reply.
    fn first_reply(
        &self,
        key: &str,
        payload: Option<Vec<u8>>,
        timeout: Duration,
    ) -> Result<Result<Vec<u8>, Vec<u8>>> {
        let mut get = self.session.get(key).timeout(timeout);
        if let Some(bytes) = payload {
            get = get.payload(bytes);
        }
        let replies = get.wait().map_err(|e| anyhow!("{key}: {e}"))?;
        let reply = replies
            .recv_timeout(timeout + Duration::from_millis(500))
            .map_err(|e| anyhow!("{key}: {e}"))?
            .ok_or_else(|| {
                anyhow!(
                    "no answer on {key} within {timeout:?}: is the server of world `{}` up?",
                    self.keys.world
                )
            })?;
        Ok(match reply.result() {
            Ok(sample) => Ok(sample.payload().to_bytes().into_owned()),
            Err(err) => Err(err.payload().to_bytes().into_owned()),
        })
    }

    /// Every frame from now on, in order.
    pub fn frames(&self) -> Result<FrameStream> {
        self.session
            .declare_subscriber(&self.keys.frame)
            .with(zenoh::handlers::FifoChannel::new(4096))
            .wait()
            .map_err(|e| anyhow!("subscribe to frames: {e}"))
    }

    /// The latest `capacity` frames: for viewers, which must never hold the server back.
    pub fn latest_frames(&self, capacity: usize) -> Result<LatestFrames> {
        self.session
            .declare_subscriber(&self.keys.frame)
            .with(RingChannel::new(capacity.max(1)))
            .wait()
            .map_err(|e| anyhow!("subscribe to frames: {e}"))
    }

    /// Statics snapshots re-published when static bodies change.
    pub fn snapshots(&self) -> Result<FrameStream> {
        self.session
            .declare_subscriber(&self.keys.snapshot)
            .with(zenoh::handlers::FifoChannel::new(64))
            .wait()
            .map_err(|e| anyhow!("subscribe to snapshots: {e}"))
    }

    /// Events: one per command the server handled.
    pub fn events(&self) -> Result<FrameStream> {
        self.session
            .declare_subscriber(&self.keys.event)
            .with(zenoh::handlers::FifoChannel::new(4096))
            .wait()
            .map_err(|e| anyhow!("subscribe to events: {e}"))
    }

    /// Fetches the statics snapshot (what a late joiner needs besides the frames).
    pub fn snapshot(&self, timeout: Duration) -> Result<Vec<u8>> {
        self.fetch(&self.keys.snapshot, timeout)
    }

    /// Fetches a key frame of the dynamic state now: a late joiner applies it, then the
    /// frames that follow it, instead of waiting for the next key frame.
    pub fn state(&self, timeout: Duration) -> Result<Vec<u8>> {
        self.fetch(&self.keys.state, timeout)
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
        let mut decoder = crate::frame::FrameDecoder::new();
        decoder
            .apply(&self.snapshot(timeout)?)
            .map_err(|e| anyhow!("snapshot: {e}"))?;
        decoder
            .apply(&self.state(timeout)?)
            .map_err(|e| anyhow!("state: {e}"))?;
        Ok((stream, decoder))
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
    let replies = session
        .liveliness()
        .get(keys::ALL_ALIVE)
        .timeout(timeout)
        .wait()
        .map_err(|e| anyhow!("list worlds: {e}"))?;
    let mut worlds = Vec::new();
    while let Ok(reply) = replies.recv() {
        if let Ok(sample) = reply.result() {
            if let Some(w) = keys::world_of_alive(sample.key_expr().as_str()) {
                worlds.push(w.to_string());
            }
        }
    }
    worlds.sort();
    worlds.dedup();
    Ok(worlds)
}
