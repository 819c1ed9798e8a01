//! Time travel: named saves of a world's whole state (`save`, `restore`), a history of
//! its run to go back through (`rewind`), and a hash of its state at every frame
//! (`hashes`), so a client checks that a restored or replayed run is the same, bit for
//! bit.
//!
//! The history is a copy of the world every
//! [`TravelLimits::history_every`] frames, and every world command applied since the
//! oldest: a rewind to frame F restores the last checkpoint at or before F and replays
//! the commands and steps up to F, as the engine is deterministic. It is bounded in
//! bytes: the oldest checkpoints go first, and a rewind past the oldest kept is refused,
//! naming how far back it reaches. A `load`, `reset` or `restore` starts it afresh (the
//! world before them is another run). Saves and history are the host's state: the
//! journal's checkpoints carry them, so a resumed server rewinds and restores as the live
//! one did.

use std::collections::{BTreeMap, VecDeque};
use std::path::PathBuf;

use ricochet_engine::world::{Limits, World};
use ricochet_protocol::command::{Command, FrameHash, MAX_HASHES_A_REPLY};
use serde::{Deserialize, Serialize};

/// How much time travel a host keeps (`run --saves`, `--save-bytes`, `--history-bytes`,
/// `--history-every`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TravelLimits {
    /// Named saves at most.
    pub saves: usize,
    /// Bytes of all saves at most.
    pub save_bytes: u64,
    /// Bytes of the history's copies of the world at most, as estimated by
    /// [`World::memory_estimate`] (0: no history, `rewind` refused).
    pub history_bytes: u64,
    /// Frames between two checkpoints of the history: a rewind replays at most this many
    /// steps.
    pub history_every: u64,
    /// Frames whose state hash is kept.
    pub hashes: usize,
}

impl Default for TravelLimits {
    fn default() -> Self {
        TravelLimits {
            saves: 16,
            save_bytes: 256 << 20,
            history_bytes: 64 << 20,
            history_every: 60,
            hashes: 1 << 16,
        }
    }
}

/// A world kept by `save`, with the scene it came from (a `reset` after a `restore`
/// reloads that scene).
#[derive(Clone, Serialize, Deserialize)]
pub struct Saved {
    pub frame: u64,
    #[serde(with = "serde_bytes")]
    pub world: Vec<u8>,
    pub hash: u64,
    pub scene_text: String,
    pub scene_name: PathBuf,
}

/// A checkpoint of the history: a copy of the world (a copy costs a tenth to a fiftieth
/// of its bytes as a checkpoint file, and is taken every `history_every` frames while the
/// world runs).
#[derive(Clone, Serialize, Deserialize)]
struct Mark {
    frame: u64,
    world: Box<World>,
    /// What the copy takes in memory, about ([`World::memory_estimate`]).
    bytes: u64,
}

/// A host's saves, history and frame hashes.
#[derive(Clone, Default, Serialize, Deserialize)]
pub struct Travel {
    saves: BTreeMap<String, Saved>,
    marks: VecDeque<Mark>,
    /// The world commands applied since the oldest mark, each with the frame at whose
    /// boundary it ran, in order.
    log: VecDeque<(u64, Command)>,
    /// (frame, state hash) of the frames kept, in order.
    hashes: VecDeque<(u64, u64)>,
    #[serde(skip)]
    limits: Option<TravelLimits>,
}

impl Travel {
    /// A history starting at `world` as it is now.
    pub fn new(world: &World, limits: TravelLimits) -> Travel {
        let mut travel = Travel {
            limits: Some(limits),
            ..Travel::default()
        };
        travel.start_over(world);
        travel
    }

    /// Under `limits` (a travel read back from a checkpoint has none of its own).
    pub fn with_limits(mut self, limits: TravelLimits) -> Travel {
        self.limits = Some(limits);
        self
    }

    fn limits(&self) -> TravelLimits {
        self.limits.unwrap_or_default()
    }

