//! Requests answered by id, so a retried request is answered again, not applied twice.
//!
//! A client may give a command an id (`"id": "..."`, see
//! [`ricochet_protocol::command::Command::parse_request`]). The first command with an id
//! is applied and its reply remembered under (sender, id); a later command with the same
//! sender and id is not applied: it gets the remembered reply (or, for a `step` still
//! running, the reply when it is done). The most recent [`REMEMBERED`] ids are kept; ids
//! are the client's to make unique (Ricochet's clients use 128 random bits).

use std::collections::{HashMap, VecDeque};
use std::hash::BuildHasher;
use std::time::{Duration, Instant};

use ricochet_protocol::command::Reply;

use super::inbox::Sender;

/// Ids remembered at most (the oldest are forgotten first).
pub const REMEMBERED: usize = 16_384;

/// Bytes of remembered ids and replies at most (the oldest are forgotten first): a reply
/// may list every body of a large world, and 16 384 of them must not hold gigabytes.
pub const REMEMBERED_BYTES: usize = 16 << 20;

/// How long an id is remembered: a client retries within seconds (its timeout and
/// back-off; a resumed server remembers the journal's ids from when it resumed).
pub const REMEMBER_FOR: Duration = Duration::from_secs(30);

/// A sender's claimed zenoh id, hashed (the claim is the sender's own, so a collision
/// gives nothing a peer could not get by claiming another's id), and the request id hashed
/// with a key random to this process (a peer cannot aim at another's id); the id itself is
/// kept too and compared, so a collision is a miss, never another's answer.
type Key = (u64, u64);

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

/// One remembered answer; its id, reply and sender are in [`Answered::bytes`] from
/// `start`, in that order (the sender kept for checkpoints: [`Answered::export`]).
struct Entry {
    key: Key,
    at: Instant,
    due_at_step: u64,
    /// Position of its bytes, counted from the first byte ever stored.
    start: u64,
    id_len: u32,
    reply_len: u32,
    /// The sender's length; `None` for no sender.
    sender_len: Option<u32>,
}

impl Entry {
    fn len(&self) -> usize {
        self.id_len as usize + self.reply_len as usize + self.sender_len.unwrap_or(0) as usize
    }
}

/// A remembered answer as a checkpoint keeps it.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Remembered {
    pub sender: Sender,
    pub id: String,
    /// The reply as sent (JSON).
    pub reply: String,
    pub due_at_step: u64,
    /// Seconds since it was given.
    pub age: f64,
}

/// The remembered answers, first in first out, in three buffers: an index, the entries
/// and their bytes (ids and replies) in one ring. Not an allocation per answer: a burst
/// of answers, once forgotten, gives its memory back whole instead of leaving it in holes
/// between longer-lived allocations (which keeps heap pages resident for good).
pub struct Answered {
    /// Key to sequence number (`first` is `order[0]`'s).
    index: HashMap<Key, u64, rustc_hash::FxBuildHasher>,
    order: VecDeque<Entry>,
    bytes: VecDeque<u8>,
    /// Sequence number of `order[0]`, and position of `bytes[0]`.
    first: u64,
    first_byte: u64,
    senders: rustc_hash::FxBuildHasher,
    ids: std::hash::RandomState,
}

impl Default for Answered {
    fn default() -> Self {
        Answered {
            index: HashMap::default(),
            order: VecDeque::new(),
            bytes: VecDeque::new(),
            first: 0,
            first_byte: 0,
            senders: rustc_hash::FxBuildHasher,
            ids: std::hash::RandomState::new(),
        }
    }
}

impl Answered {
    fn key(&self, sender: &Sender, id: &str) -> Key {
        (self.senders.hash_one(sender), self.ids.hash_one(id))
    }

    fn entry(&self, key: &Key) -> Option<&Entry> {
        let seq = *self.index.get(key)?;
        self.order.get((seq - self.first) as usize)
    }

    fn bytes_of(&self, from: u64, len: u32) -> impl Iterator<Item = &u8> {
        let at = (from - self.first_byte) as usize;
        self.bytes.range(at..at + len as usize)
    }

