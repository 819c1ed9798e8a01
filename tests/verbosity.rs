//! `-v` and `-q` on every binary: `-q` silences the info lines a binary logs by default,
//! `-v` adds debug lines. Real processes; `RUST_LOG` unset, so the defaults are the
//! binaries' own.

mod common;

use std::process::{Command as Process, Output, Stdio};

use common::*;

/// `ricochet-server FLAG run` until it answers, then stopped: what it logged.
fn served_log(flag: Option<&str>) -> String {
    let endpoint = free_endpoint();
    let mut server = Process::new(bin("ricochet-server"));
    server.args(flag);
    let child = server
        .args(["run", "--world", "logs", "--listen", &endpoint, "--scene"])
        .arg(scene("bounds.toml"))
        .env_remove("RUST_LOG")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("ricochet-server starts");
    let mut server = Running(child);
    let client = ricochet_protocol::client::Client::open(
        &ricochet_protocol::net::Network::client(
            ricochet_protocol::net::Mode::Peer,
            vec![endpoint.clone()],
        ),
        "logs",
    )
    .unwrap();
    wait_answered(&client, "the logging server");
    let mut stderr = server.0.stderr.take().unwrap();
    server.0.kill().unwrap();
    server.0.wait().unwrap();
    let mut log = String::new();
    std::io::Read::read_to_string(&mut stderr, &mut log).unwrap();
    log
}

fn logged(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

#[test]
fn quiet_silences_info_and_verbose_shows_debug_on_the_server() {
    let default = served_log(None);
    assert!(default.contains(" INFO ricochet_server"), "{default}");
    assert!(!default.contains("DEBUG"), "{default}");
    let quiet = served_log(Some("-q"));
    assert!(!quiet.contains("INFO"), "-q: {quiet}");
    let verbose = served_log(Some("-v"));
    assert!(verbose.contains(" INFO ricochet_server"), "-v: {verbose}");
    assert!(verbose.contains("DEBUG ricochet"), "-v: {verbose}");
}

#[test]
fn quiet_silences_info_and_verbose_shows_debug_on_the_viewer() {
    let server = Server::start("bounds.toml", "seen", &[]);
    let dir = temp_dir();
    let viewer = |flag: &str| {
        let mut viewer = Process::new(bin("ricochet-viewer"));
        if !flag.is_empty() {
            viewer.arg(flag);
        }
        let out = viewer
            .args([
                "--world",
                "seen",
                "--connect",
                &server.endpoint,
                "--frames",
                "3",
            ])
            .arg("--save")
            .arg(dir.path().join(format!("seen{flag}.rrd")))
            .env_remove("RUST_LOG")
            .output()
            .expect("ricochet-viewer runs");
        let log = logged(&out);
        assert!(out.status.success(), "{log}");
        log
    };
    let default = viewer("");
    assert!(default.contains(" INFO ricochet_viewer"), "{default}");
    assert!(!viewer("-q").contains("INFO"));
    assert!(viewer("-v").contains("DEBUG ricochet"));
}

#[test]
fn verbose_shows_debug_on_the_client_and_the_lab() {
    // The client logs warnings only by default; -v opens its debug lines, -q its errors.
    let client = |flag: &str| {
        Process::new(bin("ricochet"))
            .args([
                flag,
                "--connect",
                &free_endpoint(),
                "--timeout",
                "0.2",
                "worlds",
            ])
            .env_remove("RUST_LOG")
            .output()
            .expect("ricochet runs")
    };
    assert!(logged(&client("-v")).contains("DEBUG ricochet"));
    assert!(!logged(&client("-q")).contains("DEBUG"));
    let lab = |flag: &str| {
        Process::new(bin("ricochet-lab"))
            .args([flag, "bench", "--only", "no-such-scene", "--scenes"])
            .arg(scene("bench"))
            .env_remove("RUST_LOG")
            .output()
            .expect("ricochet-lab runs")
    };
    assert!(logged(&lab("-v")).contains("DEBUG ricochet"));
    assert!(!logged(&lab("-q")).contains("DEBUG"));
    // Both at once is refused, named.
    let both = client("-vq");
    assert!(!both.status.success() && logged(&both).contains("--quiet"));
}
