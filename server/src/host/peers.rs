//! Which claimed senders keep rate buckets, queues and budgets of their own.
//!
//! A sender is the zenoh id a message's source info claims, and a peer may claim any id:
//! one process could claim a thousand and take a thousand senders' buckets, or claim a
//! connected client's id (it rides on that client's every message) and spend its rate. A
//! claim keeps buckets of its own only when both hold (the default, [`SenderIds::Signed`]):
//!
//! - **the id is a session connected to the server.** zenoh tells a session which sessions
//!   it has a transport with (its transport events), and a transport costs a real
//!   connection and handshake, which zenoh bounds in all (`max_sessions`) and the
//!   operator's firewall per address and per local user (docs/security.md). Claiming ids
//!   no longer multiplies buckets.
//! - **the message proves it is from that session.** Its attachment carries a public key
//!   that derives the claimed id and a signature over the message
//!   ([`ricochet_protocol::identity`]), and a counter the sender has not used before: a
//!   copy of a client's message, sent again by a peer that saw it, is not that client's.
//!
//! Any other claim shares the anonymous sender's buckets.
//!
//! Through a router (the secured deployment), clients are not connected to the server: a
//! server in client mode (its one transport is to the router it dialled) takes a claim
//! whose signature holds, whatever session it names, and the router's access control
//! decides who may send at all. A server that listens takes a router-mode session that
//! connects to it as one more peer: any process may open one, and the ids of the clients
//! behind it are not connected sessions, so their claims share the anonymous sender's.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};

use ricochet_protocol::identity::{Proof, Window};
use zenoh::config::WhatAmI;
use zenoh::sample::SampleKind;
use zenoh::session::TransportEventsListener;
use zenoh::{Session, Wait};

use super::inbox::Sender;

/// Which claims keep buckets of their own (`--sender-ids`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SenderIds {
    /// Claims of connected sessions proven by the message's signature (the default).
    #[default]
    Signed,
    /// Claims of connected sessions, signed or not: a peer that sees a client's id may
    /// spend its rate.
    Connected,
    /// Every claim as it is ([`Peers::trusting`]).
    Claimed,
}

/// Senders whose counters are remembered at most; past it, the one unused longest among
/// those not connected is forgotten (through a router, the one unused longest).
pub const MAX_WINDOWS: usize = 4096;

/// The sessions connected to the server, kept up to date by zenoh's transport events.
#[derive(Clone, Default)]
pub struct Peers {
    /// `None`: claims are taken as they are (tests, and a server with no session).
    known: Option<Arc<Mutex<Known>>>,
    /// Whether a claim must be signed ([`SenderIds::Signed`]).
    signed: bool,
}

#[derive(Default)]
struct Known {
    /// Zenoh ids of the peers and clients with a transport to the server.
    direct: HashMap<String, usize>,
    /// Routers connected: through them, claims cannot be checked.
    routers: usize,
    /// Claims through a connected router name no connected session: the server is in
    /// client mode, and the only router it has is the one it dialled.
    through_routers: bool,
    /// Each signing sender's counters, and when it last used one (`uses`).
    windows: HashMap<String, (Window, u64)>,
    uses: u64,
}

/// What a message claims of its sender.
#[derive(Clone, Copy, Debug)]
pub struct Claim<'a> {
    /// The id its source info names.
    pub sender: &'a Sender,
    /// Its attachment: the signed proof, if it has one.
    pub attachment: Option<&'a [u8]>,
    /// The key expression it came on, and its payload: what the signature covers.
    pub key: &'a str,
    pub payload: &'a [u8],
}

impl Known {
    /// Whether a claim of `zid` may keep buckets of its own, signature aside.
    fn reachable(&self, zid: &str) -> bool {
        self.direct.contains_key(zid) || (self.through_routers && self.routers > 0)
    }

    /// Takes `counter` from `zid`'s window (made if new, forgetting the longest unused
    /// one not connected when there are [`MAX_WINDOWS`]).
    fn take(&mut self, zid: &str, counter: u64) -> bool {
        self.uses += 1;
        let uses = self.uses;
        if !self.windows.contains_key(zid) && self.windows.len() >= MAX_WINDOWS {
            let oldest = self
                .windows
                .iter()
                .filter(|(z, _)| !self.direct.contains_key(*z))
                .min_by_key(|(_, (_, used))| *used)
                .map(|(z, _)| z.clone());
            match oldest {
                Some(z) => {
                    self.windows.remove(&z);
                }
                None => return false,
            }
        }
        let (window, used) = self.windows.entry(zid.to_string()).or_default();
        *used = uses;
        window.take(counter)
    }
}

impl Peers {
    /// Claims taken as they are.
    pub fn trusting() -> Peers {
        Peers::default()
    }

    /// Follows `session`'s transports (those open now, then each opening and closing).
    /// The listener must be kept for as long as the peers are asked. `through_routers`:
    /// the session is in client mode, so a connected router is the one it dialled and
    /// signed claims through it are taken whatever session they name. `ids`: which
    /// claims keep buckets of their own ([`SenderIds::Claimed`] is [`Peers::trusting`]).
    pub fn watch(
        session: &Session,
        through_routers: bool,
        ids: SenderIds,
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
        let peers = Peers {
            known: Some(known),
            signed: ids == SenderIds::Signed,
        };
        Ok((peers, listener))
    }

