//! A server stopped by SIGTERM checkpoints its world, and the same command line resumes
//! it. A server killed mid-run (SIGKILL) is resumed from its journal bit for bit: the resumed
//! world at the last journaled frame is the killed server's at that frame, and from there
//! it steps to the frames a headless run of the same scene and the journal's commands
//! gives. A retried request after the resume is answered, not applied again. Real
//! processes on loopback; every wait is bounded.

mod common;

use std::collections::BTreeMap;
use std::path::Path;
use std::process::Command as Process;
use std::time::Duration;

use common::*;
use ricochet_protocol::client::Client;
use ricochet_protocol::command::{Action, Command, ServerCommand, TimedAction};
use ricochet_protocol::net::{Mode, Network};

/// A dump's lines by frame (the last line may be cut short by a kill: skipped).
fn dump_lines(path: &Path) -> BTreeMap<u64, String> {
    let text = std::fs::read_to_string(path).unwrap();
    text.lines()
        .filter_map(|line| {
            let value: serde_json::Value = serde_json::from_str(line).ok()?;
            Some((value["frame"].as_u64()?, line.to_string()))
        })
        .collect()
}

/// Spawns `n` minions in a row, each request answered as applied, `pause` apart.
fn spawn_minions(client: &Client, n: usize, pause: Duration) {
    for i in 0..n {
        let reply = request(
            client,
            Command::World(Action::SpawnMinion {
                at: [40.0 + 15.0 * i as f64, 80.0],
                shape: None,
            }),
        );
        assert!(reply.ok, "{reply:?}");
        std::thread::sleep(pause);
    }
}

#[test]
fn a_killed_server_resumes_from_its_journal_bit_for_bit() {
    let dir = temp_dir();
    let path = |name: &str| dir.path().join(name).to_str().unwrap().to_string();
    let (journal, dump_a, dump_b) = (path("world.journal"), path("a.jsonl"), path("b.jsonl"));

    // A runs in real time, journaled, while a client acts on it; then it is killed.
    let a = Server::start(
        "emitters.toml",
        "phoenix",
        &["--journal", &journal, "--dump", &dump_a],
    );
    let client = a.client();
    spawn_minions(&client, 8, Duration::from_millis(40));
    let retried = br#"{"do":"agitate","strength":30,"id":"once"}"#.to_vec();
    let first = client.request_raw(retried.clone(), TIMEOUT).unwrap();
    assert!(first.ok, "{first:?}");
    let set_gravity = br#"{"do":"set","name":"gravity","value":[5,-40]}"#.to_vec();
    assert!(client.request_raw(set_gravity, TIMEOUT).unwrap().ok);
    std::thread::sleep(Duration::from_millis(300));
    let endpoint = a.endpoint.clone();
    a.kill();

    // What the journal holds: its last stepped frame, and its world commands as an input
    // log for a headless run.
    let text = std::fs::read_to_string(&journal).unwrap();
    let mut last = 0;
    let mut inputs = String::new();
    for line in text.lines().skip(1) {
        // Each line ends with a tab and its checksum.
        let line = line.rsplit_once('\t').map_or(line, |(text, _)| text);
        let Ok(value) = serde_json::from_str::<serde_json::Value>(line) else {
            continue; // a last line cut short by the kill
        };
        if let Some(at) = value["at"].as_u64() {
            last = at;
        } else if !value["apply"].is_null() {
            // Written before it ran; a refused one changes nothing when replayed.
            let command: Command = serde_json::from_value(value["apply"].clone()).unwrap();
            let Command::World(action) = command else {
                panic!("only world commands were sent: {line}")
            };
            let timed = TimedAction {
                frame: value["frame"].as_u64().unwrap(),
                action,
            };
            inputs.push_str(&serde_json::to_string(&timed).unwrap());
            inputs.push('\n');
        }
    }
    assert!(last > 20, "A stepped for a while: {last} frames journaled");
    // 8 spawns, agitate, set, and the deselects that asked whether A was up.
    assert!(inputs.lines().count() >= 11, "{inputs}");
    let killed = dump_lines(Path::new(&dump_a));

    // B resumes the journal, paused, and steps on.
    // On A's endpoint, so A's client reconnects to it: the same sender retries.
    let _resumed = Server::launch_at(
        &endpoint,
        "phoenix",
        &["--resume", &journal, "--paused", "--dump", &dump_b],
    );
    let again = client.request_raw(retried, TIMEOUT).unwrap();
    assert_eq!(
        again, first,
        "the retry after the resume got the first answer"
    );
    let more = 120;
    assert!(request(&client, Command::Server(ServerCommand::Step { n: more })).ok);
    let resumed = dump_lines(Path::new(&dump_b));
    assert_eq!(
        resumed.keys().next(),
        Some(&last),
        "B starts at the last journaled frame"
    );
    assert_eq!(
        resumed[&last], killed[&last],
        "the resumed world is the killed one at frame {last}"
    );

    // The headless reference: the scene, the journal's commands, the same steps.
    let inputs_file = path("inputs.jsonl");
    std::fs::write(&inputs_file, inputs).unwrap();
    let reference = path("reference.jsonl");
    ok(&Process::new(bin("ricochet-server"))
        .args(["simulate", "--scene", &scene("emitters.toml")])
        .args(["--inputs", &inputs_file, "--dump", &reference, "--steps"])
        .arg((last + u64::from(more)).to_string())
        .output()
        .unwrap());
    let reference = dump_lines(Path::new(&reference));
    for frame in 0..=last {
        assert_eq!(
            killed.get(&frame),
            reference.get(&frame),
            "A's frame {frame} is the headless run's"
        );
    }
    for frame in last..=last + u64::from(more) {
        assert_eq!(
            resumed.get(&frame),
            reference.get(&frame),
            "the resumed frame {frame} is the headless run's"
        );
    }
}

