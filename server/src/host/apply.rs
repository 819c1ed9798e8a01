//! The frame boundary's work on one command or request: a retried id gets its first
//! answer; anything else is handled by the world, journaled, and made an event.

use ricochet_protocol::command::{Command, Event, Reply, ServerCommand, MAX_ERROR_BYTES};
use zenoh::query::Query;

use std::time::Instant;

use super::answered::{Answer, Answered};
use super::budget::Budgets;
use super::hosted::{Handled, Hosted};
use super::inbox::Incoming;
use super::inbox::Sender;
use super::journal::{Intent, Journal};
use super::outbox::Outbox;

/// A reply waiting for the steps its `step` asked for.
pub(super) struct Deferred {
    pub due_at_step: u64,
    pub query: Query,
    pub reply: Box<[u8]>,
}

/// What the frame boundary keeps from one command to the next.
pub(super) struct Boundary<'a> {
    pub answered: &'a mut Answered,
    pub budgets: &'a mut Budgets,
    pub deferred: &'a mut Vec<Deferred>,
    pub journal: &'a mut Option<Journal>,
    pub outbox: &'a Outbox,
    /// The world's place among the server's (`fork`, `close`).
    pub slot: Option<&'a super::worlds::Slot>,
}

/// Applies one command or request at the frame boundary: a retried id gets its first
/// answer; a command its sender's budget (or the budget in all) cannot pay for is refused
/// before it runs; anything else is handled by the world, charged what it took, and made
/// an event.
pub(super) fn apply_incoming(host: &mut Hosted, incoming: Incoming, at: Boundary<'_>) {
    let Boundary {
        answered,
        budgets,
        deferred,
        journal,
        outbox,
        slot,
    } = at;
    let Incoming {
        payload,
        sender,
        key,
        query,
    } = incoming;
    let frame = host.world.frame();
    let (id, parsed) = Command::parse_request(&payload, host.world.limits().command_bytes as usize);
    let answer = match id.as_deref().and_then(|id| answered.get(&sender, id)) {
        Some(first) => {
            host.accounts.health.retries += 1;
            first
        }
        None => {
            let price = parsed
                .as_ref()
                .ok()
                .map(|command| host.price(command, &key));
            if let Some(price) = &price {
                if let Err(over) = budgets.admit(&key, price.time(), Instant::now()) {
                    host.accounts.health.over_budget += 1;
                    tracing::debug!(frame, "command over budget: {over}");
                    if let Some(query) = query {
                        let mut reply = Reply::refused(frame, over.to_string());
                        reply.id = id;
                        outbox.reply(query, Answer::new(&reply, 0).reply.into_vec());
                    }
                    return;
                }
            }
            let began = Instant::now();
            let mut journaled_as = Journaled::Written;
            let Handled {
                mut reply,
                due_at_step,
            } = match &parsed {
                // Starting or stopping a world changes nothing in this one: not journaled.
                Ok(Command::Server(
                    command @ (ServerCommand::Fork { .. } | ServerCommand::Close),
                )) if slot.is_some() => slot.expect("matched").handle(host, command),
                Ok(command) => match journal.as_mut() {
                    None => host.handle(command),
                    Some(journal) => {
                        let (handled, how) = journaled(host, command, &sender, &id, journal);
                        journaled_as = how;
                        handled
                    }
                },
                Err(error) => {
                    host.accounts.health.refused += 1;
                    Handled {
                        reply: Reply::refused(frame, error.clone()),
                        due_at_step: 0,
                    }
                }
            };
            reply.id = id.clone();
            tracing::trace!(
                frame,
                ok = reply.ok,
                pending = host.stepping.pending_steps,
                "applied"
            );
            if let (Some(journal), Journaled::Written) = (journal.as_mut(), journaled_as) {
                journal.replied(&reply);
            }
            if !reply.ok {
                tracing::debug!(
                    frame,
                    "command refused: {}",
                    reply.error.as_deref().unwrap_or("")
                );
            }
            outbox.publish_event(&Event {
                frame: reply.frame,
                ok: reply.ok,
                command: echoed(parsed.ok(), reply.ok),
                ids: reply.ids.clone(),
                error: reply.error.clone(),
            });
            let answer = Answer::new(&reply, due_at_step);
            let took = began.elapsed();
            budgets.charge(&key, took);
            if let Some(price) = &price {
                host.learn(&key, price, took);
            }
            // A command refused because the journal could not be written is tried afresh
            // when sent again: the disk may have room by then.
            if let (Some(id), false) = (id, journaled_as == Journaled::Failed) {
                answered.remember(sender, id, answer.clone());
            }
            answer
        }
    };
    if let Some(query) = query {
        if answer.due_at_step > host.stepping.steps_run {
            deferred.push(Deferred {
                due_at_step: answer.due_at_step,
                query,
                reply: answer.reply,
            });
        } else {
            outbox.reply(query, answer.reply.into_vec());
        }
    }
}

