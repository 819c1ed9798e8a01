//! Ricochet's wire protocol and data formats: bytes and text flow in and out, engine
//! values on the other side. No network here unless the `client` feature is on.
//!
//! - [`keys`]: the key expressions of a world;
//! - [`command`]: commands in JSON, replies and events;
//! - [`frame`]: the binary frame and snapshot layout (versioned), encoder and decoder;
//! - [`dump`]: the JSON Lines frames of headless runs;
//! - [`world`]: an engine world as frames, snapshots and dump records.
//!
//! With the `client` feature:
//! - [`net`]: the network flags, zenoh session and tracing set-up every binary shares;
//! - [`client`]: a typed zenoh client for tools, viewers and tests (and the `ricochet`
//!   command-line client, `src/bin/ricochet.rs`).

pub mod command;
pub mod dump;
pub mod frame;
pub mod keys;
pub mod world;

#[cfg(feature = "client")]
pub mod client;
#[cfg(feature = "client")]
pub mod net;

/// The protocol's version: the frame layout's version byte.
pub const PROTOCOL_VERSION: u8 = 5;
