//! The fuzz target of the files a resume reads back: a journal that starts from a
//! checkpoint, mutated as an attacker or a damaged disk would (bytes flipped, inserted or
//! deleted; numbers of the checkpoint's CBOR or of a journal line's JSON changed, their
//! checksums made again so the decoder and the checks behind them are reached), resumed.
//! Every case must end, refused or resumed, within a bound: never a panic, a hang or a
//! read without bound. `cargo test` runs a bounded number of cases (a few seconds in
//! release); `PROPTEST_CASES=100000` runs more.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

use ciborium::Value;
use proptest::prelude::*;
use ricochet_engine::world::Limits;
use ricochet_protocol::command::Command;

use super::super::answered::{Answer, Answered};
use super::super::hosted::Hosted;
use super::super::inbox::Sender;
use super::checkpoint::Checkpoints;
use super::{resume, signed, text_of, Intent, Journal};
use crate::host::HostOptions;

/// A resume of a case takes at most this (they take milliseconds).
const BOUND: Duration = Duration::from_secs(5);

/// Tight limits, so that no mutated command makes a replay long.
fn options() -> HostOptions {
    HostOptions {
        limits: Limits {
            bodies: 500,
            particles: 5_000,
            particles_per_action: 1_000,
            emitters: 10,
            step_work: 1e6,
            ..Limits::default()
        },
        checkpoints: Checkpoints {
            journal_bytes: 4096,
            replay_ms: f64::INFINITY,
        },
        ..HostOptions::for_tests("fuzzed")
    }
}

/// The corpus: a journal of the 10-level pyramid with commands, started again from a
/// checkpoint (its text, and the checkpoint's name and bytes).
struct Corpus {
    journal: String,
    checkpoint: String,
    bytes: Vec<u8>,
}

fn corpus() -> &'static Corpus {
    static CORPUS: OnceLock<Corpus> = OnceLock::new();
    CORPUS.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("world.journal");
        let opts = options();
        let scene = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../assets/scenes/pyramid-10.toml"
        );
        let text = std::fs::read_to_string(scene).unwrap();
        let mut host = Hosted::load(text, PathBuf::from(scene), &opts).unwrap();
        let mut journal = Journal::create(&path, "fuzzed", &host, &opts).unwrap();
        let mut answered = Answered::default();
        let sender: Sender = Some("peer".into());
        for k in 0..240u64 {
            let frame = host.world.frame();
            let json = match k % 40 {
                5 => Some(r#"{"do":"agitate","strength":3}"#),
                15 => Some(r#"{"do":"spawn_particles","preset":"fire","at":[0,12],"count":30}"#),
                25 => Some(r#"{"do":"start_emitter","preset":"fire","at":[2,12],"count":40}"#),
                35 => Some(r#"{"do":"set","name":"gravity","value":[0,-12]}"#),
                _ => None,
            };
            if let Some(json) = json {
                let command = Command::parse(json.as_bytes()).unwrap();
                let id = format!("c{k}");
                journal
                    .before(Intent::Apply(&command), frame, &sender, &Some(id.clone()))
                    .unwrap();
                let mut handled = host.handle(&command);
                handled.reply.id = Some(id.clone());
                journal.replied(&handled.reply);
                answered.remember(sender.clone(), id, Answer::new(&handled.reply, 0));
            }
            host.advance();
            journal.stepped(host.world.frame(), 0.1);
            if journal.checkpoint_due() {
                journal.checkpoint(&host, &answered, "fuzzed", &opts);
            }
            journal.poll(true);
        }
        drop(journal);
        let text = std::fs::read_to_string(&path).unwrap();
        let second = text_of(text.lines().nth(1).unwrap()).unwrap().to_string();
        let value: serde_json::Value = serde_json::from_str(&second).unwrap();
        let checkpoint = value["checkpoint"]["file"]
            .as_str()
            .expect("the corpus starts from a checkpoint")
            .to_string();
        let bytes = std::fs::read(dir.path().join(&checkpoint)).unwrap();
        assert!(text.lines().count() > 20, "lines after the checkpoint");
        Corpus {
            journal: text,
            checkpoint,
            bytes,
        }
    })
}

/// A value to put in place of a number: the edges of every range a field may have.
fn extreme(pick: usize, old: &Value) -> Value {
    let old = match old {
        Value::Integer(i) => i128::from(*i) as f64,
        Value::Float(f) => *f,
        _ => 0.0,
    };
    let float = [
        f64::NAN,
        f64::INFINITY,
        f64::NEG_INFINITY,
        1e300,
        -1e300,
        0.0,
        -old,
        old * 1e6,
        old + 1.0,
        f64::MIN_POSITIVE,
    ];
    let int: [i128; 8] = [
        -1,
        0,
        1 << 31,
        u32::MAX as i128,
        u32::MAX as i128 + 1,
        u64::MAX as i128,
        i64::MIN as i128,
        old as i128 + 1,
    ];
    if pick < float.len() {
        Value::Float(float[pick])
    } else {
        let i = int[(pick - float.len()) % int.len()];
        Value::Integer(i.try_into().unwrap_or(0.into()))
    }
}

/// The `n`th number (integer or float) of `value`, depth first, if it has that many.
fn nth_number<'a>(value: &'a mut Value, n: &mut usize) -> Option<&'a mut Value> {
    match value {
        Value::Integer(_) | Value::Float(_) => {
            if *n == 0 {
                return Some(value);
            }
            *n -= 1;
            None
        }
        Value::Array(items) => items.iter_mut().find_map(|v| nth_number(v, n)),
        Value::Map(entries) => entries.iter_mut().find_map(|(_, v)| nth_number(v, n)),
        Value::Tag(_, inner) => nth_number(inner, n),
        _ => None,
    }
}

