//! End to end over zenoh on loopback: real server processes, the `ricochet` command-line
//! client, the typed Rust client and the Python client. Every wait is bounded.

mod common;

use std::process::Command as Process;
use std::time::{Duration, Instant};

use common::*;
use ricochet_protocol::client::Client;
use ricochet_protocol::command::{Action, Command, Direction, ServerCommand};
use ricochet_protocol::frame::FrameDecoder;
use ricochet_protocol::net::{Mode, Network};

/// One subscription to a world's frames, decoded as they come.
struct Follower {
    stream: ricochet_protocol::client::FrameStream,
    decoder: FrameDecoder,
}

impl Follower {
    fn new(client: &Client) -> Follower {
        let (stream, decoder) = client.join(TIMEOUT).expect("join the world");
        Follower { stream, decoder }
    }

    /// Decodes frames until `until` says stop (bounded by `limit`).
    fn until(
        &mut self,
        limit: Duration,
        mut until: impl FnMut(&FrameDecoder) -> bool,
    ) -> &FrameDecoder {
        let began = Instant::now();
        while began.elapsed() < limit {
            if let Ok(Some(sample)) = self.stream.recv_timeout(Duration::from_millis(100)) {
                if self.decoder.apply(&sample.payload().to_bytes()).is_ok() && until(&self.decoder)
                {
                    return &self.decoder;
                }
            }
        }
        let d = &self.decoder;
        panic!(
            "condition not met within {limit:?} (frame {}, synced {})",
            d.frame, d.synced
        );
    }
}

/// Decodes frames from a new subscription until `until` says stop (bounded by `limit`).
fn follow(
    client: &Client,
    limit: Duration,
    until: impl FnMut(&FrameDecoder) -> bool,
) -> FrameDecoder {
    Follower::new(client).until(limit, until).clone()
}

#[test]
fn the_hero_moves_while_a_direction_is_held_and_is_not_pushed_after_release() {
    let server = Server::start("impulse.toml", "hero", &[]);
    let client = server.client();
    resume(&client);
    let mut frames = Follower::new(&client);
    // Let the hero land.
    frames.until(TIMEOUT, |d| {
        d.frame > 150 && d.body("hero").is_some_and(|h| h.vel()[1].abs() < 1.0)
    });
    let x0 = frames.decoder.body("hero").unwrap().pos()[0];
    let out = server.cli(&["send", "press", "dir=right"]);
    assert!(ok(&out).contains("\"ok\":true"));
    let held = frames.until(TIMEOUT, |d| d.body("hero").unwrap().vel()[0] > 10.0);
    assert!(held.body("hero").unwrap().pos()[0] > x0);
    let out = ok(&server.cli(&["send", "{\"do\":\"release\",\"dir\":\"right\"}"]));
    let released: ricochet_protocol::command::Reply = serde_json::from_str(out.trim()).unwrap();
    // After the frame the release took effect in, friction (or the platform it runs into)
    // slows the hero; nothing pushes it on.
    let mut vx = Vec::new();
    frames.until(TIMEOUT, |d| {
        if d.frame > released.frame {
            vx.push(d.body("hero").unwrap().vel()[0]);
        }
        vx.len() > 40
    });
    assert!(
        vx[vx.len() - 1] < vx[0],
        "not slowing down after release: {vx:?}"
    );
    assert!(
        vx.windows(2).all(|w| w[1] <= w[0] + 1e-9 || w[0] <= 0.0),
        "pushed after release: {vx:?}"
    );
}

#[test]
fn spawned_minions_appear_with_the_returned_ids() {
    let server = Server::start("impulse.toml", "spawn", &[]);
    let client = server.client();
    resume(&client);
    let reply = request(
        &client,
        Command::World(Action::SpawnMinion {
            at: [100.0, 60.0],
            shape: None,
        }),
    );
    assert!(reply.ok, "{reply:?}");
    assert_eq!(reply.ids.len(), 1);
    let id = reply.ids[0].clone();
    let seen = follow(&client, TIMEOUT, |d| d.body(&id).is_some());
    let m = seen.body(&id).unwrap();
    assert!(m.circle);
    assert!((m.pos()[1] - 60.0).abs() < 0.01, "spawned at {:?}", m.pos());
    // The command-line client gets ids too.
    let out = ok(&server.cli(&["send", "spawn_dumb_minion", "at=[90,90]"]));
    let reply: ricochet_protocol::command::Reply = serde_json::from_str(out.trim()).unwrap();
    let dumb = reply.ids[0].clone();
    follow(&client, TIMEOUT, |d| d.body(&dumb).is_some());
}

