//! `ricochet-server`: runs Ricochet worlds.
//!
//! `run` hosts a world on zenoh in real time; `simulate` runs a scene headless, with no
//! network, and can dump every frame as JSON Lines; `router` runs a zenoh router where
//! servers and clients on several hosts meet; `certs` makes a secured deployment's
//! certificates. What measures the server is `ricochet-lab`. Each command here reads its
//! flags, calls the library and says what it wrote.

use std::process::ExitCode;

use anyhow::Result;
use clap::Parser;
use ricochet_protocol::net::{init_tracing, Mode};
use ricochet_server::host;

mod args;
mod simulate;

use args::{Cli, Command};

/// Errors are printed as a user reads them (the chain of causes on one line), never as a
/// debug dump with a backtrace, whatever `RUST_BACKTRACE` says.
fn main() -> ExitCode {
    let cli = Cli::parse();
    init_tracing("info", cli.verbosity);
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("ricochet-server: {e:#}");
            ExitCode::FAILURE
        }
    }
}

fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Run(args) => {
            host::without_thread_caches();
            host::run(args.host_options()?)
        }
        Command::Simulate(args) => simulate::simulate(args),
        Command::Doc(doc) => {
            use clap::CommandFactory;
            doc.write(Cli::command(), &mut std::io::stdout().lock())
        }
        Command::Router { network } => {
            let mut net = network.server();
            net.mode = Some(Mode::Router);
            host::run_router(&net)
        }
        Command::Certs { out, hosts, days } => {
            for file in ricochet_server::certs::make(&out, &hosts, days)? {
                eprintln!("wrote {}", file.display());
            }
            Ok(())
        }
    }
}