    /// The sender whose buckets a message is charged to: the id it claims when the claim
    /// holds (see the module's notes), else the anonymous sender.
    pub fn bucket(&self, claim: &Claim) -> Sender {
        let Some(known) = &self.known else {
            return claim.sender.clone();
        };
        let lock = || known.lock().unwrap_or_else(|e| e.into_inner());
        let zid = claim.sender.as_ref()?;
        if !lock().reachable(zid) {
            return None;
        }
        if !self.signed {
            return Some(zid.clone());
        }
        // The cheap checks first: the key names the id, and the counter is new.
        let proof = claim.attachment.and_then(Proof::read)?;
        if proof.zid() != *zid
            || lock()
                .windows
                .get(zid)
                .is_some_and(|(w, _)| !w.is_new(proof.counter))
        {
            return None;
        }
        // Outside the lock: zenoh's other receive threads go on meanwhile.
        if !proof.verify(claim.key, claim.payload) {
            return None;
        }
        // Taken under the lock: of two copies verified at once, one counts.
        let mut known = lock();
        (known.reachable(zid) && known.take(zid, proof.counter)).then(|| zid.clone())
    }
}

#[cfg(test)]
mod tests {
    use ricochet_protocol::identity::Identity;

    use super::*;

    /// Peers with `connected` connected, claims checked as `ids` says.
    fn peers(connected: &[&str], ids: SenderIds) -> Peers {
        let known = Known {
            direct: connected.iter().map(|z| (z.to_string(), 1)).collect(),
            ..Known::default()
        };
        Peers {
            known: Some(Arc::new(Mutex::new(known))),
            signed: ids == SenderIds::Signed,
        }
    }

    impl Claim<'_> {
        /// A claim with no proof.
        fn bare(sender: &Sender) -> Claim<'_> {
            Claim {
                sender,
                attachment: None,
                key: "",
                payload: &[],
            }
        }
    }

    fn claim<'a>(sender: &'a Sender, attachment: &'a [u8], payload: &'a [u8]) -> Claim<'a> {
        Claim {
            sender,
            attachment: Some(attachment),
            key: "ricochet/w/cmd",
            payload,
        }
    }

    #[test]
    fn a_signed_claim_of_a_connected_session_keeps_its_own_bucket_once_per_counter() {
        let me = Identity::generate();
        let peers = peers(&[me.zid()], SenderIds::Signed);
        let sender = Some(me.zid().to_string());
        let first = me.sign("ricochet/w/cmd", b"{}");
        assert_eq!(peers.bucket(&claim(&sender, &first, b"{}")), sender);
        // The same message again (a copy someone saw), or a claim with no proof: anonymous.
        assert_eq!(peers.bucket(&claim(&sender, &first, b"{}")), None);
        assert_eq!(peers.bucket(&Claim::bare(&sender)), None);
        let second = me.sign("ricochet/w/cmd", b"{}");
        assert_eq!(peers.bucket(&claim(&sender, &second, b"{}")), sender);
    }

    #[test]
    fn a_claim_signed_by_another_key_or_for_another_message_is_anonymous() {
        let me = Identity::generate();
        let spy = Identity::generate();
        let peers = peers(&[me.zid(), spy.zid()], SenderIds::Signed);
        let mine = Some(me.zid().to_string());
        let spys = spy.sign("ricochet/w/cmd", b"{}");
        assert_eq!(peers.bucket(&claim(&mine, &spys, b"{}")), None);
        let signed = me.sign("ricochet/w/cmd", b"{}");
        assert_eq!(peers.bucket(&claim(&mine, &signed, b"[]")), None);
        let mut moved = signed.clone();
        moved[33] ^= 1;
        assert_eq!(peers.bucket(&claim(&mine, &moved, b"{}")), None);
        // The message as signed still counts: the forgeries marked nothing.
        assert_eq!(peers.bucket(&claim(&mine, &signed, b"{}")), mine);
    }

    #[test]
    fn a_signed_claim_of_a_session_not_connected_is_anonymous_unless_through_the_router() {
        let me = Identity::generate();
        let sender = Some(me.zid().to_string());
        let attachment = me.sign("ricochet/w/cmd", b"{}");
        let alone = peers(&[], SenderIds::Signed);
        assert_eq!(alone.bucket(&claim(&sender, &attachment, b"{}")), None);
        let routed = peers(&[], SenderIds::Signed);
        {
            let mut known = routed.known.as_ref().unwrap().lock().unwrap();
            known.through_routers = true;
            known.routers = 1;
        }
        assert_eq!(routed.bucket(&claim(&sender, &attachment, b"{}")), sender);
    }

    #[test]
    fn connected_takes_bare_claims_of_connected_sessions() {
        let sender = Some("abc".to_string());
        assert_eq!(
            peers(&["abc"], SenderIds::Connected).bucket(&Claim::bare(&sender)),
            sender
        );
        assert_eq!(
            peers(&[], SenderIds::Connected).bucket(&Claim::bare(&sender)),
            None
        );
    }

    #[test]
    fn past_the_window_bound_a_connected_senders_counters_are_kept() {
        let me = Identity::generate();
        let peers = peers(&[me.zid()], SenderIds::Signed);
        let sender = Some(me.zid().to_string());
        let first = me.sign("ricochet/w/cmd", b"{}");
        assert_eq!(peers.bucket(&claim(&sender, &first, b"{}")), sender);
        {
            let mut known = peers.known.as_ref().unwrap().lock().unwrap();
            known.through_routers = true;
            known.routers = 1;
            for k in 0..MAX_WINDOWS + 10 {
                assert!(known.take(&format!("other{k}"), 0));
            }
            assert!(known.windows.len() <= MAX_WINDOWS);
        }
        assert_eq!(
            peers.bucket(&claim(&sender, &first, b"{}")),
            None,
            "a replay"
        );
    }
}
