//! A user's own scene driven only by the commands for any body, and its time travelled
//! (real server and CLI processes on loopback): bodies spawned whole and from the scene's
//! template, struck; the world saved, run on, restored and run again to the same bits;
//! rewound across a checkpoint of its history to the same bits; forked under another
//! setting, which differs, both keeping real time; every refusal naming its field.

mod common;

use std::collections::BTreeMap;
use std::process::Command as Process;
use std::time::{Duration, Instant};

use common::*;
use ricochet_protocol::action::{Action, BodySpec, ShapeKind};
use ricochet_protocol::client::Client;
use ricochet_protocol::command::{Command, FrameHash, Reply, ServerCommand};

/// A billiard table of the user's: no gravity, walls, a ball template, room for 9 bodies.
const TABLE: &str = r#"
[world]
gravity = [0, 0]
bounds = [[0, 0], [40, 20]]

[limits]
bodies = 9

[[template]]
name = "ball"
group = "balls"
shape = "circle"
radius = 1
restitution = 0.9
friction = 0.1

[[generate]]
kind = "row"
id = "wall"
group = "walls"
shape = "rect"
size = [40, 1]
start = [20, 0]
step = [0, 20]
count = 2
mass = 0

[[generate]]
kind = "row"
id = "side"
group = "walls"
shape = "rect"
size = [1, 20]
start = [0, 10]
step = [40, 0]
count = 2
mass = 0

[[interact]]
a = "balls"
b = "balls"

[[interact]]
a = "balls"
b = "walls"
"#;

fn server_command(client: &Client, command: ServerCommand) -> Reply {
    request(client, Command::Server(command))
}

fn world_command(client: &Client, action: Action) -> Reply {
    request(client, Command::World(action))
}

fn step(client: &Client, n: u32) -> u64 {
    let reply = server_command(client, ServerCommand::Step { n });
    assert!(reply.ok, "{:?}", reply.error);
    reply.frame + u64::from(n)
}

fn hashes(client: &Client, from: u64, to: u64) -> Vec<FrameHash> {
    let reply = server_command(
        client,
        ServerCommand::Hashes {
            from: Some(from),
            to: Some(to),
        },
    );
    assert!(reply.ok, "{:?}", reply.error);
    reply.hashes
}

fn refused(reply: Reply, needle: &str) {
    assert!(!reply.ok, "accepted, where `{needle}` was expected");
    let error = reply.error.unwrap_or_default();
    assert!(error.contains(needle), "`{needle}` not in: {error}");
}

/// Every body's state as the `bodies` reply gives it, as text (bits compared).
fn dump(client: &Client) -> String {
    let reply = server_command(
        client,
        ServerCommand::Bodies {
            ids: Vec::new(),
            within: None,
        },
    );
    assert!(reply.ok, "{:?}", reply.error);
    serde_json::to_string(&reply.bodies).unwrap()
}

