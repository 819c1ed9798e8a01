//! Hostile bytes into every decoder: the frame and snapshot decoder and the command
//! parser never panic, never take a refused payload half-way, and never allocate more than
//! the payload can back.
//!
//! The fuzzing here is property testing (proptest, on stable Rust: a coverage-guided
//! fuzzer needs a nightly toolchain this project does not assume). Inputs are arbitrary
//! bytes, and mutations (byte flips, cuts, splices, inserted varints) of a corpus of valid
//! payloads: frames and snapshots encoded from the shipped demo as it runs, the commands in
//! `protocol/tests/corpus/commands.txt`, and for the scene parser every shipped scene. Seeds are
//! fixed so CI runs the same cases every time; a failure proptest finds is kept in
//! `proptest-regressions/` and replayed first from then on.

use std::path::Path;

use proptest::prelude::*;
use proptest::test_runner::{Config, RngSeed};
use ricochet_engine::scene;
use ricochet_protocol::command::{Command, MAX_ERROR_BYTES};
use ricochet_protocol::frame::{DecodeError, FrameDecoder, FrameEncoder};
use ricochet_server::wire::{encode_frame, statics_snapshot};

fn root() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
}

/// Valid payloads: the demo's statics snapshot and its first frames (key and delta).
fn frames() -> Vec<Vec<u8>> {
    let path = root().join("assets/scenes/emitters.toml");
    let mut world = scene::load(&path).unwrap();
    let mut encoder = FrameEncoder::new(30);
    let mut out = vec![statics_snapshot(&world)];
    for _ in 0..90 {
        world.step();
        out.push(encode_frame(&mut encoder, &world, 0.1, 0));
    }
    out
}

fn commands() -> Vec<Vec<u8>> {
    include_str!("../../protocol/tests/corpus/commands.txt")
        .lines()
        .filter(|l| !l.trim().is_empty() && !l.starts_with("//"))
        .map(|l| l.as_bytes().to_vec())
        .collect()
}

/// One way to spoil a payload.
#[derive(Clone, Debug)]
enum Mutation {
    Flip {
        at: usize,
        bits: u8,
    },
    Cut {
        at: usize,
    },
    Insert {
        at: usize,
        bytes: Vec<u8>,
    },
    Splice {
        at: usize,
        other: usize,
        from: usize,
    },
}

fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        (any::<usize>(), 1u8..=255).prop_map(|(at, bits)| Mutation::Flip { at, bits }),
        any::<usize>().prop_map(|at| Mutation::Cut { at }),
        (
            any::<usize>(),
            prop_oneof![
                // A huge varint: a count or a gap the payload cannot back.
                Just(vec![
                    0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0x01
                ]),
                Just(vec![0xff, 0xff, 0xff, 0xff, 0x0f]),
                proptest::collection::vec(any::<u8>(), 1..16),
            ]
        )
            .prop_map(|(at, bytes)| Mutation::Insert { at, bytes }),
        (any::<usize>(), any::<usize>(), any::<usize>())
            .prop_map(|(at, other, from)| Mutation::Splice { at, other, from }),
    ]
}

fn mutate(mut bytes: Vec<u8>, corpus: &[Vec<u8>], m: &Mutation) -> Vec<u8> {
    let n = bytes.len().max(1);
    match m {
        Mutation::Flip { at, bits } => {
            if !bytes.is_empty() {
                bytes[at % n] ^= bits;
            }
        }
        Mutation::Cut { at } => bytes.truncate(at % n),
        Mutation::Insert { at, bytes: b } => {
            let at = at % (bytes.len() + 1);
            bytes.splice(at..at, b.iter().copied());
        }
        Mutation::Splice { at, other, from } => {
            let other = &corpus[other % corpus.len()];
            let from = from % other.len().max(1);
            bytes.truncate(at % n);
            bytes.extend_from_slice(&other[from.min(other.len())..]);
        }
    }
    bytes
}

fn config(seed: u64, cases: u32) -> Config {
    Config {
        cases,
        rng_seed: RngSeed::Fixed(seed),
        ..Config::default()
    }
}

/// Applies `bytes`; a refusal must leave the decoder as it was, but for a delta frame out
/// of order, which says a frame was lost: then only `synced` drops, until a key frame.
fn apply_checked(decoder: &mut FrameDecoder, bytes: &[u8]) {
    let mut expected = decoder.clone();
    if let Err(e) = decoder.apply(bytes) {
        if matches!(e, DecodeError::OutOfSync { .. }) {
            expected.synced = false;
        }
        assert!(
            format!("{decoder:?}") == format!("{expected:?}"),
            "a refused payload ({e}) changed the state"
        );
    }
}

