//! The lab's report commands through the real `ricochet-lab` binary: `bench` writes its
//! CSV and table, `tradeoff --scene` measures a scene written here.

mod common;

use std::process::Command;

use common::*;

#[test]
fn bench_measures_shipped_scenes_and_writes_its_csv_and_table() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("README.md"),
        "# Figures\n<!-- bench:begin -->\nold\n<!-- bench:end -->\nprose\n",
    )
    .unwrap();
    let out = Command::new(bin("ricochet-lab"))
        .args(["bench", "--only", "platforms-10.", "--scenes"])
        .arg(scene(""))
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
        Command::new(bin("ricochet-lab"))
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

#[test]
fn profile_times_every_stage_of_a_scene_and_writes_its_table() {
    let scenes = scene("");
    let text = report_page(
        "profile",
        &[
            "profile",
            "--steps",
            "30",
            "--scenes",
            &scenes,
            "--scene",
            "pyramid-10.toml",
            "--scene",
            "emitters.toml",
        ],
    );
    let row = |stage: &str| -> Vec<f64> {
        let line = text
            .lines()
            .find(|l| l.starts_with(&format!("| {stage} |")))
            .unwrap_or_else(|| panic!("no row {stage}: {text}"));
        line.split('|')
            .skip(2)
            .filter(|c| !c.trim().is_empty())
            .map(|c| c.trim().split(' ').next().unwrap().parse().unwrap())
            .collect()
    };
    let (step, passes, particles) = (
        row("whole step, mean (median)"),
        row("- velocity passes"),
        row("particles moved, emitters"),
    );
    assert_eq!(step.len(), 2, "{text}");
    // The pyramid's passes take time and it has no particles; the chapter's emitters
    // demo runs the relaxation (no passes of the impulse solver) and moves particles.
    assert!(passes[0] > 0.0 && passes[0] < step[0], "{text}");
    assert!(particles[0] == 0.0 && particles[1] > 0.0, "{text}");
    assert!(passes[1] == 0.0, "{text}");
}

#[test]
fn profile_runs_every_scene_under_the_settings_it_is_given() {
    let scenes = scene("");
    let text = report_page(
        "profile",
        &[
            "profile",
            "--steps",
            "20",
            "--scenes",
            &scenes,
            "--scene",
            "pyramid-10.toml",
            "--set",
            "solver=relaxation",
        ],
    );
    // The pyramid's own solver is the impulse solver: under the chapter's relaxation its
    // impulse passes take no time, and the page says what it ran under.
    let passes = text
        .lines()
        .find(|l| l.starts_with("| - velocity passes |"))
        .unwrap_or_else(|| panic!("no passes row: {text}"));
    assert!(passes.contains("| 0.0 (0%) |"), "{text}");
    assert!(
        text.contains("every scene under `solver=relaxation`"),
        "{text}"
    );
}

#[test]
fn tradeoff_writes_beside_the_user_not_into_docs() {
    let dir = temp_dir();
    std::fs::write(
        dir.path().join("mine.toml"),
        r#"[[body]]
id = "ground"
shape = "rect"
size = [20, 1]
pos = [0, 0]
mass = 0

[[body]]
id = "ball"
group = "balls"
shape = "circle"
radius = 0.5
pos = [0, 3]
mass = 1

[[interact]]
a = "balls"
b = "default"
"#,
    )
    .unwrap();
    let tradeoff = |out: Option<&str>| {
        let mut command = Command::new(bin("ricochet-lab"));
        command
            .current_dir(dir.path())
            .args(["tradeoff", "--steps", "30", "--reference-budget", "30"])
            .args(["--candidate", "solver=impulses", "--scene", "mine.toml"])
            .env("RUST_LOG", "warn");
        if let Some(out) = out {
            command.args(["--out", out]);
        }
        let out = command.output().unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
    };
    // No --out: a directory named after the scene, where the command ran.
    tradeoff(None);
    for file in ["mine.csv", "mine.png", "mine.md"] {
        let path = dir.path().join("mine-tradeoff").join(file);
        assert!(path.is_file(), "{} not written", path.display());
    }
    assert!(!dir.path().join("docs").exists() && !dir.path().join("tradeoff").exists());
    // --out: where asked.
    tradeoff(Some("reports/today"));
    assert!(dir.path().join("reports/today/mine.csv").is_file());
}