fn count_numbers(value: &Value) -> usize {
    match value {
        Value::Integer(_) | Value::Float(_) => 1,
        Value::Array(items) => items.iter().map(count_numbers).sum(),
        Value::Map(entries) => entries.iter().map(|(_, v)| count_numbers(v)).sum(),
        Value::Tag(_, inner) => count_numbers(inner),
        _ => 0,
    }
}

/// `bytes` with a byte flipped, bytes inserted or a run deleted at `at`.
fn damaged(mut bytes: Vec<u8>, how: usize, at: usize, junk: &[u8]) -> Vec<u8> {
    if bytes.is_empty() {
        return junk.to_vec();
    }
    let at = at % bytes.len();
    match how % 3 {
        0 => bytes[at] ^= junk[0] | 1,
        1 => {
            bytes.splice(at..at, junk.iter().copied());
        }
        _ => {
            let end = (at + junk.len()).min(bytes.len());
            bytes.drain(at..end);
        }
    }
    bytes
}

/// A checkpoint file whose engine world (CBOR) was changed by `change`, with both its
/// checksums made again.
fn checkpoint_with(bytes: &[u8], change: impl FnOnce(&mut Vec<u8>)) -> Vec<u8> {
    let mut state: super::checkpoint::State = ciborium::from_reader(&bytes[4..]).unwrap();
    let mut body = state.world[8..].to_vec();
    change(&mut body);
    let mut world = state.world[..4].to_vec();
    world.extend_from_slice(&crc32fast::hash(&body).to_le_bytes());
    world.extend_from_slice(&body);
    state.world = world;
    let mut out = bytes[..4].to_vec();
    ciborium::into_writer(&state, &mut out).unwrap();
    out
}

/// The corpus's journal naming a checkpoint of `bytes` (its size and CRC written again).
fn journal_naming(journal: &str, bytes: &[u8]) -> String {
    journal
        .lines()
        .enumerate()
        .map(|(k, l)| {
            if k != 1 {
                return l.to_string() + "\n";
            }
            let mut v: serde_json::Value = serde_json::from_str(text_of(l).unwrap()).unwrap();
            v["checkpoint"]["bytes"] = bytes.len().into();
            v["checkpoint"]["crc"] = format!("{:08x}", crc32fast::hash(bytes)).into();
            signed(&v.to_string()) + "\n"
        })
        .collect()
}

/// Resumes the journal at `path` on a thread of its own: it must end within [`BOUND`],
/// resumed or refused, and not panic.
fn resumes_or_refuses_in_time(path: &Path) -> Result<(), TestCaseError> {
    let path = path.to_path_buf();
    let (tx, rx) = std::sync::mpsc::channel();
    let began = Instant::now();
    std::thread::spawn(move || {
        let outcome = resume(&path, &options()).map(|r| r.host.world.frame());
        let _ = tx.send(outcome.map_err(|e| format!("{e:#}")));
    });
    match rx.recv_timeout(BOUND) {
        Ok(_) => Ok(()),
        Err(std::sync::mpsc::RecvTimeoutError::Timeout) => Err(TestCaseError::fail(format!(
            "no answer in {:?}",
            began.elapsed()
        ))),
        Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => {
            Err(TestCaseError::fail("the resume panicked"))
        }
    }
}

