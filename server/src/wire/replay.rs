//! An input log played into a world as it steps (`simulate --inputs`, the accuracy
//! measure, the lab's trade-off runs): the wire's timed actions, each made the engine's
//! ([`super::to_engine`]) and applied when due.

use ricochet_engine::action::{ActionError, ActionOutcome};
use ricochet_engine::world::World;
use ricochet_protocol::command::TimedAction;

use super::to_engine;

/// An input log played into a world as it steps: before each step, the actions due (those
/// of frames up to the world's), in log order. `simulate --inputs`, the trade-off runs and
/// the accuracy measure all step this way, so the same log means the same frames.
pub struct Replay<'a> {
    next: std::iter::Peekable<std::slice::Iter<'a, TimedAction>>,
}

/// What one step of a [`Replay`] did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Replayed {
    /// Actions that were due before the step (applied or refused).
    pub due: usize,
    /// Of them, those the world refused.
    pub refused: usize,
    /// The time of the step alone, the actions' not included.
    pub step_time: std::time::Duration,
}

impl<'a> Replay<'a> {
    pub fn new(log: &'a [TimedAction]) -> Replay<'a> {
        Replay {
            next: log.iter().peekable(),
        }
    }

    /// Applies the actions due to `world`, handing each with its outcome to `seen`, then
    /// steps it once.
    pub fn step(
        &mut self,
        world: &mut World,
        mut seen: impl FnMut(&TimedAction, &Result<ActionOutcome, String>),
    ) -> Replayed {
        let mut done = Replayed::default();
        while let Some(input) = self.next.next_if(|a| a.frame <= world.frame()) {
            let outcome = to_engine(&input.action)
                .and_then(|a| world.apply(&a).map_err(|e: ActionError| e.to_string()));
            done.due += 1;
            done.refused += usize::from(outcome.is_err());
            seen(input, &outcome);
        }
        let t = std::time::Instant::now();
        world.step();
        done.step_time = t.elapsed();
        done
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ricochet_protocol::command::parse_input_log;

    #[test]
    fn a_replay_applies_what_is_due_before_each_step() {
        let mut world = ricochet_engine::scene::parse(
            include_str!("../../../assets/scenes/particles.toml"),
            std::path::Path::new("particles.toml"),
            &[],
        )
        .unwrap();
        let log = parse_input_log(
            r#"{"frame":0,"action":{"do":"spawn_particles","preset":"fire","at":[50,50],"count":3}}
{"frame":2,"action":{"do":"spawn_particles","preset":"nope","at":[50,50]}}
{"frame":2,"action":{"do":"deselect"}}"#,
        )
        .unwrap();
        let mut replay = Replay::new(&log);
        let mut seen = Vec::new();
        let mut steps = Vec::new();
        for _ in 0..4 {
            let frame = world.frame();
            let done = replay.step(&mut world, |a, r| seen.push((frame, a.frame, r.is_ok())));
            steps.push((done.due, done.refused));
        }
        assert_eq!(steps, [(1, 0), (0, 0), (2, 1), (0, 0)]);
        assert_eq!(seen, [(0, 0, true), (2, 2, false), (2, 2, true)]);
        assert_eq!(world.frame(), 4);
    }
}
