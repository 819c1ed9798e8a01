//! Replay end to end: a server's input log, recorded while clients drive it, replayed by
//! the command-line client into a fresh world gives the same frames and the same dump,
//! bit for bit. Real processes on loopback; every wait is bounded.

mod common;

use std::path::Path;
use std::process::{Command as Process, Stdio};
use std::time::{Duration, Instant};

use common::*;
use ricochet_protocol::client::Client;
use ricochet_protocol::command::{Action, Command, Direction};
use ricochet_protocol::dump::read_dump;
use ricochet_protocol::frame::FrameDecoder;

/// Replays `log` with the command-line client and returns the decoded bodies and
/// particles of each frame it produces (the step's wall-time figures left out).
fn replayed_frames(server: &Server, client: &Client, log: &Path, until: u64) -> Vec<String> {
    let stream = client.frames().unwrap();
    ok(&server.cli(&[
        "replay",
        log.to_str().unwrap(),
        "--until",
        &until.to_string(),
    ]));
    let mut decoder = FrameDecoder::new();
    let mut frames = Vec::new();
    // Frames from before the replay's reset may still be queued: collect from frame 0 on.
    let mut started = false;
    let began = Instant::now();
    while began.elapsed() < TIMEOUT && !(started && decoder.frame >= until) {
        if let Ok(Some(sample)) = stream.recv_timeout(Duration::from_millis(100)) {
            if decoder.apply(&sample.payload().to_bytes()).is_err() {
                continue;
            }
            if decoder.frame == 0 {
                started = true;
                frames.clear();
            }
            if started {
                let bodies: Vec<_> = decoder
                    .bodies
                    .iter()
                    .map(|b| (b.id.clone(), b.p, b.d, b.collided))
                    .collect();
                let particles: Vec<_> = decoder.particles.iter().map(|p| (p.id, p.pos)).collect();
                frames.push(format!("{} {:?} {:?}", decoder.frame, bodies, particles));
            }
        }
    }
    frames
}

#[test]
fn a_recorded_input_log_replays_to_the_same_frames() {
    let dir = temp_dir();
    let served_dump = dir.path().join("replay-served.jsonl");
    let server = Server::start(
        "emitters.toml",
        "replay",
        &["--dump", served_dump.to_str().unwrap()],
    );
    let client = server.client();
    resume(&client);
    let log = dir.path().join("recorded.jsonl");
    let recorder = Process::new(bin("ricochet"))
        .args([
            "--world",
            "replay",
            "--connect",
            &server.endpoint,
            "record",
            log.to_str().unwrap(),
            "--seconds",
            "4",
        ])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut recorder = Running(recorder);
    std::thread::sleep(Duration::from_millis(1000));
    for command in [
        Action::Press {
            dir: Direction::Right,
        },
        Action::FireDyePack { at: [150.0, 90.0] },
        Action::SpawnDumbMinion { at: [100.0, 90.0] },
        Action::SpawnParticles {
            preset: "fire".into(),
            at: [60.0, 60.0],
            count: 30,
        },
        Action::Release {
            dir: Direction::Right,
        },
        Action::Agitate { strength: None },
    ] {
        assert!(request(&client, Command::World(command)).ok);
        std::thread::sleep(Duration::from_millis(150));
    }
    // A refused command is not part of the log.
    assert!(
        !request(
            &client,
            Command::World(Action::Clear {
                group: "nobody".into()
            })
        )
        .ok
    );
    // The recorder stops by itself after its 4 seconds.
    let began = Instant::now();
    while recorder.0.try_wait().unwrap().is_none() {
        assert!(began.elapsed() < TIMEOUT, "the recorder did not stop");
        std::thread::sleep(Duration::from_millis(100));
    }
    let text = std::fs::read_to_string(&log).unwrap();
    let entries = ricochet_protocol::command::parse_input_log(&text).unwrap();
    assert_eq!(entries.len(), 6, "{text}");
    let last = entries.last().unwrap().frame;

    let until = last + 90;
    let first = replayed_frames(&server, &client, &log, until);
    let second = replayed_frames(&server, &client, &log, until);
    assert_eq!(
        first.len() as u64,
        until + 1,
        "frames 0 to {until} of the replay"
    );
    assert_eq!(first, second, "two replays of the same log differ");

    // The headless run of the same scene and log agrees with the served frames.
    let dump = dir.path().join("replay-dump.jsonl");
    let out = Process::new(bin("ricochet-server"))
        .args([
            "simulate",
            "--scene",
            &scene("emitters.toml"),
            "--steps",
            &until.to_string(),
            "--inputs",
            log.to_str().unwrap(),
            "--dump",
            dump.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    ok(&out);
    let headless = std::fs::read_to_string(&dump).unwrap();
    let headless: Vec<&str> = headless.lines().collect();
    assert_eq!(headless.len() as u64, until + 1);
    // The server's own dump of what it published: the last replay is the run from the
    // last frame-0 line on. Whole states, every body and particle, compared as text that
    // holds every bit.
    let served = std::fs::read_to_string(&served_dump).unwrap();
    let served: Vec<&str> = served.lines().collect();
    let start = served
        .iter()
        .rposition(|l| l.starts_with("{\"frame\":0,"))
        .expect("a frame 0 in the served dump");
    let replayed = &served[start..];
    assert!(replayed.len() as u64 > until, "{} lines", replayed.len());
    for (k, (a, b)) in headless.iter().zip(replayed).enumerate() {
        assert!(
            a == b,
            "frame {k} differs between the headless run and the replay"
        );
    }
    // And the dump reads back.
    assert_eq!(
        read_dump(&headless.join("\n")).unwrap().len() as u64,
        until + 1
    );
}
