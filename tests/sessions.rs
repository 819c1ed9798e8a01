//! One address cannot take every session slot of a server, with the shipped firewall rule
//! (`assets/firewall/sessions.nft`): zenoh bounds sessions only in all (`max_sessions`),
//! so without a bound per address one process fills the server and honest clients cannot
//! connect.
//!
//! Three network namespaces made by the test: the server's, an attacker's and an honest
//! client's, each client joined to the server by a veth pair of its own. The server (a
//! real `ricochet-server`, `max_sessions` 12 here) runs in its namespace; the attacker
//! opens 20 zenoh sessions from its address (the Python client's zenoh) and holds them;
//! the honest client sends a command with the `ricochet` CLI. Without the rule the
//! attacker takes every slot and the honest command goes unanswered; with it the
//! attacker gets 8 and the honest command is answered.
//!
//! A second test does the same for local users on loopback: one user of the machine holds
//! every slot without the rule, and at most 8 with it.
//!
//! Needs root and nftables (CI runs as root; `.ci/install` installs nftables). Every wait
//! is bounded; the namespaces are removed when the test ends.

mod common;

use std::process::{Command as Process, Stdio};
use std::time::{Duration, Instant};

use common::*;

const PORT: u16 = 7447;
/// The server's sessions in all, for the test (256 by default).
const MAX_SESSIONS: usize = 12;
/// Sessions the attacker tries to open.
const ATTACK: usize = 20;

/// The three namespaces and their links; removed when dropped.
struct Namespaces {
    server: String,
    attacker: String,
    honest: String,
    /// The server's address on each client's link.
    to_attacker: String,
    to_honest: String,
}

impl Namespaces {
    /// The namespaces of test `tag` (each test of this file its own).
    fn make(tag: u32) -> Result<Namespaces, String> {
        let id = (std::process::id() * 2 + tag) % 10_000;
        let net = 100 + id % 150;
        let ns = Namespaces {
            server: format!("rss{id}"),
            attacker: format!("rsx{id}"),
            honest: format!("rsh{id}"),
            to_attacker: format!("10.212.{net}.1"),
            to_honest: format!("10.213.{net}.1"),
        };
        for name in [&ns.server, &ns.attacker, &ns.honest] {
            sh(&["ip", "netns", "add", name])?;
            sh(&["ip", "-n", name, "link", "set", "lo", "up"])?;
        }
        for (peer, here, there, server_ip, peer_ip) in [
            (
                &ns.attacker,
                format!("rsxa{id}"),
                format!("rsxb{id}"),
                &ns.to_attacker,
                format!("10.212.{net}.2"),
            ),
            (
                &ns.honest,
                format!("rsha{id}"),
                format!("rshb{id}"),
                &ns.to_honest,
                format!("10.213.{net}.2"),
            ),
        ] {
            sh(&[
                "ip", "-n", &ns.server, "link", "add", &here, "type", "veth", "peer", "name",
                &there, "netns", peer,
            ])?;
            sh(&[
                "ip",
                "-n",
                &ns.server,
                "addr",
                "add",
                &format!("{server_ip}/24"),
                "dev",
                &here,
            ])?;
            sh(&["ip", "-n", &ns.server, "link", "set", &here, "up"])?;
            sh(&[
                "ip",
                "-n",
                peer,
                "addr",
                "add",
                &format!("{peer_ip}/24"),
                "dev",
                &there,
            ])?;
            sh(&["ip", "-n", peer, "link", "set", &there, "up"])?;
        }
        Ok(ns)
    }

    /// A process in namespace `ns`.
    fn exec(ns: &str, program: &str) -> Process {
        let mut p = Process::new("ip");
        p.args(["netns", "exec", ns, program]);
        p
    }
}

impl Drop for Namespaces {
    fn drop(&mut self) {
        // Deleting a namespace deletes its veth ends, and their peers with them.
        for name in [&self.server, &self.attacker, &self.honest] {
            let _ = sh(&["ip", "netns", "del", name]);
        }
    }
}

