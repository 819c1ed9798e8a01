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

#[test]
fn bench_measures_shipped_scenes_and_writes_its_csv_and_table() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("README.md"),
        "# Figures\n<!-- bench:begin -->\nold\n<!-- bench:end -->\nprose\n",
    )
    .unwrap();
    let out = Command::new(server_bin())
        .args(["bench", "--only", "platforms-10.", "--scenes"])
        .arg(root().join("assets/scenes"))
        .arg("--out")
        .arg(dir.path())
        .env("RUST_LOG", "warn")
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let csv = std::fs::read_to_string(dir.path().join("bench.csv")).unwrap();
    let rows: Vec<&str> = csv.lines().collect();
    // The header, then the scene as shipped and under each impulse setting.
    assert_eq!(rows.len(), 4, "{csv}");
    for (row, start) in rows[1..].iter().zip([
        "bench/platforms-10,shipped,,11,0,600,",
        "bench/platforms-10,relaxation,solver=relaxation,11,0,20,",
        "bench/platforms-10,\"impulses, sweep\",broad_phase=sweep,11,0,600,",
    ]) {
        assert!(row.starts_with(start), "{csv}");
    }
    let page = std::fs::read_to_string(dir.path().join("README.md")).unwrap();
    assert!(
        page.contains("| bench/platforms-10 | shipped | 11 |"),
        "{page}"
    );
    assert!(!page.contains("old") && page.ends_with("<!-- bench:end -->\nprose\n"));
}

#[test]
fn tradeoff_measures_a_scene_it_has_never_seen() {
    let dir = temp_dir();
    // A scene written here, unlike any shipped one: balls dropped on a staircase of
    // boxes, with a fire emitter over it.
    let scene = dir.path().join("stairs.toml");
    std::fs::write(
        &scene,
        r#"[world]
gravity = [0, -9.8]
mass_scaled_acceleration = false

[[generate]]
kind = "row"
id = "step"
group = "stairs"
shape = "rect"
size = [4, 1]
start = [0, 0]
step = [4, 1]
count = 6
mass = 0

[[generate]]
kind = "row"
id = "ball"
group = "balls"
shape = "circle"
radius = 0.5
start = [1, 3]
step = [3.9, 0.7]
count = 5
mass = 1
restitution = 0.4
friction = 0.3

[[emitter]]
preset = "fire"
count = 200
pos = [10, 12]

[[interact]]
a = "balls"
b = "stairs"

[[interact]]
a = "balls"
b = "balls"

[[interact]]
a = "particles"
b = "stairs"
"#,
    )
    .unwrap();
    let out_dir = dir.path().join("out");
    let run = |extra: &[&str]| {
        Command::new(server_bin())
            .args([
                "tradeoff",
                "--steps",
                "90",
                "--reference-budget",
                "60",
                "--scene",
            ])
            .arg(&scene)
            .arg("--out")
            .arg(&out_dir)
            .args(extra)
            .env("RUST_LOG", "warn")
            .output()
            .unwrap()
    };
    let out = run(&[]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let table = String::from_utf8_lossy(&out.stdout);
    assert!(
        table.contains("5 dynamic, 6 static bodies, contacts, particles"),
        "{table}"
    );
    assert!(table.contains("Reference: impulses"), "{table}");
    let csv = std::fs::read_to_string(out_dir.join("stairs.csv")).unwrap();
    let rows: Vec<&str> = csv.lines().skip(1).collect();
    assert!(rows.len() >= 10, "{csv}");
    // Every row measured: finite errors (not NaN) and particle errors, some on the front.
    for row in &rows {
        let fields: Vec<&str> = row.split(',').collect();
        // The last columns: ..., particle worst, particle RMS, nan, on_front, fails.
        let n = fields.len();
        assert_eq!(fields[n - 3], "false", "NaN in {row}");
        let particle_worst: f64 = fields[n - 5].parse().expect("a particle error");
        assert!(particle_worst.is_finite() && particle_worst >= 0.0, "{row}");
    }
    assert!(
        rows.iter()
            .any(|r| r.split(',').rev().nth(1) == Some("true")),
        "a front: {csv}"
    );
    let page = std::fs::read_to_string(out_dir.join("stairs.md")).unwrap();
    assert!(
        page.contains("| setting | mean ms/step (whole run) | median")
            && page.contains("particle error")
            && page.contains("| fails |")
    );
    let png = std::fs::read(out_dir.join("stairs.png")).unwrap();
    assert_eq!(&png[1..4], b"PNG");

    // A bad candidate is refused before anything runs, named.
    let out = run(&["--candidate", "solver=impulses;impulse_iterations=0"]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("candidate `solver=impulses, impulse_iterations=0`"),
        "{err}"
    );
    assert!(err.contains("impulse_iterations"), "{err}");
}
