//! The suite of scene kinds (`assets/scenes/suite/`) under named settings, each scene held
//! to the criteria it states (`ricochet-lab suite`): which settings hold which kinds,
//! and what a step costs over the whole run (start-up included), mean beside median.
//!
//! The first setting is the default a scene that names no solver gets; the others take
//! one of its parts away or are the settings it replaced, so each row says what that part
//! buys.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use serde::Serialize;

use ricochet_engine::criteria::{Criteria, Judgement, Monitor};
use ricochet_engine::scene;

use super::percentile;
use super::table::Table;

/// A setting measured on every scene: a label and `[world]` overrides.
pub struct Setting {
    pub label: &'static str,
    pub overrides: &'static [&'static str],
}

/// The default, then what it replaced and what it is without each of its parts.
pub const SETTINGS: &[Setting] = &[
    Setting {
        label: "the default",
        overrides: &[],
    },
    Setting {
        label: "the default without the resting load",
        overrides: &["rest_load=false"],
    },
    Setting {
        label: "the default without the support sweep",
        overrides: &["shock_propagation=false"],
    },
    Setting {
        label: "the default without exact sliding",
        overrides: &["exact_sliding=false"],
    },
    Setting {
        label: "the default without split impulses",
        overrides: &["split_impulses=false", "slop=0.001"],
    },
    Setting {
        label: "the default at 1 sub-step of 4 passes",
        overrides: &["substeps=1", "impulse_iterations=4"],
    },
    Setting {
        label: "the chapter's relaxation",
        overrides: &["solver=relaxation"],
    },
    Setting {
        label: "impulses as before: 8 passes, 1 sub-step",
        overrides: &[
            "impulse_iterations=8",
            "substeps=1",
            "split_impulses=false",
            "slop=0.001",
            "rest_load=false",
            "shock_propagation=false",
            "exact_sliding=false",
            "broad_phase=sweep",
        ],
    },
    Setting {
        label: "pyramid-100's former setting: 300 start passes",
        overrides: &[
            "baumgarte=0.5",
            "start_iterations=300",
            "start_frames=20",
            "rest_load=false",
            "shock_propagation=false",
            "exact_sliding=false",
        ],
    },
    Setting {
        label: "soft step (Box2D v3's): 4 sub-steps, 1 pass + 1 relax, 30 Hz",
        overrides: &[
            "substeps=4",
            "impulse_iterations=1",
            "relax_iterations=1",
            "contact_hertz=30",
            "split_impulses=false",
            "slop=0.001",
            "rest_load=false",
            "shock_propagation=false",
            "exact_sliding=false",
        ],
    },
];

/// One scene under one setting.
#[derive(Clone, Debug, Serialize)]
pub struct Row {
    pub scene: String,
    pub setting: String,
    pub overrides: String,
    pub bodies: usize,
    pub steps: u64,
    /// Mean wall time of a step over every step of the run, in milliseconds.
    pub ms_mean: f64,
    pub ms_median: f64,
    /// Every stated criterion held.
    pub holds: bool,
    /// Each criterion as `name figure/limit`, `!` before a failed one.
    pub criteria: String,
    #[serde(skip)]
    pub verdict: Vec<Judgement>,
}