/// With a small bound the journal starts again from checkpoints of the world as the server
/// runs; a server killed after several is resumed from its last checkpoint and the lines
/// after it, to the killed server's frame bit for bit, and a retried request from before
/// the checkpoint is still answered, not applied again.
#[test]
fn a_killed_server_resumes_from_its_last_checkpoint_bit_for_bit() {
    let dir = temp_dir();
    let path = |name: &str| dir.path().join(name).to_str().unwrap().to_string();
    let (journal, dump_a, dump_b) = (path("world.journal"), path("a.jsonl"), path("b.jsonl"));
    let a = Server::start(
        "emitters.toml",
        "checkpointed",
        &[
            "--journal",
            &journal,
            "--dump",
            &dump_a,
            "--journal-bytes",
            "4096",
            "--checkpoint-after-ms",
            "0.5",
        ],
    );
    let client = a.client();
    let retried = br#"{"do":"agitate","strength":30,"id":"before"}"#.to_vec();
    let first = client.request_raw(retried.clone(), TIMEOUT).unwrap();
    assert!(first.ok, "{first:?}");
    spawn_minions(&client, 6, Duration::from_millis(150));
    let checkpoints = || {
        std::fs::read_dir(dir.path())
            .unwrap()
            .filter(|e| {
                let name = e.as_ref().unwrap().file_name();
                name.to_string_lossy().ends_with(".checkpoint")
            })
            .count()
    };
    let text = std::fs::read_to_string(&journal).unwrap();
    assert!(
        text.lines()
            .nth(1)
            .is_some_and(|l| l.contains("\"checkpoint\"")),
        "the journal starts from a checkpoint: {}",
        text.lines().take(2).collect::<Vec<_>>().join("\n")
    );
    // The one the journal names, and at most one being written.
    assert!(
        checkpoints() <= 2,
        "the older checkpoints were removed: {}",
        checkpoints()
    );
    assert!(
        text.len() < 8192,
        "the journal is bounded: {} bytes",
        text.len()
    );
    let endpoint = a.endpoint.clone();
    a.kill();

    let text = std::fs::read_to_string(&journal).unwrap();
    let last = text
        .lines()
        .rev()
        .find_map(|l| {
            let l = l.rsplit_once('\t').map_or(l, |(t, _)| t);
            serde_json::from_str::<serde_json::Value>(l).ok()?["at"].as_u64()
        })
        .unwrap_or_else(|| {
            // Killed right after a checkpoint: its frame.
            let l = text.lines().nth(1).unwrap();
            let l = l.rsplit_once('\t').unwrap().0;
            serde_json::from_str::<serde_json::Value>(l).unwrap()["checkpoint"]["frame"]
                .as_u64()
                .unwrap()
        });
    let killed = dump_lines(Path::new(&dump_a));
    let _resumed = Server::launch_at(
        &endpoint,
        "checkpointed",
        &["--resume", &journal, "--paused", "--dump", &dump_b],
    );
    let again = client.request_raw(retried, TIMEOUT).unwrap();
    assert_eq!(
        again, first,
        "the retry after the resume got the first answer"
    );
    assert!(request(&client, Command::Server(ServerCommand::Step { n: 30 })).ok);
    let resumed = dump_lines(Path::new(&dump_b));
    assert_eq!(
        resumed.keys().next(),
        Some(&last),
        "B starts at the last journaled frame"
    );
    assert_eq!(
        resumed[&last], killed[&last],
        "the resumed world is the killed one at frame {last}"
    );
    assert!(resumed.contains_key(&(last + 30)), "B stepped on");
}

