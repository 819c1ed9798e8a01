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
/// The layout's version (2: one home for the contacts and their warm starts).
pub const CHECKPOINT_VERSION: u8 = 2;

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
    /// refused, naming why.
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
        Ok(world)
    }
}