    /// The answer given to `id` from `sender`, if it is remembered.
    pub fn get(&self, sender: &Sender, id: &str) -> Option<Answer> {
        let e = self.entry(&self.key(sender, id))?;
        if !self.bytes_of(e.start, e.id_len).eq(id.as_bytes()) {
            return None;
        }
        Some(Answer {
            reply: self
                .bytes_of(e.start + u64::from(e.id_len), e.reply_len)
                .copied()
                .collect(),
            due_at_step: e.due_at_step,
        })
    }

    /// Remembers the answer to `id` from `sender` (unless an answer to it is remembered),
    /// forgetting what is older than [`REMEMBER_FOR`] or past [`REMEMBERED`] answers or
    /// [`REMEMBERED_BYTES`].
    pub fn remember(&mut self, sender: Sender, id: String, answer: Answer) {
        self.remember_at(sender, id, answer, Instant::now());
    }

    /// [`Answered::remember`] at a given time (a resumed server's answers are as old as
    /// they were when it stopped).
    pub fn remember_at(&mut self, sender: Sender, id: String, answer: Answer, now: Instant) {
        let key = self.key(&sender, &id);
        if !self.index.contains_key(&key) {
            let seq = self.first + self.order.len() as u64;
            self.index.insert(key, seq);
            self.order.push_back(Entry {
                key,
                at: now,
                due_at_step: answer.due_at_step,
                start: self.first_byte + self.bytes.len() as u64,
                id_len: id.len() as u32,
                reply_len: answer.reply.len() as u32,
                sender_len: sender.as_ref().map(|s| s.len() as u32),
            });
            self.bytes.extend(id.as_bytes());
            self.bytes.extend(&answer.reply[..]);
            self.bytes.extend(sender.iter().flat_map(|s| s.as_bytes()));
        }
        self.forget_at(now);
    }

    /// Forgets what is older than [`REMEMBER_FOR`] or past [`REMEMBERED`] answers or
    /// [`REMEMBERED_BYTES`] (cheap when
    /// there is nothing to forget: the host calls it every pass).
    pub fn forget(&mut self) {
        if !self.order.is_empty() {
            self.forget_at(Instant::now());
        }
    }

    fn forget_at(&mut self, now: Instant) {
        while let Some(old) = self.order.front() {
            if self.order.len() <= REMEMBERED
                && self.bytes.len() <= REMEMBERED_BYTES
                && now.saturating_duration_since(old.at) < REMEMBER_FOR
            {
                break;
            }
            let len = old.len();
            if self.index.get(&old.key) == Some(&self.first) {
                self.index.remove(&old.key);
            }
            self.bytes.drain(..len);
            self.first_byte += len as u64;
            self.first += 1;
            self.order.pop_front();
        }
        if self.order.is_empty() {
            // Nothing to remember: hold no memory.
            if self.order.capacity() > 0 {
                self.index = HashMap::default();
                self.order = VecDeque::new();
                self.bytes = VecDeque::new();
            }
        } else if self.order.capacity() > 4 * self.order.len().max(256) {
            // After a burst: give the memory back.
            self.index.shrink_to_fit();
            self.order.shrink_to_fit();
            self.bytes.shrink_to_fit();
        }
    }

    pub fn len(&self) -> usize {
        self.order.len()
    }

    /// Every remembered answer, oldest first, with its age at `now`.
    pub fn export(&self, now: Instant) -> Vec<Remembered> {
        let text = |from: u64, len: u32| {
            String::from_utf8_lossy(&self.bytes_of(from, len).copied().collect::<Vec<u8>>())
                .into_owned()
        };
        self.order
            .iter()
            .map(|e| {
                let reply_at = e.start + u64::from(e.id_len);
                let sender_at = reply_at + u64::from(e.reply_len);
                Remembered {
                    sender: e.sender_len.map(|n| text(sender_at, n)),
                    id: text(e.start, e.id_len),
                    reply: text(reply_at, e.reply_len),
                    due_at_step: e.due_at_step,
                    age: now.saturating_duration_since(e.at).as_secs_f64(),
                }
            })
            .collect()
    }

