//! Ricochet's wire protocol and data formats, and a typed zenoh client.
//!
//! - [`keys`]: the key expressions of a world;
//! - [`command`]: commands in JSON, replies and events;
//! - [`frame`]: the binary frame and snapshot layout (versioned), encoder and decoder;
//! - [`client`]: a typed zenoh client for tools, viewers and tests;
//! - [`dump`]: the JSON Lines frames of headless runs.

pub mod client;
pub mod command;
pub mod dump;
pub mod frame;
pub mod keys;

/// The protocol's version: the frame layout's version byte and the `v` of key expressions.
pub const PROTOCOL_VERSION: u8 = 1;
