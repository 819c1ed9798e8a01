//! The checkpoints' tests: journals that start again from each checkpoint, answers and
//! time travel remembered across them, checkpoints changed or named out of place.

use ricochet_protocol::command::Command;

use super::super::super::answered::Answer;
use super::super::super::inbox::Sender;
use super::super::{resume, Intent};
use super::*;

/// A change made to a checkpoint's CBOR, as an attacker would.
type Change = Box<dyn FnOnce(&mut ciborium::Value)>;

fn options(policy: Checkpoints) -> HostOptions {
    HostOptions {
        checkpoints: policy,
        ..HostOptions::for_tests("journaled")
    }
}

fn command(json: &str) -> Command {
    Command::parse(json.as_bytes()).expect("a valid command")
}

/// The bits a frame shows: every body's position and velocity, every particle's
/// position.
fn bits(world: &World) -> Vec<u64> {
    let mut out: Vec<u64> = world
        .bodies()
        .iter()
        .flat_map(|b| [b.pos.x, b.pos.y, b.vel.x, b.vel.y].map(f64::to_bits))
        .collect();
    let p = world.particles();
    out.extend((0..p.len()).flat_map(|i| [p.x[i], p.y[i]].map(|v| u64::from(v.to_bits()))));
    out
}

/// A journaled run of the 10-level pyramid with commands (an agitation draws on the
/// random generator; a spawn adds a body) and a checkpoint whenever the bound is
/// passed. Returns the live host, the answers it remembers and the checkpoints taken.
fn run(path: &Path, opts: &HostOptions, frames: u64) -> (Hosted, Answered, usize) {
    let scene = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../assets/scenes/pyramid-10.toml"
    );
    let text = std::fs::read_to_string(scene).unwrap();
    let mut host = Hosted::load(text, PathBuf::from(scene), opts).unwrap();
    let mut journal = Journal::create(path, "journaled", &host, opts).unwrap();
    let mut answered = Answered::default();
    let sender: Sender = Some("peer".into());
    let mut taken = 0;
    for _ in 0..frames {
        let frame = host.world.frame();
        let json = match frame % 97 {
            13 => Some(r#"{"do":"agitate","strength":3}"#),
            50 => Some(r#"{"do":"spawn_particles","preset":"fire","at":[0,12],"count":20}"#),
            _ => None,
        };
        if let Some(json) = json {
            let cmd = command(json);
            let id = format!("c{frame}");
            journal
                .before(Intent::Apply(&cmd), frame, &sender, &Some(id.clone()))
                .unwrap();
            let mut handled = host.handle(&cmd);
            handled.reply.id = Some(id.clone());
            journal.replied(&handled.reply);
            answered.remember(sender.clone(), id, Answer::new(&handled.reply, 0));
        }
        host.advance();
        journal.stepped(host.world.frame(), f64::from(host.stepping.last_step_ms));
        if journal.checkpoint_due() {
            journal.checkpoint(&host, &answered, "journaled", opts);
            taken += 1;
        }
        // Written while the world steps on, and switched to once whole: waited for
        // every fifth step here (the disk's speed decides nothing).
        journal.poll(frame.is_multiple_of(5));
    }
    journal.poll(true);
    (host, answered, taken)
}

#[test]
fn a_journal_starts_again_from_each_checkpoint_and_resumes_to_the_same_bits() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("world.journal");
    let policy = Checkpoints {
        journal_bytes: 4096,
        replay_ms: f64::INFINITY,
    };
    let opts = options(policy);
    let (mut host, _, taken) = run(&path, &opts, 600);
    assert!(taken >= 3, "{taken} checkpoints");
    // The journal holds what followed the last checkpoint: within its bound, plus a
    // line.
    let size = std::fs::metadata(&path).unwrap().len();
    assert!(size <= policy.journal_bytes + 1024, "{size} bytes");
    // One checkpoint beside it: the ones before were removed.
    let files: Vec<String> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".checkpoint"))
        .collect();
    assert_eq!(files.len(), 1, "{files:?}");
    // What a kill in the middle of a switch leaves is removed by a resume; other
    // files are not.
    for stray in [
        "world.journal.5.checkpoint",
        "world.journal.7.checkpoint.tmp",
        "world.journal.notes",
    ] {
        std::fs::write(dir.path().join(stray), b"x").unwrap();
    }
    let mut resumed = resume(&path, &opts).unwrap();
    let left: Vec<String> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert!(
        left.contains(&files[0]) && left.contains(&"world.journal.notes".to_string()),
        "{left:?}"
    );
    assert!(
        !left
            .iter()
            .any(|n| n == "world.journal.5.checkpoint" || n == "world.journal.7.checkpoint.tmp"),
        "{left:?}"
    );
    assert_eq!(resumed.host.world.frame(), host.world.frame());
    assert_eq!(bits(&resumed.host.world), bits(&host.world));
    assert_eq!(resumed.host.stepping.steps_run, host.stepping.steps_run);
    // And on: the same steps give the same bits.
    for _ in 0..120 {
        host.advance();
        resumed.host.advance();
    }
    assert_eq!(bits(&resumed.host.world), bits(&host.world));
}

