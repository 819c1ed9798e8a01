//! What a receiver holds is the world's state within the bounds the frame layout states,
//! at every frame of whole runs of the shipped demos: every dynamic body's position within
//! `POS_BOUND` of the engine's (and half a `FINE` unit, the grid receivers hold it on) and
//! its displacement over the frame within twice that, every particle's position within
//! `PARTICLE_BOUND`, and the same bodies and particles (by id) as the engine has. The receivers move bodies and particles
//! themselves between the records (frame/mod.rs); this checks that the records the
//! encoder sends are enough, against the engine's own state, frame by frame.

use std::path::Path;

use ricochet_engine::scene;
use ricochet_protocol::frame::{FrameDecoder, FrameEncoder, FINE, PARTICLE_BOUND, POS_BOUND};
use ricochet_server::wire::encode_frame_thinned;

fn root() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
}

/// Runs `scene_file` for `steps`, encoding and decoding every `stride`-th frame with one
/// particle in `stride` (as a server's reduced-rate stream sends), and returns the worst
/// distances seen (bodies' positions, their displacements, particles).
fn worst(scene_file: &str, steps: u64, stride: u64) -> (f64, f64, f64) {
    let mut world = scene::load(&root().join("assets/scenes").join(scene_file)).unwrap();
    let mut encoder = FrameEncoder::new(60);
    let mut decoder = FrameDecoder::new();
    let (mut body_off, mut disp_off, mut particle_off) = (0.0f64, 0.0f64, 0.0f64);
    // Each body's true position at the frame before, by id.
    let mut before = std::collections::HashMap::new();
    for k in 0..=steps {
        if k > 0 {
            world.step();
        }
        if !k.is_multiple_of(stride) {
            continue;
        }
        decoder
            .apply(&encode_frame_thinned(
                &mut encoder,
                &world,
                0.0,
                0,
                stride as u32,
            ))
            .unwrap();
        let dynamic: Vec<_> = world
            .bodies()
            .iter()
            .zip(world.infos())
            .filter(|(b, _)| !b.is_static())
            .collect();
        assert_eq!(
            decoder.bodies.len(),
            dynamic.len(),
            "{scene_file} frame {k}"
        );
        for (got, (b, info)) in decoder.bodies.iter().zip(&dynamic) {
            assert_eq!(got.id, info.id);
            let now = [b.pos.x, b.pos.y];
            let was: Option<[f64; 2]> = before.insert(info.id.clone(), now);
            for i in 0..2 {
                body_off = body_off.max((got.pos()[i] - now[i]).abs());
                if let Some(was) = was {
                    let d = got.d[i] as f64 * FINE;
                    disp_off = disp_off.max((d - (now[i] - was[i])).abs());
                }
            }
        }
        let p = world.particles();
        let kept: Vec<usize> = (0..p.len())
            .filter(|&j| u64::from(p.id[j]).is_multiple_of(stride))
            .collect();
        assert_eq!(
            decoder.particles.len(),
            kept.len(),
            "{scene_file} frame {k}"
        );
        for (got, &j) in decoder.particles.iter().zip(&kept) {
            assert_eq!(got.id, p.id[j]);
            particle_off = particle_off
                .max((got.pos[0] as f64 - p.x[j] as f64).abs())
                .max((got.pos[1] as f64 - p.y[j] as f64).abs());
        }
    }
    (body_off, disp_off, particle_off)
}

#[test]
fn receivers_hold_every_body_and_particle_within_the_stated_bounds() {
    for (scene_file, steps, stride) in [
        ("emitters.toml", 600, 1),
        ("particles.toml", 600, 1),
        ("particles-10k.toml", 240, 1),
        ("suite/rain.toml", 300, 1),
        ("wire/rain-irregular.toml", 300, 1),
        ("emitters.toml", 600, 4),
        ("particles-10k.toml", 240, 8),
        ("suite/rain.toml", 300, 2),
    ] {
        let (bodies, displacements, particles) = worst(scene_file, steps, stride);
        assert!(
            bodies <= POS_BOUND + FINE / 2.0,
            "{scene_file}, every {stride}: a body {bodies} units off"
        );
        assert!(
            displacements <= 2.0 * POS_BOUND + FINE,
            "{scene_file}, every {stride}: a displacement {displacements} units off"
        );
        assert!(
            particles <= PARTICLE_BOUND + 1e-6,
            "{scene_file}, every {stride}: a particle {particles} units off"
        );
    }
}
