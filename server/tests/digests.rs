//! Every shipped scene's state over 300 steps, hashed frame by frame, against digests
//! taken before the engine was reorganised: a refactor that changes physics by accident
//! fails here. The hash covers exactly what a `--dump` line holds (body ids, positions,
//! velocities and collided flags, particle positions, sizes and colours, emitter count),
//! by bits. The chapter's demos run with a fixed input log that walks the hero, fires dye
//! packs, spawns and agitates minions and particles, so behaviours and actions are covered.
//!
//! A change that alters physics on purpose regenerates the table with
//! `RICOCHET_PRINT_DIGESTS=1 cargo test -p ricochet-server --test digests -- --nocapture`
//! and says so in its commit.

use std::path::Path;

use sha2::{Digest, Sha256};

const STEPS: u64 = 300;

/// (scene, digest of its 301 states: before the first step and after each).
const EXPECTED: &[(&str, &str)] = &[];

/// The chapter demos' input log: frame, action as a client sends it.
const DEMO_INPUTS: &[(u64, &str)] = &[
    (5, r#"{"do":"press","dir":"right"}"#),
    (40, r#"{"do":"release","dir":"right"}"#),
    (45, r#"{"do":"press","dir":"up"}"#),
    (55, r#"{"do":"release","dir":"up"}"#),
    (60, r#"{"do":"fire_dye_pack","at":[150,90]}"#),
    (70, r#"{"do":"fire_dye_pack","at":[60,40]}"#),
    (80, r#"{"do":"spawn_dumb_minion","at":[100,95]}"#),
    (82, r#"{"do":"spawn_dumb_minion","at":[104,95]}"#),
    (84, r#"{"do":"spawn_minion","at":[120,60]}"#),
    (90, r#"{"do":"spawn_particles","preset":"fire","at":[100,60],"count":50}"#),
    (95, r#"{"do":"start_emitter","preset":"fire","count":120,"at":[80,50]}"#),
    (100, r#"{"do":"select","at":[100,95],"group":"dumb_minions"}"#),
    (110, r#"{"do":"drag","to":[60,80]}"#),
    (111, r#"{"do":"deselect"}"#),
    (150, r#"{"do":"agitate","strength":40}"#),
    (200, r#"{"do":"press","dir":"left"}"#),
    (260, r#"{"do":"clear","group":"dumb_minions"}"#),
];

const DEMOS: &[&str] = &["bounds", "impulse", "particles", "emitters"];

fn scenes_dir() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/scenes")
}

fn hash_state(h: &mut Sha256, world: &ricochet::world::World) {
    h.update(world.frame().to_le_bytes());
    h.update(world.time().to_bits().to_le_bytes());
    h.update((world.bodies().len() as u64).to_le_bytes());
    for b in world.bodies() {
        h.update((b.id.len() as u64).to_le_bytes());
        h.update(b.id.as_bytes());
        for v in [b.pos.x, b.pos.y, b.vel.x, b.vel.y] {
            h.update(v.to_bits().to_le_bytes());
        }
        h.update([b.collided as u8]);
    }
    let p = world.particles();
    h.update((p.len() as u64).to_le_bytes());
    for i in 0..p.len() {
        for v in [p.x[i], p.y[i], p.size[i]] {
            h.update(v.to_bits().to_le_bytes());
        }
        for c in p.color_of(i).to_array() {
            h.update(c.to_bits().to_le_bytes());
        }
    }
    h.update((world.emitters().len() as u64).to_le_bytes());
}

fn digest(name: &str) -> String {
    let path = scenes_dir().join(format!("{name}.toml"));
    let mut world = ricochet::scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
    let inputs: Vec<(u64, ricochet::action::Action)> = if DEMOS.contains(&name) {
        DEMO_INPUTS
            .iter()
            .map(|(f, a)| (*f, serde_json::from_str(a).expect("a valid action")))
            .collect()
    } else {
        Vec::new()
    };
    let mut h = Sha256::new();
    hash_state(&mut h, &world);
    for frame in 0..STEPS {
        for (_, action) in inputs.iter().filter(|(f, _)| *f == frame) {
            // Refusals (no hero in a scene, nothing under the point) are part of the run.
            let _ = world.apply(action);
        }
        world.step();
        hash_state(&mut h, &world);
    }
    h.finalize().iter().map(|b| format!("{b:02x}")).collect()
}

fn shipped_scenes() -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(scenes_dir())
        .expect("assets/scenes")
        .filter_map(|e| {
            let name = e.ok()?.file_name().into_string().ok()?;
            name.strip_suffix(".toml").map(str::to_string)
        })
        .collect();
    names.sort();
    names
}

#[test]
fn every_shipped_scene_steps_to_the_same_bits_as_before() {
    let print = std::env::var_os("RICOCHET_PRINT_DIGESTS").is_some();
    let mut wrong = Vec::new();
    for name in shipped_scenes() {
        let got = digest(&name);
        if print {
            println!("    (\"{name}\", \"{got}\"),");
        }
        match EXPECTED.iter().find(|(n, _)| *n == name) {
            Some((_, want)) if *want == got => {}
            Some((_, want)) => wrong.push(format!("{name}: {got}, expected {want}")),
            None => wrong.push(format!("{name}: no digest recorded (got {got})")),
        }
    }
    assert!(wrong.is_empty(), "dumps changed:\n{}", wrong.join("\n"));
}
