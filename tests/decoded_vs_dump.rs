//! What a viewer decodes is what the server ran: a real server with `--dump` writes every
//! frame it publishes (the engine's own state, as `simulate --dump` does); a client joins
//! over loopback, decodes every frame, and each decoded frame is checked against the dump
//! line of the same frame, over a whole run of the particles and emitters demos: the same
//! bodies and particles, every position within the bound the frame layout states, every
//! particle's size and colour as the engine computes them from its birth record.

mod common;

use std::collections::HashMap;
use std::time::{Duration, Instant};

use common::*;
use ricochet_protocol::dump::read_dump;
use ricochet_protocol::frame::{FINE, PARTICLE_BOUND, POS_BOUND};

struct Decoded {
    bodies: Vec<(String, [f64; 2])>,
    particles: Vec<([f32; 2], f32, [f32; 4])>,
}

fn check(scene_file: &str, frames: u64) {
    let dir = temp_dir();
    let dump = dir.path().join("served.jsonl");
    let world = scene_file.trim_end_matches(".toml");
    let server = Server::start(
        scene_file,
        world,
        &["--paused", "--dump", dump.to_str().unwrap()],
    );
    let client = server.client();
    let (stream, mut decoder) = client.join(Duration::from_secs(10)).unwrap();
    resume(&client);
    let mut decoded: HashMap<u64, Decoded> = HashMap::new();
    let began = Instant::now();
    while decoder.frame < frames {
        assert!(
            began.elapsed() < Duration::from_secs(60),
            "{scene_file}: stuck at frame {}",
            decoder.frame
        );
        let Ok(Some(sample)) = stream.recv_timeout(Duration::from_millis(100)) else {
            continue;
        };
        let Ok(h) = decoder.apply(&sample.payload().to_bytes()) else {
            continue;
        };
        decoded.insert(
            h.frame,
            Decoded {
                bodies: decoder
                    .bodies
                    .iter()
                    .map(|b| (b.id.clone(), b.pos()))
                    .collect(),
                particles: decoder
                    .particles
                    .iter()
                    .map(|p| (p.pos(), p.size_at(h.frame), p.color_at(h.frame)))
                    .collect(),
            },
        );
    }
    // Every frame the server published is in the dump, flushed as it was published.
    let served = read_dump(&std::fs::read_to_string(&dump).unwrap()).unwrap();
    let mut compared = 0;
    for record in &served {
        let Some(d) = decoded.get(&record.frame) else {
            continue;
        };
        compared += 1;
        let at = format!("{scene_file} frame {}", record.frame);
        for (id, pos) in &d.bodies {
            let r = record.bodies.iter().find(|b| &b.id == id).unwrap();
            for (got, was) in pos.iter().zip([r.x, r.y]) {
                assert!(
                    (got - was).abs() <= POS_BOUND + FINE / 2.0,
                    "{at}: body {id} at {pos:?}, served at ({}, {})",
                    r.x,
                    r.y
                );
            }
        }
        assert_eq!(d.particles.len(), record.particles.len(), "{at}: particles");
        for (k, ((pos, size, color), r)) in d.particles.iter().zip(&record.particles).enumerate() {
            for (got, was) in pos.iter().zip([r.x, r.y]) {
                assert!(
                    (got - was).abs() as f64 <= PARTICLE_BOUND + 1e-6,
                    "{at}: particle {k} at {pos:?}, served at ({}, {})",
                    r.x,
                    r.y
                );
            }
            assert!(
                (size - r.size).abs() <= 1e-5 * r.size.abs().max(1.0),
                "{at}: particle {k} of size {size}, served {}",
                r.size
            );
            // Colours travel as bytes of 1/31.875: within half of that.
            for (got, was) in color.iter().zip(r.color) {
                assert!(
                    (got - was).abs() <= 0.5 / 31.875 + 1e-4,
                    "{at}: particle {k} of colour {color:?}, served {:?}",
                    r.color
                );
            }
        }
    }
    assert!(
        compared as u64 >= frames / 2,
        "{scene_file}: {compared} of {frames} frames compared"
    );
}

#[test]
fn decoded_frames_are_the_served_dump_within_the_stated_bounds() {
    check("emitters.toml", 600);
    check("particles.toml", 600);
}
