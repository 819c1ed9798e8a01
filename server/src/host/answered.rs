//! Requests answered by id, so a retried request is answered again, not applied twice.
//!
//! A client may give a command an id (`"id": "..."`, see
//! [`ricochet_protocol::command::Command::parse_request`]). The first command with an id
//! is applied and its reply remembered under (sender, id); a later command with the same
//! sender and id is not applied: it gets the remembered reply (or, for a `step` still
//! running, the reply when it is done). The most recent [`REMEMBERED`] ids are kept; ids
//! are the client's to make unique (Ricochet's clients use 128 random bits).

use std::collections::{HashMap, VecDeque};

use ricochet_protocol::command::Reply;

use super::inbox::Sender;

/// Ids remembered at most (the oldest are forgotten first).
pub const REMEMBERED: usize = 16_384;

type Key = (Sender, String);

/// A remembered answer.
#[derive(Clone, Debug)]
pub struct Answer {
    pub reply: Reply,
    /// Due once the host's `steps_run` reaches this (a `step`); at once if 0.
    pub due_at_step: u64,
}

#[derive(Default)]
pub struct Answered {
    answers: HashMap<Key, Answer>,
    order: VecDeque<Key>,
}

impl Answered {
    /// The answer given to `id` from `sender`, if it is remembered.
    pub fn get(&self, sender: &Sender, id: &str) -> Option<&Answer> {
        self.answers.get(&(sender.clone(), id.to_string()))
    }

    /// Remembers the answer to `id` from `sender`, forgetting the oldest past the bound.
    pub fn remember(&mut self, sender: Sender, id: String, answer: Answer) {
        let key = (sender, id);
        if self.answers.insert(key.clone(), answer).is_none() {
            self.order.push_back(key);
        }
        while self.order.len() > REMEMBERED {
            if let Some(old) = self.order.pop_front() {
                self.answers.remove(&old);
            }
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
        Answer {
            reply: Reply::refused(frame, "x"),
            due_at_step: 0,
        }
    }

    #[test]
    fn ids_are_per_sender_and_bounded() {
        let mut a = Answered::default();
        a.remember(Some("s1".into()), "r".into(), answer(1));
        a.remember(Some("s2".into()), "r".into(), answer(2));
        assert_eq!(a.get(&Some("s1".into()), "r").unwrap().reply.frame, 1);
        assert_eq!(a.get(&Some("s2".into()), "r").unwrap().reply.frame, 2);
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
}
