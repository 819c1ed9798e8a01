//! Which claimed senders are sessions connected to this server.
//!
//! A sender is the zenoh id a message's source info claims, and a peer may claim any id:
//! one process could claim a thousand and take a thousand senders' rate buckets and budgets.
//! zenoh tells a session which sessions it has a transport with (its transport events),
//! and a transport costs a real connection and handshake, which zenoh bounds in all
//! (`max_sessions`) and the operator's firewall per address (docs/security.md). So a claim
//! naming a session connected to the server keeps its own buckets, and any other claim
//! shares the anonymous sender's: claiming ids no longer multiplies buckets.
//!
//! Through a router (the secured deployment), clients are not connected to the server, and
//! their ids cannot be checked here: a server in client mode (its one transport is to the
//! router it dialled) takes claims as they are, and the router's access control decides
//! who may send at all. A server that listens takes a router-mode session that connects
//! to it as one more peer: any process may open one, and trusting every claim while one
//! was connected let a single session take twenty senders' buckets.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};

use zenoh::config::WhatAmI;
use zenoh::sample::SampleKind;
use zenoh::session::TransportEventsListener;
use zenoh::{Session, Wait};

use super::inbox::Sender;

/// The sessions connected to the server, kept up to date by zenoh's transport events.
#[derive(Clone, Default)]
pub struct Peers {
    /// `None`: claims are taken as they are (tests, and a server with no session).
    known: Option<Arc<Mutex<Known>>>,
}

#[derive(Default)]
struct Known {
    /// Zenoh ids of the peers and clients with a transport to the server.
    direct: HashMap<String, usize>,
    /// Routers connected: through them, claims cannot be checked.
    routers: usize,
    /// Claims through a connected router are taken as they are: the server is in client
    /// mode, and the only router it has is the one it dialled.
    through_routers: bool,
}

impl Peers {
    /// Claims taken as they are.
    pub fn trusting() -> Peers {
        Peers::default()
    }

    /// Follows `session`'s transports (those open now, then each opening and closing).
    /// The listener must be kept for as long as the peers are asked. `through_routers`:
    /// the session is in client mode, so a connected router is the one it dialled and
    /// claims through it are taken as they are.
    pub fn watch(
        session: &Session,
        through_routers: bool,
    ) -> zenoh::Result<(Peers, TransportEventsListener<()>)> {
        let known = Arc::new(Mutex::new(Known {
            through_routers,
            ..Known::default()
        }));
        let listener = session
            .info()
            .transport_events_listener()
            .history(true)
            .callback({
                let known = Arc::clone(&known);
                move |event| {
                    let transport = event.transport();
                    let zid = transport.zid().to_string();
                    let mut known = known.lock().unwrap_or_else(|e| e.into_inner());
                    let opened = event.kind() == SampleKind::Put;
                    if transport.whatami() == WhatAmI::Router {
                        known.routers = if opened {
                            known.routers + 1
                        } else {
                            known.routers.saturating_sub(1)
                        };
                    } else if opened {
                        *known.direct.entry(zid).or_default() += 1;
                    } else if let Some(n) = known.direct.get_mut(&zid) {
                        *n -= 1;
                        if *n == 0 {
                            known.direct.remove(&zid);
                        }
                    }
                }
            })
            .wait()?;
        Ok((Peers { known: Some(known) }, listener))
    }

    /// The sender whose buckets a message claiming `claimed` is charged to: the claim when
    /// it names a session connected to the server (or cannot be checked), else the
    /// anonymous sender.
    pub fn bucket(&self, claimed: &Sender) -> Sender {
        let Some(known) = &self.known else {
            return claimed.clone();
        };
        let known = known.lock().unwrap_or_else(|e| e.into_inner());
        match claimed {
            _ if known.through_routers && known.routers > 0 => claimed.clone(),
            Some(zid) if known.direct.contains_key(zid) => claimed.clone(),
            _ => None,
        }
    }
}