    /// The history starts afresh at `world` (a new scene, a reset or a restore); the hashes
    /// of frames from its frame on are forgotten, and its own kept.
    pub fn start_over(&mut self, world: &World) {
        self.marks.clear();
        self.log.clear();
        self.hashes.retain(|&(f, _)| f < world.frame());
        self.hashed(world);
        if self.limits().history_bytes > 0 {
            self.mark(world);
        }
    }

    /// After a step: the frame's hash, and a checkpoint when one is due.
    pub fn stepped(&mut self, world: &World) {
        self.hashed(world);
        let limits = self.limits();
        if limits.history_bytes > 0 && world.frame().is_multiple_of(limits.history_every.max(1)) {
            self.mark(world);
        }
    }

    fn hashed(&mut self, world: &World) {
        self.hashes.push_back((world.frame(), world.state_hash()));
        while self.hashes.len() > self.limits().hashes.max(1) {
            self.hashes.pop_front();
        }
    }

    fn mark(&mut self, world: &World) {
        let frame = world.frame();
        if self.marks.back().is_some_and(|m| m.frame == frame) {
            return;
        }
        self.marks.push_back(Mark {
            frame,
            world: Box::new(world.clone()),
            bytes: world.memory_estimate() as u64,
        });
        let bound = self.limits().history_bytes;
        // The newest checkpoint is kept whatever its size: a rewind within the last
        // `history_every` frames always works.
        while self.marks.len() > 1 && self.history_bytes() > bound {
            self.marks.pop_front();
        }
        let first = self.marks.front().map_or(frame, |m| m.frame);
        while self.log.front().is_some_and(|(f, _)| *f < first) {
            self.log.pop_front();
        }
    }

    fn history_bytes(&self) -> u64 {
        self.marks.iter().map(|m| m.bytes).sum()
    }

    /// A world command applied at the boundary after `frame` (a rewind replays it).
    pub fn applied(&mut self, frame: u64, command: &Command) {
        if !self.marks.is_empty() {
            self.log.push_back((frame, command.clone()));
        }
    }

    /// The first frame a rewind reaches, if any.
    pub fn rewinds_to(&self) -> Option<u64> {
        self.marks.front().map(|m| m.frame)
    }

    /// The kept hashes from `from` to `to`: the latest [`MAX_HASHES_A_REPLY`] of them.
    pub fn hashes(&self, from: Option<u64>, to: Option<u64>) -> Vec<FrameHash> {
        let picked: Vec<&(u64, u64)> = self
            .hashes
            .iter()
            .filter(|(f, _)| from.is_none_or(|a| *f >= a) && to.is_none_or(|b| *f <= b))
            .collect();
        let skip = picked.len().saturating_sub(MAX_HASHES_A_REPLY);
        picked[skip..]
            .iter()
            .map(|&&(frame, h)| FrameHash {
                frame,
                hash: hex(h),
            })
            .collect()
    }

    /// Keeps `world` (made from the scene `scene_text`, named `scene_name`) as `name`,
    /// within the bounds in count and bytes.
    pub fn save(
        &mut self,
        name: &str,
        world: &World,
        scene_text: &str,
        scene_name: &std::path::Path,
    ) -> Result<u64, String> {
        let limits = self.limits();
        if name.is_empty() {
            return Err("`name` must not be empty".into());
        }
        if !self.saves.contains_key(name) && self.saves.len() >= limits.saves {
            return Err(format!(
                "`name`: {} saves are kept already, the most this server keeps (`run --saves`); save over one of them",
                self.saves.len()
            ));
        }
        let bytes = world.save();
        let others: u64 = self
            .saves
            .iter()
            .filter(|(n, _)| n.as_str() != name)
            .map(|(_, s)| (s.world.len() + s.scene_text.len()) as u64)
            .sum();
        let size = (bytes.len() + scene_text.len()) as u64;
        if others + size > limits.save_bytes {
            return Err(format!(
                "`name`: this state takes {size} bytes and the saves {others}, over the {} this server keeps (`run --save-bytes`)",
                limits.save_bytes
            ));
        }
        let hash = world.state_hash();
        self.saves.insert(
            name.to_string(),
            Saved {
                frame: world.frame(),
                world: bytes,
                hash,
                scene_text: scene_text.to_string(),
                scene_name: scene_name.to_path_buf(),
            },
        );
        Ok(hash)
    }

