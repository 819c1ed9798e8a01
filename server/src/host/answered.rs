//! Requests answered by id, so a retried request is answered again, not applied twice.
//!
//! A client may give a command an id (`"id": "..."`, see
//! [`ricochet_protocol::command::Command::parse_request`]). The first command with an id
//! is applied and its reply remembered under (sender, id); a later command with the same
//! sender and id is not applied: it gets the remembered reply (or, for a `step` still
//! running, the reply when it is done). The most recent [`REMEMBERED`] ids are kept; ids
//! are the client's to make unique (Ricochet's clients use 128 random bits).

use std::collections::{HashMap, VecDeque};
use std::hash::{BuildHasher, Hash};
use std::time::{Duration, Instant};

use ricochet_protocol::command::Reply;

use super::inbox::Sender;

/// Ids remembered at most (the oldest are forgotten first).
pub const REMEMBERED: usize = 16_384;

/// How long an id is remembered: a client retries within seconds (its timeout and
/// back-off; a resumed server remembers the journal's ids from when it resumed).
pub const REMEMBER_FOR: Duration = Duration::from_secs(30);

/// A sender's claimed zenoh id, hashed (the claim is the sender's own, so a collision
/// gives nothing a peer could not get by claiming another's id), and the request id.
type Key = (u64, Box<str>);

/// A remembered answer: the reply as sent (JSON), compact.
#[derive(Clone, Debug)]
pub struct Answer {
    pub reply: Box<[u8]>,
    /// Due once the host's `steps_run` reaches this (a `step`); at once if 0.
    pub due_at_step: u64,
}

impl Answer {
    pub fn new(reply: &Reply, due_at_step: u64) -> Answer {
        Answer {
            reply: serde_json::to_vec(reply)
                .expect("replies serialise")
                .into_boxed_slice(),
            due_at_step,
        }
    }
}

pub struct Answered {
    answers: HashMap<Key, Answer, rustc_hash::FxBuildHasher>,
    /// Keys in the order remembered, with when.
    order: VecDeque<(Key, Instant)>,
    senders: rustc_hash::FxBuildHasher,
}

impl Default for Answered {
    fn default() -> Self {
        Answered {
            answers: HashMap::default(),
            order: VecDeque::new(),
            senders: rustc_hash::FxBuildHasher,
        }
    }
}

impl Answered {
    fn key(&self, sender: &Sender, id: &str) -> Key {
        let mut h = self.senders.build_hasher();
        sender.hash(&mut h);
        (std::hash::Hasher::finish(&h), id.into())
    }

    /// The answer given to `id` from `sender`, if it is remembered.
    pub fn get(&self, sender: &Sender, id: &str) -> Option<&Answer> {
        self.answers.get(&self.key(sender, id))
    }

    /// Remembers the answer to `id` from `sender`, forgetting what is older than
    /// [`REMEMBER_FOR`] or past [`REMEMBERED`].
    pub fn remember(&mut self, sender: Sender, id: String, answer: Answer) {
        self.remember_at(sender, id, answer, Instant::now());
    }

    fn remember_at(&mut self, sender: Sender, id: String, answer: Answer, now: Instant) {
        let key = self.key(&sender, &id);
        if self.answers.insert(key.clone(), answer).is_none() {
            self.order.push_back((key, now));
        }
        self.forget_at(now);
    }

    /// Forgets what is older than [`REMEMBER_FOR`] or past [`REMEMBERED`] (cheap when
    /// there is nothing to forget: the host calls it every pass).
    pub fn forget(&mut self) {
        if !self.order.is_empty() {
            self.forget_at(Instant::now());
        }
    }

    fn forget_at(&mut self, now: Instant) {
        while let Some((old, at)) = self.order.front() {
            if self.order.len() <= REMEMBERED && now.duration_since(*at) < REMEMBER_FOR {
                break;
            }
            self.answers.remove(old);
            self.order.pop_front();
        }
        if self.answers.capacity() > 4 * self.answers.len().max(256) {
            // After a burst: give the memory back.
            self.answers.shrink_to_fit();
            self.order.shrink_to_fit();
        }
    }

    pub fn len(&self) -> usize {
        self.answers.len()
    }

    pub fn is_empty(&self) -> bool {
        self.answers.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn answer(frame: u64) -> Answer {
        Answer::new(&Reply::refused(frame, "x"), 0)
    }

    fn frame(a: &Answer) -> u64 {
        serde_json::from_slice::<Reply>(&a.reply).unwrap().frame
    }

    #[test]
    fn ids_are_per_sender_and_bounded() {
        let mut a = Answered::default();
        a.remember(Some("s1".into()), "r".into(), answer(1));
        a.remember(Some("s2".into()), "r".into(), answer(2));
        assert_eq!(frame(a.get(&Some("s1".into()), "r").unwrap()), 1);
        assert_eq!(frame(a.get(&Some("s2".into()), "r").unwrap()), 2);
        assert!(a.get(&None, "r").is_none());
        for i in 0..REMEMBERED {
            a.remember(None, i.to_string(), answer(3));
        }
        assert_eq!(a.len(), REMEMBERED);
        assert!(
            a.get(&Some("s1".into()), "r").is_none(),
            "the oldest is forgotten"
        );
        assert!(a.get(&None, "0").is_some());
    }

    #[test]
    fn ids_are_forgotten_after_a_while() {
        let mut a = Answered::default();
        let t0 = Instant::now();
        a.remember_at(None, "old".into(), answer(1), t0);
        a.remember_at(None, "new".into(), answer(2), t0 + REMEMBER_FOR / 2);
        assert_eq!(a.len(), 2);
        a.remember_at(None, "newer".into(), answer(3), t0 + REMEMBER_FOR);
        assert!(
            a.get(&None, "old").is_none(),
            "forgotten after REMEMBER_FOR"
        );
        assert!(a.get(&None, "new").is_some());
        assert_eq!(a.len(), 2);
    }
}