/// `ricochet-server run ARGS` on `endpoint` as a service runs it: logging at `info` to
/// `log`, stopped by a signal. Killed if the test fails first.
fn service(endpoint: &str, world: &str, args: &[&str], log: &Path) -> Running {
    let child = Process::new(bin("ricochet-server"))
        .args(["run", "--world", world, "--listen", endpoint])
        .args(args)
        .env("RUST_LOG", "info")
        .env("NO_COLOR", "1")
        .stdout(std::process::Stdio::null())
        .stderr(std::fs::File::create(log).unwrap())
        .spawn()
        .expect("ricochet-server starts");
    let running = Running(child);
    let client = Client::open(&Network::client(Mode::Peer, vec![endpoint.into()]), world)
        .expect("client session");
    wait_answered(&client, world);
    running
}

/// `kill -SIGNAL` of the service, then its exit status once it has stopped (bounded).
fn stop(service: &mut Running, signal: &str) -> std::process::ExitStatus {
    let pid = service.0.id().to_string();
    ok(&Process::new("kill")
        .args([&format!("-{signal}"), &pid])
        .output()
        .unwrap());
    let began = std::time::Instant::now();
    loop {
        if let Some(status) = service.0.try_wait().unwrap() {
            return status;
        }
        assert!(
            began.elapsed() < TIMEOUT,
            "the server did not stop on {signal}"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// A service stopped as systemd or docker stops it (SIGTERM) checkpoints its world and
/// says so; the same command line again resumes the journal it names (which the first
/// start created), at the stopped frame, bit for bit, and steps on to the frames a
/// headless run of the scene and the journal's commands gives. SIGINT stops it too.
#[test]
fn a_server_stopped_by_sigterm_resumes_bit_for_bit_from_the_same_command_line() {
    let dir = temp_dir();
    let path = |name: &str| dir.path().join(name).to_str().unwrap().to_string();
    let (journal, dump, log) = (path("world.journal"), path("dump.jsonl"), path("log"));
    let scene = scene("emitters.toml");
    // No checkpoint before the stop: the journal keeps every command, for the reference.
    let args = [
        "--scene",
        &scene,
        "--journal",
        &journal,
        "--dump",
        &dump,
        "--paused",
        "--checkpoint-after-ms",
        "1e9",
    ];
    assert!(!Path::new(&journal).exists());
    let endpoint = free_endpoint();
    let mut a = service(&endpoint, "service", &args, Path::new(&log));
    let client = Client::open(
        &Network::client(Mode::Peer, vec![endpoint.clone()]),
        "service",
    )
    .unwrap();
    spawn_minions(&client, 3, Duration::ZERO);
    assert!(request(&client, Command::Server(ServerCommand::Step { n: 40 })).ok);
    spawn_minions(&client, 2, Duration::ZERO);
    assert!(request(&client, Command::Server(ServerCommand::Step { n: 25 })).ok);
    let before = std::fs::read_to_string(&journal).unwrap();

    let status = stop(&mut a, "TERM");
    assert!(status.success(), "{status:?}");
    let logged = std::fs::read_to_string(&log).unwrap();
    assert!(
        logged.contains("stopping on SIGTERM; the world is checkpointed"),
        "{logged}"
    );
    let stopped = dump_lines(Path::new(&dump));
    let last = *stopped.keys().last().unwrap();
    assert_eq!(last, 65, "A stepped 65 frames");
    let text = std::fs::read_to_string(&journal).unwrap();
    let second = text.lines().nth(1).unwrap();
    let second = second.rsplit_once('\t').unwrap().0;
    let second: serde_json::Value = serde_json::from_str(second).unwrap();
    assert_eq!(
        second["checkpoint"]["frame"].as_u64(),
        Some(last),
        "the journal starts from a checkpoint of the stopped frame: {text}"
    );
    assert!(dir
        .path()
        .join(format!("world.journal.{last}.checkpoint"))
        .exists());

    // The same command line: the journal exists, so it is resumed.
    let mut b = service(&endpoint, "service", &args, Path::new(&log));
    let more = 50;
    assert!(request(&client, Command::Server(ServerCommand::Step { n: more })).ok);
    let resumed = dump_lines(Path::new(&dump));
    assert_eq!(
        resumed.keys().next(),
        Some(&last),
        "B starts at the stopped frame"
    );
    assert_eq!(
        resumed[&last], stopped[&last],
        "the resumed world is the stopped one at frame {last}"
    );
    let logged = std::fs::read_to_string(&log).unwrap();
    assert!(
        logged.contains("the journal exists: resuming it"),
        "{logged}"
    );

    // The headless reference: the scene and A's commands, as its journal held them.
    let mut inputs = String::new();
    for line in before.lines().skip(1) {
        let line = line.rsplit_once('\t').map_or(line, |(text, _)| text);
        let value: serde_json::Value = serde_json::from_str(line).unwrap();
        if let Ok(Command::World(action)) = serde_json::from_value(value["apply"].clone()) {
            let timed = TimedAction {
                frame: value["frame"].as_u64().unwrap(),
                action,
            };
            inputs.push_str(&serde_json::to_string(&timed).unwrap());
            inputs.push('\n');
        }
    }
    assert!(inputs.lines().count() >= 5, "{inputs}");
    let inputs_file = path("inputs.jsonl");
    std::fs::write(&inputs_file, inputs).unwrap();
    let reference = path("reference.jsonl");
    ok(&Process::new(bin("ricochet-server"))
        .args(["simulate", "--scene", &scene])
        .args(["--inputs", &inputs_file, "--dump", &reference, "--steps"])
        .arg((last + u64::from(more)).to_string())
        .output()
        .unwrap());
    let reference = dump_lines(Path::new(&reference));
    for frame in 0..=last {
        assert_eq!(
            stopped.get(&frame),
            reference.get(&frame),
            "A's frame {frame}"
        );
    }
    for frame in last..=last + u64::from(more) {
        assert_eq!(
            resumed.get(&frame),
            reference.get(&frame),
            "the resumed frame {frame} is the headless run's"
        );
    }

    let status = stop(&mut b, "INT");
    assert!(status.success(), "{status:?}");
    let logged = std::fs::read_to_string(&log).unwrap();
    assert!(logged.contains("stopping on SIGINT"), "{logged}");
}

/// `--resume FILE` needs FILE; `--journal FILE` with it must name the same file.
#[test]
fn resume_needs_its_journal_and_journal_names_the_same_file() {
    let dir = temp_dir();
    let missing = dir.path().join("missing.journal");
    let run = |args: &[&str]| {
        Process::new(bin("ricochet-server"))
            .args(["run", "--listen", &free_endpoint()])
            .args(args)
            .env("RUST_LOG", "warn")
            // An error is said as a user reads it, never as a debug dump with a backtrace.
            .env("RUST_BACKTRACE", "1")
            .output()
            .unwrap()
    };
    let out = run(&["--resume", missing.to_str().unwrap()]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.starts_with("ricochet-server: ")
            && err.contains("the journal")
            && err.contains("missing.journal"),
        "{err}"
    );
    assert!(
        !err.contains("acktrace") && err.lines().count() == 1,
        "{err}"
    );
    let other = dir.path().join("other.journal");
    let out = run(&[
        "--journal",
        other.to_str().unwrap(),
        "--resume",
        missing.to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("name different files"), "{err}");
    assert!(!other.exists(), "nothing was started");
}

/// A tmpfs mounted for a test, unmounted when dropped (whatever the test did).
struct Mounted(std::path::PathBuf);

impl Mounted {
    /// A tmpfs of `size` at `dir`, or why not (not root, no mount).
    fn tmpfs(dir: &Path, size: &str) -> Result<Mounted, String> {
        let uid = Process::new("id")
            .arg("-u")
            .output()
            .map_err(|e| e.to_string())?;
        if String::from_utf8_lossy(&uid.stdout).trim() != "0" {
            return Err("not root".into());
        }
        std::fs::create_dir_all(dir).map_err(|e| e.to_string())?;
        let out = Process::new("mount")
            .args(["-t", "tmpfs", "-o", &format!("size={size}"), "tmpfs"])
            .arg(dir)
            .output()
            .map_err(|e| e.to_string())?;
        if !out.status.success() {
            return Err(String::from_utf8_lossy(&out.stderr).into_owned());
        }
        Ok(Mounted(dir.to_path_buf()))
    }
}

impl Drop for Mounted {
    fn drop(&mut self) {
        let _ = Process::new("umount").arg("-l").arg(&self.0).status();
    }
}

/// Writes `path` until the disk under it is full; the bytes written.
fn fill(path: &Path) -> u64 {
    use std::io::Write;
    let mut file = std::fs::File::create(path).unwrap();
    let chunk = vec![0u8; 1024];
    let mut written = 0;
    loop {
        match file.write(&chunk) {
            Ok(0) | Err(_) => return written,
            Ok(n) => written += n as u64,
        }
    }
}

/// The journal's disk fills while a client sends commands, then frees: a command whose
/// line cannot be written is refused, and the journal stays one that resumes, after a
/// kill, to the live world at the last frame it holds, with every command the server
/// accepted in it (the last accepted one's retry is answered as it was, not applied
/// again). Needs root to mount a small tmpfs; skipped, saying so, without.
#[test]
fn a_journal_whose_disk_filled_and_freed_resumes_to_the_last_command_accepted() {
    let dir = temp_dir();
    let disk = dir.path().join("disk");
    let _mounted = match Mounted::tmpfs(&disk, "256k") {
        Ok(m) => m,
        Err(why) => {
            eprintln!("SKIPPED: a tmpfs cannot be mounted here ({why}); run as root");
            return;
        }
    };
    let journal = disk.join("world.journal").to_str().unwrap().to_string();
    let path = |name: &str| dir.path().join(name).to_str().unwrap().to_string();
    let (dump_a, dump_b) = (path("a.jsonl"), path("b.jsonl"));
    let a = Server::start(
        "emitters.toml",
        "brimful",
        &["--journal", &journal, "--dump", &dump_a],
    );
    let client = a.client();
    let mut accepted = Vec::new();
    let mut refused = 0;
    let send = |k: usize, accepted: &mut Vec<_>, refused: &mut usize| {
        let json = format!(
            r#"{{"do":"spawn_dumb_minion","at":[{},90],"id":"c{k}"}}"#,
            20 + 7 * (k % 25)
        );
        let reply = client.request_raw(json.into_bytes(), TIMEOUT).unwrap();
        if reply.ok {
            accepted.push((k, reply));
        } else {
            let error = reply.error.clone().unwrap_or_default();
            assert!(
                error.contains("journal"),
                "refused for another reason: {error}"
            );
            *refused += 1;
        }
        std::thread::sleep(Duration::from_millis(30));
    };
    for k in 0..5 {
        send(k, &mut accepted, &mut refused);
    }
    assert_eq!(accepted.len(), 5);
    // The disk fills: commands are refused (frames keep stepping, their lines owed).
    let filler = disk.join("filler");
    let filled = fill(&filler);
    assert!(filled > 100_000, "{filled} bytes of filler");
    let mut k = 5;
    while refused < 5 && k < 200 {
        send(k, &mut accepted, &mut refused);
        k += 1;
    }
    assert!(refused >= 5, "only {refused} refused with the disk full");
    // Until the journal stops growing: its last page full too, the frames' lines fail
    // (owed) as the commands' do.
    let size = || std::fs::metadata(&journal).unwrap().len();
    let began = std::time::Instant::now();
    let mut stable = (size(), std::time::Instant::now());
    while stable.1.elapsed() < Duration::from_millis(500) {
        assert!(
            began.elapsed() < TIMEOUT,
            "the journal grows on a full disk"
        );
        std::thread::sleep(Duration::from_millis(20));
        if size() != stable.0 {
            stable = (size(), std::time::Instant::now());
        }
    }
    send(k, &mut accepted, &mut refused);
    k += 1;
    // The disk frees: commands are accepted again.
    std::fs::remove_file(&filler).unwrap();
    let before = accepted.len();
    for _ in 0..5 {
        send(k, &mut accepted, &mut refused);
        k += 1;
    }
    assert_eq!(
        accepted.len(),
        before + 5,
        "accepted once the disk had room"
    );
    std::thread::sleep(Duration::from_millis(300));
    let endpoint = a.endpoint.clone();
    a.kill();
    let killed = dump_lines(Path::new(&dump_a));

    let _b = Server::launch_at(
        &endpoint,
        "brimful",
        &["--resume", &journal, "--paused", "--dump", &dump_b],
    );
    let resumed = dump_lines(Path::new(&dump_b));
    let (&last, line) = resumed.iter().next().expect("B dumps its first frame");
    let (k_last, reply_last) = accepted.last().unwrap();
    assert!(
        last >= reply_last.frame,
        "resumed at frame {last}, before the last accepted command's {}",
        reply_last.frame
    );
    assert_eq!(
        Some(line),
        killed.get(&last),
        "the resumed world is the live one at frame {last}"
    );
    // Every accepted command is in it: its retry gets the first answer.
    let retry = format!(r#"{{"do":"spawn_dumb_minion","at":[0,90],"id":"c{k_last}"}}"#);
    let again = client.request_raw(retry.into_bytes(), TIMEOUT).unwrap();
    assert_eq!(
        &again, reply_last,
        "the last accepted command, answered again"
    );
}
