//! Commands: what clients ask of a world, in a text form a person can type.
//!
//! A command is a JSON object whose `do` field names it. World actions
//! (`{"do": "fire_dye_pack", "at": [50, 60]}`) are applied by the engine at a frame
//! boundary; server controls (`{"do": "pause"}`, `{"do": "step", "n": 10}`) steer the
//! server's clock. [`Command::parse`] tells the two apart and names what is wrong with a
//! malformed one.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use crate::text::short;

pub use crate::action::{Action, Direction, MinionShape, Point};

/// Controls of the server's clock and world, besides the world actions.
#[derive(
    Clone, Debug, PartialEq, Serialize, Deserialize, strum::VariantNames, schemars::JsonSchema,
)]
#[serde(tag = "do", rename_all = "snake_case", deny_unknown_fields)]
#[strum(serialize_all = "snake_case")]
pub enum ServerCommand {
    /// Stops stepping; commands are still applied.
    Pause,
    /// Steps in real time again.
    Resume,
    /// Runs `n` steps at once (pausing first), then replies.
    Step {
        #[serde(default = "one_step")]
        n: u32,
    },
    /// Reloads the world's scene from scratch: frame 0, the scene's seed.
    Reset {
        /// Stay paused after the reset (for replays).
        #[serde(default)]
        paused: bool,
    },
    /// Reports bodies as they are at this frame (changes nothing): those named in `ids`,
    /// else those whose centre lies `within` [[x0, y0], [x1, y1]], else every body; at
    /// most [`MAX_BODIES_A_REPLY`], in the reply's `bodies`.
    Bodies {
        #[serde(default, skip_serializing_if = "Vec::is_empty")]
        ids: Vec<String>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        within: Option<[Point; 2]>,
    },
    /// Loads another scene: `path`, a file name under the server's scenes directory
    /// (`ricochet-server run --scenes DIR`), or `text`, the scene's TOML.
    Load {
        #[serde(default)]
        path: Option<String>,
        #[serde(default)]
        text: Option<String>,
    },
    /// Keeps the world's whole state at this frame under `name` (replacing a save of
    /// that name): bodies, contacts and their warm starts, particles, emitters, the
    /// random generator, the settings and the scene it came from. The reply's `hash` is
    /// the state's.
    Save { name: String },
    /// Puts the world back as it was saved under `name`: what it does next is bit for bit
    /// what it did after the save.
    Restore { name: String },
    /// Puts the world back at an earlier `frame` of this run, as it was published then
    /// (before the commands of that frame's boundary), from the history the server keeps;
    /// refused, saying how far back it reaches, past it.
    Rewind { frame: u64 },
    /// The state hash of each kept frame from `from` to `to` (both optional; at most
    /// [`MAX_HASHES_A_REPLY`] a reply, the latest when more are asked), in the reply's
    /// `hashes`.
    Hashes {
        #[serde(default, skip_serializing_if = "Option::is_none")]
        from: Option<u64>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        to: Option<u64>,
    },
    /// Starts a second world, named `world`, from this one at this frame, served by the
    /// same server on its own keys, with its own clock and budgets; `settings` (`[world]`
    /// field names and values, as `set` takes them) are applied to it first.
    Fork {
        world: String,
        #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
        settings: BTreeMap<String, serde_json::Value>,
    },
    /// Stops serving this world, when it is a fork (the server's own world stops with the
    /// server).
    Close,
}

/// Frame hashes a `hashes` reply carries at most.
pub const MAX_HASHES_A_REPLY: usize = 1000;

/// A frame and the hash of the world's state after it (16 hexadecimal digits of XXH3-64).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct FrameHash {
    pub frame: u64,
    pub hash: String,
}

fn one_step() -> u32 {
    1
}

/// The names of the server commands (the variants of [`ServerCommand`]), to tell them
/// from world actions.
pub const SERVER_COMMANDS: &[&str] = <ServerCommand as strum::VariantNames>::VARIANTS;

/// Any command a client can send.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum Command {
    Server(ServerCommand),
    World(Action),
}

/// The largest command [`Command::parse`] reads, in bytes (a scene's text included); a
/// server lowers it to its world's `command_bytes` limit with [`Command::parse_limited`].
pub const MAX_COMMAND_BYTES: usize = 1 << 20;

/// The longest name (group, preset, scene) a command may carry, in bytes.
pub const MAX_NAME_BYTES: usize = 256;

