//! README.md's first quick start, run as written: its scene written to the file its first
//! line names, its commands run by bash with the built binaries on the PATH, against real
//! processes. README and test cannot drift apart: the test reads the README.
//!
//! The commands use the default endpoint (tcp/127.0.0.1:7447), so they run in a network
//! namespace of their own (`unshare --net`, as root), apart from anything else on the
//! machine. (The viewer's quick start is run by tests/remote_viewer.rs.)

mod common;

use std::process::{Command as Process, Stdio};
use std::time::{Duration, Instant};

use common::*;

#[test]
fn the_readme_quick_start_for_your_own_scene_runs_as_written() {
    let blocks = readme_blocks("Quick start: your own scene");
    let dir = temp_dir();
    let mut script = String::new();
    for (lang, text) in &blocks {
        match lang.as_str() {
            "toml" => {
                let name = text
                    .lines()
                    .next()
                    .and_then(|l| l.strip_prefix("# "))
                    .expect("a scene block's first line is `# FILE`");
                std::fs::write(dir.path().join(name.trim()), text).unwrap();
            }
            "sh" => script.push_str(text),
            other => panic!("a block of `{other}` in the quick start"),
        }
    }
    assert!(
        script.contains("ricochet-server run") && script.contains("send impulse"),
        "the quick start serves a scene and strikes it:\n{script}"
    );
    let mut shell = Process::new("unshare");
    shell
        .args(["--net", "bash", "-euo", "pipefail", "-c"])
        .arg(format!("ip link set lo up\n{script}"))
        .current_dir(dir.path())
        .env("PATH", path_with_binaries())
        .env_remove("RUST_LOG")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    let mut run = Group::spawn(&mut shell);
    let began = Instant::now();
    while run.0.try_wait().unwrap().is_none() {
        assert!(
            began.elapsed() < Duration::from_secs(60),
            "the quick start did not finish within 60 s"
        );
        std::thread::sleep(Duration::from_millis(100));
    }
    let (mut stdout, mut stderr) = (String::new(), String::new());
    std::io::Read::read_to_string(run.0.stdout.as_mut().unwrap(), &mut stdout).unwrap();
    std::io::Read::read_to_string(run.0.stderr.as_mut().unwrap(), &mut stderr).unwrap();
    let status = run.0.wait().unwrap();
    assert!(
        status.success(),
        "the quick start failed:\n{stdout}\n{stderr}"
    );

    // The headless run dumped 121 frames: the state before the first step and after each.
    let dump = std::fs::read_to_string(dir.path().join("mine.jsonl")).unwrap();
    assert_eq!(dump.lines().count(), 121);
    // The ball was struck: the server answered and moved it sideways. The scene gives it no
    // friction, so a bounce on the floor cannot take that speed back, whenever the strike lands.
    let replies: Vec<serde_json::Value> = stdout
        .lines()
        .filter(|l| l.starts_with('{'))
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert!(replies.iter().all(|r| r["ok"] == true), "{stdout}");
    let ball = replies
        .iter()
        .find_map(|r| r.pointer("/bodies/0").cloned())
        .unwrap_or_else(|| panic!("no body in the replies: {stdout}"));
    assert!(
        ball["vel"][0].as_f64().unwrap() > 1.0,
        "the struck ball moves: {ball}"
    );
}