#[test]
fn an_emitter_produces_particles_that_expire() {
    let server = Server::start("impulse.toml", "emit", &[]);
    let client = server.client();
    resume(&client);
    let reply = request(
        &client,
        Command::World(Action::StartEmitter {
            preset: "fire".into(),
            count: 150,
            at: [100.0, 60.0],
        }),
    );
    assert!(reply.ok);
    let burning = follow(&client, TIMEOUT, |d| d.particles.len() >= 100);
    let p = &burning.particles[0];
    let c = p.color_at(burning.frame);
    assert!(c[0] >= 1.0 - 0.02 && c[1] < 0.6, "fire is red: {c:?}");
    // Fire lives at most 230 updates: all gone within 5 s at 60 Hz.
    follow(&client, Duration::from_secs(15), |d| {
        d.particles.is_empty() && d.emitters.is_empty()
    });
}

#[test]
fn a_late_joiner_gets_the_statics_from_the_snapshot() {
    let server = Server::start("emitters.toml", "late", &[]);
    let client = server.client();
    resume(&client);
    std::thread::sleep(Duration::from_millis(500));
    // A new session, joining after the statics were published.
    let late = server.client();
    let mut decoder = FrameDecoder::new();
    decoder.apply(&late.snapshot(TIMEOUT).unwrap()).unwrap();
    // Floor 9 + ceiling 9 + walls 16 + row platforms 8.
    assert_eq!(decoder.statics.len(), 42);
    let floor = decoder.body("floor/0").unwrap();
    assert_eq!(floor.pos(), [-15.0, 2.0]);
    assert_eq!(floor.size, [30.0, 3.75]);
    assert!(decoder.bodies.is_empty(), "the snapshot holds statics only");
    // The dynamic state comes from the state query, before any key frame.
    decoder.apply(&late.state(TIMEOUT).unwrap()).unwrap();
    assert!(decoder.synced && decoder.body("hero").is_some());
    // Statics are never in frames; the deltas that follow apply on top of the state.
    let d = follow(&late, TIMEOUT, |d| d.frame > decoder.frame + 5);
    assert!(d.bodies.iter().all(|b| !b.id.starts_with("floor")));
}

