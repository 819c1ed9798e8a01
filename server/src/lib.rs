//! Ricochet's server: hosts engine worlds on zenoh in real time.
//!
//! - [`host`]: the authoritative host: commands flow in from zenoh, are stamped with the
//!   frame they take effect in and applied between fixed steps; frames, snapshots and
//!   events flow out;
//! - [`accuracy`]: an accuracy target instead of solver knobs: the scene measured under
//!   candidate settings against a converged reference ([`accuracy::measure`]), and the
//!   cheapest setting that meets the target;
//! - [`certs`]: the secured deployment's TLS certificates (`ricochet-server certs`);
//! - [`scenes`]: the scenes directory, the only files a `load` from the network reads;
//! - [`wire`]: engine worlds as the protocol's frames, snapshots and dump records, wire
//!   actions as the engine's, input logs replayed, and what frames cost on the wire.
//!
//! The physics is [`ricochet_engine`]; the wire forms are [`ricochet_protocol`]. What
//! measures the server (benchmarks, reports, attacks) is the `ricochet-lab` crate, which
//! depends on this one and never the other way.

pub mod accuracy;
pub mod certs;
pub mod host;
pub mod scenes;
pub mod wire;
