//! Ricochet's wire protocol and data formats: bytes and text flow in and out, the wire's
//! own types on the other side. No physics here (the server turns engine worlds into these
//! types, `ricochet_server::wire`), and no network unless the `client` feature is on.
//!
//! - [`keys`]: the key expressions of a world;
//! - [`action`]: world actions as they travel;
//! - [`command`]: commands in JSON, replies and events;
//! - [`frame`]: the binary frame and snapshot layout (versioned), encoder and decoder;
//! - [`dump`]: the JSON Lines frames of headless runs;
//! - [`text`]: what of a peer's text a message may show.
//!
//! With the `identity` feature (the `client` feature has it):
//! - [`identity`]: the signed attachment that proves a message's sender.
//!
//! With the `client` feature:
//! - [`net`]: the network flags, zenoh session and tracing set-up every binary shares;
//! - [`client`]: a typed zenoh client for tools, viewers and tests (and the `ricochet`
//!   command-line client, `src/bin/ricochet.rs`).

pub mod action;
pub mod command;
pub mod dump;
pub mod frame;
#[cfg(feature = "identity")]
pub mod identity;
pub mod keys;
pub mod reference;
pub mod text;

#[cfg(feature = "client")]
pub mod client;
#[cfg(feature = "client")]
pub mod net;

/// The protocol's version: the frame layout's version byte.
pub const PROTOCOL_VERSION: u8 = 5;

/// What every Ricochet binary's `--version` says: the crate's version and the commit it
/// was built from (`unknown` outside a git checkout).
pub const VERSION: &str = concat!(
    env!("CARGO_PKG_VERSION"),
    " (commit ",
    env!("RICOCHET_COMMIT"),
    ")"
);