    /// The world saved as `name`, under `limits`.
    pub fn restore(&self, name: &str, limits: &Limits) -> Result<(World, &Saved), String> {
        let saved = self.saves.get(name).ok_or_else(|| {
            let known: Vec<&str> = self.saves.keys().map(String::as_str).collect();
            format!(
                "`name`: no save `{}` (saved: {})",
                ricochet_protocol::text::short(name, 64),
                if known.is_empty() {
                    "none".to_string()
                } else {
                    ricochet_protocol::text::short(&known.join(", "), 256)
                }
            )
        })?;
        let world = World::restore(&saved.world, limits.clone()).map_err(|e| e.to_string())?;
        Ok((world, saved))
    }

    /// The saves' names and frames, in order.
    pub fn saves(&self) -> Vec<(String, u64)> {
        self.saves
            .iter()
            .map(|(n, s)| (n.clone(), s.frame))
            .collect()
    }

    /// The world as it was published at `frame` (`now` is the world as it is): the last
    /// checkpoint at or before it, with the commands and steps after it replayed. The
    /// history after `frame` is forgotten: the world goes on from there.
    pub fn rewind(&mut self, frame: u64, now: &World) -> Result<World, String> {
        if frame > now.frame() {
            return Err(format!(
                "`frame`: {frame} is ahead of the world, at frame {}",
                now.frame()
            ));
        }
        let Some(first) = self.rewinds_to() else {
            return Err(
                "`frame`: this server keeps no history (`run --history-bytes 0`)".to_string(),
            );
        };
        if frame < first {
            return Err(format!(
                "`frame`: {frame} is before the history this server keeps, which starts at frame {first} (a load, reset or restore starts it again; `run --history-bytes` bounds it)"
            ));
        }
        let mark = self
            .marks
            .iter()
            .rev()
            .find(|m| m.frame <= frame)
            .expect("the first mark is at or before the frame");
        let mut world = (*mark.world).clone();
        let mut log = self.log.iter().filter(|(f, _)| *f >= mark.frame).peekable();
        while world.frame() < frame {
            while let Some((_, command)) = log.next_if(|(f, _)| *f == world.frame()) {
                replay(&mut world, command);
            }
            world.step();
        }
        self.marks.retain(|m| m.frame <= frame);
        self.log.retain(|(f, _)| *f < frame);
        self.hashes.retain(|&(f, _)| f <= frame);
        Ok(world)
    }

    /// Steps a rewind replays at most (its price).
    pub fn replay_steps(&self) -> u64 {
        self.limits().history_every
    }
}

/// Applies a logged world command again (it was accepted when it ran, so it is again).
fn replay(world: &mut World, command: &Command) {
    if let Command::World(action) = command {
        if let Ok(action) = crate::wire::to_engine(action) {
            if let Err(e) = world.apply(&action) {
                tracing::warn!("a rewind's replay refused a command accepted before: {e}");
            }
        }
    }
}