/// Saves, restores and rewinds journaled across checkpoints: the resumed host has the
/// live one's world, saves, history and hashes, and travels as it does.
#[test]
fn time_travel_resumes_across_checkpoints_as_it_ran() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("world.journal");
    let opts = HostOptions {
        travel: crate::host::travel::TravelLimits {
            history_every: 20,
            ..Default::default()
        },
        ..options(Checkpoints {
            journal_bytes: 4096,
            replay_ms: f64::INFINITY,
        })
    };
    let scene = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../assets/scenes/pyramid-10.toml"
    );
    let text = std::fs::read_to_string(scene).unwrap();
    let mut host = Hosted::load(text, PathBuf::from(scene), &opts).unwrap();
    let mut journal = Journal::create(&path, "journaled", &host, &opts).unwrap();
    let answered = Answered::default();
    let mut taken = 0;
    let mut travelled = 0;
    for i in 0..500u64 {
        let frame = host.world.frame();
        let json = match i % 61 {
            5 => Some(r#"{"do":"agitate","strength":3}"#.to_string()),
            10 => Some(format!(r#"{{"do":"save","name":"s{}"}}"#, i % 3)),
            30 => Some(format!(
                r#"{{"do":"rewind","frame":{}}}"#,
                frame.saturating_sub(13)
            )),
            45 => Some(format!(r#"{{"do":"restore","name":"s{}"}}"#, (i + 1) % 3)),
            _ => None,
        };
        if let Some(json) = json {
            let cmd = command(&json);
            journal
                .before(Intent::Apply(&cmd), frame, &None, &None)
                .unwrap();
            let handled = host.handle(&cmd);
            travelled += usize::from(handled.reply.ok && !json.contains("agitate"));
        }
        host.advance();
        journal.stepped(host.world.frame(), f64::from(host.stepping.last_step_ms));
        if journal.checkpoint_due() {
            journal.checkpoint(&host, &answered, "journaled", &opts);
            taken += 1;
        }
        journal.poll(i.is_multiple_of(5));
    }
    journal.poll(true);
    assert!(taken >= 2, "{taken} checkpoints");
    assert!(travelled >= 12, "{travelled} saves, rewinds and restores");
    let mut resumed = resume(&path, &opts).unwrap().host;
    assert_eq!(resumed.world.frame(), host.world.frame());
    assert_eq!(bits(&resumed.world), bits(&host.world));
    assert_eq!(resumed.travel.saves(), host.travel.saves());
    assert_eq!(resumed.travel.rewinds_to(), host.travel.rewinds_to());
    assert_eq!(
        resumed.travel.hashes(None, None),
        host.travel.hashes(None, None)
    );
    // And they travel alike.
    let back = host.travel.rewinds_to().unwrap() + 3;
    for json in [
        format!(r#"{{"do":"rewind","frame":{back}}}"#),
        r#"{"do":"restore","name":"s1"}"#.to_string(),
    ] {
        let cmd = command(&json);
        let (a, b) = (host.handle(&cmd), resumed.handle(&cmd));
        assert!(a.reply.ok, "{json}: {:?}", a.reply.error);
        assert_eq!((a.reply.frame, a.reply.hash), (b.reply.frame, b.reply.hash));
        for _ in 0..30 {
            host.advance();
            resumed.advance();
        }
        assert_eq!(bits(&resumed.world), bits(&host.world));
    }
}

#[test]
fn answers_remembered_at_a_checkpoint_are_remembered_after_a_resume() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("world.journal");
    // A checkpoint once the steps since the last one took any time at all: after
    // every step.
    let opts = options(Checkpoints {
        journal_bytes: 1 << 30,
        replay_ms: 1e-9,
    });
    let (host, answered, taken) = run(&path, &opts, 200);
    assert!(taken >= 30, "{taken}");
    let resumed = resume(&path, &opts).unwrap();
    assert_eq!(bits(&resumed.host.world), bits(&host.world));
    let sender: Sender = Some("peer".into());
    for id in ["c13", "c50", "c110", "c147"] {
        let before = answered.get(&sender, id).expect("answered live");
        let after = resumed
            .answered
            .get(&sender, id)
            .expect("remembered after the resume");
        assert_eq!(before.reply, after.reply, "{id}");
    }
    assert!(resumed.answered.get(&None, "c13").is_none(), "per sender");
}

#[test]
fn a_checkpoint_changed_or_named_outside_the_journals_directory_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("world.journal");
    let opts = options(Checkpoints {
        journal_bytes: 4096,
        replay_ms: f64::INFINITY,
    });
    run(&path, &opts, 300);
    let text = std::fs::read_to_string(&path).unwrap();
    let second = text.lines().nth(1).unwrap();
    let reference = match serde_json::from_str::<Line>(super::super::text_of(second).unwrap()) {
        Ok(Line::Checkpoint { checkpoint }) => checkpoint,
        _ => panic!("no checkpoint line: {second}"),
    };
    let refusal = |opts: &HostOptions| format!("{:#}", resume(&path, opts).err().expect("refused"));
    // A byte of the checkpoint changed.
    let file = dir.path().join(&reference.file);
    let good = std::fs::read(&file).unwrap();
    let mut bad = good.clone();
    let mid = bad.len() / 2;
    bad[mid] ^= 0x40;
    std::fs::write(&file, &bad).unwrap();
    let e = refusal(&opts);
    assert!(e.contains("line 2") && e.contains("checksum"), "{e}");
    std::fs::write(&file, &good).unwrap();
    // A checkpoint named by a path (the line signed again, as an edit would): never read.
    for name in ["../world.journal.0.checkpoint", "/etc/passwd", ".."] {
        let moved = CheckpointRef {
            file: name.to_string(),
            ..reference.clone()
        };
        let line = serde_json::to_string(&Line::Checkpoint { checkpoint: moved }).unwrap();
        let changed: String = text
            .lines()
            .enumerate()
            .map(|(k, l)| if k == 1 { signed(&line) } else { l.to_string() } + "\n")
            .collect();
        std::fs::write(&path, changed).unwrap();
        let e = refusal(&opts);
        assert!(e.contains("must be a file name"), "{name}: {e}");
    }
    // Missing: named.
    std::fs::write(&path, &text).unwrap();
    std::fs::remove_file(&file).unwrap();
    let e = refusal(&opts);
    assert!(e.contains("cannot read the checkpoint"), "{e}");
}

/// A journal of the pyramid that starts from a checkpoint, and the checkpoint's
/// line.
fn checkpointed(dir: &Path) -> (PathBuf, CheckpointRef, HostOptions) {
    let path = dir.join("world.journal");
    let opts = options(Checkpoints {
        journal_bytes: 4096,
        replay_ms: f64::INFINITY,
    });
    run(&path, &opts, 300);
    let text = std::fs::read_to_string(&path).unwrap();
    let second = text.lines().nth(1).unwrap();
    match serde_json::from_str::<Line>(super::super::text_of(second).unwrap()) {
        Ok(Line::Checkpoint { checkpoint }) => (path, checkpoint, opts),
        _ => panic!("no checkpoint line: {second}"),
    }
}

/// Makes the journal at `path` name `reference` (its line signed again, as an
/// attacker who can write the journal would).
fn renamed(path: &Path, reference: &CheckpointRef) {
    let text = std::fs::read_to_string(path).unwrap();
    let line = serde_json::to_string(&Line::Checkpoint {
        checkpoint: reference.clone(),
    })
    .unwrap();
    let changed: String = text
        .lines()
        .enumerate()
        .map(|(k, l)| if k == 1 { signed(&line) } else { l.to_string() } + "\n")
        .collect();
    std::fs::write(path, changed).unwrap();
}

/// The refusal of a resume, run on a thread of its own: a resume that has not
/// answered in 10 s hangs, and fails the test.
fn refused_in_time(path: &Path, opts: &HostOptions) -> String {
    let (path, opts) = (path.to_path_buf(), opts.clone());
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let _ = tx.send(resume(&path, &opts).err().map(|e| format!("{e:#}")));
    });
    rx.recv_timeout(std::time::Duration::from_secs(10))
        .expect("the resume answers, refused or not")
        .expect("refused")
}

/// The checkpoint's world rewritten by `change` (as CBOR), signed again by the
/// engine's CRC, the file's size and CRC written again into the journal: what passes
/// every checksum.
fn crafted(path: &Path, reference: &CheckpointRef, change: impl FnOnce(&mut ciborium::Value)) {
    let file = path.parent().unwrap().join(&reference.file);
    let bytes = std::fs::read(&file).unwrap();
    let mut state: State = ciborium::from_reader(&bytes[4..]).unwrap();
    let mut world: ciborium::Value = ciborium::from_reader(&state.world[8..]).unwrap();
    change(&mut world);
    let mut body = Vec::new();
    ciborium::into_writer(&world, &mut body).unwrap();
    let mut saved = state.world[..4].to_vec();
    saved.extend_from_slice(&crc32fast::hash(&body).to_le_bytes());
    saved.extend_from_slice(&body);
    state.world = saved;
    let mut out = MAGIC.to_vec();
    out.push(FILE_VERSION);
    ciborium::into_writer(&state, &mut out).unwrap();
    std::fs::write(&file, &out).unwrap();
    renamed(
        path,
        &CheckpointRef {
            bytes: out.len() as u64,
            crc: format!("{:08x}", crc32fast::hash(&out)),
            ..reference.clone()
        },
    );
}

/// The entry `key` of a CBOR map.
fn entry<'a>(value: &'a mut ciborium::Value, key: &str) -> &'a mut ciborium::Value {
    value
        .as_map_mut()
        .unwrap()
        .iter_mut()
        .find(|(k, _)| k.as_text() == Some(key))
        .map(|(_, v)| v)
        .unwrap_or_else(|| panic!("no `{key}`"))
}