proptest! {
    #![proptest_config(config(0x51ce, 400))]

    #[test]
    fn arbitrary_bytes_never_panic_the_frame_decoder(
        bytes in proptest::collection::vec(any::<u8>(), 0..512),
        synced in any::<bool>(),
    ) {
        let corpus = frames();
        let mut decoder = FrameDecoder::new();
        if synced {
            decoder.apply(&corpus[1]).unwrap();
        }
        // With a valid header in front, the body of the payload is what gets read.
        let mut framed = corpus[2][..61.min(corpus[2].len())].to_vec();
        framed.extend_from_slice(&bytes);
        apply_checked(&mut decoder, &bytes);
        apply_checked(&mut decoder, &framed);
    }
}

proptest! {
    #![proptest_config(config(0xf7a3e, 600))]

    #[test]
    fn mutated_frames_are_refused_whole_or_applied_never_half(
        start in 0usize..60,
        mutations in proptest::collection::vec(mutation(), 1..4),
    ) {
        let corpus = frames();
        let mut decoder = FrameDecoder::new();
        decoder.apply(&corpus[0]).unwrap();
        // Follow the run up to `start`, then feed a spoiled copy of the next payload.
        for frame in &corpus[1..=start + 1] {
            decoder.apply(frame).unwrap();
        }
        let mut bytes = corpus[start + 2].clone();
        for m in &mutations {
            bytes = mutate(bytes, &corpus, m);
        }
        apply_checked(&mut decoder, &bytes);
        // Whatever happened, the decoder takes a key frame again.
        let key = corpus.iter().skip(1).step_by(30).next().unwrap();
        prop_assert!(decoder.apply(key).is_ok());
    }
}

proptest! {
    #![proptest_config(config(0xc0ffee, 800))]

    #[test]
    fn commands_parse_or_are_refused_briefly(
        pick in any::<usize>(),
        mutations in proptest::collection::vec(mutation(), 0..4),
        noise in proptest::collection::vec(any::<u8>(), 0..200),
        raw in any::<bool>(),
    ) {
        let corpus = commands();
        let mut bytes = if raw { noise } else { corpus[pick % corpus.len()].clone() };
        for m in &mutations {
            bytes = mutate(bytes, &corpus, m);
        }
        match Command::parse(&bytes) {
            Ok(command) => {
                // What parses writes back to JSON that parses to the same command.
                let again = Command::parse(command.to_json().as_bytes());
                prop_assert_eq!(again, Ok(command));
            }
            Err(e) => prop_assert!(e.len() <= MAX_ERROR_BYTES + 4, "{} bytes", e.len()),
        }
    }
}

proptest! {
    #![proptest_config(config(0x5ce7e, 300))]

    #[test]
    fn mutated_scenes_load_or_are_refused_with_a_line(
        pick in any::<usize>(),
        mutations in proptest::collection::vec(mutation(), 1..4),
    ) {
        let dir = root().join("assets/scenes");
        let mut names: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|x| x == "toml"))
            // The large scenes generate thousands of bodies: a mutation may multiply them.
            .filter(|p| std::fs::metadata(p).map(|m| m.len() < 8_000).unwrap_or(false))
            .collect();
        names.sort();
        let corpus: Vec<Vec<u8>> = names.iter().map(|p| std::fs::read(p).unwrap()).collect();
        let mut bytes = corpus[pick % corpus.len()].clone();
        for m in &mutations {
            bytes = mutate(bytes, &corpus, m);
        }
        let text = String::from_utf8_lossy(&bytes);
        // Small limits: a mutated count cannot make the test slow.
        let limits = ricochet_engine::world::Limits::default()
            .with(&["bodies=2000".into(), "particles=20000".into()])
            .unwrap();
        match scene::parse_with(&text, Path::new("fuzz.toml"), &[], &limits) {
            Ok(mut world) => {
                world.step_n(3);
                prop_assert!(world.bodies().iter().all(|b| b.pos.is_finite()));
            }
            Err(e) => {
                prop_assert_eq!(e.file.as_path(), Path::new("fuzz.toml"));
                prop_assert!(e.to_string().len() < 1000, "{}", e);
            }
        }
    }
}

#[test]
fn the_corpus_is_what_it_claims() {
    let frames = frames();
    let mut decoder = FrameDecoder::new();
    for f in &frames {
        decoder.apply(f).unwrap();
    }
    assert_eq!(decoder.frame, 90);
    let commands = commands();
    assert!(commands.len() >= 10);
    let parsed = commands
        .iter()
        .filter(|c| Command::parse(c).is_ok())
        .count();
    assert!(
        parsed >= 5 && parsed < commands.len(),
        "valid and invalid commands: {parsed}"
    );
}