    pub fn is_empty(&self) -> bool {
        self.order.is_empty()
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
    fn an_export_gives_back_every_answer_with_its_sender() {
        let mut a = Answered::default();
        let now = Instant::now();
        a.remember_at(
            Some("s1".into()),
            "r1".into(),
            answer(1),
            now - Duration::from_secs(3),
        );
        a.remember_at(
            None,
            "r2".into(),
            Answer::new(&Reply::refused(2, "y"), 7),
            now,
        );
        let out = a.export(now);
        assert_eq!(out.len(), 2);
        assert_eq!(
            (out[0].sender.as_deref(), out[0].id.as_str()),
            (Some("s1"), "r1")
        );
        assert!((out[0].age - 3.0).abs() < 1e-6, "{}", out[0].age);
        assert_eq!((out[1].sender.as_deref(), out[1].due_at_step), (None, 7));
        let reply: Reply = serde_json::from_str(&out[1].reply).unwrap();
        assert_eq!(reply.frame, 2);
        // Remembered again elsewhere, each is found under its sender.
        let mut b = Answered::default();
        for r in out {
            let answer = Answer {
                reply: r.reply.into_bytes().into_boxed_slice(),
                due_at_step: r.due_at_step,
            };
            b.remember_at(r.sender, r.id, answer, now);
        }
        assert_eq!(frame(&b.get(&Some("s1".into()), "r1").unwrap()), 1);
        assert_eq!(b.get(&None, "r2").unwrap().due_at_step, 7);
    }

    #[test]
    fn ids_are_per_sender_and_bounded() {
        let mut a = Answered::default();
        a.remember(Some("s1".into()), "r".into(), answer(1));
        a.remember(Some("s2".into()), "r".into(), answer(2));
        assert_eq!(frame(&a.get(&Some("s1".into()), "r").unwrap()), 1);
        assert_eq!(frame(&a.get(&Some("s2".into()), "r").unwrap()), 2);
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
    fn large_answers_are_held_within_a_byte_budget() {
        // Replies listing the ids of a large world: 200 of about a MiB each.
        let mut a = Answered::default();
        let t0 = Instant::now();
        let big = |i: u64| {
            let mut reply = Reply::refused(i, "");
            reply.ok = true;
            reply.error = None;
            reply.ids = (0..90_000).map(|k| format!("b{k}")).collect();
            Answer::new(&reply, 0)
        };
        let one = big(0).reply.len();
        assert!(one > 500_000, "{one} bytes");
        for i in 0..200u64 {
            a.remember_at(None, format!("id-{i}"), big(i), t0);
            assert!(
                a.bytes.len() <= REMEMBERED_BYTES,
                "{} bytes held",
                a.bytes.len()
            );
        }
        // The newest are remembered, whole; the oldest went first.
        assert_eq!(frame(&a.get(&None, "id-199").unwrap()), 199);
        assert!(a.get(&None, "id-0").is_none());
        assert!(
            a.len() >= REMEMBERED_BYTES / one - 1,
            "{} remembered",
            a.len()
        );
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

    #[test]
    fn answers_come_back_whole_as_the_ring_turns_and_its_memory_goes_back() {
        let mut a = Answered::default();
        let t0 = Instant::now();
        for i in 0..3 * REMEMBERED as u64 {
            let sender = (i % 3 == 0).then(|| format!("s{}", i % 7));
            let answer = Answer::new(&Reply::refused(i, "x".repeat((i % 50) as usize)), i);
            a.remember_at(sender.clone(), format!("id-{i}"), answer.clone(), t0);
            // The newest and one a while back, byte for byte.
            let got = a.get(&sender, &format!("id-{i}")).unwrap();
            assert_eq!((got.reply, got.due_at_step), (answer.reply, i));
            if i >= 1000 {
                let j = i - 1000;
                let sender = (j % 3 == 0).then(|| format!("s{}", j % 7));
                assert_eq!(frame(&a.get(&sender, &format!("id-{j}")).unwrap()), j);
                assert!(a.get(&sender, &format!("id-{j}x")).is_none());
            }
        }
        assert_eq!(a.len(), REMEMBERED);
        a.forget_at(t0 + REMEMBER_FOR);
        assert!(a.is_empty());
        assert_eq!(
            (a.order.capacity(), a.bytes.capacity(), a.index.capacity()),
            (0, 0, 0),
            "nothing remembered, nothing held"
        );
    }
}
