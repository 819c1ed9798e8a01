//! The secured deployment, end to end with the shipped configurations of `assets/zenoh/`:
//! a router holding the credentials, the TLS certificate (made by `ricochet-server certs`)
//! and the access-control rules, a server, a client, a viewer and an impostor connecting
//! to it as real processes and sessions on loopback. A peer without credentials, with a
//! wrong password, without TLS or trusting another authority cannot connect; a viewer
//! cannot command; an authenticated client cannot publish frames or answer requests in the
//! server's place; the authorised client works. Every wait is bounded.
//!
//! The configurations name their files (credentials, certificates) relative to the
//! directory a process starts in, as a deployment would: every process here, this test's
//! own sessions included, runs in one temporary directory holding them.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command as Process, Stdio};
use std::time::{Duration, Instant};

use common::*;
use ricochet_protocol::client::Client;
use ricochet_protocol::command::{Action, Command};
use ricochet_protocol::net::{Mode, Network};
use zenoh::Wait;

fn config(name: &str) -> PathBuf {
    root().join("assets/zenoh").join(name)
}

/// A session of `role` (its shipped configuration) connecting to the router.
fn as_role(role: &str, endpoint: &str) -> Network {
    Network {
        connect: vec![endpoint.to_string()],
        config: Some(config(&format!("{role}.json5"))),
        ..Network::default()
    }
}

/// Whether a session of `config` fails to connect (each try bounded to 3 s).
fn refused(mut config: zenoh::Config) -> bool {
    config.insert_json5("connect/timeout_ms", "3000").unwrap();
    config
        .insert_json5("connect/exit_on_failure", "true")
        .unwrap();
    zenoh::open(config).wait().is_err()
}