/// The suite's scenes in `dir` (those whose path contains `only`, if given), by name.
pub fn scenes(dir: &Path, only: Option<&str>) -> Result<Vec<PathBuf>> {
    let mut out: Vec<PathBuf> = std::fs::read_dir(dir)
        .with_context(|| format!("cannot read {}", dir.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .filter(|p| only.is_none_or(|o| p.to_string_lossy().contains(o)))
        .collect();
    out.sort();
    Ok(out)
}

/// The accuracy target the suite is also run under.
pub const TARGET: f64 = 0.01;

/// One scene under an accuracy target: the setting the target picked, how long picking
/// took, and the scene's run under it.
#[derive(Clone, Debug)]
pub struct Targeted {
    /// Wall time of the measure that picked (no cache).
    pub measure_s: f64,
    pub pick: ricochet_server::accuracy::Pick,
    /// The scene under the picked setting, judged by its criteria over its whole run.
    pub row: Row,
}

/// Picks a setting for `path` under `target` (measured afresh, as a server would at
/// start-up without a cache), then runs the scene under it against its criteria.
pub fn under_target(path: &Path, target: f64) -> Result<Targeted> {
    under_target_judged(path, target, |c| c)
}

/// [`under_target`], the run judged by `judged` of the scene's criteria.
pub fn under_target_judged(
    path: &Path,
    target: f64,
    judged: impl Fn(Criteria) -> Criteria,
) -> Result<Targeted> {
    use crate::scene_tradeoff::Subject;
    let subject = Subject::read(path, ricochet_server::accuracy::MEASURE_STEPS, Vec::new())?;
    let started = Instant::now();
    let pick = ricochet_server::accuracy::pick(&subject, target, None)?;
    let measure_s = started.elapsed().as_secs_f64();
    let overrides: Vec<&str> = pick
        .candidate
        .overrides
        .iter()
        .map(String::as_str)
        .collect();
    let row = measure_judged(path, &format!("accuracy = {target}"), &overrides, judged)?;
    Ok(Targeted {
        measure_s,
        pick,
        row,
    })
}

/// Every scene of `dir` (whose name contains `only`) under `target`.
pub fn run_targeted(
    dir: &Path,
    only: Option<&str>,
    target: f64,
    progress: &indicatif::ProgressBar,
) -> Result<Vec<Targeted>> {
    let scenes = scenes(dir, only)?;
    progress.set_length(progress.length().unwrap_or(0) + scenes.len() as u64);
    let mut out = Vec::new();
    for path in &scenes {
        progress.set_message(format!("{} / accuracy = {target}", path.display()));
        out.push(under_target(path, target)?);
        progress.inc(1);
    }
    Ok(out)
}

/// The targeted runs as a Markdown table.
pub fn targeted_markdown(runs: &[Targeted]) -> String {
    let Some(first) = runs.first() else {
        return String::new();
    };
    let mut table = Table::new([
        "scene",
        "bodies",
        "measure s",
        "setting picked",
        "position error judged over",
        "criteria in the measure",
        "holds over the whole run",
        "mean ms/step",
        "median",
    ]);
    for t in runs {
        let p = &t.pick;
        let window = match p.error() {
            None if p.refined => "no frame: the trajectories diverge from the start".to_string(),
            None => "none: the reference got one refinement in the time budget".to_string(),
            Some(e) if p.horizon >= p.steps => format!("all {} steps ({e:.1e})", p.steps),
            Some(e) => format!(
                "the first {} of {} steps ({e:.1e}); {} after",
                p.horizon,
                p.steps,
                if p.diverges {
                    "diverges"
                } else {
                    "not resolved"
                }
            ),
        };
        let held = if p.candidate.fails.is_empty() {
            format!("held ({} of {} candidates hold)", p.holding, p.measured)
        } else {
            format!("**fails {}**", p.candidate.fails.join(", "))
        };
        table.row([
            t.row.scene.clone(),
            t.row.bodies.to_string(),
            format!("{:.1}", t.measure_s),
            format!(
                "{}{}",
                p.candidate.name,
                if p.met { "" } else { " (target not met)" }
            ),
            window,
            held,
            if t.row.holds {
                "yes".to_string()
            } else {
                format!("**no: {}**", t.row.criteria)
            },
            format!("{:.3}", t.row.ms_mean),
            format!("{:.3}", t.row.ms_median),
        ]);
    }
    format!(
        "Every scene under `accuracy = {}` (picked by a fresh measure of {} steps, as a server without a cache does at start-up; then run for the steps its criteria state):\n\n{table}",
        first.pick.target, first.pick.steps
    )
}

/// Runs `path` under `overrides` for the steps its criteria ask, timing every step.
pub fn measure(path: &Path, label: &str, overrides: &[&str]) -> Result<Row> {
    measure_judged(path, label, overrides, |c| c)
}

/// [`measure`], the run judged by `judged` of the scene's criteria (tighter limits, say).
pub fn measure_judged(
    path: &Path,
    label: &str,
    overrides: &[&str],
    judged: impl Fn(Criteria) -> Criteria,
) -> Result<Row> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    let overrides: Vec<String> = overrides.iter().map(|s| s.to_string()).collect();
    let mut world = scene::parse(&text, path, &overrides)?;
    let criteria = judged(
        scene::criteria(&text, path)?
            .with_context(|| format!("{} states no [criteria]", path.display()))?,
    );
    let mut monitor = Monitor::new(&world, &criteria);
    let mut times = Vec::with_capacity(criteria.steps as usize);
    for _ in 0..criteria.steps {
        let t = Instant::now();
        world.step();
        times.push(t.elapsed().as_secs_f64() * 1e3);
        monitor.observe(&world);
    }
    let ms_mean = times.iter().sum::<f64>() / times.len() as f64;
    times.sort_by(f64::total_cmp);
    let verdict = monitor.verdict();
    Ok(Row {
        scene: path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default(),
        setting: label.to_string(),
        overrides: overrides.join(" "),
        bodies: world.bodies().len(),
        steps: criteria.steps,
        ms_mean,
        ms_median: percentile(&times, 0.5),
        holds: verdict.iter().all(|j| j.pass),
        criteria: verdict
            .iter()
            .map(|j| {
                format!(
                    "{}{} {}/{}",
                    if j.pass { "" } else { "!" },
                    j.name,
                    figure(j.figure),
                    j.limit
                )
            })
            .collect::<Vec<_>>()
            .join(" "),
        verdict,
    })
}

fn figure(v: f64) -> String {
    if v == 0.0 || (1e-3..1e4).contains(&v.abs()) {
        format!("{v:.4}")
    } else {
        format!("{v:.2e}")
    }
}

/// Every scene of `dir` (whose name contains `only`, if given) under every setting, in
/// the order of [`SETTINGS`], each run ticking `progress`.
pub fn run_all(
    dir: &Path,
    only: Option<&str>,
    progress: &indicatif::ProgressBar,
) -> Result<Vec<Row>> {
    let scenes = scenes(dir, only)?;
    progress.set_length((scenes.len() * SETTINGS.len()) as u64);
    let mut rows = Vec::new();
    for setting in SETTINGS {
        for path in &scenes {
            progress.set_message(format!("{} / {}", path.display(), setting.label));
            rows.push(measure(path, setting.label, setting.overrides)?);
            progress.inc(1);
        }
    }
    Ok(rows)
}

/// Writes `dir/suite.csv` and the tables into `dir/README.md` (between its `suite`
/// markers), headed by the command that measured them.
pub fn write(dir: &Path, rows: &[Row], targeted: &[Targeted], command: &str) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let mut all = rows.to_vec();
    all.extend(targeted.iter().map(|t| t.row.clone()));
    std::fs::write(dir.join("suite.csv"), to_csv(&all)?)?;
    super::splice(
        &dir.join("README.md"),
        "suite",
        &format!(
            "Measured by `{command}` on {}.\n\n{}",
            super::machine(),
            tables(rows, targeted)
        ),
    )
}

