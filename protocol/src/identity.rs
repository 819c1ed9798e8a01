//! Who sent a message, proven: a sender id no other peer can borrow.
//!
//! The server keeps a rate bucket, a queue and a share of its time per sender, and a sender
//! is the zenoh id a message's source info names. Anyone can write any id there, and a
//! client's id is no secret (it rides on every message it sends), so a peer could claim a
//! connected client's id and spend that client's rate. A client therefore proves its id:
//!
//! - it makes an Ed25519 key pair when it opens its session, and takes as its zenoh id the
//!   one [`zid_of`] derives from the public key (so the id names the key);
//! - each message it sends carries, as zenoh's attachment, the public key, a counter that
//!   grows by one a message, and a signature over the key expression, the counter and the
//!   payload ([`Identity::attach`]);
//! - the server gives a claimed id its own buckets only when the attachment's key derives
//!   that id and the signature holds ([`Proof::verify`]), and each counter once
//!   ([`Window`]): a copy of a client's message, sent again by whoever saw it, is charged
//!   to the anonymous sender, not to that client.
//!
//! The attachment is [`ATTACHMENT_BYTES`] bytes: the version byte [`VERSION`], the public
//! key (32 bytes), the counter (u64, little-endian), the signature (64 bytes). What is
//! signed is [`DOMAIN`], the key expression, a zero byte, the counter (u64 little-endian),
//! then the payload. docs/network.md, "Sender ids", gives the layout for clients in other
//! languages.

use std::sync::atomic::{AtomicU64, Ordering};

use ring::rand::SystemRandom;
use ring::signature::{Ed25519KeyPair, KeyPair, UnparsedPublicKey, ED25519};

/// The attachment layout's version.
pub const VERSION: u8 = 1;
/// Bytes of an attachment: version, public key, counter, signature.
pub const ATTACHMENT_BYTES: usize = 1 + 32 + 8 + 64;
/// What every signed message starts with, so a signature made for Ricochet means nothing
/// elsewhere.
pub const DOMAIN: &[u8] = b"ricochet sender v1\0";

/// The zenoh id a public key names: the first 16 bytes of SHA-256 over [`DOMAIN`] then the
/// key, read as a big-endian number with its top bit set, in lowercase hex (32 digits; zenoh
/// ids are written without leading zeros, and the top bit makes sure there are none).
pub fn zid_of(public: &[u8; 32]) -> String {
    let mut hashed = Vec::with_capacity(DOMAIN.len() + 32);
    hashed.extend_from_slice(DOMAIN);
    hashed.extend_from_slice(public);
    let digest = ring::digest::digest(&ring::digest::SHA256, &hashed);
    let mut first = [0u8; 16];
    first.copy_from_slice(&digest.as_ref()[..16]);
    format!("{:032x}", u128::from_be_bytes(first) | 1 << 127)
}

/// The bytes a signature covers.
fn signed(key: &str, counter: u64, payload: &[u8]) -> Vec<u8> {
    let mut message = Vec::with_capacity(DOMAIN.len() + key.len() + 9 + payload.len());
    message.extend_from_slice(DOMAIN);
    message.extend_from_slice(key.as_bytes());
    message.push(0);
    message.extend_from_slice(&counter.to_le_bytes());
    message.extend_from_slice(payload);
    message
}

/// A client's key pair and the zenoh id it names.
pub struct Identity {
    pair: Ed25519KeyPair,
    public: [u8; 32],
    zid: String,
    /// The counter of the next message [`Identity::sign`] signs.
    next: AtomicU64,
}

impl std::fmt::Debug for Identity {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Identity").field("zid", &self.zid).finish()
    }
}

impl Identity {
    /// A new key pair from the system's random source.
    pub fn generate() -> Identity {
        let rng = SystemRandom::new();
        let pkcs8 = Ed25519KeyPair::generate_pkcs8(&rng).expect("the system's random source");
        let pair = Ed25519KeyPair::from_pkcs8(pkcs8.as_ref()).expect("a key ring just made");
        let mut public = [0u8; 32];
        public.copy_from_slice(pair.public_key().as_ref());
        Identity {
            zid: zid_of(&public),
            pair,
            public,
            next: AtomicU64::new(0),
        }
    }

    /// The attachment for the next message this identity sends (its counter is one more
    /// than the last's, whichever client or world of this identity sent that).
    pub fn sign(&self, key: &str, payload: &[u8]) -> Vec<u8> {
        self.attach(key, self.next.fetch_add(1, Ordering::Relaxed), payload)
    }

    /// The zenoh id a session of this identity must have (zenoh's `id` setting).
    pub fn zid(&self) -> &str {
        &self.zid
    }

    /// The attachment proving this identity sent `payload` on `key` as message `counter`.
    pub fn attach(&self, key: &str, counter: u64, payload: &[u8]) -> Vec<u8> {
        let signature = self.pair.sign(&signed(key, counter, payload));
        let mut out = Vec::with_capacity(ATTACHMENT_BYTES);
        out.push(VERSION);
        out.extend_from_slice(&self.public);
        out.extend_from_slice(&counter.to_le_bytes());
        out.extend_from_slice(signature.as_ref());
        out
    }
}

