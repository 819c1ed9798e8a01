//! Micro-benchmarks of the frame codec (divan): `cargo bench -p ricochet-lab --bench decode`.
//!
//! What a viewer pays per frame: decoding a run of frames of a shipped scene, deltas
//! between key frames every 60, as the server sends them.

use std::path::Path;

use ricochet_engine::scene;
use ricochet_protocol::frame::{FrameDecoder, FrameEncoder};
use ricochet_server::wire::encode_frame;

fn main() {
    divan::main();
}

/// The frames of 120 steps of a shipped scene, after its first second.
fn frames(name: &str) -> Vec<Vec<u8>> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../assets/scenes")
        .join(name);
    let text = std::fs::read_to_string(&path).expect("a shipped scene");
    let mut world = scene::parse(&text, &path, &[]).expect("the scene loads");
    for _ in 0..60 {
        world.step();
    }
    let mut encoder = FrameEncoder::new(60);
    encoder.force_key_frame();
    (0..120)
        .map(|_| {
            world.step();
            encode_frame(&mut encoder, &world, 0.0, 0)
        })
        .collect()
}

/// Decoding 120 frames (two key frames, the rest deltas), per frame.
#[divan::bench(args = ["pyramid-100.toml", "particles-10k.toml", "emitters.toml"])]
fn decode(bencher: divan::Bencher, scene: &str) {
    let frames = frames(scene);
    bencher
        .counter(divan::counter::ItemsCount::new(frames.len()))
        .bench(|| {
            let mut decoder = FrameDecoder::new();
            for f in &frames {
                decoder.apply(f).expect("the server's own frames decode");
            }
            decoder.frame
        });
}
