//! End to end: the `ricochet-server simulate` contract, through the real binary.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use ricochet_protocol::dump::{read_dump, FrameRecord};

/// The server binary (Cargo builds it for this package's tests).
fn server_bin() -> PathBuf {
    PathBuf::from(env!("CARGO_BIN_EXE_ricochet-server"))
}

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn scene(name: &str) -> PathBuf {
    root().join("assets/scenes").join(name)
}

/// A fresh directory, removed with everything in it when dropped.
fn temp_dir() -> tempfile::TempDir {
    tempfile::tempdir().expect("a temporary directory")
}

fn simulate(args: &[&str]) -> Output {
    Command::new(server_bin())
        .arg("simulate")
        .args(args)
        .env("RUST_LOG", "warn")
        .output()
        .expect("ricochet-server starts")
}

fn simulate_ok(args: &[&str]) -> Output {
    let out = simulate(args);
    assert!(
        out.status.success(),
        "ricochet-server simulate {args:?} failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

fn dump_of(
    scene_name: &str,
    steps: u64,
    extra: &[&str],
    file: &str,
) -> (Vec<u8>, Vec<FrameRecord>) {
    let dir = temp_dir();
    let path = dir.path().join(file);
    let scene_path = scene(scene_name);
    let steps = steps.to_string();
    let mut args = vec![
        "--scene",
        scene_path.to_str().unwrap(),
        "--steps",
        &steps,
        "--dump",
        path.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    simulate_ok(&args);
    let bytes = std::fs::read(&path).unwrap();
    let frames = read_dump(std::str::from_utf8(&bytes).unwrap()).unwrap();
    (bytes, frames)
}

#[test]
fn a_dump_has_one_line_per_state_from_frame_zero() {
    let (_, frames) = dump_of("emitters.toml", 90, &[], "lines.jsonl");
    assert_eq!(frames.len(), 91);
    for (k, f) in frames.iter().enumerate() {
        assert_eq!(f.frame, k as u64);
        assert!(
            (f.t - k as f64 / 60.0).abs() < 1e-6,
            "t {} at frame {k}",
            f.t
        );
    }
    // Scene ids and generated ids: [[body]] tables first, then generators, in file order.
    let first = &frames[0];
    assert_eq!(first.bodies[0].id, "minion/0");
    assert!(
        first.body("hero").is_some()
            && first.body("floor/8").is_some()
            && first.body("row3/1").is_some()
    );
    assert_eq!(first.emitters, 1);
    assert!(first.particles.is_empty());
    // The emitter releases fire particles: red at birth.
    let lit = &frames[1].particles;
    assert!(!lit.is_empty());
    assert!(lit.iter().all(|p| p.color == [1.0, 0.0, 0.0, 1.0]));
    // The hero falls, lands and is flagged collided.
    let hero_y: Vec<f64> = frames.iter().map(|f| f.body("hero").unwrap().y).collect();
    assert!(hero_y[60] < hero_y[0]);
    assert!(frames.iter().any(|f| f.body("hero").unwrap().collided));
}

#[test]
fn the_same_scene_and_seed_give_the_same_dump_bit_for_bit() {
    let (a, _) = dump_of("emitters.toml", 240, &["--seed", "7"], "det-a.jsonl");
    let (b, _) = dump_of("emitters.toml", 240, &["--seed", "7"], "det-b.jsonl");
    assert!(a == b, "two runs of the same scene and seed differ");
    let (c, _) = dump_of("emitters.toml", 240, &["--seed", "8"], "det-c.jsonl");
    assert!(a != c, "the seed does not change the particles");
}

#[test]
fn set_overrides_a_world_field() {
    let (_, frames) = dump_of("impulse.toml", 30, &["--set", "gravity=[0,0]"], "set.jsonl");
    let hero = frames.last().unwrap().body("hero").unwrap();
    assert_eq!(
        (hero.y, hero.vy),
        (60.0, 0.0),
        "no gravity: the hero floats"
    );
}

#[test]
fn inputs_are_applied_at_their_frame_and_replay_identically() {
    let dir = temp_dir();
    let inputs = dir.path().join("inputs.jsonl");
    std::fs::write(
        &inputs,
        concat!(
            "# steer right, then fire a dye pack\n",
            "{\"frame\": 60, \"action\": {\"do\": \"press\", \"dir\": \"right\"}}\n",
            "{\"frame\": 90, \"action\": {\"do\": \"release\", \"dir\": \"right\"}}\n",
            "{\"frame\": 90, \"action\": {\"do\": \"fire_dye_pack\", \"at\": [150, 80]}}\n",
            "{\"frame\": 95, \"action\": {\"do\": \"clear\", \"group\": \"no_such_group\"}}\n",
        ),
    )
    .unwrap();
    let args = ["--inputs", inputs.to_str().unwrap()];
    let (a, frames) = dump_of("emitters.toml", 150, &args, "in-a.jsonl");
    let (b, _) = dump_of("emitters.toml", 150, &args, "in-b.jsonl");
    assert!(a == b, "replaying the same inputs differs");
    let x = |k: usize| frames[k].body("hero").unwrap().x;
    assert_eq!(x(60), x(0), "nothing pushed the hero before frame 60");
    assert!(
        x(90) > x(60) + 5.0,
        "held right for 30 frames: {} -> {}",
        x(60),
        x(90)
    );
    assert!(
        frames[91].body("dye_pack-1").is_some(),
        "the dye pack appears after frame 90"
    );
    assert!(frames[90].body("dye_pack-1").is_none());
}

#[test]
fn a_bad_scene_is_refused_with_file_line_and_field() {
    let dir = temp_dir();
    let bad = dir.path().join("bad-scene.toml");
    std::fs::write(
        &bad,
        "[world]\ndt = 0.01\n\n[[body]]\nid = \"b\"\nshape = \"circle\"\nradius = 0\n",
    )
    .unwrap();
    let out = simulate(&["--scene", bad.to_str().unwrap(), "--steps", "1"]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains(&format!("{}:7: body[0].radius", bad.display())),
        "{err}"
    );
}

#[test]
fn a_bad_input_line_is_refused_with_its_line() {
    let dir = temp_dir();
    let inputs = dir.path().join("bad-inputs.jsonl");
    std::fs::write(&inputs, "{\"frame\": 1, \"action\": {\"do\": \"press\", \"dir\": \"left\"}}\n{\"frame\": 2, \"action\": {\"do\": \"teleport\"}}\n").unwrap();
    let out = simulate(&[
        "--scene",
        scene("impulse.toml").to_str().unwrap(),
        "--steps",
        "5",
        "--inputs",
        inputs.to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("line 2: not an input line") && err.contains("teleport"),
        "{err}"
    );
}

#[test]
fn stats_has_one_line_per_step_with_the_passes_counted() {
    let dir = temp_dir();
    let stats = dir.path().join("stats.jsonl");
    simulate_ok(&[
        "--scene",
        scene("stack-20.toml").to_str().unwrap(),
        "--steps",
        "30",
        "--set",
        "solver=impulses",
        "--set",
        "substeps=2",
        "--set",
        "impulse_iterations=8",
        "--stats",
        stats.to_str().unwrap(),
    ]);
    let text = std::fs::read_to_string(&stats).unwrap();
    let lines: Vec<serde_json::Value> = text
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines.len(), 30);
    assert_eq!(lines[0]["frame"], 1);
    assert_eq!(lines[29]["frame"], 30);
    // 8 impulse iterations in each of 2 sub-steps, counted as they ran.
    assert!(lines.iter().all(|l| l["passes"] == 16), "{}", lines[0]);
    assert!(lines.iter().any(|l| l["contacts"].as_u64().unwrap() > 0));
}

/// `--steps 0` checks a scene: an interaction naming a group no body is in is refused with
/// the line, a caret and a suggestion; a scene that passes is reported group by group,
/// the groups joined only at run time named as such.
#[test]
fn steps_0_checks_the_groups_of_a_scene() {
    let dir = temp_dir();
    let typo = dir.path().join("typo.toml");
    std::fs::write(
        &typo,
        "[[body]]\nid = \"ground\"\ngroup = \"ground\"\nshape = \"rect\"\nsize = [40, 2]\nmass = 0\n\n\
         [[body]]\nid = \"ball\"\ngroup = \"ball\"\nshape = \"circle\"\nradius = 1\npos = [0, 10]\n\n\
         [[interact]]\na = \"ball\"\nb = \"grund\"\n",
    )
    .unwrap();
    let out = simulate(&["--scene", typo.to_str().unwrap(), "--steps", "0"]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    for needle in [
        "interact[0].b: no body or generator is in group `grund`",
        &format!("{}:17:5", typo.display()),
        "b = \"grund\"",
        "^^^^^^^",
        "help: did you mean `ground`?",
    ] {
        assert!(err.contains(needle), "`{needle}` missing from\n{err}");
    }
    let out = simulate_ok(&[
        "--scene",
        scene("impulse.toml").to_str().unwrap(),
        "--steps",
        "0",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("groups checked"), "{err}");
    assert!(
        err.contains("dye_packs (no body yet: joined at run time)"),
        "{err}"
    );
    assert!(err.contains("platforms (42 bodies)"), "{err}");
}