/// An attachment as read: what a message says proves its sender.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Proof {
    pub public: [u8; 32],
    pub counter: u64,
    pub signature: [u8; 64],
}

impl Proof {
    /// Reads an attachment; `None` unless it is exactly one of this version's.
    pub fn read(attachment: &[u8]) -> Option<Proof> {
        if attachment.len() != ATTACHMENT_BYTES || attachment[0] != VERSION {
            return None;
        }
        let mut public = [0u8; 32];
        public.copy_from_slice(&attachment[1..33]);
        let counter = u64::from_le_bytes(attachment[33..41].try_into().ok()?);
        let mut signature = [0u8; 64];
        signature.copy_from_slice(&attachment[41..]);
        Some(Proof {
            public,
            counter,
            signature,
        })
    }

    /// The zenoh id the attachment's key names.
    pub fn zid(&self) -> String {
        zid_of(&self.public)
    }

    /// Whether the signature holds for `payload` sent on `key` (the costly part: tens of
    /// microseconds; check the id and the counter first).
    pub fn verify(&self, key: &str, payload: &[u8]) -> bool {
        UnparsedPublicKey::new(&ED25519, &self.public)
            .verify(&signed(key, self.counter, payload), &self.signature)
            .is_ok()
    }
}

/// The counters a sender has used, to take each once: the highest, and which of the 128
/// below it. A counter further back than that is refused too, so a client's messages may
/// arrive out of order by up to 128 and still count.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Window {
    /// One more than the highest counter taken (0: none yet).
    next: u64,
    /// Bit `i`: counter `next - 1 - i` was taken.
    seen: u128,
}

impl Window {
    /// Whether `counter` is new (it is not marked: see [`Window::take`]).
    pub fn is_new(&self, counter: u64) -> bool {
        if counter == u64::MAX {
            // The last counter would leave no room to mark it.
            return false;
        }
        if counter >= self.next {
            return true;
        }
        let back = self.next - 1 - counter;
        back < 128 && self.seen & (1 << back) == 0
    }

    /// Marks `counter` taken; false when it was not new.
    pub fn take(&mut self, counter: u64) -> bool {
        if !self.is_new(counter) {
            return false;
        }
        if counter >= self.next {
            let shift = counter - self.next + 1;
            self.seen = if shift >= 128 { 0 } else { self.seen << shift };
            self.seen |= 1;
            self.next = counter + 1;
        } else {
            self.seen |= 1 << (self.next - 1 - counter);
        }
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_signed_message_verifies_and_names_its_senders_id() {
        let me = Identity::generate();
        let attachment = me.attach("ricochet/w/rpc", 7, b"{\"do\":\"step\"}");
        let proof = Proof::read(&attachment).expect("an attachment of this version");
        assert_eq!(proof.counter, 7);
        assert_eq!(proof.zid(), me.zid());
        assert_eq!(me.zid().len(), 32);
        assert!(proof.verify("ricochet/w/rpc", b"{\"do\":\"step\"}"));
    }

    #[test]
    fn a_signature_holds_for_its_own_key_counter_and_payload_only() {
        let me = Identity::generate();
        let attachment = me.attach("ricochet/w/rpc", 7, b"step");
        let proof = Proof::read(&attachment).unwrap();
        assert!(!proof.verify("ricochet/other/rpc", b"step"));
        assert!(!proof.verify("ricochet/w/rpc", b"pause"));
        let moved = Proof {
            counter: 8,
            ..proof
        };
        assert!(!moved.verify("ricochet/w/rpc", b"step"));
        let someone = Identity::generate();
        let borrowed = Proof {
            public: Proof::read(&someone.attach("k", 0, b"")).unwrap().public,
            ..proof
        };
        assert!(!borrowed.verify("ricochet/w/rpc", b"step"));
        assert_ne!(someone.zid(), me.zid());
    }

    #[test]
    fn attachments_of_another_size_or_version_are_not_read() {
        let mut attachment = Identity::generate().attach("k", 1, b"x");
        assert!(Proof::read(&attachment[..ATTACHMENT_BYTES - 1]).is_none());
        attachment[0] = VERSION + 1;
        assert!(Proof::read(&attachment).is_none());
        assert!(Proof::read(&[]).is_none());
    }

    #[test]
    fn the_window_takes_each_counter_once_in_any_order_within_its_reach() {
        let mut window = Window::default();
        assert!(window.take(0));
        assert!(!window.take(0));
        assert!(window.take(5));
        assert!(window.take(3), "late but within reach");
        assert!(!window.take(3));
        assert!(window.take(4));
        assert!(window.take(200));
        assert!(!window.take(5), "further back than 128");
        assert!(window.take(199));
        assert!(window.take(u64::MAX - 1));
        assert!(!window.take(u64::MAX - 1));
        assert!(!window.take(u64::MAX), "no room past the last");
        assert!(!window.take(200));
    }
}