/// Writes a case: the journal's text and the checkpoint's bytes, in a directory of its
/// own.
fn case(journal: &[u8], checkpoint: &[u8]) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("world.journal");
    std::fs::write(&path, journal).unwrap();
    std::fs::write(dir.path().join(&corpus().checkpoint), checkpoint).unwrap();
    (dir, path)
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 96,
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    /// A number of the checkpoint's world set to an extreme, both checksums made again.
    #[test]
    fn a_checkpoint_with_a_number_changed_resumes_or_is_refused_in_time(
        n in any::<usize>(),
        pick in 0usize..18,
    ) {
        let c = corpus();
        let bytes = checkpoint_with(&c.bytes, |body| {
            let mut world: Value = ciborium::from_reader(&body[..]).unwrap();
            let mut k = n % count_numbers(&world);
            if let Some(v) = nth_number(&mut world, &mut k) {
                *v = extreme(pick, v);
            }
            body.clear();
            ciborium::into_writer(&world, &mut *body).unwrap();
        });
        let (_dir, path) = case(journal_naming(&c.journal, &bytes).as_bytes(), &bytes);
        resumes_or_refuses_in_time(&path)?;
    }

    /// The checkpoint's CBOR with bytes flipped, inserted or deleted, both checksums made
    /// again: the decoder reads what no encoder wrote.
    #[test]
    fn a_checkpoint_with_bytes_damaged_resumes_or_is_refused_in_time(
        how in 0usize..3,
        at in any::<usize>(),
        junk in proptest::collection::vec(any::<u8>(), 1..9),
    ) {
        let c = corpus();
        let bytes = checkpoint_with(&c.bytes, |body| {
            *body = damaged(std::mem::take(body), how, at, &junk);
        });
        let (_dir, path) = case(journal_naming(&c.journal, &bytes).as_bytes(), &bytes);
        resumes_or_refuses_in_time(&path)?;
    }

    /// A number of a journal line (the header's, a command's, a frame's) set to an
    /// extreme, the line signed again.
    #[test]
    fn a_journal_line_with_a_number_changed_resumes_or_is_refused_in_time(
        line in any::<usize>(),
        n in any::<usize>(),
        pick in 0usize..18,
    ) {
        let c = corpus();
        let lines: Vec<&str> = c.journal.lines().collect();
        let k = line % lines.len();
        let mut value: serde_json::Value = serde_json::from_str(text_of(lines[k]).unwrap()).unwrap();
        let numbers = json_numbers(&value);
        if numbers > 0 {
            let mut left = n % numbers;
            set_json_number(&mut value, &mut left, pick);
        }
        let text: String = lines
            .iter()
            .enumerate()
            .map(|(j, l)| if j == k { signed(&value.to_string()) } else { l.to_string() } + "\n")
            .collect();
        let (_dir, path) = case(text.as_bytes(), &c.bytes);
        resumes_or_refuses_in_time(&path)?;
    }

    /// The journal's bytes flipped, inserted or deleted (not signed again: the checksums
    /// and the torn-line rule are what is tried).
    #[test]
    fn a_journal_with_bytes_damaged_resumes_or_is_refused_in_time(
        how in 0usize..3,
        at in any::<usize>(),
        junk in proptest::collection::vec(any::<u8>(), 1..9),
    ) {
        let c = corpus();
        let text = damaged(c.journal.as_bytes().to_vec(), how, at, &junk);
        let (_dir, path) = case(&text, &c.bytes);
        resumes_or_refuses_in_time(&path)?;
    }
}

fn json_numbers(value: &serde_json::Value) -> usize {
    match value {
        serde_json::Value::Number(_) => 1,
        serde_json::Value::Array(items) => items.iter().map(json_numbers).sum(),
        serde_json::Value::Object(map) => map.values().map(json_numbers).sum(),
        _ => 0,
    }
}

/// Sets the `n`th number of `value` to an extreme JSON can spell (no NaN in JSON: its
/// largest, smallest and negative numbers instead).
fn set_json_number(value: &mut serde_json::Value, n: &mut usize, pick: usize) -> bool {
    match value {
        serde_json::Value::Number(old) => {
            if *n > 0 {
                *n -= 1;
                return false;
            }
            let old = old.as_f64().unwrap_or(0.0);
            let choices: [serde_json::Value; 18] = [
                (-1).into(),
                0.into(),
                u32::MAX.into(),
                (u64::from(u32::MAX) + 1).into(),
                u64::MAX.into(),
                i64::MIN.into(),
                1e300.into(),
                (-1e300).into(),
                (old + 1.0).into(),
                (old * 1e6).into(),
                (-old).into(),
                0.5.into(),
                1e-300.into(),
                (1u64 << 53).into(),
                100_000.into(),
                10_000.into(),
                65_536.into(),
                f64::MAX.into(),
            ];
            *value = choices[pick % choices.len()].clone();
            true
        }
        serde_json::Value::Array(items) => items.iter_mut().any(|v| set_json_number(v, n, pick)),
        serde_json::Value::Object(map) => map.values_mut().any(|v| set_json_number(v, n, pick)),
        _ => false,
    }
}