#[test]
fn a_users_scene_is_saved_restored_rewound_and_forked_to_the_same_bits() {
    let dir = temp_dir();
    let scene = dir.path().join("table.toml");
    std::fs::write(&scene, TABLE).unwrap();
    let server = Server::launch(
        "table",
        &[
            "--scene",
            scene.to_str().unwrap(),
            "--paused",
            "--history-every",
            "50",
            "--max-worlds",
            "2",
        ],
    );
    let client = server.client();

    // A cue ball of the user's own, and three from the scene's template.
    let cue = BodySpec {
        id: Some("cue".into()),
        group: Some("balls".into()),
        shape: ShapeKind::Circle,
        size: None,
        radius: Some(1.0),
        pos: Some([6.0, 10.0]),
        vel: None,
        mass: Some(2.0),
        restitution: Some(0.9),
        friction: Some(0.1),
        gravity: None,
    };
    let reply = world_command(
        &client,
        Action::Spawn {
            body: Some(Box::new(cue.clone())),
            template: None,
            at: None,
            vel: None,
        },
    );
    assert!(reply.ok, "{:?}", reply.error);
    assert_eq!(reply.ids, ["cue"]);
    let mut balls = Vec::new();
    for (x, y) in [(25.0, 10.0), (27.0, 11.1), (27.0, 8.9)] {
        let reply = world_command(
            &client,
            Action::Spawn {
                body: None,
                template: Some("ball".into()),
                at: Some([x, y]),
                vel: None,
            },
        );
        assert!(reply.ok, "{:?}", reply.error);
        balls.extend(reply.ids);
    }
    assert_eq!(balls, ["ball-1", "ball-2", "ball-3"]);
    // The command line's short form spawns too.
    let out = ok(&server.cli(&["send", "spawn", "template=ball", "at=[10,3]"]));
    assert!(out.contains("ball-4"), "{out}");
    let reply = world_command(
        &client,
        Action::Impulse {
            body: "cue".into(),
            impulse: [60.0, 1.0],
        },
    );
    assert!(reply.ok, "{:?}", reply.error);
    let saved_at = step(&client, 20);

    // The served run is the headless run of the same commands, hash for hash: the
    // world commands (all applied at frame 0, the world paused) replayed by `simulate`.
    let log: String = [
        serde_json::json!({"do": "spawn", "body": cue}),
        serde_json::json!({"do": "spawn", "template": "ball", "at": [25.0, 10.0]}),
        serde_json::json!({"do": "spawn", "template": "ball", "at": [27.0, 11.1]}),
        serde_json::json!({"do": "spawn", "template": "ball", "at": [27.0, 8.9]}),
        serde_json::json!({"do": "spawn", "template": "ball", "at": [10, 3]}),
        serde_json::json!({"do": "impulse", "body": "cue", "impulse": [60.0, 1.0]}),
    ]
    .iter()
    .map(|action| format!("{}\n", serde_json::json!({"frame": 0, "action": action})))
    .collect();
    let inputs = dir.path().join("inputs.jsonl");
    std::fs::write(&inputs, log).unwrap();
    let headless = dir.path().join("hashes.jsonl");
    let out = std::process::Command::new(bin("ricochet-server"))
        .args(["simulate", "--scene", scene.to_str().unwrap(), "--steps"])
        .arg(saved_at.to_string())
        .args(["--inputs", inputs.to_str().unwrap()])
        .args(["--hashes", headless.to_str().unwrap()])
        .output()
        .unwrap();
    ok(&out);
    let headless: Vec<FrameHash> = std::fs::read_to_string(&headless)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(headless.len() as u64, saved_at + 1);
    assert_eq!(hashes(&client, 0, saved_at), headless);

    // Saved at frame N, run 300 steps; restored, run 300 steps again: the same bits.
    let save = server_command(
        &client,
        ServerCommand::Save {
            name: "break".into(),
        },
    );
    assert!(save.ok, "{:?}", save.error);
    assert_eq!(save.frame, saved_at);
    let end = step(&client, 300);
    let first = hashes(&client, saved_at, end);
    assert_eq!(first.len(), 301);
    assert_eq!(Some(&first[0].hash), save.hash.as_ref());
    let first_dump = dump(&client);
    let info = client.info(TIMEOUT).unwrap();
    assert_eq!(info.templates, ["ball"]);
    assert_eq!(info.saves, [("break".to_string(), saved_at)]);

    let restore = server_command(
        &client,
        ServerCommand::Restore {
            name: "break".into(),
        },
    );
    assert!(restore.ok, "{:?}", restore.error);
    assert_eq!((restore.frame, &restore.hash), (saved_at, &save.hash));
    assert_eq!(step(&client, 300), end);
    assert_eq!(hashes(&client, saved_at, end), first);
    assert_eq!(dump(&client), first_dump);

    // Rewound across a checkpoint of the history (one every 50 frames): the same bits at
    // the frame it names, and the same run from there.
    let back = saved_at + 120;
    let rewind = server_command(&client, ServerCommand::Rewind { frame: back });
    assert!(rewind.ok, "{:?}", rewind.error);
    assert_eq!(rewind.frame, back);
    let expected = first.iter().find(|h| h.frame == back).unwrap();
    assert_eq!(rewind.hash.as_ref(), Some(&expected.hash));
    assert_eq!(step(&client, (end - back) as u32), end);
    assert_eq!(hashes(&client, saved_at, end), first);
    assert_eq!(dump(&client), first_dump);

    // Refusals, each naming what was wrong; none changes the world.
    refused(
        world_command(
            &client,
            Action::Impulse {
                body: "ball-9".into(),
                impulse: [1.0, 0.0],
            },
        ),
        "no body `ball-9`",
    );
    refused(
        world_command(
            &client,
            Action::Spawn {
                body: None,
                template: Some("ball".into()),
                at: Some([50.0, 10.0]),
                vel: None,
            },
        ),
        "`at`",
    );
    refused(
        world_command(
            &client,
            Action::Spawn {
                body: Some(Box::new(BodySpec {
                    id: Some("cue2".into()),
                    pos: Some([35.0, 15.0]),
                    ..cue.clone()
                })),
                template: None,
                at: None,
                vel: None,
            },
        ),
        "bodies",
    );
    refused(
        server_command(
            &client,
            ServerCommand::Restore {
                name: "brake".into(),
            },
        ),
        "no save `brake` (saved: break)",
    );
    refused(
        server_command(&client, ServerCommand::Rewind { frame: 3 }),
        &format!("starts at frame {saved_at}"),
    );
    refused(
        server_command(&client, ServerCommand::Close),
        "server's own world",
    );
    assert_eq!(hashes(&client, end, end)[0], *first.last().unwrap());

    // A fork under another setting: served beside the first under its own name, listed,
    // running in real time like it, and its bits differ.
    let fork = server_command(
        &client,
        ServerCommand::Fork {
            world: "table-chapter".into(),
            settings: BTreeMap::from([("solver".to_string(), serde_json::json!("relaxation"))]),
        },
    );
    assert!(fork.ok, "{:?}", fork.error);
    refused(
        server_command(
            &client,
            ServerCommand::Fork {
                world: "table-third".into(),
                settings: BTreeMap::new(),
            },
        ),
        "--max-worlds",
    );
    let listed = ok(&server.cli(&["worlds"]));
    assert!(
        listed.contains("table") && listed.contains("table-chapter"),
        "{listed}"
    );
    let forked = Client::open(&server.network(), "table-chapter").unwrap();
    wait_answered(&forked, "the fork");
    let fork_info = forked.info(TIMEOUT).unwrap();
    assert_eq!(fork_info.forked_from.as_deref(), Some("table"));
    let fork_start = server_command(
        &forked,
        ServerCommand::Hashes {
            from: None,
            to: None,
        },
    );
    assert_eq!(
        fork_start.hashes.first().map(|h| h.frame),
        Some(end),
        "the fork starts at the frame it was forked at"
    );
    // The same strike in both, so both move (a world at rest holds the same bits under
    // either solver).
    for world in [&client, &forked] {
        let reply = world_command(
            world,
            Action::Impulse {
                body: "cue".into(),
                impulse: [-40.0, 7.0],
            },
        );
        assert!(reply.ok, "{:?}", reply.error);
    }
    let fork_end = step(&forked, 60);
    assert_eq!(step(&client, 60), fork_end);
    let (a, b) = (
        hashes(&client, fork_end, fork_end),
        hashes(&forked, fork_end, fork_end),
    );
    assert_ne!(
        a, b,
        "the chapter's relaxation gave the same bits as impulses"
    );

    // Both run in real time at once (60 steps a second each).
    resume(&client);
    resume(&forked);
    let began = Instant::now();
    std::thread::sleep(Duration::from_secs(2));
    let (fa, fb) = (
        request(&client, Command::World(Action::Deselect)).frame,
        request(&forked, Command::World(Action::Deselect)).frame,
    );
    let seconds = began.elapsed().as_secs_f64();
    for (name, frames) in [("table", fa - fork_end), ("table-chapter", fb - fork_end)] {
        let rate = frames as f64 / seconds;
        assert!(
            rate > 40.0 && rate < 75.0,
            "{name}: {frames} frames in {seconds:.2} s"
        );
    }

    // Closed from the command line, the fork says so, is no longer served, and its place
    // is free again.
    let closed = Process::new(bin("ricochet"))
        .args(["--world", "table-chapter", "--connect", &server.endpoint])
        .args(["send", "close"])
        .env("RUST_LOG", "warn")
        .output()
        .expect("ricochet starts");
    ok(&closed);
    let began = Instant::now();
    while ok(&server.cli(&["worlds"])).contains("table-chapter") {
        assert!(began.elapsed() < TIMEOUT, "the closed fork is still listed");
        std::thread::sleep(Duration::from_millis(100));
    }
    let again = server_command(
        &client,
        ServerCommand::Fork {
            world: "table-chapter".into(),
            settings: BTreeMap::new(),
        },
    );
    assert!(again.ok, "{:?}", again.error);
}

/// `ricochet watch` on a paused world says so instead of printing nothing.
#[test]
fn watch_says_the_world_is_paused() {
    let dir = temp_dir();
    let scene = dir.path().join("table.toml");
    std::fs::write(&scene, TABLE).unwrap();
    let server = Server::launch("still", &["--scene", scene.to_str().unwrap(), "--paused"]);
    let out = server.cli(&["watch", "--seconds", "3.5"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(err.contains("world `still` is paused at frame 0"), "{err}");
    // Running, it says nothing of the kind.
    resume(&server.client());
    let out = server.cli(&["watch", "--seconds", "3.5"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!err.contains("paused"), "{err}");
    assert!(String::from_utf8_lossy(&out.stdout).lines().count() > 60);
}