#[test]
fn a_checkpoint_that_is_a_device_or_a_fifo_is_refused_without_reading_or_waiting() {
    let dir = tempfile::tempdir().unwrap();
    let (path, reference, opts) = checkpointed(dir.path());
    let file = dir.path().join(&reference.file);
    // A link to /dev/zero was read until 1 GiB.
    std::fs::remove_file(&file).unwrap();
    std::os::unix::fs::symlink("/dev/zero", &file).unwrap();
    let e = refused_in_time(&path, &opts);
    assert!(e.contains("a device") && e.contains(&reference.file), "{e}");
    // A FIFO with no writer hung the resume.
    std::fs::remove_file(&file).unwrap();
    let c = std::ffi::CString::new(file.to_str().unwrap()).unwrap();
    assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
    let e = refused_in_time(&path, &opts);
    assert!(e.contains("a FIFO") && e.contains(&reference.file), "{e}");
}

#[test]
fn a_crafted_checkpoint_is_refused_naming_its_file_and_field() {
    use ciborium::Value;
    let dir = tempfile::tempdir().unwrap();
    let (path, reference, opts) = checkpointed(dir.path());
    let file = dir.path().join(&reference.file);
    let good = std::fs::read(&file).unwrap();
    let journal = std::fs::read(&path).unwrap();
    let cases: Vec<(&str, Change)> = vec![
        // Panicked in Duration arithmetic.
        (
            "`config`",
            Box::new(|w| *entry(entry(w, "config"), "dt") = Value::Float(1e300)),
        ),
        // Panicked in the integrator.
        (
            "`movers`",
            Box::new(|w| {
                entry(w, "movers")
                    .as_array_mut()
                    .unwrap()
                    .push(Value::Integer(4_000_000.into()))
            }),
        ),
        // Served, with non-finite numbers in every frame.
        (
            "`bodies[1].pos`",
            Box::new(|w| {
                let body = &mut entry(w, "bodies").as_array_mut().unwrap()[1];
                entry(body, "pos").as_array_mut().unwrap()[0] = Value::Float(f64::NAN)
            }),
        ),
    ];
    for (field, change) in cases {
        std::fs::write(&file, &good).unwrap();
        std::fs::write(&path, &journal).unwrap();
        crafted(&path, &reference, change);
        let e = refused_in_time(&path, &opts);
        assert!(
            e.contains(field) && e.contains(&reference.file),
            "{field}: {e}"
        );
    }
    // 56 bodies under --limit bodies=10 (the journal's header lowered to it and
    // signed again): served, before.
    std::fs::write(&file, &good).unwrap();
    let lowered: String = String::from_utf8(journal)
        .unwrap()
        .lines()
        .enumerate()
        .map(|(k, l)| {
            if k == 0 {
                let text = super::super::text_of(l).unwrap();
                signed(&text.replacen("bodies = 100000", "bodies = 10", 1))
            } else {
                l.to_string()
            }
        } + "\n")
        .collect();
    assert!(
        lowered.contains("bodies = 10\\n"),
        "the header's limits as TOML"
    );
    std::fs::write(&path, lowered).unwrap();
    let strict = HostOptions {
        limits: opts.limits.with(&["bodies=10".into()]).unwrap(),
        ..opts.clone()
    };
    let e = refused_in_time(&path, &strict);
    assert!(e.contains("`bodies`") && e.contains("limit of 10"), "{e}");
}
