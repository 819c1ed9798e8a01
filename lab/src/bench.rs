//! Benchmarks of the engine on shipped scenes: figures and ratios, not pass/fail
//! (`ricochet-lab bench`).
//!
//! Every case loads a scene users can run themselves (`assets/scenes/`), under named
//! settings written as the `--set NAME=VALUE` overrides they are, steps it, and reports
//! the median wall time per step, its spread, and an accuracy or size figure where one
//! applies (the worst drift over the whole run, not at a chosen step). Run them on a
//! quiet machine, in a release build; the numbers are this machine's.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use glam::DVec2;
use serde::Serialize;

use ricochet_engine::scene;
use ricochet_engine::world::World;

use super::table::Table;
use super::{percentile, splice};

/// What a case reports besides time.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Figure {
    /// Worst displacement of any dynamic body from where the scene put it, over every
    /// step, in units of the smallest dynamic body's size; and at the last step.
    Drift,
    /// Wall time per particle per step, in nanoseconds.
    NsPerParticle,
    /// Time only.
    None,
}

/// One benchmark: a shipped scene under one or more settings.
#[derive(Clone, Debug)]
pub struct Case {
    /// The scene, relative to the scenes directory.
    pub scene: &'static str,
    /// Steps run before timing starts (emitters releasing, for instance).
    pub warmup: u64,
    pub steps: u64,
    /// (label, overrides of the scene's `[world]` as `NAME=VALUE`); no overrides is the
    /// scene's own setting.
    pub settings: Vec<(String, Vec<String>)>,
    pub figure: Figure,
}

/// One measured row, as the CSV holds it.
#[derive(Clone, Debug, Serialize)]
pub struct Row {
    pub scene: String,
    pub setting: String,
    /// The overrides of the scene's setting, space-separated (empty: as shipped).
    pub overrides: String,
    pub bodies: usize,
    pub particles: usize,
    pub steps: u64,
    /// Mean wall time of a step over the whole run (the warm-up steps included, as a live
    /// server runs them), in milliseconds.
    pub ms_mean: f64,
    /// Median wall time of one step over the whole run, in milliseconds.
    pub ms_median: f64,
    /// The 10th and 90th percentiles of the step's wall time, in milliseconds.
    pub ms_p10: f64,
    pub ms_p90: f64,
    /// Worst drift over the run, in body sizes (Figure::Drift only).
    pub worst_drift: Option<f64>,
    /// Drift at the last step, in body sizes (Figure::Drift only).
    pub final_drift: Option<f64>,
    /// Nanoseconds per particle per step (Figure::NsPerParticle only).
    pub ns_per_particle: Option<f64>,
    /// A body or particle went NaN or infinite.
    pub nan: bool,
}

/// The platform scenes under every solver (as shipped: the default, impulses on the grid):
/// static bodies no contact touches must cost nothing under any of them.
fn platform_settings() -> Vec<(String, Vec<String>)> {
    let mut v = vec![("shipped".to_string(), Vec::new())];
    v.push(("relaxation".into(), set(&["solver=relaxation"])));
    v.push(("impulses, sweep".into(), set(&["broad_phase=sweep"])));
    v
}

fn set(overrides: &[&str]) -> Vec<String> {
    overrides.iter().map(|s| s.to_string()).collect()
}

