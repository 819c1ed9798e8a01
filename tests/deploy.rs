//! The deployment files in assets/deploy/: the systemd unit passes `systemd-analyze
//! verify` with the built server in its `ExecStart` (where systemd's tools are installed;
//! it is skipped, and says so, where they are not), and the Dockerfile copies binaries the
//! workspace builds and runs the server journaled. Docker itself is not run here: the
//! image is built with the command at the top of the Dockerfile.

mod common;

use std::process::Command as Process;

use common::*;

fn deploy_file(name: &str) -> String {
    std::fs::read_to_string(root().join("assets/deploy").join(name)).unwrap()
}

/// `systemd-analyze verify` of `unit` written as `ricochet.service` in a fresh directory:
/// its success and what it said.
fn verify(unit: &str) -> Option<(bool, String)> {
    let dir = temp_dir();
    let path = dir.path().join("ricochet.service");
    std::fs::write(&path, unit).unwrap();
    let out = Process::new("systemd-analyze")
        .arg("verify")
        .arg(&path)
        .output()
        .ok()?;
    let said = String::from_utf8_lossy(&out.stderr).to_string();
    Some((out.status.success(), said))
}

#[test]
fn the_systemd_unit_verifies_and_stops_the_server_with_sigterm() {
    let unit = deploy_file("ricochet.service");
    for needle in [
        "ExecStart=/usr/local/bin/ricochet-server run",
        "--journal ${STATE_DIRECTORY}/world.journal",
        "KillSignal=SIGTERM",
        "NoNewPrivileges=yes",
        "ProtectSystem=strict",
    ] {
        assert!(unit.contains(needle), "`{needle}` missing from the unit");
    }
    let built = bin("ricochet-server");
    let here = unit.replace("/usr/local/bin/ricochet-server", built.to_str().unwrap());
    let Some((ok, said)) = verify(&here) else {
        eprintln!("systemd-analyze is not installed: the unit is not verified here");
        return;
    };
    assert!(ok, "{said}");
    assert!(said.trim().is_empty(), "systemd-analyze warned:\n{said}");
    // The check can fail: a binary that is not there, a signal systemd does not know.
    let missing = unit.replace(
        "/usr/local/bin/ricochet-server",
        "/nonexistent/ricochet-server",
    );
    assert!(!verify(&missing).unwrap().0, "a missing binary verified");
    let bogus = here.replace("KillSignal=SIGTERM", "KillSignal=SIGBOGUS");
    assert!(!verify(&bogus).unwrap().1.is_empty(), "a bad signal passed");
}

#[test]
fn the_dockerfile_copies_built_binaries_and_journals_the_world() {
    let dockerfile = deploy_file("Dockerfile");
    for binary in ["ricochet-server", "ricochet-viewer", "ricochet"] {
        assert!(
            dockerfile.contains(&format!("target/release/{binary} ")),
            "{binary} is not copied"
        );
        assert!(bin(binary).exists(), "the workspace builds no {binary}");
    }
    for needle in [
        "STOPSIGNAL SIGTERM",
        "\"--journal\", \"/var/lib/ricochet/",
        "router",
    ] {
        assert!(dockerfile.contains(needle), "`{needle}` missing");
    }
}