#[test]
fn malformed_commands_get_error_replies_and_the_server_keeps_stepping() {
    let server = Server::start("emitters.toml", "garbage", &[]);
    let client = server.client();
    resume(&client);
    let cases: Vec<(Vec<u8>, &str)> = vec![
        (b"\xff\xfe not json".to_vec(), "not JSON"),
        (br#"{"do":"teleport"}"#.to_vec(), "unknown command"),
        (br#"{"do":"fire_dye_pack","at":[1e400,0]}"#.to_vec(), "at"),
        (
            br#"{"do":"fire_dye_pack","at":["a",0]}"#.to_vec(),
            "fire_dye_pack",
        ),
        (br#"{"do":"spawn_minion","at":[1e300,0]}"#.to_vec(), "at"),
        (br#"{"do":"set","name":"dt","value":-1}"#.to_vec(), "dt"),
        (
            br#"{"do":"set","name":"gravity","value":null}"#.to_vec(),
            "value",
        ),
        (br#"{"do":"clear","group":"nobody"}"#.to_vec(), "nobody"),
        (
            br#"{"do":"load","path":"/nonexistent.toml"}"#.to_vec(),
            "no scene",
        ),
        (
            br#"{"do":"load","text":"[[body]]\nshape = \"hexagon\""}"#.to_vec(),
            ":2: body[0].shape",
        ),
        (Vec::new(), "not JSON"),
    ];
    for (bytes, needle) in cases {
        let reply = client.request_raw(bytes.clone(), TIMEOUT).expect("a reply");
        assert!(
            !reply.ok,
            "{:?} was accepted",
            String::from_utf8_lossy(&bytes)
        );
        let error = reply.error.unwrap();
        assert!(
            error.contains(needle),
            "{:?}: `{error}` should mention {needle}",
            String::from_utf8_lossy(&bytes)
        );
    }
    // A flood of garbage, fire and forget.
    for i in 0..3000 {
        client
            .send_raw(format!("garbage {i}").into_bytes())
            .unwrap();
    }
    let before = follow(&client, TIMEOUT, |d| d.synced).frame;
    let after = follow(&client, TIMEOUT, |d| d.frame > before + 60);
    assert!(after.body("hero").is_some());
    assert!(
        request(
            &client,
            Command::World(Action::Press {
                dir: Direction::Left
            })
        )
        .ok,
        "still serving"
    );
}

#[test]
fn worlds_are_listed_and_a_script_plays() {
    let dir = temp_dir();
    let server = Server::start("impulse.toml", "listed", &[]);
    let out = ok(&server.cli(&["worlds"]));
    assert!(out.lines().any(|l| l == "listed"), "{out}");
    resume(&server.client());
    let script = dir.path().join("short.ricochet");
    std::fs::write(&script, "# a short script\n@5 spawn_minion at=[100,60]\n+0.1 fire_dye_pack at=[150,90]\n@20 {\"do\": \"agitate\"}\n").unwrap();
    let out = ok(&server.cli(&["script", script.to_str().unwrap()]));
    let lines: Vec<&str> = out.lines().collect();
    assert_eq!(lines.len(), 3, "{out}");
    assert!(lines.iter().all(|l| l.contains("\"ok\":true")), "{out}");
    assert!(lines[0].contains("minion-"));
    // A script line that is not a command is refused before anything is sent.
    std::fs::write(&script, "@5 teleport\n").unwrap();
    let out = server.cli(&["script", script.to_str().unwrap()]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("short.ricochet:1"));
}

#[test]
fn a_server_and_a_client_meet_through_a_router() {
    let router_endpoint = free_endpoint();
    let _router = Running(
        Process::new(bin("ricochet-server"))
            .args(["router", "--listen", &router_endpoint])
            .env("RUST_LOG", "warn")
            .spawn()
            .unwrap(),
    );
    let _server = Running(
        Process::new(bin("ricochet-server"))
            .args([
                "run",
                "--scene",
                &scene("impulse.toml"),
                "--world",
                "routed",
                "--mode",
                "client",
                "--connect",
                &router_endpoint,
            ])
            .env("RUST_LOG", "warn")
            .spawn()
            .unwrap(),
    );
    let network = Network::client(Mode::Client, vec![router_endpoint.clone()]);
    let client = Client::open(&network, "routed").unwrap();
    let began = Instant::now();
    let reply = loop {
        if let Ok(r) = client.request(
            &Command::World(Action::SpawnMinion {
                at: [100.0, 60.0],
                shape: None,
            }),
            Duration::from_millis(500),
        ) {
            break r;
        }
        assert!(began.elapsed() < TIMEOUT * 3, "no reply through the router");
        std::thread::sleep(Duration::from_millis(200));
    };
    assert!(reply.ok);
    let id = reply.ids[0].clone();
    follow(&client, TIMEOUT, |d| d.body(&id).is_some());
    let out = Process::new(bin("ricochet"))
        .args(["--mode", "client", "--connect", &router_endpoint, "worlds"])
        .output()
        .unwrap();
    assert!(ok(&out).lines().any(|l| l == "routed"));
}

#[test]
fn the_python_client_sends_commands_and_decodes_frames() {
    let python = python();
    let probe = Process::new(&python)
        .args(["-c", "import zenoh"])
        .output()
        .expect("python3 runs");
    assert!(
        probe.status.success(),
        "the Python client needs numpy and eclipse-zenoh: `bash .ci/install` puts them in its virtual environment"
    );
    let server = Server::start("emitters.toml", "python", &[]);
    resume(&server.client());
    let script = root().join("assets/scripts/ricochet_client.py");
    let py = |args: &[&str]| {
        Process::new(&python)
            .arg(&script)
            .args(["--world", "python", "--connect", &server.endpoint])
            .args(args)
            .output()
            .unwrap()
    };
    let out = ok(&py(&["send", "spawn_minion", "at=[100,60]"]));
    let reply: serde_json::Value = serde_json::from_str(out.trim()).unwrap();
    let id = reply["ids"][0].as_str().unwrap().to_string();
    // Each Python process names itself as the sender: the same request id from two of them
    // is two requests (the server remembers answers per sender), each applied; without a
    // sender both would be the anonymous one and the second would get the first's answer.
    let same = r#"{"do":"spawn_minion","at":[100,60],"id":"python-same-id"}"#;
    let answer = |out: &std::process::Output| -> serde_json::Value {
        serde_json::from_str(ok(out).trim()).unwrap()
    };
    let (first, second) = (answer(&py(&["send", same])), answer(&py(&["send", same])));
    assert_ne!(first["ids"], second["ids"], "{first} {second}");
    let refused = py(&["send", "--raw", "not json"]);
    assert_eq!(refused.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&refused.stdout).contains("not JSON"));
    let out = ok(&py(&["watch", "--frames", "90"]));
    let frames: Vec<serde_json::Value> = out
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(frames.len(), 90);
    let last = frames.last().unwrap();
    assert_eq!(last["statics"], 42);
    assert!(last["bodies"]
        .as_array()
        .unwrap()
        .iter()
        .any(|b| b["id"] == id.as_str()));
    assert!(frames
        .windows(2)
        .all(|w| w[1]["frame"].as_u64().unwrap() == w[0]["frame"].as_u64().unwrap() + 1));
    // The scene's emitter: particles with their colours.
    let particles: usize = frames
        .iter()
        .map(|f| f["particles"].as_array().unwrap().len())
        .max()
        .unwrap();
    assert!(particles > 0 || frames[0]["frame"].as_u64().unwrap() > 400);
}

#[test]
fn the_info_key_gives_the_scene_its_bounds_and_groups_and_changes_on_load() {
    let server = Server::start("emitters.toml", "info", &[]);
    let client = server.client();
    let info = client.info(TIMEOUT).expect("info");
    assert_eq!(info.scene, "emitters.toml");
    assert_eq!(info.bounds, [[0.0, 0.0], [200.0, 112.5]]);
    assert!((info.dt - 1.0 / 60.0).abs() < 1e-6, "{}", info.dt);
    for g in ["platforms", "hero", "minions"] {
        assert!(info.groups.iter().any(|x| x == g), "{g}: {:?}", info.groups);
    }
    let reply = request(
        &client,
        Command::Server(ServerCommand::Load {
            path: Some("bounds.toml".into()),
            text: None,
        }),
    );
    assert!(reply.ok, "{reply:?}");
    let loaded = client.info(TIMEOUT).expect("info");
    assert_eq!(loaded.scene, "bounds.toml");
    assert!(loaded.generation > info.generation);
}

#[test]
fn a_server_given_an_accuracy_target_runs_the_setting_it_picked_and_says_why() {
    // The bounce (restitution 1): only exact flight keeps its height within 0.01.
    let cache = tempfile::tempdir().unwrap();
    let cache_dir = cache.path().to_str().unwrap();
    let server = Server::start(
        "bounce.toml",
        "accuracy",
        &["--accuracy", "0.01", "--accuracy-cache", cache_dir],
    );
    let info = server.client().info(TIMEOUT).expect("info");
    let why = info.accuracy.expect("the pick, in the info reply");
    assert!(why.starts_with("accuracy 1e-2: `"), "{why}");
    assert!(why.contains("exact flight"), "{why}");
    assert!(why.contains("measured at start-up"), "{why}");
    // A second server on the same scene and target reads the measure the first cached.
    let again = Server::start(
        "bounce.toml",
        "accuracy-again",
        &["--accuracy", "0.01", "--accuracy-cache", cache_dir],
    );
    let why_again = again.client().info(TIMEOUT).unwrap().accuracy.unwrap();
    assert!(why_again.contains("cached measure"), "{why_again}");
    // Without a target, nothing is picked.
    let plain = Server::start("bounce.toml", "no-accuracy", &[]);
    assert_eq!(plain.client().info(TIMEOUT).unwrap().accuracy, None);
}

#[test]
fn a_set_solver_knob_shows_in_the_next_frames_figures() {
    let server = Server::start(
        "pyramid-10.toml",
        "live-figures",
        &[
            "--set",
            "solver=impulses",
            "--set",
            "substeps=1",
            "--set",
            "impulse_iterations=2",
            // Awake: a pyramid asleep whole runs no passes at all.
            "--set",
            "sleeping=false",
        ],
    );
    let client = server.client();
    let frames = client.frames().unwrap();
    let header = |frames: &ricochet_protocol::client::FrameStream| {
        let sample = frames
            .recv_timeout(TIMEOUT)
            .expect("frames")
            .expect("a frame");
        ricochet_protocol::frame::peek_header(&sample.payload().to_bytes()).expect("a header")
    };
    let before = header(&frames).stats;
    assert_eq!(before.solver_passes, 2, "{before:?}");
    assert!(before.residual.is_finite() && before.energy_change.is_finite());
    let reply = client
        .request_raw(
            br#"{"do":"set","name":"impulse_iterations","value":24}"#.to_vec(),
            TIMEOUT,
        )
        .unwrap();
    assert!(reply.ok, "{reply:?}");
    // The set took effect at the boundary after frame `reply.frame`: the next frame's
    // figures show it (at 60 frames a second, a sixtieth of a second later).
    let began = Instant::now();
    loop {
        assert!(began.elapsed() < TIMEOUT, "no frame after the set");
        let h = header(&frames);
        if h.frame > reply.frame {
            assert_eq!(
                h.stats.solver_passes, 24,
                "frame {}: {:?}",
                h.frame, h.stats
            );
            break;
        }
    }
}
