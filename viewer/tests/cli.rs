//! The viewer's command line: bad options and an absent world are refused with a message
//! naming what was wrong (real processes; every wait bounded).

use std::process::{Command, Output};

fn viewer(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_ricochet-viewer"))
        .args(args)
        .env("RUST_LOG", "error")
        .output()
        .expect("ricochet-viewer runs")
}

fn refused(out: &Output, needle: &str) {
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "accepted: {err}");
    assert!(err.contains(needle), "`{needle}` not in: {err}");
}

#[test]
fn two_sinks_at_once_are_refused() {
    refused(
        &viewer(&["--web", "--save", "x.rrd"]),
        "cannot be used with",
    );
}

#[test]
fn zero_frames_and_negative_rates_are_refused() {
    refused(&viewer(&["--frames", "0"]), "--frames must be at least 1");
    refused(&viewer(&["--fps=-1"]), "--fps must be 0 or more");
    refused(&viewer(&["--fps=NaN"]), "--fps must be 0 or more");
}

#[test]
fn a_world_nobody_serves_is_named_when_the_wait_runs_out() {
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let endpoint = format!("tcp/127.0.0.1:{port}");
    let out = viewer(&[
        "--world",
        "nobody_here",
        "--connect",
        &endpoint,
        "--wait",
        "1",
        "--save",
        "never.rrd",
    ]);
    refused(&out, "nobody_here");
    assert!(!std::path::Path::new("never.rrd").exists());
}