/// The longest request id (`"id"`, chosen by the client) a command may carry, in bytes.
pub const MAX_ID_BYTES: usize = 64;

/// Bytes of an error message a refusal echoes at most: what a peer sent is never
/// repeated at length to it, to event subscribers or to the log.
pub const MAX_ERROR_BYTES: usize = 300;

impl Command {
    /// Parses a command from JSON, naming what is wrong: not JSON, no `do`, an unknown
    /// command, a bad argument of a known one, or a name too long. At most
    /// [`MAX_COMMAND_BYTES`].
    pub fn parse(bytes: &[u8]) -> Result<Command, String> {
        Self::parse_limited(bytes, MAX_COMMAND_BYTES)
    }

    /// [`Command::parse`] of at most `max_bytes`; errors are cut to [`MAX_ERROR_BYTES`].
    pub fn parse_limited(bytes: &[u8], max_bytes: usize) -> Result<Command, String> {
        Self::parse_unshortened(bytes, max_bytes).map_err(|e| short(&e, MAX_ERROR_BYTES))
    }

    /// A command with the request id a client may give it (`"id": "..."`, at most
    /// [`MAX_ID_BYTES`]): a server applies a command once per id, and answers a retry
    /// with the first answer. The id is read even when the command is refused, so the
    /// refusal can name it; an id that is not a short string refuses the command.
    pub fn parse_request(
        bytes: &[u8],
        max_bytes: usize,
    ) -> (Option<String>, Result<Command, String>) {
        let (id, command) = Self::parse_with_id(bytes, max_bytes);
        (id, command.map_err(|e| short(&e, MAX_ERROR_BYTES)))
    }

    /// The command alone: a request id, if any, is checked and set aside.
    fn parse_unshortened(bytes: &[u8], max_bytes: usize) -> Result<Command, String> {
        Self::parse_with_id(bytes, max_bytes).1
    }

    fn parse_with_id(bytes: &[u8], max_bytes: usize) -> (Option<String>, Result<Command, String>) {
        if bytes.len() > max_bytes {
            return (
                None,
                Err(format!(
                    "command of {} bytes is larger than the limit of {max_bytes}",
                    bytes.len()
                )),
            );
        }
        let mut value = match serde_json::from_slice::<Distinct>(bytes) {
            Ok(Distinct(value)) => value,
            Err(e) if e.is_data() => return (None, Err(e.to_string())),
            Err(e) => return (None, Err(format!("not JSON: {e}"))),
        };
        let id = match value.as_object_mut().and_then(|o| o.remove("id")) {
            None => None,
            Some(serde_json::Value::String(id)) if !id.is_empty() && id.len() <= MAX_ID_BYTES => {
                Some(id)
            }
            Some(_) => {
                return (
                    None,
                    Err(format!(
                        "`id` must be a string of 1 to {MAX_ID_BYTES} bytes"
                    )),
                )
            }
        };
        (id, Self::parse_value(value))
    }

    /// A command from a JSON value already read (the CLI's `NAME ARG=VALUE` form), checked
    /// as [`Command::parse`] checks one; errors are cut to [`MAX_ERROR_BYTES`].
    pub fn from_value(value: serde_json::Value) -> Result<Command, String> {
        Self::parse_value(value).map_err(|e| short(&e, MAX_ERROR_BYTES))
    }

    fn parse_value(value: serde_json::Value) -> Result<Command, String> {
        let name = value
            .get("do")
            .ok_or("a command is a JSON object with a `do` field naming it")?
            .as_str()
            .ok_or("`do` must be a string")?;
        let name = short(name, 64);
        // serde ignores unknown fields of a variant without any (`pause`, `deselect`):
        // every field given must be one the command has.
        let given: Vec<String> = value
            .as_object()
            .map(|o| o.keys().cloned().collect())
            .unwrap_or_default();
        let command = if SERVER_COMMANDS.contains(&name.as_str()) {
            serde_json::from_value(value)
                .map(Command::Server)
                .map_err(|e| format!("`{name}`: {e}"))?
        } else {
            serde_json::from_value(value)
                .map(Command::World)
                .map_err(|e| {
                    let msg = e.to_string();
                    if msg.starts_with(&format!("unknown variant `{name}`")) {
                        format!(
                            "unknown command `{name}` (server: {}; world: {})",
                            SERVER_COMMANDS.join(", "),
                            Action::NAMES.join(", ")
                        )
                    } else {
                        format!("`{name}`: {msg}")
                    }
                })?
        };
        let known = serde_json::to_value(&command).map_err(|e| e.to_string())?;
        if let Some(field) = given.iter().find(|k| known.get(k.as_str()).is_none()) {
            return Err(format!("`{name}`: unknown field `{}`", short(field, 64)));
        }
        if let Command::World(Action::Set { name: setting, .. }) = &command {
            if !crate::action::SETTING_NAMES.contains(&setting.as_str()) {
                return Err(format!(
                    "`set`: unknown setting `{}` (known: {})",
                    short(setting, 64),
                    crate::action::SETTING_NAMES.join(", ")
                ));
            }
        }
        for (field, text) in command.names() {
            if text.len() > MAX_NAME_BYTES {
                return Err(format!(
                    "`{name}`: `{field}` is {} bytes long; names are at most {MAX_NAME_BYTES}",
                    text.len()
                ));
            }
        }
        Ok(command)
    }

