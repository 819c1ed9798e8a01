//! A user's own scene driven body by body (real server and CLI processes on loopback):
//! a ball struck, one moved and given a velocity, one removed, each by its id, and the
//! served run bit for bit what a headless run of the same actions at the same frames gives.

mod common;

use common::*;
use ricochet_protocol::action::Action;
use ricochet_protocol::command::{Command, ServerCommand, TimedAction};
use ricochet_protocol::dump::read_dump;

/// A table of the user's: four balls in a row without gravity, walls around them.
const TABLE: &str = r#"
[world]
gravity = [0, 0]
bounds = [[0, 0], [40, 20]]

[[body]]
id = "cue"
group = "balls"
shape = "circle"
radius = 1
pos = [5, 10]
mass = 2
restitution = 1
friction = 0

[[generate]]
kind = "row"
id = "ball"
group = "balls"
shape = "circle"
radius = 1
start = [20, 10]
step = [2.5, 0]
count = 3
mass = 1
restitution = 1
friction = 0

[[body]]
id = "wall"
group = "walls"
shape = "rect"
size = [2, 20]
pos = [39, 10]
mass = 0

[[interact]]
a = "balls"
b = "balls"

[[interact]]
a = "balls"
b = "walls"
"#;

#[test]
fn a_users_scene_is_driven_by_its_bodies_ids_and_replays_bit_for_bit() {
    let dir = temp_dir();
    let scene = dir.path().join("table.toml");
    std::fs::write(&scene, TABLE).unwrap();
    let served = dir.path().join("served.jsonl");
    let server = Server::launch(
        "table",
        &[
            "--scene",
            scene.to_str().unwrap(),
            "--paused",
            "--dump",
            served.to_str().unwrap(),
        ],
    );
    let client = server.client();
    let mut log: Vec<TimedAction> = Vec::new();
    let mut act = |action: Action| {
        let reply = request(&client, Command::World(action.clone()));
        assert!(reply.ok, "{action:?}: {:?}", reply.error);
        log.push(TimedAction {
            frame: reply.frame,
            action,
        });
        reply
    };
    let step = |n: u32| {
        let reply = request(&client, Command::Server(ServerCommand::Step { n }));
        assert!(reply.ok, "{:?}", reply.error);
    };

    // Strike the cue (its mass is 2: 10 of impulse is 5 units/s).
    let reply = act(Action::Impulse {
        body: "cue".into(),
        impulse: [10.0, 0.0],
    });
    assert_eq!(reply.ids, ["cue"]);
    step(30);
    // Move a ball out of the row and send it up; remove another.
    act(Action::SetBody {
        body: "ball/2".into(),
        pos: Some([30.0, 4.0]),
        vel: Some([0.0, 3.0]),
    });
    step(30);
    act(Action::Remove {
        body: "ball/1".into(),
    });
    step(60);

    // Refusals name what was wrong; the command line takes the short form.
    for (command, needle) in [
        (
            Action::Impulse {
                body: "ball/9".into(),
                impulse: [1.0, 0.0],
            },
            "no body `ball/9`",
        ),
        (
            Action::Impulse {
                body: "wall".into(),
                impulse: [1.0, 0.0],
            },
            "static",
        ),
        (
            Action::SetBody {
                body: "cue".into(),
                pos: None,
                vel: None,
            },
            "nothing to set",
        ),
    ] {
        let reply = request(&client, Command::World(command));
        assert!(!reply.ok);
        let error = reply.error.unwrap_or_default();
        assert!(error.contains(needle), "{error}");
    }
    let out = server.cli(&["send", "impulse", "body=cue", "impulse=[0,oops]"]);
    assert!(!out.status.success());
    ok(&server.cli(&["send", "set_body", "body=cue", "vel=[0,0]"]));
    let last = request(&client, Command::World(Action::Deselect)).frame;
    log.push(TimedAction {
        frame: last,
        action: Action::SetBody {
            body: "cue".into(),
            pos: None,
            vel: Some([0.0, 0.0]),
        },
    });
    step(10);

    // Where the bodies are, at the frame the reply names: by id, or within a box.
    let bodies = |ids: &[&str], within: Option<[[f64; 2]; 2]>| {
        request(
            &client,
            Command::Server(ServerCommand::Bodies {
                ids: ids.iter().map(|s| s.to_string()).collect(),
                within,
            }),
        )
    };
    let reply = bodies(&["cue", "wall"], None);
    assert!(reply.ok, "{:?}", reply.error);
    let (cue, wall) = (&reply.bodies[0], &reply.bodies[1]);
    assert_eq!(
        (cue.id.as_str(), cue.shape.as_str(), cue.mass),
        ("cue", "circle", 2.0)
    );
    assert_eq!((cue.size, cue.vel), ([2.0, 2.0], [0.0, 0.0]));
    assert_eq!(
        (wall.group.as_str(), wall.mass, wall.size),
        ("walls", 0.0, [2.0, 20.0])
    );
    let everything = bodies(&[], None);
    assert_eq!(everything.bodies.len(), 4, "cue, two balls and the wall");
    let right = bodies(&[], Some([[35.0, 0.0], [40.0, 20.0]]));
    assert_eq!(
        right
            .bodies
            .iter()
            .map(|b| b.id.as_str())
            .collect::<Vec<_>>(),
        ["wall"]
    );
    for (reply, needle) in [
        (bodies(&["ball/1"], None), "no body `ball/1`"),
        (bodies(&[], Some([[5.0, 0.0], [1.0, 1.0]])), "`within`"),
    ] {
        assert!(!reply.ok);
        let error = reply.error.unwrap_or_default();
        assert!(error.contains(needle), "{error}");
    }
    drop(server);

    let frames = read_dump(&std::fs::read_to_string(&served).unwrap()).unwrap();
    let at = |k: usize, id: &str| frames[k].bodies.iter().find(|b| b.id == id).cloned();
    assert_eq!(
        at(1, "cue").unwrap().vx,
        5.0,
        "10 of impulse on a mass of 2"
    );
    assert!(at(59, "ball/2").unwrap().vy > 0.0);
    assert!(at(frames.len() - 1, "ball/1").is_none(), "removed");
    assert_eq!(at(frames.len() - 1, "cue").unwrap().vx, 0.0);

    // The same actions at the same frames, headless: the same frames, bit for bit.
    let inputs = dir.path().join("inputs.jsonl");
    let lines: Vec<String> = log
        .iter()
        .map(|a| serde_json::to_string(a).unwrap())
        .collect();
    std::fs::write(&inputs, lines.join("\n")).unwrap();
    let headless = dir.path().join("headless.jsonl");
    ok(&std::process::Command::new(bin("ricochet-server"))
        .args(["simulate", "--scene", scene.to_str().unwrap(), "--steps"])
        .arg((frames.len() - 1).to_string())
        .args(["--inputs", inputs.to_str().unwrap(), "--dump"])
        .arg(&headless)
        .output()
        .unwrap());
    let served = std::fs::read_to_string(&served).unwrap();
    let headless = std::fs::read_to_string(&headless).unwrap();
    assert_eq!(served.lines().count(), headless.lines().count());
    for (k, (a, b)) in served.lines().zip(headless.lines()).enumerate() {
        assert!(a == b, "frame {k} differs from the headless run");
    }
}
