//! Ricochet's server: hosts engine worlds on zenoh in real time and measures them.
//!
//! - [`host`]: the authoritative host: commands flow in from zenoh, are stamped with the
//!   frame they take effect in and applied between fixed steps; frames, snapshots and
//!   events flow out;
//! - [`accuracy`]: an accuracy target instead of solver knobs: the cheapest measured
//!   setting that meets it;
//! - [`certs`]: the secured deployment's TLS certificates (`ricochet-server certs`);
//! - [`scenes`]: the scenes directory, the only files a `load` from the network reads;
//! - [`report`]: the measuring commands (benchmark, trade-off), which step scenes and
//!   write figures, CSV and charts.
//!
//! The physics is [`ricochet_engine`]; the wire forms are [`ricochet_protocol`].

pub mod accuracy;
pub mod certs;
pub mod host;
pub mod report;
pub mod scenes;