/// What the journal holds of a command.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Journaled {
    /// Its line, written before it ran.
    Written,
    /// Nothing: it was refused before it could run (a scene that cannot be read).
    Refused,
    /// Nothing: its line could not be written, so it did not run.
    Failed,
}

/// Runs `command` with the journal: what it is about to do is written first, and a
/// command whose line cannot be written is refused, not run.
fn journaled(
    host: &mut Hosted,
    command: &Command,
    sender: &Sender,
    id: &Option<String>,
    journal: &mut Journal,
) -> (Handled, Journaled) {
    let frame = host.world.frame();
    let refused = |host: &mut Hosted, e: anyhow::Error| {
        tracing::error!("{e:#}");
        let error = format!("not applied: the server cannot write its journal ({e:#})");
        (host.refuse(&error), Journaled::Failed)
    };
    match command {
        Command::Server(ServerCommand::Load { path, text }) => {
            let (text, name) = match host.scene_to_load(path.as_deref(), text.as_deref()) {
                Ok(scene) => scene,
                Err(e) => return (host.refuse(&e), Journaled::Refused),
            };
            let intent = Intent::Load {
                name: &name,
                text: &text,
            };
            match journal.before(intent, frame, sender, id) {
                Ok(()) => (host.handle_scene(text, name), Journaled::Written),
                Err(e) => refused(host, e),
            }
        }
        _ => match journal.before(Intent::Apply(command), frame, sender, id) {
            Ok(()) => (host.handle(command), Journaled::Written),
            Err(e) => refused(host, e),
        },
    }
}

/// The command an event shows: a refused one only when its JSON is at most
/// [`MAX_ERROR_BYTES`] (a refused `load` of a 60 KiB scene text is not sent to every
/// subscriber; the refusal's error names it short).
fn echoed(command: Option<Command>, ok: bool) -> Option<Command> {
    command.filter(|c| ok || c.to_json().len() <= MAX_ERROR_BYTES)
}

#[cfg(test)]
mod tests {
    use super::*;
    use ricochet_protocol::command::ServerCommand;

    #[test]
    fn a_command_whose_journal_line_cannot_be_written_is_refused_and_not_run() {
        let path =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/scenes/emitters.toml");
        let text = std::fs::read_to_string(&path).unwrap();
        let opts = crate::host::HostOptions::for_tests("full-disk");
        let mut host = Hosted::load(text, path, &opts).unwrap();
        let before = host.world.bodies().len();
        let spawn = Command::parse(br#"{"do":"spawn_dumb_minion","at":[100,95]}"#).unwrap();
        let id = Some("r1".to_string());
        let mut full = Journal::full();
        let (handled, how) = journaled(&mut host, &spawn, &None, &id, &mut full);
        assert!(how == Journaled::Failed);
        assert!(!handled.reply.ok);
        let error = handled.reply.error.unwrap_or_default();
        assert!(
            error.contains("not applied") && error.contains("journal"),
            "{error}"
        );
        assert_eq!(
            host.world.bodies().len(),
            before,
            "the spawn ran unjournaled"
        );
        // With a journal that takes the line, the same command runs.
        let dir = tempfile::tempdir().unwrap();
        let mut journal = Journal::create(&dir.path().join("j"), "w", &host, &opts).unwrap();
        let (handled, how) = journaled(&mut host, &spawn, &None, &id, &mut journal);
        assert!(how == Journaled::Written && handled.reply.ok);
        assert_eq!(host.world.bodies().len(), before + 1);
    }

    #[test]
    fn a_refused_command_is_echoed_only_when_short() {
        let short = Command::Server(ServerCommand::Step { n: 1 });
        let long = Command::parse(
            format!(r#"{{"do":"load","text":"{}"}}"#, "x".repeat(60_000)).as_bytes(),
        )
        .expect("a load of inline text parses");
        assert!(echoed(Some(short.clone()), false).is_some());
        assert!(echoed(Some(long.clone()), false).is_none());
        assert!(
            echoed(Some(long), true).is_some(),
            "what was applied is shown"
        );
    }
}