/// The attacker: `ATTACK` sessions to `endpoint`, held until killed; prints how many
/// reached the server.
const ATTACKER: &str = r#"
import json, sys, time, zenoh
endpoint, count = sys.argv[1], int(sys.argv[2])
sessions = []
for _ in range(count):
    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("scouting/multicast/enabled", "false")
    conf.insert_json5("listen/endpoints", "[]")
    conf.insert_json5("connect/endpoints", json.dumps([endpoint]))
    try:
        sessions.append(zenoh.open(conf))
    except Exception:
        pass
time.sleep(1.0)
print(sum(1 for s in sessions if list(s.info.peers_zid())), flush=True)
time.sleep(120)
"#;

/// Starts the attacker in its namespace and returns it with how many sessions it holds.
fn attack(ns: &Namespaces) -> (Running, usize) {
    attack_from(&ns.attacker, &format!("tcp/{}:{PORT}", ns.to_attacker))
}

/// The attacker in namespace `ns`, connecting to `endpoint`, with how many sessions it
/// holds.
fn attack_from(ns: &str, endpoint: &str) -> (Running, usize) {
    let python = python().display().to_string();
    let mut child = Namespaces::exec(ns, &python)
        .args(["-c", ATTACKER, endpoint, &ATTACK.to_string()])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("python3 runs");
    let stdout = child.stdout.take().unwrap();
    let running = Running(child);
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        use std::io::BufRead;
        let mut line = String::new();
        let _ = std::io::BufReader::new(stdout).read_line(&mut line);
        let _ = tx.send(line);
    });
    let line = rx
        .recv_timeout(Duration::from_secs(60))
        .expect("the attacker says how many sessions it holds");
    let held = line.trim().parse().expect("a count");
    (running, held)
}

/// Whether the honest client's command is answered (within a bound).
fn honest_answered(ns: &Namespaces) -> bool {
    let ricochet = bin("ricochet").display().to_string();
    let endpoint = format!("tcp/{}:{PORT}", ns.to_honest);
    answered(Namespaces::exec(&ns.honest, &ricochet), &endpoint)
}

