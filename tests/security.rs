//! Hostile input to a running server, end to end: every refused input of the security
//! issue gets a reply naming the problem, changes nothing (the world's dump is bit for bit
//! a run without it), and the server keeps stepping. Real processes on loopback; every
//! wait is bounded.

mod common;

use std::process::Command as Process;

use common::*;
use ricochet_protocol::command::{Command, ServerCommand};
use ricochet_protocol::dump::read_dump;

/// The refused inputs: raw command bytes and what the reply must mention.
fn hostile_inputs(long_name: &str) -> Vec<(Vec<u8>, String)> {
    let mut cases: Vec<(String, &str)> = vec![
        // Reading outside the scenes directory, or what is not a scene file.
        (r#"{"do":"load","path":"/etc/passwd"}"#.into(), "no scene"),
        (
            r#"{"do":"load","path":"../../../../../../etc/passwd"}"#.into(),
            "no scene",
        ),
        (r#"{"do":"load","path":"link.toml"}"#.into(), "no scene"),
        (
            r#"{"do":"load","path":"fifo.toml"}"#.into(),
            "not a regular file",
        ),
        (r#"{"do":"load","path":"big.toml"}"#.into(), "over the"),
        (r#"{"do":"load","path":"/dev/zero"}"#.into(), "no scene"),
        (
            r#"{"do":"load","path":"nothing-here.toml"}"#.into(),
            "no scene",
        ),
        // Settings that would freeze or flood the clock.
        (r#"{"do":"set","name":"dt","value":1e-300}"#.into(), "dt"),
        (r#"{"do":"set","name":"dt","value":1e300}"#.into(), "dt"),
        (
            r#"{"do":"set","name":"relaxation_iterations","value":4000000000}"#.into(),
            "relaxation_iterations",
        ),
        (
            r#"{"do":"set","name":"gravity","value":[0,-1e300]}"#.into(),
            "gravity",
        ),
        (
            r#"{"do":"set","name":"relaxation_iterations","value":10000}"#.into(),
            "step_work",
        ),
        // Counts over the world's limits.
        (
            r#"{"do":"spawn_particles","preset":"fire","at":[50,50],"count":1000000}"#.into(),
            "count",
        ),
        (
            r#"{"do":"start_emitter","preset":"fire","at":[50,50],"count":4294967295}"#.into(),
            "count",
        ),
        (
            r#"{"do":"spawn_minion","at":[50,50]}"#.into(),
            "limits.bodies",
        ),
        // Names and commands too long to echo.
        (
            format!(r#"{{"do":"clear","group":"{long_name}"}}"#),
            "names are at most",
        ),
        (
            format!(r##"{{"do":"load","text":"# {}"}}"##, "x".repeat(70_000)),
            "larger than the limit",
        ),
    ];
    cases
        .drain(..)
        .map(|(text, needle)| (text.into_bytes(), needle.to_string()))
        .collect()
}

#[test]
fn refused_inputs_are_answered_change_nothing_and_the_server_keeps_stepping() {
    let dir = temp_dir();
    let scenes = dir.path().join("scenes");
    std::fs::create_dir(&scenes).unwrap();
    std::os::unix::fs::symlink("/etc/passwd", scenes.join("link.toml")).unwrap();
    let fifo = Process::new("mkfifo")
        .arg(scenes.join("fifo.toml"))
        .status()
        .unwrap();
    assert!(fifo.success(), "mkfifo");
    std::fs::write(scenes.join("big.toml"), vec![b'#'; 2 << 20]).unwrap();

    // The reference: the same scene stepped headless, with no input at all.
    let inputs = hostile_inputs(&"g".repeat(10_000));
    let steps = inputs.len() as u64;
    let reference = dir.path().join("reference.jsonl");
    ok(&Process::new(bin("ricochet-server"))
        .args(["simulate", "--scene", &scene("emitters.toml"), "--steps"])
        .arg(steps.to_string())
        .arg("--dump")
        .arg(&reference)
        .output()
        .unwrap());
    let reference = std::fs::read_to_string(&reference).unwrap();
    let bodies = read_dump(&reference).unwrap()[0].bodies.len();

    // A paused server at its body limit, with a small work budget: each hostile input,
    // then one step.
    let served = dir.path().join("served.jsonl");
    let server = Server::start(
        "emitters.toml",
        "hostile",
        &[
            "--paused",
            "--scenes",
            scenes.to_str().unwrap(),
            "--limit",
            &format!("bodies={bodies}"),
            "--limit",
            "step_work=100000",
            "--dump",
            served.to_str().unwrap(),
        ],
    );
    let client = server.client();
    for (bytes, needle) in &inputs {
        let shown = String::from_utf8_lossy(&bytes[..bytes.len().min(80)]).into_owned();
        let reply = client.request_raw(bytes.clone(), TIMEOUT).expect("a reply");
        assert!(!reply.ok, "{shown} was accepted");
        let error = reply.error.unwrap_or_default();
        assert!(
            error.contains(needle.as_str()),
            "{shown}: `{error}` should mention {needle}"
        );
        assert!(error.len() <= 400, "{shown}: a {} byte error", error.len());
        assert!(!error.contains("root:"), "{shown}: echoed a file: {error}");
        assert!(
            request(&client, Command::Server(ServerCommand::Step { n: 1 })).ok,
            "{shown}: the step after it"
        );
    }

    // Every frame the server stepped is bit for bit the headless run's.
    let served = std::fs::read_to_string(&served).unwrap();
    let (served, reference): (Vec<&str>, Vec<&str>) =
        (served.lines().collect(), reference.lines().collect());
    assert_eq!(served.len(), reference.len(), "frames 0 to {steps}");
    for (k, (a, b)) in served.iter().zip(&reference).enumerate() {
        assert!(
            a == b,
            "frame {k} differs from the run without hostile input"
        );
    }

    // And it keeps stepping in real time.
    resume(&client);
    let frames = client.frames().unwrap();
    let mut decoder = ricochet_protocol::frame::FrameDecoder::new();
    let began = std::time::Instant::now();
    while decoder.frame < steps + 30 {
        assert!(
            began.elapsed() < TIMEOUT,
            "frames stopped at {}",
            decoder.frame
        );
        if let Ok(Some(sample)) = frames.recv_timeout(std::time::Duration::from_millis(100)) {
            let _ = decoder.apply(&sample.payload().to_bytes());
        }
    }
}
