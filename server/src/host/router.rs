//! `ricochet-server router`: a zenoh router where servers and clients on several hosts
//! meet.

use std::time::Duration;

use anyhow::{anyhow, Result};
use ricochet_protocol::net::Network;
use zenoh::Wait;

use super::wiring::{frame_queues, set};

/// Runs a zenoh router: where servers and clients on several hosts meet. Without a
/// configuration file its links queue frames as the server's do ([`super::wiring::frame_queues`]).
pub fn run_router(network: &Network) -> Result<()> {
    let mut config = network.config()?;
    if network.config.is_none() {
        // Its links carry frames to viewers as the server's do.
        set(&mut config, frame_queues())?;
    }
    let _session = zenoh::open(config).wait().map_err(|e| {
        anyhow!(
            "cannot open the router's zenoh session (listen {:?}, connect {:?}): {e}",
            network.listen,
            network.connect
        )
    })?;
    tracing::info!(listen = ?network.listen, connect = ?network.connect, "router up");
    loop {
        std::thread::sleep(Duration::from_secs(3600));
    }
}
