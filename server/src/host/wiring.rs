//! The server's zenoh wiring: its session's configuration, and every key it declares (a
//! publisher per frame stream, the snapshot's and the events', the command subscriber,
//! the request and query queryables, the liveliness token), each handing what arrives to
//! the [`Inbox`] and nothing more.

use std::sync::Arc;

use anyhow::{anyhow, Result};
use ricochet_protocol::keys::WorldKeys;
use zenoh::liveliness::LivelinessToken;
use zenoh::pubsub::Subscriber;
use zenoh::qos::CongestionControl;
use zenoh::query::Queryable;
use zenoh::session::TransportEventsListener;
use zenoh::Wait;

use super::frames_out::FramesOut;
use super::hosted::Hosted;
use super::inbox::{Ask, Inbox, InboxLimits};
use super::outbox::Outbox;
use super::publish::Publisher;
use super::{
    peers, HostOptions, BLOCK_WAIT_BEFORE_CLOSE, FRAGMENTS_WAIT_BEFORE_DROP, STEP_PRIORITY,
};

/// The server's zenoh configuration: the network's, with the receive size bounded to what
/// a command needs, a blocked send bounded in time and the frames' queues
/// ([`frame_queues`]), unless a configuration file was given: then its values hold, and
/// `assets/zenoh/server.json5` sets them all.
pub fn server_config(opts: &HostOptions) -> Result<zenoh::Config> {
    let mut config = opts.network.config()?;
    if opts.network.config.is_none() {
        let max_message = (opts.limits.command_bytes as usize).saturating_add(64 << 10);
        let own = [
            (
                "transport/link/rx/max_message_size",
                max_message.to_string(),
            ),
            (
                "transport/link/tx/queue/congestion_control/block/wait_before_close",
                BLOCK_WAIT_BEFORE_CLOSE.as_micros().to_string(),
            ),
        ];
        set(&mut config, own.into_iter().chain(frame_queues()))?;
    }
    Ok(config)
}

/// How the links that carry frames queue them, for the server and for a router between it
/// and viewers: room for a key frame of many particles (16 batches of 64 KiB, zenoh's
/// most; its default is 2), allocated only when needed, and the fragments' wait.
pub(super) fn frame_queues() -> [(&'static str, String); 3] {
    [
        (
            "transport/link/tx/queue/congestion_control/drop/max_wait_before_drop_fragments",
            FRAGMENTS_WAIT_BEFORE_DROP.as_micros().to_string(),
        ),
        ("transport/link/tx/queue/size/data_low", "16".to_string()),
        (
            "transport/link/tx/queue/allocation/mode",
            "\"lazy\"".to_string(),
        ),
    ]
}

pub(super) fn set(
    config: &mut zenoh::Config,
    values: impl IntoIterator<Item = (&'static str, String)>,
) -> Result<()> {
    for (key, value) in values {
        config
            .insert_json5(key, &value)
            .map_err(|e| anyhow!("zenoh configuration {key} = {value}: {e}"))?;
    }
    Ok(())
}

/// What the server declared on its session: kept alive as long as the world is served.
pub(super) struct Wiring {
    pub outbox: Outbox,
    pub inbox: Arc<Inbox>,
    _commands: Subscriber<()>,
    _requests: Queryable<()>,
    _queries: Vec<Queryable<()>>,
    _alive: LivelinessToken,
    /// Which sessions are connected (none kept when claims are trusted as they are).
    _transports: Option<TransportEventsListener<()>>,
}

impl Wiring {
    /// Declares the world's keys on `session`, as `opts` say, for the streams `host` has;
    /// frames leave through the [`Publisher`] it returns beside.
    pub fn declare(
        session: &zenoh::Session,
        keys: &WorldKeys,
        host: &Hosted,
        opts: &HostOptions,
    ) -> Result<(Wiring, Publisher)> {
        let z = |e: zenoh::Error| anyhow!("zenoh: {e}");
        let publisher = |key: String| {
            session
                .declare_publisher(key)
                .congestion_control(CongestionControl::Drop)
                .priority(STEP_PRIORITY)
                .wait()
                .map_err(z)
        };
        // One publisher per frame stream (streams.rs), in the streams' order.
        let mut publishers = host
            .wire
            .streams
            .streams
            .iter()
            .map(|s| publisher(keys.frame_every(s.every)))
            .collect::<Result<Vec<_>>>()?;
        let snapshot = publishers.len();
        publishers.push(publisher(keys.snapshot.clone())?);
        let publisher =
            Publisher::new(FramesOut::start(publishers), snapshot, opts.dump.as_deref())?;
        let events = session
            .declare_publisher(keys.event.clone())
            .congestion_control(CongestionControl::Drop)
            .wait()
            .map_err(z)?;
        let outbox = Outbox::start(events);
        let (peers, transports) = if opts.sender_ids == peers::SenderIds::Claimed {
            (peers::Peers::trusting(), None)
        } else {
            // In client mode the server's only transport is to the router it dialled.
            let client_mode = server_config(opts)?
                .get_json("mode")
                .is_ok_and(|mode| mode.contains("client"));
            let (peers, listener) =
                peers::Peers::watch(session, client_mode, opts.sender_ids).map_err(z)?;
            (peers, Some(listener))
        };
        let inbox = Arc::new(Inbox::new(
            InboxLimits {
                command_bytes: opts.limits.command_bytes as usize,
                ..opts.inbox
            },
            outbox.clone(),
            peers,
        ));
        let commands = session
            .declare_subscriber(&keys.cmd)
            .callback({
                let inbox = Arc::clone(&inbox);
                move |sample| inbox.offer_command(sample)
            })
            .wait()
            .map_err(z)?;
        let requests = session
            .declare_queryable(&keys.rpc)
            .callback({
                let inbox = Arc::clone(&inbox);
                move |query| inbox.offer_request(query)
            })
            .wait()
            .map_err(z)?;
        let mut asks = vec![
            (keys.snapshot.clone(), Ask::Snapshot),
            (keys.info.clone(), Ask::Info),
        ];
        for s in &host.wire.streams.streams {
            asks.push((keys.state_every(s.every), Ask::State(s.every)));
        }
        let queries = asks
            .into_iter()
            .map(|(key, ask)| {
                let inbox = Arc::clone(&inbox);
                session
                    .declare_queryable(key)
                    .callback(move |query| inbox.offer_query(ask, query))
                    .wait()
                    .map_err(z)
            })
            .collect::<Result<Vec<_>>>()?;
        let alive = session
            .liveliness()
            .declare_token(keys.alive_token(&session.zid().to_string()))
            .wait()
            .map_err(z)?;
        let wiring = Wiring {
            outbox,
            inbox,
            _commands: commands,
            _requests: requests,
            _queries: queries,
            _alive: alive,
            _transports: transports,
        };
        Ok((wiring, publisher))
    }
}