/// The rigid settings of the pyramid beyond its shipped one: the chapter's relaxation,
/// the impulse solver without split impulses (sweep, then grid), split impulses at other
/// iteration counts, and soft contacts.
fn pyramid_settings() -> Vec<(String, Vec<String>)> {
    // The shipped scene names no solver: the default, impulses at 2 iterations and 2
    // sub-steps, split impulses (baumgarte 0.2, slop 1e-4), grid, the first frame started
    // from the resting load (every row keeps those unless it says otherwise). Without
    // split impulses the slop goes back to 1e-3.
    let plain = ["split_impulses=false", "slop=0.001", "impulse_iterations=4"];
    let with = |extra: &[&str]| {
        let mut v = set(&plain);
        v.extend(set(extra));
        v
    };
    vec![
        (
            "shipped (the default): impulses 2 it, 2 sub-steps, split, grid, resting load".into(),
            Vec::new(),
        ),
        (
            "shipped, 2 threads (contacts in blocks: the same bits)".into(),
            set(&["threads=2"]),
        ),
        ("shipped, 4 it".into(), set(&["impulse_iterations=4"])),
        (
            "shipped without the resting load".into(),
            set(&["rest_load=false"]),
        ),
        (
            "shipped without the resting load, 300 passes the first 20 frames instead".into(),
            set(&["rest_load=false", "start_iterations=300"]),
        ),
        (
            "shipped without the resting load, settled: 1000 passes before the first step".into(),
            set(&["rest_load=false", "settle_iterations=1000"]),
        ),
        (
            "relaxation 15 (chapter), sweep".into(),
            set(&["solver=relaxation", "broad_phase=sweep"]),
        ),
        (
            "impulses 4 it, 2 sub-steps, sweep".into(),
            with(&["broad_phase=sweep"]),
        ),
        ("impulses 4 it, 2 sub-steps, grid".into(), with(&[])),
        (
            "impulses 8 it, 1 sub-step, grid".into(),
            with(&["impulse_iterations=8", "substeps=1"]),
        ),
        (
            "impulses 6 it, 1 sub-step, split, grid".into(),
            set(&["impulse_iterations=6", "substeps=1"]),
        ),
        (
            "impulses 8 it, 2 sub-steps, split, grid".into(),
            set(&["impulse_iterations=8"]),
        ),
        (
            "soft (30 Hz) 1 it + 1 relax, 4 sub-steps, grid".into(),
            with(&[
                "contact_hertz=30",
                "impulse_iterations=1",
                "relax_iterations=1",
                "substeps=4",
            ]),
        ),
    ]
}

/// The stack under both solvers, and under impulses with sleeping on: next to the
/// stack's variants with features it does not use (particle interactions without
/// particles, a group of statics nothing interacts with), whose cost must be the stack's.
fn feature_settings() -> Vec<(String, Vec<String>)> {
    vec![
        ("shipped (the default)".to_string(), Vec::new()),
        (
            "relaxation 15 (chapter)".into(),
            set(&["solver=relaxation"]),
        ),
        ("the default, sleeping on".into(), set(&["sleeping=true"])),
    ]
}

/// Every case, in the order the report lists them. `pyramid` replaces the pyramid's
/// settings (`--set`), `steps` its step count.
pub fn cases(pyramid: Option<Vec<String>>, steps: u64) -> Vec<Case> {
    let threaded = || {
        vec![
            ("shipped".to_string(), Vec::new()),
            ("2 threads".to_string(), set(&["threads=2"])),
        ]
    };
    vec![
        Case {
            scene: "pyramid-100.toml",
            warmup: 0,
            steps,
            settings: match pyramid {
                Some(overrides) => vec![(overrides.join(" "), overrides)],
                None => pyramid_settings(),
            },
            figure: Figure::Drift,
        },
        Case {
            scene: "bench/particles-100k-shapes.toml",
            warmup: 150,
            steps: 50,
            settings: threaded(),
            figure: Figure::NsPerParticle,
        },
        Case {
            scene: "bench/particles-1m-free.toml",
            warmup: 150,
            steps: 20,
            settings: threaded(),
            figure: Figure::NsPerParticle,
        },
        Case {
            scene: "bench/platforms-10.toml",
            warmup: 0,
            steps: 600,
            settings: platform_settings(),
            figure: Figure::None,
        },
        Case {
            scene: "bench/platforms-10k.toml",
            warmup: 0,
            steps: 600,
            settings: platform_settings(),
            figure: Figure::None,
        },
        Case {
            scene: "stack-20.toml",
            warmup: 0,
            steps: 600,
            settings: feature_settings(),
            figure: Figure::None,
        },
        Case {
            scene: "bench/stack-20-particle-interactions.toml",
            warmup: 0,
            steps: 600,
            settings: feature_settings(),
            figure: Figure::None,
        },
        Case {
            scene: "bench/stack-20-unused-statics.toml",
            warmup: 0,
            steps: 600,
            settings: feature_settings(),
            figure: Figure::None,
        },
    ]
}

/// Loads `scene` from `dir` with `overrides` over its `[world]`.
pub fn load(dir: &Path, scene: &str, overrides: &[String]) -> Result<World> {
    let path: PathBuf = dir.join(scene);
    let text = std::fs::read_to_string(&path)
        .with_context(|| format!("cannot read {}", path.display()))?;
    Ok(scene::parse(&text, &path, overrides)?)
}