/// Whether `ricochet`'s command (`command`, the CLI and what starts it) to `endpoint` is
/// answered (within a bound).
fn answered(mut command: Process, endpoint: &str) -> bool {
    let mut child = command
        .args(["--world", "slots", "--connect", endpoint])
        .args(["send", "--timeout", "4", "deselect"])
        .env("RUST_LOG", "error")
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("ricochet runs");
    let began = Instant::now();
    loop {
        if let Some(status) = child.try_wait().unwrap() {
            let out = child.wait_with_output().unwrap();
            let text = String::from_utf8_lossy(&out.stdout);
            return status.success() && text.contains("\"ok\":true");
        }
        if began.elapsed() > Duration::from_secs(30) {
            let _ = child.kill();
            let _ = child.wait();
            return false;
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// A real `ricochet-server` in the server's namespace, listening on `listen` with
/// [`MAX_SESSIONS`] sessions at most (its config written into `dir`).
fn serve(ns: &Namespaces, dir: &std::path::Path, listen: &str) -> Running {
    let config = dir.join("server.json5");
    std::fs::write(
        &config,
        format!(
            r#"{{ mode: "peer", listen: {{ endpoints: ["tcp/{listen}:{PORT}"] }},
               scouting: {{ multicast: {{ enabled: false }} }},
               transport: {{ unicast: {{ max_sessions: {MAX_SESSIONS} }} }} }}"#
        ),
    )
    .unwrap();
    Running(
        Namespaces::exec(&ns.server, &bin("ricochet-server").display().to_string())
            .args(["run", "--world", "slots", "--scene", &scene("impulse.toml")])
            .arg("--config")
            .arg(&config)
            .env("RUST_LOG", "error")
            .stdout(Stdio::null())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("ricochet-server starts"),
    )
}

/// Loads the shipped rule, on the test's port, in the server's namespace.
fn load_rule(ns: &Namespaces, dir: &std::path::Path) {
    let rule = std::fs::read_to_string(root().join("assets/firewall/sessions.nft"))
        .unwrap()
        .replace("7447", &PORT.to_string());
    let rule_file = dir.join("sessions.nft");
    std::fs::write(&rule_file, rule).unwrap();
    sh(&[
        "ip",
        "netns",
        "exec",
        &ns.server,
        "nft",
        "-f",
        &rule_file.display().to_string(),
    ])
    .expect("the shipped rule loads (nftables installed?)");
}

#[test]
fn one_address_cannot_take_every_session_slot_with_the_shipped_firewall_rule() {
    let ns = match Namespaces::make(0) {
        Ok(ns) => ns,
        Err(e) => panic!("cannot make the namespaces (the test needs root): {e}"),
    };
    let dir = temp_dir();
    let _server = serve(&ns, dir.path(), "0.0.0.0");
    // Bounded: until the server answers the honest client.
    let began = Instant::now();
    while !honest_answered(&ns) {
        assert!(
            began.elapsed() < Duration::from_secs(60),
            "the server never answered"
        );
    }

    // No rule: the attacker fills every slot.
    let (attacker, held) = attack(&ns);
    eprintln!("without the rule: the attacker holds {held} sessions");
    assert!(
        held >= MAX_SESSIONS - 1,
        "the attacker held {held} sessions of {MAX_SESSIONS}"
    );
    assert!(
        !honest_answered(&ns),
        "the honest client was answered with every slot taken"
    );
    drop(attacker);

    // The shipped rule, on the test's port.
    load_rule(&ns, dir.path());
    // The attacker's old sessions closed: the server takes new ones again.
    let began = Instant::now();
    while !honest_answered(&ns) {
        assert!(
            began.elapsed() < Duration::from_secs(60),
            "the server never took a session again"
        );
    }
    let (_attacker, held) = attack(&ns);
    eprintln!("with the rule: the attacker holds {held} sessions");
    assert!(held <= 8, "the attacker held {held} sessions past the rule");
    assert!(
        honest_answered(&ns),
        "the honest client was not answered with the rule in place"
    );
}

/// A user of the machine whose every connection comes from loopback: the shipped rule
/// bounds each local user's connections (by the socket's owner, `meta skuid`) and leaves
/// loopback out of the per-address bound, so one local user (here root, holding 20
/// sessions from a Python process) cannot take every slot from another (uid 65534, the
/// `ricochet` CLI). Without the rule the honest user's command goes unanswered.
#[test]
fn one_local_user_cannot_take_every_session_slot_with_the_shipped_firewall_rule() {
    let ns = match Namespaces::make(1) {
        Ok(ns) => ns,
        Err(e) => panic!("cannot make the namespaces (the test needs root): {e}"),
    };
    let dir = temp_dir();
    // The honest user's copy of the CLI, where uid 65534 may run it.
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(dir.path(), std::fs::Permissions::from_mode(0o755)).unwrap();
    let cli = dir.path().join("ricochet");
    std::fs::copy(bin("ricochet"), &cli).unwrap();
    std::fs::set_permissions(&cli, std::fs::Permissions::from_mode(0o755)).unwrap();
    let endpoint = format!("tcp/127.0.0.1:{PORT}");
    let honest = || {
        let mut p = Namespaces::exec(&ns.server, "setpriv");
        p.args(["--reuid=65534", "--regid=65534", "--clear-groups"])
            .arg(&cli)
            .env("HOME", dir.path());
        answered(p, &endpoint)
    };
    let _server = serve(&ns, dir.path(), "127.0.0.1");
    let began = Instant::now();
    while !honest() {
        assert!(
            began.elapsed() < Duration::from_secs(60),
            "the server never answered the honest user"
        );
    }

    // No rule: root's process fills every slot.
    let (attacker, held) = attack_from(&ns.server, &endpoint);
    eprintln!("without the rule: the local attacker holds {held} sessions");
    assert!(
        held >= MAX_SESSIONS - 1,
        "the attacker held {held} sessions of {MAX_SESSIONS}"
    );
    assert!(
        !honest(),
        "the honest user was answered with every slot taken"
    );
    drop(attacker);

    load_rule(&ns, dir.path());
    let began = Instant::now();
    while !honest() {
        assert!(
            began.elapsed() < Duration::from_secs(60),
            "the server never took a session again"
        );
    }
    let (_attacker, held) = attack_from(&ns.server, &endpoint);
    eprintln!("with the rule: the local attacker holds {held} sessions");
    assert!(held <= 8, "the attacker held {held} sessions past the rule");
    assert!(
        honest(),
        "the honest user was not answered with the rule in place"
    );
}
