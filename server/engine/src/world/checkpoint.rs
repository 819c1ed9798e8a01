//! Checkpoints: a world's whole state as bytes and back, so a run resumes where it was
//! instead of replaying every step from its scene (the server's journal keeps one and
//! only the commands after it).
//!
//! A restored world continues bit for bit as the saved one would have: the bytes hold
//! every field a step reads (bodies, particles, emitters, the random generator, the
//! contacts and the impulses they carry for warm starting, the solver's blocks)
//! and leave out only scratch space a step rebuilds. The engine's tests step every
//! shipped scene on from a checkpoint and compare.
//!
//! Layout: `RCK` magic, a version byte, the CRC-32 of the rest (u32, little-endian), then
//! the world in CBOR (self-describing: a field added later reads as missing, not as
//! another field's bytes; floats are exact, infinities included).

use super::{Limits, World};

const MAGIC: &[u8; 3] = b"RCK";
/// The layout's version (2: one home for the contacts and their warm starts; 3: the
/// persistent pair set saves its fat boxes only, their tree built again on restore).
pub const CHECKPOINT_VERSION: u8 = 3;

/// Why bytes are not a checkpoint this engine can restore.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CheckpointError {
    #[error("not a checkpoint (no RCK magic)")]
    Magic,
    #[error("checkpoint version {0}; this server reads version {CHECKPOINT_VERSION}")]
    Version(u8),
    #[error("checkpoint damaged: its checksum does not match its bytes")]
    Checksum,
    #[error("checkpoint unreadable: {0}")]
    Decode(String),
    /// Decoded, but not a world a scene could have made: a number out of range, an
    /// index out of bounds, a count over the server's limits.
    #[error("checkpoint field `{field}`: {reason}")]
    Invalid { field: String, reason: String },
}

impl World {
    /// The world's whole state as a checkpoint (see the module).
    pub fn save(&self) -> Vec<u8> {
        let mut body = Vec::new();
        ciborium::into_writer(self, &mut body).expect("a world serialises into memory");
        let mut out = Vec::with_capacity(body.len() + 8);
        out.extend_from_slice(MAGIC);
        out.push(CHECKPOINT_VERSION);
        out.extend_from_slice(&crc32fast::hash(&body).to_le_bytes());
        out.extend_from_slice(&body);
        out
    }

    /// The world a checkpoint holds, under the limits it ran under where they are within
    /// `limits` (the operator's), else under `limits`. Damaged or foreign bytes are
    /// refused, naming why; so is a world no scene could have made, or one over `limits`
    /// ([`World::validate`]).
    pub fn restore(bytes: &[u8], limits: Limits) -> Result<World, CheckpointError> {
        if bytes.len() < 8 || &bytes[..3] != MAGIC {
            return Err(CheckpointError::Magic);
        }
        if bytes[3] != CHECKPOINT_VERSION {
            return Err(CheckpointError::Version(bytes[3]));
        }
        let sum = u32::from_le_bytes(bytes[4..8].try_into().expect("four bytes"));
        let body = &bytes[8..];
        if crc32fast::hash(body) != sum {
            return Err(CheckpointError::Checksum);
        }
        let mut world: World = ciborium::from_reader(body)
            .map_err(|e| CheckpointError::Decode(super::short(&e.to_string(), 200)))?;
        // The saved world's own limits (a scene's `[limits]` lowers the operator's) hold
        // where they are within the operator's; the operator's where any is above.
        let saved = std::mem::replace(&mut world.limits, limits);
        if saved.above(&world.limits).is_none() {
            world.limits = saved;
        }
        world.validate()?;
        Ok(world)
    }
}

#[cfg(test)]
mod tests {
    use ciborium::Value;

    use super::*;

    /// A change made to a checkpoint's CBOR, as an attacker would.
    type Change = Box<dyn FnOnce(&mut ciborium::Value)>;