/// Runs one case under one setting.
pub fn measure(
    dir: &Path,
    case: &Case,
    label: &str,
    overrides: &[String],
    steps: u64,
) -> Result<Row> {
    let mut w = load(dir, case.scene, overrides)?;
    let mut times = Vec::with_capacity((case.warmup + steps) as usize);
    for _ in 0..case.warmup {
        let t = Instant::now();
        w.step();
        times.push(t.elapsed().as_secs_f64() * 1e3);
    }
    let start: Vec<DVec2> = w.bodies().iter().map(|b| b.pos).collect();
    let unit = w
        .bodies()
        .iter()
        .filter(|b| !b.is_static())
        .map(|b| b.shape.half_extents().min_element() * 2.0)
        .fold(f64::INFINITY, f64::min);
    let mut worst: f64 = 0.0;
    let drift_now = |w: &World| {
        w.bodies()
            .iter()
            .zip(&start)
            .filter(|(b, _)| !b.is_static())
            .map(|(b, p)| (b.pos - *p).length())
            .fold(0.0, f64::max)
    };
    for _ in 0..steps {
        let t = Instant::now();
        w.step();
        times.push(t.elapsed().as_secs_f64() * 1e3);
        if case.figure == Figure::Drift {
            worst = worst.max(drift_now(&w));
        }
    }
    let ms_mean = times.iter().sum::<f64>() / times.len().max(1) as f64;
    times.sort_by(f64::total_cmp);
    let ms_median = percentile(&times, 0.5);
    let nan = w
        .bodies()
        .iter()
        .any(|b| !(b.pos.is_finite() && b.vel.is_finite()))
        || w.particles().x.iter().any(|x| !x.is_finite());
    let particles = w.particles().len();
    let drift = |v: f64| (case.figure == Figure::Drift).then_some(v / unit);
    Ok(Row {
        scene: case.scene.trim_end_matches(".toml").to_string(),
        setting: label.to_string(),
        overrides: overrides.join(" "),
        bodies: w.bodies().len(),
        particles,
        steps,
        ms_mean,
        ms_median,
        ms_p10: percentile(&times, 0.1),
        ms_p90: percentile(&times, 0.9),
        worst_drift: drift(worst),
        final_drift: drift(drift_now(&w)),
        ns_per_particle: (case.figure == Figure::NsPerParticle && particles > 0)
            .then(|| ms_median * 1e6 / particles as f64),
        nan,
    })
}

/// Measures every case whose scene contains `only` under each of its settings (the
/// pyramid under `set` alone when given), ticking `progress` once a setting.
pub fn run_all(
    scenes: &Path,
    steps: u64,
    only: Option<&str>,
    set: Vec<String>,
    progress: &indicatif::ProgressBar,
) -> Result<Vec<Row>> {
    let pyramid = (!set.is_empty()).then_some(set);
    let cases: Vec<Case> = cases(pyramid, steps)
        .into_iter()
        .filter(|c| only.is_none_or(|o| c.scene.contains(o)))
        .collect();
    progress.set_length(cases.iter().map(|c| c.settings.len() as u64).sum());
    let mut rows = Vec::new();
    for case in &cases {
        for (label, overrides) in &case.settings {
            progress.set_message(format!("{} / {label}", case.scene));
            // The chapter's relaxation is quadratic in the pile: a few steps show its cost.
            let relaxation = overrides.iter().any(|o| o == "solver=relaxation");
            let n = if relaxation {
                case.steps.min(20)
            } else {
                case.steps
            };
            rows.push(measure(scenes, case, label, overrides, n)?);
            progress.inc(1);
        }
    }
    Ok(rows)
}

/// The report's tables: every row, then the speed-ups on 2 threads if any were measured.
pub fn tables(rows: &[Row]) -> String {
    let mut out = to_markdown(rows);
    let speedups = speedups(rows);
    if !speedups.is_empty() {
        out += &format!("\nSpeed-up on 2 threads (same run, same bits):\n\n{speedups}");
    }
    out
}

/// Writes `dir/bench.csv` and the tables into `dir/README.md` (between its `bench`
/// markers), saying they were measured by `command`.
pub fn write(dir: &Path, rows: &[Row], command: &str) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    std::fs::write(dir.join("bench.csv"), to_csv(rows)?)?;
    splice(
        &dir.join("README.md"),
        "bench",
        &format!(
            "Measured by `{command}` on {}.\n\n{}",
            super::machine(),
            tables(rows)
        ),
    )
}