/// A state hash as replies show it: 16 hexadecimal digits.
pub fn hex(hash: u64) -> String {
    format!("{hash:016x}")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn world() -> World {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../assets/scenes/suite/rain.toml");
        let text = std::fs::read_to_string(&path).unwrap();
        ricochet_engine::scene::parse(&text, &path, &[]).unwrap()
    }

    fn run(world: &mut World, travel: &mut Travel, to: u64, at: &[(u64, &str)]) {
        while world.frame() < to {
            for (f, json) in at {
                if *f == world.frame() {
                    let command = Command::parse(json.as_bytes()).unwrap();
                    let Command::World(action) = &command else {
                        panic!()
                    };
                    world
                        .apply(&crate::wire::to_engine(action).unwrap())
                        .unwrap();
                    travel.applied(*f, &command);
                }
            }
            world.step();
            travel.stepped(world);
        }
    }

    #[test]
    fn a_rewind_gives_the_frame_as_it_was_whatever_happened_after() {
        let limits = TravelLimits {
            history_every: 25,
            ..TravelLimits::default()
        };
        let mut world = world();
        let mut travel = Travel::new(&world, limits);
        let commands = [
            (30, r#"{"do":"set","name":"gravity","value":[3,-20]}"#),
            (
                61,
                r#"{"do":"spawn","body":{"shape":"circle","radius":1,"pos":[0,30]}}"#,
            ),
            (90, r#"{"do":"set","name":"gravity","value":[0,-5]}"#),
        ];
        run(&mut world, &mut travel, 120, &commands);
        let hashes = travel.hashes(None, None);
        for frame in [0, 24, 25, 61, 62, 89, 119, 120] {
            let mut t = travel.clone();
            let back = t.rewind(frame, &world).unwrap();
            assert_eq!(back.frame(), frame);
            let expected = hashes.iter().find(|h| h.frame == frame).unwrap();
            assert_eq!(hex(back.state_hash()), expected.hash, "frame {frame}");
        }
        // And the world goes on from there as it did: the same commands give the same
        // frames.
        let back = travel.rewind(50, &world).unwrap();
        let mut again = back;
        run(&mut again, &mut travel, 120, &commands);
        assert_eq!(again.state_hash(), world.state_hash());
        assert_eq!(travel.hashes(None, None), hashes);
    }

    #[test]
    fn rewinds_past_the_history_or_ahead_of_the_world_are_refused() {
        let mut world = world();
        let limits = TravelLimits {
            history_every: 10,
            history_bytes: 1,
            ..TravelLimits::default()
        };
        let mut travel = Travel::new(&world, limits);
        run(&mut world, &mut travel, 35, &[]);
        assert_eq!(travel.rewinds_to(), Some(30), "one checkpoint kept");
        let e = travel.rewind(12, &world).err().unwrap();
        assert!(e.contains("starts at frame 30"), "{e}");
        let e = travel.rewind(36, &world).err().unwrap();
        assert!(e.contains("ahead"), "{e}");
        let none = TravelLimits {
            history_bytes: 0,
            ..limits
        };
        let travel = Travel::new(&world, none);
        assert_eq!(travel.rewinds_to(), None);
    }

    #[test]
    fn saves_are_bounded_in_count_and_bytes_and_restore_the_same_bits() {
        let mut world = world();
        let limits = TravelLimits {
            saves: 2,
            ..TravelLimits::default()
        };
        let mut travel = Travel::new(&world, limits);
        let scene = std::path::Path::new("rain.toml");
        run(&mut world, &mut travel, 40, &[]);
        let hash = travel.save("a", &world, "text", scene).unwrap();
        let mut later = world.clone();
        for _ in 0..50 {
            later.step();
        }
        let (mut back, saved) = travel.restore("a", world.limits()).unwrap();
        assert_eq!((saved.frame, back.state_hash()), (40, hash));
        for _ in 0..50 {
            back.step();
        }
        assert_eq!(back.state_hash(), later.state_hash());
        travel.save("b", &world, "text", scene).unwrap();
        travel.save("a", &world, "text", scene).unwrap();
        let e = travel.save("c", &world, "text", scene).unwrap_err();
        assert!(e.contains("2 saves"), "{e}");
        let e = travel.restore("nope", world.limits()).err().unwrap();
        assert!(e.contains("no save `nope`") && e.contains("a, b"), "{e}");
        let mut small = Travel::new(
            &world,
            TravelLimits {
                save_bytes: 100,
                ..limits
            },
        );
        let e = small.save("a", &world, "text", scene).unwrap_err();
        assert!(e.contains("over the 100"), "{e}");
    }
}