    /// The names the command carries (groups, presets, a scene path), by field.
    fn names(&self) -> Vec<(&'static str, &str)> {
        match self {
            Command::World(Action::Clear { group }) => vec![("group", group)],
            Command::World(
                Action::Remove { body }
                | Action::Impulse { body, .. }
                | Action::SetBody { body, .. },
            ) => vec![("body", body)],
            Command::World(Action::Select {
                group: Some(group), ..
            }) => vec![("group", group)],
            Command::World(Action::Spawn { body, template, .. }) => {
                let mut names = Vec::new();
                if let Some(template) = template {
                    names.push(("template", template.as_str()));
                }
                if let Some(body) = body {
                    names.extend(body.id.as_deref().map(|id| ("body.id", id)));
                    names.extend(body.group.as_deref().map(|g| ("body.group", g)));
                }
                names
            }
            Command::World(
                Action::SpawnParticles { preset, .. } | Action::StartEmitter { preset, .. },
            ) => vec![("preset", preset)],
            Command::Server(ServerCommand::Load {
                path: Some(path), ..
            }) => vec![("path", path)],
            Command::Server(ServerCommand::Bodies { ids, .. }) => {
                ids.iter().map(|id| ("ids", id.as_str())).collect()
            }
            Command::Server(ServerCommand::Save { name } | ServerCommand::Restore { name }) => {
                vec![("name", name)]
            }
            Command::Server(ServerCommand::Fork { world, settings }) => {
                let mut names = vec![("world", world.as_str())];
                names.extend(settings.keys().map(|k| ("settings", k.as_str())));
                names
            }
            _ => Vec::new(),
        }
    }

    pub fn to_json(&self) -> String {
        serde_json::to_string(self).expect("commands serialise")
    }
}

/// A JSON value whose objects were read with every key distinct: a key given twice is
/// refused, where a plain read would keep one of the two values unseen.
struct Distinct(serde_json::Value);

impl<'de> Deserialize<'de> for Distinct {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        d.deserialize_any(DistinctVisitor).map(Distinct)
    }
}

struct DistinctVisitor;

impl<'de> serde::de::Visitor<'de> for DistinctVisitor {
    type Value = serde_json::Value;

    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str("a JSON value")
    }

    fn visit_bool<E>(self, v: bool) -> Result<Self::Value, E> {
        Ok(v.into())
    }

    fn visit_i64<E>(self, v: i64) -> Result<Self::Value, E> {
        Ok(v.into())
    }

    fn visit_u64<E>(self, v: u64) -> Result<Self::Value, E> {
        Ok(v.into())
    }

    fn visit_f64<E>(self, v: f64) -> Result<Self::Value, E> {
        Ok(serde_json::Number::from_f64(v).map_or(serde_json::Value::Null, Into::into))
    }

    fn visit_str<E>(self, v: &str) -> Result<Self::Value, E> {
        Ok(v.into())
    }

    fn visit_string<E>(self, v: String) -> Result<Self::Value, E> {
        Ok(v.into())
    }

    fn visit_unit<E>(self) -> Result<Self::Value, E> {
        Ok(serde_json::Value::Null)
    }

    fn visit_seq<A: serde::de::SeqAccess<'de>>(self, mut seq: A) -> Result<Self::Value, A::Error> {
        let mut items = Vec::new();
        while let Some(Distinct(item)) = seq.next_element()? {
            items.push(item);
        }
        Ok(items.into())
    }

    fn visit_map<A: serde::de::MapAccess<'de>>(self, mut map: A) -> Result<Self::Value, A::Error> {
        let mut object = serde_json::Map::new();
        while let Some(key) = map.next_key::<String>()? {
            if object.contains_key(&key) {
                return Err(serde::de::Error::custom(format!(
                    "duplicate key `{}`",
                    short(&key, 64)
                )));
            }
            let Distinct(value) = map.next_value()?;
            object.insert(key, value);
        }
        Ok(object.into())
    }
}

