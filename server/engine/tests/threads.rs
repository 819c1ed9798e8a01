//! A world stepped on several threads gives the one-thread world, bit for bit, on every
//! shipped scene: particle passes split in chunks, and the impulse solver's contacts in
//! blocks (the 100-level pyramid).

mod common;

use std::path::Path;

use common::{set, state};
use ricochet_engine::prelude::*;
use ricochet_engine::scene;

fn shipped() -> Vec<std::path::PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/scenes");
    let mut scenes = Vec::new();
    for d in [dir.clone(), dir.join("bench")] {
        for e in std::fs::read_dir(d).unwrap() {
            let p = e.unwrap().path();
            if p.extension().is_some_and(|x| x == "toml") {
                scenes.push(p);
            }
        }
    }
    scenes.sort();
    scenes
}

#[test]
fn every_shipped_scene_steps_to_the_same_bits_on_any_thread_count() {
    let scenes = shipped();
    assert!(scenes.len() > 20, "{scenes:?}");
    let mut split = 0;
    let mut blocked = 0;
    for path in scenes {
        let run = |threads: u32| {
            let mut w = scene::load(&path).unwrap();
            w.apply(&set(&format!("threads={threads}"))).unwrap();
            let mut states = Vec::new();
            for _ in 0..4 {
                w.step_n(30);
                states.push(state(&w));
            }
            let moving = w.bodies().iter().filter(|b| !b.is_static()).count();
            let rigid_split = w.config.solver == Solver::Impulses
                && ricochet_engine::dynamics::impulse::block_count(moving) > 1;
            (states, w.particles().len(), rigid_split)
        };
        let (one, particles, rigid_split) = run(1);
        for threads in [2, 8] {
            let (many, _, _) = run(threads);
            assert!(
                one == many,
                "{}: {threads} threads differ from one",
                path.display()
            );
        }
        if particles >= ricochet_engine::parallel::MIN_SPLIT {
            split += 1;
        }
        blocked += usize::from(rigid_split);
    }
    // Scenes whose particle passes were split (when the machine has two cores or more).
    if ricochet_engine::parallel::effective(2) > 1 {
        assert!(
            split >= 3,
            "only {split} scenes had particles enough to split"
        );
        // The 100-level pyramid's contacts are solved in blocks on both threads.
        assert!(blocked >= 1, "no scene's contacts were split into blocks");
    }
}

#[test]
fn a_thread_count_is_checked_like_any_setting() {
    let mut w = World::new(WorldConfig::default());
    for bad in ["threads=0", "threads=65"] {
        let e = w.apply(&set(bad)).unwrap_err().to_string();
        assert!(e.contains("threads"), "{bad}: {e}");
    }
    w.apply(&set("threads=4")).unwrap();
    assert_eq!(w.config.threads, 4);
}
