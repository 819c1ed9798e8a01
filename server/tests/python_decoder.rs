//! The Python client's frame decoder (`assets/scripts/ricochet_client.py`), a second
//! reader of the layout written from its documentation, decodes what the Rust encoder
//! writes to the same state, bit for bit: every body's position and velocity (which the
//! receiver predicts frame by frame between records) and every particle's position, at
//! every frame, from the first key frame and from a resync key frame taken mid-run. The
//! `ricochet` package's numpy decoder (`python/src/ricochet/decode.py`, `decode --numpy`)
//! is held to the same, with key frames read by numpy alone and by the Rust decoder's
//! module (`python/native`, which `.ci/install` installs).

use std::io::Write;
use std::path::Path;
use std::process::Command;

use ricochet_engine::scene;
use ricochet_protocol::frame::FrameDecoder;
use ricochet_protocol::frame::FrameEncoder;
use ricochet_server::wire::{encode_frame, statics_snapshot};

#[path = "../../tests/common/python.rs"]
mod python;

fn root() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
}

/// What `ricochet_client.py decode` prints of each frame, as the Rust decoder holds it.
fn view(d: &FrameDecoder) -> serde_json::Value {
    let bodies: Vec<_> = d
        .bodies
        .iter()
        .map(|b| {
            serde_json::json!({"id": b.id, "x": b.pos()[0], "y": b.pos()[1],
                "vx": b.vel()[0], "vy": b.vel()[1], "collided": b.collided})
        })
        .collect();
    let particles: Vec<_> = d.particles.iter().map(|p| p.pos()).collect();
    serde_json::json!({"frame": d.frame, "bodies": bodies, "particles": particles})
}

/// Which of the package's readings decodes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Reader {
    /// `ricochet.pure`.
    Plain,
    /// The numpy decoder, key frames too.
    Numpy,
    /// The numpy decoder, key frames by `ricochet_native` (the Rust decoder's module).
    Native,
}

/// The Python decoder's frames (the plain one, or with `numpy` the package's numpy one),
/// with each particle's position as the f32 the Rust decoder gives.
fn python_views(payloads: &[Vec<u8>], reader: Reader) -> Vec<serde_json::Value> {
    let mut file = tempfile::NamedTempFile::new().unwrap();
    for p in payloads {
        file.write_all(&(p.len() as u32).to_le_bytes()).unwrap();
        file.write_all(p).unwrap();
    }
    file.flush().unwrap();
    let out = Command::new(python::python())
        .arg(root().join("assets/scripts/ricochet_client.py"))
        .args(["decode", file.path().to_str().unwrap()])
        .args((reader != Reader::Plain).then_some("--numpy"))
        // Key frames read by the Rust decoder's module (`ricochet_native`, which must be
        // installed), or by numpy alone.
        .env(
            "RICOCHET_NATIVE",
            if reader == Reader::Native { "1" } else { "0" },
        )
        .output()
        .expect("python3 runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(|l| {
            let v: serde_json::Value = serde_json::from_str(l).unwrap();
            let bodies: Vec<_> = v["bodies"]
                .as_array()
                .unwrap()
                .iter()
                .map(|b| {
                    serde_json::json!({"id": b["id"], "x": b["x"], "y": b["y"],
                        "vx": b["vx"], "vy": b["vy"], "collided": b["collided"]})
                })
                .collect();
            let particles: Vec<_> = v["particles"]
                .as_array()
                .unwrap()
                .iter()
                .map(|p| {
                    [
                        p["x"].as_f64().unwrap() as f32,
                        p["y"].as_f64().unwrap() as f32,
                    ]
                })
                .collect();
            serde_json::json!({"frame": v["frame"], "bodies": bodies, "particles": particles})
        })
        .collect()
}

/// Checks a run of `steps` steps, one frame in `stride` sent (a reduced-rate tier), a late
/// joiner resyncing at frame `resync_at` (a multiple of `stride`).
fn check(scene_file: &str, steps: u64, resync_at: u64, stride: u64) {
    let mut world = scene::load(&root().join("assets/scenes").join(scene_file)).unwrap();
    let mut encoder = FrameEncoder::new(60);
    let statics = statics_snapshot(&world);
    let mut all = vec![statics.clone(), encode_frame(&mut encoder, &world, 0.0, 0)];
    let mut late = vec![statics];
    for _ in 0..steps {
        world.step();
        if !world.frame().is_multiple_of(stride) {
            continue;
        }
        let frame = encode_frame(&mut encoder, &world, 0.0, 0);
        if world.frame() > resync_at {
            late.push(frame.clone());
        } else if world.frame() == resync_at {
            late.push(encoder.resync_frame().unwrap());
        }
        all.push(frame);
    }
    // A key frame that is not the stream's (a fresh encoder's, of the run's last state,
    // numbered ahead) in the middle of it: both decoders apply it, then drop it at the
    // next delta.
    let mut forged = all.clone();
    let at = (forged.len() / 2..forged.len())
        .find(|&k| {
            ricochet_protocol::frame::peek_header(&forged[k])
                .unwrap()
                .kind
                == ricochet_protocol::frame::KIND_DELTA
        })
        .expect("a delta frame in the second half");
    forged.insert(at, encode_frame(&mut FrameEncoder::new(60), &world, 0.0, 0));
    for (n, payloads) in [all, late, forged].into_iter().enumerate() {
        let mut rust = FrameDecoder::new();
        let mut expected = Vec::new();
        for p in &payloads {
            let header = rust.apply(p).unwrap();
            if header.kind != ricochet_protocol::frame::KIND_STATICS {
                expected.push(view(&rust));
            }
        }
        assert_eq!(rust.dropped_key_frames, u64::from(n == 2), "{scene_file}");
        for reader in [Reader::Plain, Reader::Numpy, Reader::Native] {
            let got = python_views(&payloads, reader);
            compare(scene_file, reader, &got, &expected);
        }
    }
}

/// Each Python frame against the Rust decoder's, naming the first body and particle that
/// differ.
fn compare(
    scene_file: &str,
    reader: Reader,
    got: &[serde_json::Value],
    expected: &[serde_json::Value],
) {
    assert_eq!(
        got.len(),
        expected.len(),
        "{scene_file}: frames decoded by {reader:?}"
    );
    for (g, e) in got.iter().zip(expected) {
        if g != e {
            let first = |v: &serde_json::Value, k: &str, i: usize| v[k][i].clone();
            let n = e["bodies"].as_array().unwrap().len();
            let body = (0..n).find(|&i| first(g, "bodies", i) != first(e, "bodies", i));
            let particle = (0..e["particles"].as_array().unwrap().len())
                .find(|&i| first(g, "particles", i) != first(e, "particles", i));
            panic!(
                    "{scene_file}: frame {} differs: body {body:?}: {reader:?} {} rust {}; particle {particle:?}",
                    e["frame"],
                    body.map_or(serde_json::Value::Null, |i| first(g, "bodies", i)),
                    body.map_or(serde_json::Value::Null, |i| first(e, "bodies", i)),
                );
        }
    }
}

#[test]
fn the_python_decoder_holds_the_rust_decoders_state_bit_for_bit() {
    // Bodies falling, piling and resting, with key frames every 60.
    check("suite/rain.toml", 240, 130, 1);
    // Rects and circles of every size, each moving its own way.
    check("wire/rain-irregular.toml", 150, 70, 1);
    // Particles, and bodies pushed about.
    check("emitters.toml", 240, 100, 1);
    // One frame in four: particles move four steps a frame.
    check("emitters.toml", 240, 100, 4);
}
