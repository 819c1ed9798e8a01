//! The frame boundary's work on one command or request: a retried id gets its first
//! answer; anything else is handled by the world, journaled, and made an event.

use ricochet_protocol::command::{Command, Event, Reply, MAX_ERROR_BYTES};
use zenoh::query::Query;

use std::time::Instant;

use super::answered::{Answer, Answered};
use super::budget::Budgets;
use super::hosted::{Handled, Hosted};
use super::inbox::Incoming;
use super::journal::Journal;
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
    } = at;
    let Incoming {
        payload,
        sender,
        query,
    } = incoming;
    let frame = host.world.frame();
    let (id, parsed) = Command::parse_request(&payload, host.world.limits().command_bytes as usize);
    let answer = match id.as_deref().and_then(|id| answered.get(&sender, id)) {
        Some(first) => {
            host.health.retries += 1;
            first
        }
        None => {
            if let Ok(command) = &parsed {
                if let Err(over) = budgets.admit(&sender, host.price(command), Instant::now()) {
                    host.health.over_budget += 1;
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
            let Handled {
                mut reply,
                due_at_step,
            } = match &parsed {
                Ok(command) => host.handle(command),
                Err(error) => {
                    host.health.refused += 1;
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
                pending = host.pending_steps,
                "applied"
            );
            if let (Some(journal), Ok(command)) = (journal.as_mut(), &parsed) {
                journal.handled(command, &reply, &sender, &id, host);
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
            budgets.charge(&sender, began.elapsed());
            if let Some(id) = id {
                answered.remember(sender, id, answer.clone());
            }
            answer
        }
    };
    if let Some(query) = query {
        if answer.due_at_step > host.steps_run {
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