/// The report's tables: every scene under every setting, then under the accuracy target.
pub fn tables(rows: &[Row], targeted: &[Targeted]) -> String {
    format!("{}\n{}", to_markdown(rows), targeted_markdown(targeted))
}

/// The rows as CSV.
pub fn to_csv(rows: &[Row]) -> Result<String> {
    super::to_csv(rows)
}

/// Two Markdown tables: every scene under the first setting (time and each criterion),
/// then every setting's count of scenes held, the scenes it fails and its summed time.
pub fn to_markdown(rows: &[Row]) -> String {
    let Some(first) = rows.first().map(|r| r.setting.clone()) else {
        return String::new();
    };
    let mut scenes = Table::new([
        "scene",
        "bodies",
        "steps",
        "mean ms/step (whole run)",
        "median",
        "criteria (figure / limit)",
        "holds",
    ]);
    for r in rows.iter().filter(|r| r.setting == first) {
        let criteria: Vec<String> = r
            .verdict
            .iter()
            .map(|j| {
                let text = format!("{} {} / {}", j.name, figure(j.figure), j.limit);
                if j.pass {
                    text
                } else {
                    format!("**{text}**")
                }
            })
            .collect();
        scenes.row([
            r.scene.clone(),
            r.bodies.to_string(),
            r.steps.to_string(),
            format!("{:.3}", r.ms_mean),
            format!("{:.3}", r.ms_median),
            criteria.join(", "),
            (if r.holds { "yes" } else { "**no**" }).to_string(),
        ]);
    }
    let mut table = Table::new([
        "setting",
        "overrides",
        "scenes held",
        "fails",
        "sum of mean ms/step",
    ]);
    let mut settings: Vec<&str> = Vec::new();
    for r in rows {
        if !settings.contains(&r.setting.as_str()) {
            settings.push(&r.setting);
        }
    }
    for s in settings {
        let mine: Vec<&Row> = rows.iter().filter(|r| r.setting == s).collect();
        let held = mine.iter().filter(|r| r.holds).count();
        let fails: Vec<String> = mine
            .iter()
            .filter(|r| !r.holds)
            .map(|r| {
                let failed: Vec<&str> = r
                    .verdict
                    .iter()
                    .filter(|j| !j.pass)
                    .map(|j| j.name)
                    .collect();
                format!("{} ({})", r.scene, failed.join(", "))
            })
            .collect();
        let total: f64 = mine.iter().map(|r| r.ms_mean).sum();
        table.row([
            s.to_string(),
            format!("`{}`", mine[0].overrides),
            format!("{held} of {}", mine.len()),
            if fails.is_empty() {
                "none".to_string()
            } else {
                fails.join("; ")
            },
            format!("{total:.2}"),
        ]);
    }
    format!(
        "Every scene under {first}:\n\n{scenes}\nEvery setting (the criteria a scene fails, in bold above for the first):\n\n{table}"
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_scene_is_measured_against_its_criteria_and_tabled() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/scenes/suite");
        let path = dir.join("plank.toml");
        let held = measure(&path, "the default", &[]).unwrap();
        let crushed = measure(&path, "the chapter's relaxation", &["solver=relaxation"]).unwrap();
        assert!(held.holds, "{}", held.criteria);
        assert!(!crushed.holds, "{}", crushed.criteria);
        assert!(held.ms_mean > 0.0 && held.ms_median > 0.0);
        let table = to_markdown(&[held, crushed]);
        assert!(table.contains("| plank | 4 | 600 |"), "{table}");
        assert!(
            table.contains("| the chapter's relaxation | `solver=relaxation` | 0 of 1 | plank (drift, overlap) |"),
            "{table}"
        );
        let csv = to_csv(&[measure(&path, "x", &[]).unwrap()]).unwrap();
        assert!(
            csv.starts_with("scene,setting,overrides,bodies,steps,ms_mean"),
            "{csv}"
        );
    }

    /// The suite holds under an accuracy target too: the target never picks a setting
    /// that fails a scene's criteria while another candidate holds them, and the one it
    /// picks holds them over the scene's whole run, not only over the measured steps.
    #[test]
    fn every_kind_of_scene_holds_its_criteria_under_an_accuracy_target() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/scenes/suite");
        let runs = run_targeted(&dir, None, TARGET, &indicatif::ProgressBar::hidden()).unwrap();
        assert!(runs.len() >= 10, "{} scenes", runs.len());
        println!("{}", targeted_markdown(&runs));
        let failed: Vec<String> = runs
            .iter()
            .filter(|t| !t.row.holds || !t.pick.candidate.fails.is_empty())
            .map(|t| format!("{}: {} ({})", t.row.scene, t.row.criteria, t.pick.reason()))
            .collect();
        assert!(failed.is_empty(), "{}", failed.join("\n"));
    }
}