#[test]
fn only_authorised_peers_act_through_the_secured_router() {
    let dir = temp_dir();
    std::fs::copy(
        config("credentials.example"),
        dir.path().join("credentials.txt"),
    )
    .unwrap();
    for (out, host) in [("certs", "127.0.0.1"), ("other-certs", "127.0.0.1")] {
        ok(&Process::new(bin("ricochet-server"))
            .args(["certs", "--out", out, "--host", host])
            .current_dir(dir.path())
            .output()
            .unwrap());
    }
    std::env::set_current_dir(dir.path()).unwrap();
    let port = free_endpoint().rsplit(':').next().unwrap().to_string();
    let endpoint = format!("tls/127.0.0.1:{port}");
    let spawn = |args: &[&str], cwd: &Path| {
        Running(
            Process::new(bin("ricochet-server"))
                .args(args)
                .current_dir(cwd)
                .env("RUST_LOG", "warn")
                .stdout(Stdio::null())
                .stderr(Stdio::inherit())
                .spawn()
                .expect("ricochet-server starts"),
        )
    };
    let router_config = config("router.json5");
    let _router = spawn(
        &[
            "router",
            "--config",
            router_config.to_str().unwrap(),
            "--listen",
            &endpoint,
        ],
        dir.path(),
    );
    let server_config = config("server.json5");
    let _server = spawn(
        &[
            "run",
            "--scene",
            &scene("emitters.toml"),
            "--world",
            "acl",
            "--config",
            server_config.to_str().unwrap(),
            "--connect",
            &endpoint,
        ],
        dir.path(),
    );

    // The authorised client works.
    let client = Client::open(&as_role("client", &endpoint), "acl").expect("client session");
    wait_answered(&client, "world acl, through the router");
    let reply = request(
        &client,
        Command::World(Action::SpawnMinion {
            at: [100.0, 60.0],
            shape: None,
        }),
    );
    assert!(reply.ok, "{reply:?}");
    let frames = client.frames().unwrap();
    let got = frames.recv_timeout(TIMEOUT).expect("a frame").is_some();
    assert!(got, "the client receives frames");

    // An unauthenticated peer cannot even connect.
    // (It speaks TLS and trusts the deployment's authority: only the credentials lack.)
    let mut open = Network::client(Mode::Client, vec![endpoint.clone()])
        .config()
        .unwrap();
    open.insert_json5("transport/link/tls/root_ca_certificate", "\"certs/ca.pem\"")
        .unwrap();
    assert!(refused(open), "a peer without credentials connected");
    // Nor one with a client's credentials but without TLS, or trusting another authority.
    let mut plain = as_role("client", &endpoint).config().unwrap();
    plain
        .insert_json5("connect/endpoints", &format!("[\"tcp/127.0.0.1:{port}\"]"))
        .unwrap();
    assert!(refused(plain), "a peer connected without TLS");
    let mut stranger = as_role("client", &endpoint).config().unwrap();
    stranger
        .insert_json5(
            "transport/link/tls/root_ca_certificate",
            "\"other-certs/ca.pem\"",
        )
        .unwrap();
    assert!(
        refused(stranger),
        "a peer trusting another authority connected"
    );
    // Nor one with a wrong password.
    let mut wrong = as_role("client", &endpoint).config().unwrap();
    wrong
        .insert_json5("transport/auth/usrpwd/password", "\"guess\"")
        .unwrap();
    assert!(refused(wrong), "a peer with a wrong password connected");

    // A viewer watches but cannot command.
    let viewer = Client::open(&as_role("viewer", &endpoint), "acl").expect("viewer session");
    let watched = viewer.frames().unwrap();
    let began = Instant::now();
    let mut seen = false;
    while !seen && began.elapsed() < TIMEOUT {
        seen = watched
            .recv_timeout(Duration::from_millis(200))
            .ok()
            .flatten()
            .is_some();
    }
    assert!(seen, "the viewer receives frames");
    assert!(
        viewer.info(TIMEOUT).is_ok(),
        "the viewer reads the world's info"
    );
    assert!(
        viewer
            .request(
                &Command::World(Action::Clear {
                    group: "minions".into()
                }),
                Duration::from_secs(2)
            )
            .is_err(),
        "a viewer's request was answered"
    );
    viewer
        .send(&Command::World(Action::Clear {
            group: "minions".into(),
        }))
        .unwrap();

    // An impostor with a client's credentials publishes frames and answers requests.
    let impostor = Client::open(&as_role("client", &endpoint), "acl").expect("impostor");
    let queryable = answer_every_query(
        impostor.session(),
        &impostor.keys().rpc,
        br#"{"ok":true,"frame":0,"ids":["impostor"]}"#,
        Default::default(),
    );
    let watch = client.frames().unwrap();
    for _ in 0..20 {
        impostor
            .session()
            .put(&impostor.keys().frame, b"IMPOSTOR".to_vec())
            .wait()
            .unwrap();
        std::thread::sleep(Duration::from_millis(20));
    }
    let began = Instant::now();
    let mut real = 0;
    while began.elapsed() < Duration::from_secs(2) {
        if let Ok(Some(sample)) = watch.recv_timeout(Duration::from_millis(100)) {
            let bytes = sample.payload().to_bytes();
            assert_ne!(
                &bytes[..],
                b"IMPOSTOR",
                "a frame from the impostor got through"
            );
            real += 1;
        }
    }
    assert!(real > 0, "real frames kept coming");
    for _ in 0..10 {
        let reply = request(&client, Command::World(Action::Deselect));
        assert!(reply.ok);
        assert!(
            !reply.ids.contains(&"impostor".to_string()),
            "the impostor answered a request"
        );
    }
    drop(queryable);

    // The viewer's fire-and-forget command was refused by the router: the minions are
    // still there.
    let info = client.info(TIMEOUT).unwrap();
    assert!(info.groups.iter().any(|g| g == "minions"));
    let reply = request(
        &client,
        Command::World(Action::Clear {
            group: "minions".into(),
        }),
    );
    assert!(reply.ok && !reply.ids.is_empty(), "minions left: {reply:?}");

    // The Python client reads the same configuration files.
    let python = python();
    let script = root().join("assets/scripts/ricochet_client.py");
    let py = |role: &str| {
        let file = config(&format!("{role}.json5"));
        Process::new(&python)
            .current_dir(dir.path())
            .arg(&script)
            .args(["--world", "acl", "--timeout", "3", "--config"])
            .arg(file)
            .args(["--connect", &endpoint, "send", "deselect"])
            .output()
            .expect("python3 runs")
    };
    let out = ok(&py("client"));
    assert!(
        out.contains("\"ok\": true") || out.contains("\"ok\":true"),
        "{out}"
    );
    let out = py("viewer");
    assert!(
        !out.status.success(),
        "the Python viewer's request was answered"
    );
}
