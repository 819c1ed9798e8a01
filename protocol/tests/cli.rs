//! The `ricochet` command line: malformed commands and flags are refused with a message
//! naming what was wrong, before anything is sent (real processes, no server needed).

#[path = "../../tests/common/python.rs"]
mod python;

use std::process::{Command, Output};

fn ricochet(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_ricochet"))
        .args(args)
        .env("RUST_LOG", "error")
        .output()
        .expect("ricochet runs")
}

fn refused(out: &Output, needle: &str) {
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "accepted: {err}");
    assert!(err.contains(needle), "`{needle}` not in: {err}");
}

#[test]
fn malformed_commands_are_refused_before_sending() {
    refused(
        &ricochet(&["send", "teleport", "at=[1,2]"]),
        "unknown command `teleport`",
    );
    refused(
        &ricochet(&["send", "fire_dye_pack", "at"]),
        "`at` is not NAME=VALUE",
    );
    refused(&ricochet(&["send", "set", "name=warp", "value=9"]), "warp");
    refused(
        &ricochet(&["send", "spawn_minion", "at=[1,2]", "shape=hexagon"]),
        "hexagon",
    );
}

#[test]
fn network_flags_are_checked() {
    refused(&ricochet(&["--mode", "satellite", "worlds"]), "satellite");
}

#[test]
fn worlds_with_no_server_says_so() {
    // A port nothing listens on: no world can answer.
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let endpoint = format!("tcp/127.0.0.1:{port}");
    let out = ricochet(&["--connect", &endpoint, "--timeout", "1", "worlds"]);
    refused(&out, "no world answered within 1.0 s");
    refused(&out, &endpoint);
    assert!(out.stdout.is_empty());
}

/// Every command the parser knows is listed by `ricochet --help` and by the Python
/// client's `--help`: a new command cannot be added without telling users of either.
#[test]
fn every_command_is_in_the_help_of_both_clients() {
    use ricochet_protocol::command::{Action, SERVER_COMMANDS};
    let rust = ricochet(&["--help"]);
    assert!(rust.status.success());
    let rust = String::from_utf8_lossy(&rust.stdout).into_owned();
    let script = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../assets/scripts/ricochet_client.py"
    );
    let python = Command::new(python::python())
        .args([script, "--help"])
        .output()
        .expect("python3 runs");
    assert!(python.status.success(), "{python:?}");
    let python = String::from_utf8_lossy(&python.stdout).into_owned();
    for name in SERVER_COMMANDS.iter().chain(Action::NAMES) {
        let word = |text: &str| {
            text.split(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
                .any(|w| w == *name)
        };
        assert!(word(&rust), "`ricochet --help` does not list `{name}`");
        assert!(
            word(&python),
            "the Python client's --help does not list `{name}`"
        );
    }
}

/// `--version` names the commit the binary was built from; shell completions and a man
/// page come from the same flags; zenoh's short flags (`-e`, `-l`, `-m`, `-c`) are taken.
#[test]
fn version_completions_man_page_and_short_flags() {
    let out = ricochet(&["--version"]);
    assert!(out.status.success());
    let version = String::from_utf8_lossy(&out.stdout).into_owned();
    let head = Command::new("git")
        .args(["rev-parse", "--short=10", "HEAD"])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .ok()
        .filter(|o| o.status.success())
        .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string());
    match head {
        Some(head) => assert!(version.contains(&format!("(commit {head}")), "{version}"),
        None => assert!(version.contains("(commit unknown)"), "{version}"),
    }
    let bash = ricochet(&["completions", "bash"]);
    assert!(bash.status.success());
    let bash = String::from_utf8_lossy(&bash.stdout);
    assert!(
        bash.contains("_ricochet()") && bash.contains("worlds"),
        "{bash}"
    );
    let man = ricochet(&["man"]);
    assert!(man.status.success());
    let man = String::from_utf8_lossy(&man.stdout);
    assert!(
        man.contains(".TH ricochet 1") && man.contains("send"),
        "{man}"
    );
    // -e with a bad endpoint is read as an endpoint, not refused as an unknown flag.
    let out = ricochet(&["-e", "nonsense", "worlds"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!err.contains("unexpected argument"), "{err}");
    assert!(err.contains("nonsense"), "{err}");
}