/// The rows as CSV.
pub fn to_csv(rows: &[Row]) -> Result<String> {
    super::to_csv(rows)
}

/// The rows as a Markdown table.
pub fn to_markdown(rows: &[Row]) -> String {
    let opt =
        |v: Option<f64>, digits: usize| v.map(|v| format!("{v:.digits$}")).unwrap_or_default();
    let mut t = Table::new([
        "scene",
        "setting",
        "bodies",
        "particles",
        "steps",
        "mean ms/step (whole run)",
        "median (p10-p90)",
        "worst drift (body sizes)",
        "drift at the end",
        "ns per particle-step",
    ]);
    for r in rows {
        t.row([
            r.scene.clone(),
            r.setting.clone(),
            r.bodies.to_string(),
            r.particles.to_string(),
            r.steps.to_string(),
            format!("{:.4}", r.ms_mean),
            format!("{:.4} ({:.4}-{:.4})", r.ms_median, r.ms_p10, r.ms_p90),
            opt(r.worst_drift, 4) + if r.nan { " NaN" } else { "" },
            opt(r.final_drift, 4),
            opt(r.ns_per_particle, 2),
        ]);
    }
    t.to_string()
}

/// The speed-up of each scene measured both as shipped (one thread) and with
/// `threads=2` alone, as a Markdown table (empty when none was).
pub fn speedups(rows: &[Row]) -> String {
    let mut t = Table::new([
        "scene",
        "one thread, median ms/step",
        "2 threads",
        "speed-up",
    ]);
    for two in rows.iter().filter(|r| r.overrides == "threads=2") {
        let Some(one) = rows
            .iter()
            .find(|r| r.scene == two.scene && r.overrides.is_empty())
        else {
            continue;
        };
        t.row([
            two.scene.clone(),
            format!("{:.4}", one.ms_median),
            format!("{:.4}", two.ms_median),
            format!("{:.2}x", one.ms_median / two.ms_median),
        ]);
    }
    if t.is_empty() {
        String::new()
    } else {
        t.to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scenes() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/scenes")
    }

    #[test]
    fn every_case_loads_its_shipped_scene_under_every_setting() {
        for case in cases(None, 1) {
            for (label, overrides) in &case.settings {
                load(&scenes(), case.scene, overrides)
                    .unwrap_or_else(|e| panic!("{} / {label}: {e:#}", case.scene));
            }
        }
    }

    #[test]
    fn drift_is_the_worst_over_the_run_in_body_sizes() {
        let case = Case {
            scene: "stack-20.toml",
            warmup: 0,
            steps: 60,
            settings: Vec::new(),
            figure: Figure::Drift,
        };
        // The chapter's relaxation lets the stack sink: the worst drift over the run is
        // at least the drift at its end, and both are measured, not zero.
        let chapter = ["solver=relaxation".to_string()];
        let row = measure(&scenes(), &case, "chapter", &chapter, 60).unwrap();
        let (worst, last) = (row.worst_drift.unwrap(), row.final_drift.unwrap());
        assert!(worst >= last && last > 0.0, "{worst} {last}");
        assert!(row.ms_p10 <= row.ms_median && row.ms_median <= row.ms_p90);
        let csv = to_csv(std::slice::from_ref(&row)).unwrap();
        assert!(csv.starts_with("scene,setting,overrides,"), "{csv}");
        assert!(to_markdown(&[row]).contains("| stack-20 | chapter |"));
    }

    #[test]
    fn speed_ups_pair_each_two_thread_row_with_its_shipped_row() {
        let row = |scene: &str, overrides: &str, ms: f64| Row {
            scene: scene.into(),
            setting: String::new(),
            overrides: overrides.into(),
            bodies: 0,
            particles: 0,
            steps: 1,
            ms_mean: ms,
            ms_median: ms,
            ms_p10: ms,
            ms_p90: ms,
            worst_drift: None,
            final_drift: None,
            ns_per_particle: None,
            nan: false,
        };
        let rows = [
            row("a", "", 3.0),
            row("a", "impulse_iterations=4", 9.0),
            row("a", "threads=2", 2.0),
            row("b", "threads=2", 1.0),
        ];
        let table = speedups(&rows);
        assert!(table.contains("| a | 3.0000 | 2.0000 | 1.50x |"), "{table}");
        assert!(!table.contains("| b |"), "no shipped row of b: {table}");
        assert_eq!(speedups(&rows[..2]), "");
    }
}