/// The reply to a command sent as a request.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Reply {
    pub ok: bool,
    /// The frame the command took effect in: it is applied before step `frame + 1`.
    pub frame: u64,
    /// Ids the command created or chose.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub ids: Vec<String>,
    /// Why the command was refused.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
    /// The request's id, when it gave one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub id: Option<String>,
    /// The bodies a `bodies` command asked for, as they were at `frame`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub bodies: Vec<BodyState>,
    /// The state hash of `frame` (a `save`, `restore` or `rewind`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub hash: Option<String>,
    /// The frames and state hashes a `hashes` command asked for.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub hashes: Vec<FrameHash>,
}

/// Bodies a `bodies` reply carries at most: a larger world is asked by ids or `within`.
pub const MAX_BODIES_A_REPLY: usize = 1000;

/// A body as a `bodies` reply reports it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BodyState {
    pub id: String,
    pub group: String,
    /// `circle` or `rect`.
    pub shape: String,
    /// The rectangle's width and height, or the circle's diameter twice.
    pub size: [f64; 2],
    pub pos: Point,
    pub vel: Point,
    /// 0 for a static body.
    pub mass: f64,
    /// It touched something in the last step.
    pub collided: bool,
}

impl Reply {
    /// A refusal at `frame`.
    pub fn refused(frame: u64, error: impl Into<String>) -> Reply {
        Reply {
            ok: false,
            frame,
            error: Some(error.into()),
            ..Reply::default()
        }
    }
}

/// What the server publishes on the event key for every command it handles: the
/// applied ones form the world's input log.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Event {
    pub frame: u64,
    pub ok: bool,
    /// The command as applied (absent when it could not be parsed).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub command: Option<Command>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub ids: Vec<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

/// What a viewer needs to frame a world: the answer of the `info` key.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct WorldInfo {
    /// The scene's file name (or `inline` for a scene sent as text).
    pub scene: String,
    /// The scene's bounds, `[[min_x, min_y], [max_x, max_y]]`, in world units (y up).
    pub bounds: [[f64; 2]; 2],
    /// The step, seconds.
    pub dt: f64,
    /// The body groups by index, as the scene declares them.
    pub groups: Vec<String>,
    /// Changes whenever the scene is (re)loaded.
    pub generation: u64,
    /// How the server is coping: what it took, refused and dropped since it started.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub health: Option<Health>,
    /// The setting the server picked for the scene's accuracy target, and why (absent
    /// without a target).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub accuracy: Option<String>,
    /// The frame streams and the bytes each sent over the last whole second.
    #[serde(default)]
    pub streams: Vec<StreamRate>,
    /// The bodies the scene names for `spawn` (its `[[template]]` tables).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub templates: Vec<String>,
    /// The names `restore` takes, each with the frame it was saved at.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub saves: Vec<(String, u64)>,
    /// The first frame `rewind` reaches (absent when the server keeps no history).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rewinds_to: Option<u64>,
    /// The world this one was forked from, when it is a fork.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub forked_from: Option<String>,
    /// The world is paused (`pause`, `step`, `run --paused`): it sends no frames until
    /// `resume` or `step`.
    #[serde(default)]
    pub paused: bool,
}

/// A frame stream's rate.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct StreamRate {
    /// Steps a frame of the stream stands for (1: every step).
    pub every: u64,
    /// Bytes a second the stream's frames took: the peak of the last five whole seconds
    /// (a link must carry a stream's bursts).
    pub bytes_per_second: f64,
}

impl WorldInfo {
    /// The fullest stream whose measured rate fits `bits_per_second`: the stream that
    /// carries every step when it fits, else the tier of fewest steps a frame that does;
    /// the sparsest when none fits. A rate of 0 is not measured yet (a server in its first
    /// second; every frame has a header), so it is not taken to fit.
    pub fn stream_for(&self, bits_per_second: f64) -> u64 {
        let mut streams: Vec<&StreamRate> = self.streams.iter().collect();
        streams.sort_by_key(|s| s.every);
        streams
            .iter()
            .find(|s| s.bytes_per_second > 0.0 && s.bytes_per_second * 8.0 <= bits_per_second)
            .or(streams.last())
            .map_or(1, |s| s.every)
    }
}