    /// The 10-level pyramid with particles and an emitter, stepped until its contacts,
    /// the grid's boxes and the solver's blocks all hold state.
    fn stepped() -> World {
        let file = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../assets/scenes/pyramid-10.toml"
        );
        let text = std::fs::read_to_string(file).unwrap();
        let mut world =
            crate::scene::parse(&text, std::path::Path::new(file), &[]).expect("the scene");
        for action in [
            crate::action::Action::SpawnParticles {
                preset: "fire".into(),
                at: [0.0, 12.0],
                count: 20,
            },
            crate::action::Action::StartEmitter {
                preset: "fire".into(),
                count: 500,
                at: [2.0, 12.0],
            },
        ] {
            world.apply(&action).expect("applied");
        }
        for _ in 0..30 {
            world.step();
        }
        world
    }

    /// The world of a checkpoint as CBOR, to change as an attacker would.
    fn decoded(bytes: &[u8]) -> Value {
        ciborium::from_reader(&bytes[8..]).unwrap()
    }

    /// A checkpoint of `value`, with its checksum made again: what passes the CRC.
    pub(crate) fn signed(value: &Value) -> Vec<u8> {
        let mut body = Vec::new();
        ciborium::into_writer(value, &mut body).unwrap();
        let mut out = MAGIC.to_vec();
        out.push(CHECKPOINT_VERSION);
        out.extend_from_slice(&crc32fast::hash(&body).to_le_bytes());
        out.extend_from_slice(&body);
        out
    }

    /// The entry `key` of a CBOR map.
    fn entry<'a>(value: &'a mut Value, key: &str) -> &'a mut Value {
        match value {
            Value::Map(entries) => entries
                .iter_mut()
                .find(|(k, _)| k.as_text() == Some(key))
                .map(|(_, v)| v)
                .unwrap_or_else(|| panic!("no `{key}`")),
            other => panic!("not a map at `{key}`: {other:?}"),
        }
    }

    fn item(value: &mut Value, k: usize) -> &mut Value {
        &mut value.as_array_mut().expect("an array")[k]
    }

    /// The checkpoint of `world` with `change` made, restored under `limits`.
    fn crafted(world: &World, limits: Limits, change: impl FnOnce(&mut Value)) -> String {
        let mut value = decoded(&world.save());
        change(&mut value);
        match World::restore(&signed(&value), limits) {
            Ok(_) => "accepted".to_string(),
            Err(e) => e.to_string(),
        }
    }

    #[test]
    fn a_checkpoint_restores_when_whole_and_is_refused_naming_the_field_when_crafted() {
        let world = stepped();
        let limits = world.limits().clone();
        // Whole (and with every part of its state in use): restored.
        assert!(!world.contacts.pairs.is_empty() && !world.particles.is_empty());
        assert_eq!(crafted(&world, limits.clone(), |_| {}), "accepted");
        let cases: Vec<(&str, Change)> = vec![
            // dt = 1e300 panicked in Duration arithmetic.
            (
                "config",
                Box::new(|v| *entry(entry(v, "config"), "dt") = Value::Float(1e300)),
            ),
            // A mover out of range panicked in the integrator.
            (
                "movers",
                Box::new(|v| *item(entry(v, "movers"), 0) = Value::Integer(100_000.into())),
            ),
            // A body's group out of range panicked in the world.
            (
                "bodies[0].group",
                Box::new(|v| {
                    *entry(item(entry(v, "bodies"), 0), "group") = Value::Integer(999.into())
                }),
            ),
            (
                "groups[0].members",
                Box::new(|v| {
                    let members = entry(item(entry(v, "groups"), 0), "members");
                    *item(members, 0) = Value::Integer(77_777.into())
                }),
            ),
            (
                "contacts[0]",
                Box::new(|v| {
                    let pair = item(entry(entry(v, "contacts"), "pairs"), 0);
                    *entry(pair, "b") = Value::Integer(1_000_000.into())
                }),
            ),
            (
                "contacts[0]",
                Box::new(|v| {
                    let pair = item(entry(entry(v, "contacts"), "pairs"), 0);
                    *entry(pair, "pseudo_impulse") = Value::Float(f64::NAN)
                }),
            ),
            // NaN positions were served.
            (
                "bodies[3].pos",
                Box::new(|v| {
                    *item(entry(item(entry(v, "bodies"), 3), "pos"), 0) = Value::Float(f64::NAN)
                }),
            ),
            (
                "bodies[3].vel",
                Box::new(|v| {
                    *item(entry(item(entry(v, "bodies"), 3), "vel"), 1) =
                        Value::Float(f64::INFINITY)
                }),
            ),
            (
                "particles.x[0]",
                Box::new(|v| *item(entry(entry(v, "particles"), "x"), 0) = Value::Float(f64::NAN)),
            ),
            (
                "particles.vy",
                Box::new(|v| {
                    entry(entry(v, "particles"), "vy")
                        .as_array_mut()
                        .unwrap()
                        .pop();
                }),
            ),
            (
                "by_id",
                Box::new(|v| {
                    let id = entry(item(entry(v, "infos"), 1), "id");
                    *id = Value::Text("repeated".into());
                    let id = entry(item(entry(v, "infos"), 2), "id");
                    *id = Value::Text("repeated".into());
                }),
            ),
            (
                "interactions[0]",
                Box::new(|v| {
                    let side = entry(item(entry(v, "interactions"), 0), "a");
                    *side = Value::Map(vec![(
                        Value::Text("Group".into()),
                        Value::Integer(4000.into()),
                    )]);
                }),
            ),
        ];
        for (field, change) in cases {
            let e = crafted(&world, limits.clone(), change);
            assert!(e.contains(&format!("`{field}")), "{field}: {e}");
        }
    }

    #[test]
    fn a_checkpoint_over_the_servers_limits_is_refused() {
        let world = stepped();
        let bodies = world.bodies().len() as u32;
        let limits = Limits {
            bodies: bodies - 1,
            ..world.limits().clone()
        };
        let e = World::restore(&world.save(), limits).expect_err("refused");
        assert!(
            e.to_string().contains("`bodies`") && e.to_string().contains("limit"),
            "{e}"
        );
        let limits = Limits {
            particles: 1,
            ..world.limits().clone()
        };
        let e = World::restore(&world.save(), limits).expect_err("refused");
        assert!(e.to_string().contains("`particles`"), "{e}");
    }

    #[test]
    fn a_fat_box_upside_down_or_not_finite_is_refused_not_put_in_the_tree() {
        let world = stepped();
        let k = world.pair_set.first_placed().expect("a body in the tree");
        for (field, bad) in [("min", [1e9, 1e9]), ("max", [f64::NAN, 0.0])] {
            let mut value = decoded(&world.save());
            let fat = entry(entry(&mut value, "pair_set"), "fat");
            *entry(item(fat, k), field) = Value::Array(bad.map(Value::Float).to_vec());
            let e = World::restore(&signed(&value), world.limits().clone()).expect_err("refused");
            assert!(e.to_string().contains("`pair_set.fat["), "{e}");
        }
    }
}
