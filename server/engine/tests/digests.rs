//! Every shipped scene's state over 300 steps, hashed frame by frame, against digests
//! taken before the engine was reorganised: a refactor that changes physics by accident
//! fails here. The hash covers exactly what a `--dump` line holds (body ids, positions,
//! velocities and collided flags, particle positions, sizes and colours, emitter count),
//! by bits. The chapter's demos run with a fixed input log that walks the hero, fires dye
//! packs, spawns and agitates minions and particles, so behaviours and actions are covered.
//!
//! A change that alters physics on purpose regenerates the table with
//! `RICOCHET_PRINT_DIGESTS=1 cargo test -p ricochet-engine --test digests -- --nocapture`
//! and says so in its commit.

use std::path::Path;

use ricochet_engine::world::World;
use sha2::{Digest, Sha256};

const STEPS: u64 = 300;

/// (scene, digest of its 301 states: before the first step and after each). `bounce`,
/// `projectile` and `slide` were added after the reorganisation (the trade-off report's
/// scenes, once built in code) and recorded when they were. Every scene that names no
/// solver was recorded again when the default became the suite's (impulses, 2 sub-steps
/// of 2 passes, split impulses, the resting load); the chapter's demos, which name its
/// relaxation, and the scenes whose bodies never touch kept theirs. `coincident` was
/// recorded again when adaptive passes joined the default (its coincident pair is an
/// unconverged sub-step; no other shipped scene has one). `suite/crowded-box` was
/// recorded again when contacts with walls began to push out once more after each pass.
/// `bounce`, `coincident`, `suite/bullets` and `tunnelling`, whose pairs bounce, were
/// recorded again when bouncing became a collision stage of its own (the impulse solver's
/// `collisions`). Every scene whose bodies rest on others under the default, and
/// `coincident` and `huge`, were recorded again when the support sweep
/// (`shock_propagation`) joined the default and, under gravity, a pair's contact began to
/// be kept while either body alone could close its gap within the step; `overlap-quarter`
/// when that sweep began to carry the push-out too. Every scene whose bodies come to rest
/// under the default (`coincident`, `far-from-origin`, `huge`, `mass-ratio-1000`,
/// `overlap-quarter`, `pyramid-10`, `pyramid-100`, `stack-20`, `tiny` and the suite's
/// column-60, far-pyramid, heavy-on-light, masses-doubling, overlap-third, plank,
/// pyramid-100, pyramids-small and rain) was recorded again when sleeping joined the
/// default. `coincident`, `overlap-quarter` and the suite's overlap-third and rain were
/// recorded again when a body's rest began to be judged against its recent places (not
/// its last step's); `suite/smash` when impact propagation joined the default. The suite's
/// crowded-box, overlap-third and smash were recorded again when no body could be pushed
/// out faster than one size a second, however many contacts pushed it; `suite/smash` when
/// an island that nothing holds stopped sleeping while it drifts (its slow fragments fly on).
/// `suite/crowded-box` and `suite/smash` were recorded again when contacts without gravity
/// began to push as deep as they are (`CONTACT_PUSH_OUT`), each body still held to one of
/// its sizes a second; `suite/crowded-box` when a crowd held by its container began to be
/// pushed out by the mean of its contacts' pushes (`passes::spread_push_out`).
/// `coincident`, `overlap-quarter` and the suite's crowded-box, overlap-third and smash
/// were recorded again when a contact still overlapping began to start each step from
/// half the push it ended the last with (`passes::warm_push`), and a body of less than 3
/// units could be pushed out at up to 3 units a second (3 of its sizes at most).
/// `suite/smash` was recorded again when a pair that neither gravity pulls nor can bounce
/// began to be made a contact only within the gap a resting contact holds
/// (`SPECULATIVE_GAP`) or as near as it may close within the step, not within a tenth of
/// its size. Every scene whose bodies come to rest under the default (the list above where
/// sleeping joined it, but `suite/smash`) was recorded again when a body's rest began to
/// count `sleep_delay` to within a millionth of a step (summed exactly, thirty steps of
/// 1/60 s fell short of half a second by rounding, and every island slept a step late).
/// `suite/rain` was recorded again when a contact under gravity that held its bodies and
/// was lifted just past the gap a resting contact holds began to close back to that gap
/// only, half its drift a sub-step (`prepare::DRIFT_BACK`), not to touching.
const EXPECTED: &[(&str, &str)] = &[
    (
        "bounce",
        "a50ac17a6e8e1b8c072f6c65c7606fe868f396e3e733817abea24e4e63628b4f",
    ),
    (
        "bounds",
        "afc39e69edd5de140eca525bf1f789b30bcef0b61704d5c0fb4dbe7975979dca",
    ),
    (
        "coincident",
        "4ec6cd95be2249dff152f27d0ea72d2fd18896914b4826152b2c80d82e2ea8ed",
    ),
    (
        "emitters",
        "771bcb76214bb6c9c83b3ff6a0e0b71f8751c7e5d6f58d9bfea83b02597ab6fe",
    ),
    (
        "far-from-origin",
        "189d261e60fcad48b25531635426406d2501a39b221055cea59756aba2dc0361",
    ),
    (
        "huge",
        "56384c643c8617a4b8f12487319b6c40ed672f887b5634df7248e323eac06332",
    ),
    (
        "impulse",
        "b17f6debbe0252a09e61c8700297e6ff762edc3fed470db0df82e1749fd7db85",
    ),
    (
        "mass-ratio-1000",
        "de9c713e5d22ddeac710ea66ea407ce12636d8d87913c79de6e55f84ead28528",
    ),
    (
        "overlap-quarter",
        "8f0a3b394d4b145da97afff5b76997ca4f9a205948de68b93a17ae7cb034e53c",
    ),
    (
        "particles",
        "70243678c067bbae9032b786958ced9312cc160d16098c958200de243dbfbedc",
    ),
    (
        "particles-100k",
        "611cb692f496ee98b6264b7dfff539d92f04c0d0c8e2fb4319ac32243c14ba62",
    ),
    (
        "particles-10k",
        "bf2345fac26a64857008539524425f83840438d6c042062a5e315ead47bc17b9",
    ),
    (
        "particles-idle-10k",
        "309a1af1d660985ddccc63f65bcc1d738381cfc5a0b9d2418e3e2d5cd6a8c75c",
    ),
    (
        "projectile",
        "c9c2ca54960b3a8bc7b5673d29c6b77c1111c6a447167199c53fdb9c20819e23",
    ),
    (
        "pyramid-10",
        "a50c510f4311038d09560d4bc707fed7766965d4dba40286ddebfe9a3ebf75b3",
    ),
    (
        "pyramid-100",
        "126827f7ea9fa4ee30c3821c7dcdb679eca59d77233636b14f8c051ab12ec501",
    ),
    (
        "slide",
        "a6fa1b353d9df579dd0073c946c91583bc4976842bb231a1ab624861c1eb4860",
    ),
    (
        "stack-20",
        "0a25fb0f30d3d72466b29c8c59bcce097e1fb226a6084a498576323e5b5a92b6",
    ),
    (
        "suite/bullets",
        "3f9d23054e30205f1883256c9d6ca3cc2014ac77c5ccb19b0fa5f606a6b64812",
    ),
    (
        "suite/column-60",
        "c10cde9bee1ecee82631bd9aded4508531201d5da27a13a933f6ea2045062f74",
    ),
    (
        "suite/crowded-box",
        "a6bc0513e141ff8c0e72f78658e647d8b9407bcda0a73115bfb30ac15b106b9f",
    ),
    (
        "suite/far-pyramid",
        "53198fa057b5e3317eacddf285f3c107575c6a5b8f3bd6aa056bee565c6849b4",
    ),
    (
        "suite/heavy-on-light",
        "2107accbf2d8866cad1fedff43599f7ff29607235cb8cf72dbf46679b452366f",
    ),
    (
        "suite/masses-doubling",
        "9ceb17970b817b9ce8cfbbd9b31cbbce36f9d6758138e7f3bdeb65870976a601",
    ),
    (
        "suite/overlap-third",
        "101603a451a0e20e9a63d02104d1e7fa5cc10c9367860c3a5da7611cbcda5013",
    ),
    (
        "suite/plank",
        "560165d8d2a3763ae996b42ea1059acb37a474d4c3acf5904b0c5474bbfe1a78",
    ),
    (
        "suite/pyramid-100",
        "126827f7ea9fa4ee30c3821c7dcdb679eca59d77233636b14f8c051ab12ec501",
    ),
    (
        "suite/pyramids-small",
        "2bd64b95e594239a167da0ac4998ad246b6e708342eff9637758efe10f574786",
    ),
    (
        "suite/rain",
        "3111fd7a5fca8ecc1491ed261ff13703a3f49489338a8191db5aeae515c5f641",
    ),
    (
        "suite/smash",
        "597c37c22a695887383ca69be074088358b438cfa7183960b63e862be4a9ba76",
    ),
    (
        "tiny",
        "c00c8f650aea6b294968b26f4db65d7c6cf4fce1e2c982dc781662b13755de4d",
    ),
    (
        "tunnelling",
        "a318709aa052dbe22ab2e4cfa75df60f394bfd02512ea9e23b470e15da5b1e27",
    ),
    (
        "zero-mass",
        "935d939cc87c56f7ed44e3c147ce5fba90a6ffbfa7809c09f71fad6bbd2d7da8",
    ),
];

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
    (
        90,
        r#"{"do":"spawn_particles","preset":"fire","at":[100,60],"count":50}"#,
    ),
    (
        95,
        r#"{"do":"start_emitter","preset":"fire","count":120,"at":[80,50]}"#,
    ),
    (
        100,
        r#"{"do":"select","at":[100,95],"group":"dumb_minions"}"#,
    ),
    (110, r#"{"do":"drag","to":[60,80]}"#),
    (111, r#"{"do":"deselect"}"#),
    (150, r#"{"do":"agitate","strength":40}"#),
    (200, r#"{"do":"press","dir":"left"}"#),
    (260, r#"{"do":"clear","group":"dumb_minions"}"#),
];

const DEMOS: &[&str] = &["bounds", "impulse", "particles", "emitters"];

fn scenes_dir() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/scenes")
}

fn hash_state(h: &mut Sha256, world: &ricochet_engine::world::World) {
    h.update(world.frame().to_le_bytes());
    h.update(world.time().to_bits().to_le_bytes());
    h.update((world.bodies().len() as u64).to_le_bytes());
    for (b, info) in world.bodies().iter().zip(world.infos()) {
        h.update((info.id.len() as u64).to_le_bytes());
        h.update(info.id.as_bytes());
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
    digest_restoring(name, &[])
}

/// The digest of a scene's run, the world replaced at the end of each frame of `restore_at`
/// by what its checkpoint restores.
fn digest_restoring(name: &str, restore_at: &[u64]) -> String {
    let path = scenes_dir().join(format!("{name}.toml"));
    let mut world = ricochet_engine::scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
    let inputs: Vec<(u64, ricochet_engine::action::Action)> = if DEMOS.contains(&name) {
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
        if restore_at.contains(&frame) {
            let limits = world.limits().clone();
            world = World::restore(&world.save(), limits).unwrap_or_else(|e| panic!("{name}: {e}"));
        }
        hash_state(&mut h, &world);
    }
    h.finalize().iter().map(|b| format!("{b:02x}")).collect()
}

/// The scenes of `assets/scenes/` and of its suite of scene kinds (as `suite/NAME`).
fn shipped_scenes() -> Vec<String> {
    let mut names = Vec::new();
    for (dir, prefix) in [("", ""), ("suite", "suite/")] {
        names.extend(
            std::fs::read_dir(scenes_dir().join(dir))
                .expect("assets/scenes")
                .filter_map(|e| {
                    let name = e.ok()?.file_name().into_string().ok()?;
                    name.strip_suffix(".toml").map(|n| format!("{prefix}{n}"))
                }),
        );
    }
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

/// A checkpoint holds everything a step reads: every shipped scene, restored from its
/// checkpoint mid-run (the demos with a body selected and dragged, particles and an
/// emitter alive, warm-started piles), steps on to the same bits as a run never
/// interrupted.
#[test]
fn every_shipped_scene_steps_on_from_a_checkpoint_to_the_same_bits() {
    let mut wrong = Vec::new();
    for name in shipped_scenes() {
        let got = digest_restoring(&name, &[0, 105, 200]);
        match EXPECTED.iter().find(|(n, _)| *n == name) {
            Some((_, want)) if *want == got => {}
            Some((_, want)) => wrong.push(format!("{name}: {got}, expected {want}")),
            None => {}
        }
    }
    assert!(
        wrong.is_empty(),
        "restored runs differ:\n{}",
        wrong.join("\n")
    );
}

fn err_under(bytes: &[u8], limits: ricochet_engine::world::Limits) -> String {
    World::restore(bytes, limits)
        .expect_err("refused")
        .to_string()
}

/// Damaged or foreign bytes are refused, naming why; never a world.
#[test]
fn a_damaged_checkpoint_is_refused() {
    let path = scenes_dir().join("stack-20.toml");
    let mut world = ricochet_engine::scene::load(&path).expect("stack-20");
    world.step_n(10);
    let limits = world.limits().clone();
    let bytes = world.save();
    let mut flipped = bytes.clone();
    let last = flipped.len() - 1;
    flipped[last] ^= 1;
    let err = |b: &[u8]| {
        World::restore(b, limits.clone())
            .expect_err("refused")
            .to_string()
    };
    assert!(err(&flipped).contains("checksum"), "{}", err(&flipped));
    assert!(err(&bytes[..5]).contains("magic"));
    assert!(err(b"not a checkpoint at all").contains("magic"));
    let mut later = bytes.clone();
    later[3] = 99;
    assert!(err(&later).contains("version 99"));
    // Version 1 kept warm starts in two places, by broad phase, and version 2 the pair
    // set's grid cells: refused, by name.
    later[3] = 1;
    assert!(err(&later).contains("version 1;"), "{}", err(&later));
    later[3] = 2;
    assert!(err(&later).contains("version 2;"), "{}", err(&later));
    // Valid checksum over bytes that are not a world.
    let mut junk = b"RCK".to_vec();
    junk.push(ricochet_engine::world::CHECKPOINT_VERSION);
    junk.extend_from_slice(&crc32fast::hash(b"junk").to_le_bytes());
    junk.extend_from_slice(b"junk");
    assert!(err(&junk).contains("unreadable"));
    // The operator's limits replace the saved ones: a world within them restores under
    // them, one over them is refused, naming the limit.
    let tight = ricochet_engine::world::Limits {
        bodies: 21,
        ..limits.clone()
    };
    let restored = World::restore(&bytes, tight.clone()).expect("restores");
    assert_eq!(restored.limits(), &tight);
    assert_eq!(restored.frame(), 10);
    let under = ricochet_engine::world::Limits {
        bodies: 5,
        ..limits.clone()
    };
    assert!(err_under(&bytes, under).contains("`bodies`"));
}