/// A server's counts since it started (the `health` of [`WorldInfo`]).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Health {
    /// Frames stepped.
    pub frames: u64,
    /// Steps that started more than one `dt` late.
    pub overruns: u64,
    /// Commands and requests applied (a retried id counts once).
    pub applied: u64,
    /// Commands and requests refused with a reason (bad, over a limit).
    pub refused: u64,
    /// Retries answered from the first answer instead of applied again.
    pub retries: u64,
    /// Commands and requests over their sender's rate: requests are answered so.
    pub rate_limited: u64,
    /// Commands and requests that found the queue full: requests are answered so.
    pub queue_full: u64,
    /// Replies and events the network would not take at once (a slow peer): dropped.
    pub unsent: u64,
    /// Queries (state, snapshot, info) answered.
    pub queries: u64,
    /// Commands and requests refused because their sender's share of the server's time,
    /// or the share of all senders, did not hold their price: requests are answered so.
    #[serde(default)]
    pub over_budget: u64,
}

/// One line of an input log (`ricochet record`, `ricochet-server simulate --inputs`): an
/// action applied after `frame` steps.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TimedAction {
    pub frame: u64,
    pub action: Action,
}

/// Reads an input log: JSON Lines of [`TimedAction`], in frame order; blank lines and
/// lines starting with `#` are skipped. Errors name the 1-based line.
pub fn parse_input_log(text: &str) -> Result<Vec<TimedAction>, String> {
    let mut out: Vec<TimedAction> = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let action: TimedAction = serde_json::from_str(line)
            .map_err(|e| format!("line {}: not an input line: {e}", i + 1))?;
        if let Some(last) = out.last() {
            if action.frame < last.frame {
                return Err(format!(
                    "line {}: frame {} comes after frame {}; inputs must be in frame order",
                    i + 1,
                    action.frame,
                    last.frame
                ));
            }
        }
        out.push(action);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A budget picks the fullest stream that fits; a stream not yet measured (rate 0, a
    /// server in its first second) is not taken to fit, so a slow link starts sparse.
    #[test]
    fn a_budget_picks_the_fullest_measured_stream_that_fits() {
        let info = |rates: [f64; 4]| -> WorldInfo {
            let streams: Vec<_> = [1, 2, 4, 8]
                .iter()
                .zip(rates)
                .map(|(every, b)| serde_json::json!({"every": every, "bytes_per_second": b}))
                .collect();
            serde_json::from_value(serde_json::json!({"scene": "s", "bounds": [[0, 0], [1, 1]],
                "dt": 0.1, "groups": [], "generation": 0, "streams": streams}))
            .unwrap()
        };
        let measured = info([1000.0, 500.0, 250.0, 125.0]);
        assert_eq!(measured.stream_for(8000.0), 1);
        assert_eq!(measured.stream_for(3000.0), 4);
        assert_eq!(measured.stream_for(10.0), 8);
        assert_eq!(info([0.0; 4]).stream_for(8.0), 8);
        assert_eq!(info([0.0, 0.0, 250.0, 125.0]).stream_for(1e9), 4);
    }

    #[test]
    fn actions_read_as_json_a_person_can_type() {
        let a: Action = serde_json::from_str(r#"{"do":"fire_dye_pack","at":[50,60.5]}"#).unwrap();
        assert_eq!(a, Action::FireDyePack { at: [50.0, 60.5] });
        let a: Action = serde_json::from_str(r#"{"do":"press","dir":"left"}"#).unwrap();
        assert_eq!(
            a,
            Action::Press {
                dir: Direction::Left
            }
        );
        let a: Action =
            serde_json::from_str(r#"{"do":"set","name":"gravity","value":[0,-10]}"#).unwrap();
        assert!(matches!(a, Action::Set { .. }));
        let a: Action =
            serde_json::from_str(r#"{"do":"spawn_particles","preset":"fire","at":[1,2]}"#).unwrap();
        assert_eq!(
            a,
            Action::SpawnParticles {
                preset: "fire".into(),
                at: [1.0, 2.0],
                count: 1
            }
        );
    }

    #[test]
    fn commands_tell_server_controls_from_world_actions() {
        assert_eq!(
            Command::parse(br#"{"do":"pause"}"#),
            Ok(Command::Server(ServerCommand::Pause))
        );
        assert_eq!(
            Command::parse(br#"{"do":"step"}"#),
            Ok(Command::Server(ServerCommand::Step { n: 1 }))
        );
        assert_eq!(
            Command::parse(br#"{"do":"release","dir":"up"}"#),
            Ok(Command::World(Action::Release { dir: Direction::Up }))
        );
        // Round trip through the text form.
        let c = Command::World(Action::StartEmitter {
            preset: "fire".into(),
            count: 9,
            at: [1.0, 2.0],
        });
        assert_eq!(Command::parse(c.to_json().as_bytes()), Ok(c));
    }

    #[test]
    fn every_listed_name_is_a_command_the_parser_knows() {
        // The lists come from the types: each name is a `do` the parser routes, none is
        // unknown, and a name that is not a command is refused listing them all.
        for name in SERVER_COMMANDS.iter().chain(Action::NAMES) {
            // Missing arguments or not, the name itself is known.
            if let Err(e) = Command::parse(format!(r#"{{"do":"{name}"}}"#).as_bytes()) {
                assert!(!e.contains("unknown command"), "{name}: {e}");
            }
        }
        assert_eq!(
            SERVER_COMMANDS,
            [
                "pause", "resume", "step", "reset", "bodies", "load", "save", "restore", "rewind",
                "hashes", "fork", "close"
            ]
        );
        assert!(Action::NAMES.contains(&"spawn_particles") && Action::NAMES.contains(&"set"));
        let e = Command::parse(br#"{"do":"fly"}"#).unwrap_err();
        for name in SERVER_COMMANDS.iter().chain(Action::NAMES) {
            assert!(e.contains(name), "{name} not listed: {e}");
        }
    }

    #[test]
    fn malformed_commands_are_refused_with_the_reason() {
        for (text, needle) in [
            ("not json", "not JSON"),
            (r#"[1, 2]"#, "`do` field"),
            (r#"{"do": 3}"#, "must be a string"),
            (r#"{"do":"fly"}"#, "unknown command `fly`"),
            (r#"{"do":"fire_dye_pack"}"#, "at"),
            (r#"{"do":"press","dir":"sideways"}"#, "sideways"),
            (r#"{"do":"drag","to":[1,2],"speed":3}"#, "speed"),
            (r#"{"do":"step","n":-1}"#, "step"),
            (r#"{"do":"pause","nope":1}"#, "unknown field `nope`"),
            (r#"{"do":"deselect","to":[1,2]}"#, "unknown field `to`"),
        ] {
            let e = Command::parse(text.as_bytes()).unwrap_err();
            assert!(e.contains(needle), "{text}: {e}");
        }
        let huge = vec![b' '; MAX_COMMAND_BYTES + 1];
        assert!(Command::parse(&huge).unwrap_err().contains("larger"));
        assert!(Command::parse_limited(br#"{"do":"deselect"}   "#, 10)
            .unwrap_err()
            .contains("limit of 10"));
    }

    #[test]
    fn a_key_given_twice_is_refused_at_any_depth() {
        for (text, key) in [
            (r#"{"do":"press","dir":"up","dir":"down"}"#, "dir"),
            (
                r#"{"do":"set","name":"gravity","value":{"a":1,"a":2}}"#,
                "a",
            ),
            (r#"{"do":"deselect","id":"x","id":"y"}"#, "id"),
        ] {
            let e = Command::parse(text.as_bytes()).unwrap_err();
            assert!(e.contains(&format!("duplicate key `{key}`")), "{text}: {e}");
        }
        // Numbers read as a plain read reads them.
        let c = Command::parse(br#"{"do":"drag","to":[0.1,-3e300]}"#).unwrap();
        assert_eq!(c, Command::World(Action::Drag { to: [0.1, -3e300] }));
    }

    #[test]
    fn refusals_never_echo_much_of_what_was_sent() {
        let long = "y".repeat(100_000);
        for text in [
            format!(r#"{{"do":"{long}"}}"#),
            format!(r#"{{"do":"clear","group":"{long}"}}"#),
            format!(r#"{{"do":"press","dir":"{long}"}}"#),
            format!(r#"{{"do":"load","path":"{long}"}}"#),
            format!(r#"{{"do":"clear","group":"x"}}{long}"#),
        ] {
            let e = Command::parse(text.as_bytes()).unwrap_err();
            assert!(e.len() <= MAX_ERROR_BYTES + 4, "{} bytes: {e:.80}", e.len());
        }
    }
}
