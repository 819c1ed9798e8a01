//! Speed against accuracy, measured (`ricochet-lab tradeoff`): the scene tool
//! ([`super::scene_tradeoff`]) run on five shipped scenes (`assets/scenes/`, embedded at
//! build time), three with a closed form (projectile, slide, bounce) and two piles; per
//! setting the median time per step and what it buys: the error against the closed form
//! where the scene has one, against the converged reference otherwise.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};

use super::chart::{panel, register_font, write_png, Point};
use super::scene_tradeoff::{
    judged_error, measure, ClosedForm, Options, Report, ReportPages, Subject,
};
use super::table::Table;

/// One cell of the report: a scene under a setting.
#[derive(Clone, Debug)]
pub struct Cell {
    pub scene: &'static str,
    pub setting: String,
    /// Mean ms per step over every step of the run.
    pub ms_per_step: f64,
    pub ms_median: f64,
    /// The error against the scene's closed form where it has one, else the worst
    /// position error over the run against the converged reference (units).
    pub error: f64,
    pub error_name: &'static str,
    /// Worst position error over the run against the converged reference (units).
    pub reference_error: f64,
    /// Deepest penetration over the run (units).
    pub deepest_penetration: f64,
    /// Worst relative change of the bodies' energy over the run.
    pub energy_drift: f64,
    pub nan: bool,
}

/// The scenes: name, file, text, steps, closed form.
pub const SCENES: &[(&str, &str, &str, u64, Option<ClosedForm>)] = &[
    (
        "projectile",
        "projectile.toml",
        include_str!("../../assets/scenes/projectile.toml"),
        120,
        Some(ClosedForm::Flight),
    ),
    (
        "bounce",
        "bounce.toml",
        include_str!("../../assets/scenes/bounce.toml"),
        600,
        Some(ClosedForm::Energy),
    ),
    (
        "slide",
        "slide.toml",
        include_str!("../../assets/scenes/slide.toml"),
        120,
        Some(ClosedForm::Coast),
    ),
    (
        "stack-20",
        "stack-20.toml",
        include_str!("../../assets/scenes/stack-20.toml"),
        600,
        None,
    ),
    (
        "pyramid-10",
        "pyramid-10.toml",
        include_str!("../../assets/scenes/pyramid-10.toml"),
        300,
        None,
    ),
];

/// What the error of a scene without a closed form measures.
const AGAINST_REFERENCE: &str =
    "position against the converged reference, worst over the run (units)";

/// A shipped scene as the tool's subject.
pub fn subject(name: &str) -> Subject {
    let &(_, file, text, steps, closed_form) = SCENES
        .iter()
        .find(|s| s.0 == name)
        .unwrap_or_else(|| panic!("no built-in scene {name}"));
    Subject {
        path: Path::new("assets/scenes").join(file),
        text: text.to_string(),
        steps,
        inputs: Vec::new(),
        base: Vec::new(),
        closed_form,
    }
}

/// The cells of one scene's report.
pub fn cells(scene: &'static str, report: &Report) -> Vec<Cell> {
    report
        .rows
        .iter()
        .map(|r| {
            let (error, error_name) = match (r.closed_form_error, subject(scene).closed_form) {
                (Some(e), Some(form)) => (e, form.measure()),
                _ => (judged_error(r), AGAINST_REFERENCE),
            };
            Cell {
                scene,
                setting: r.name.clone(),
                ms_per_step: r.ms_mean,
                ms_median: r.ms_median,
                error: if r.nan { f64::NAN } else { error },
                error_name,
                reference_error: judged_error(r),
                deepest_penetration: r.deepest_penetration,
                energy_drift: r.worst_energy_change,
                nan: r.nan,
            }
        })
        .collect()
}

/// Each scene's reference, described: (scene, line).
pub type References = Vec<(&'static str, String)>;

/// Every scene of the report, each with its reference's line; `progress` is told each
/// step of every run.
pub fn run_all(progress: &indicatif::ProgressBar) -> Result<(Vec<Cell>, References)> {
    let mut all = Vec::new();
    let mut references = Vec::new();
    for &(scene, ..) in SCENES {
        progress.set_prefix(scene);
        let report = measure(&subject(scene), None, &Options::default(), progress)?;
        all.extend(cells(scene, &report));
        references.push((scene, report.reference_line()));
    }
    Ok((all, references))
}

/// The cells as CSV, a line each.
pub fn to_csv(cells: &[Cell]) -> Result<String> {
    #[derive(serde::Serialize)]
    struct Line<'a> {
        scene: &'a str,
        setting: &'a str,
        ms_per_step: f64,
        ms_median: f64,
        error: f64,
        error_measure: &'a str,
        reference_error: f64,
        deepest_penetration: f64,
        energy_drift: f64,
        nan: bool,
        on_front: bool,
    }
    let lines: Vec<Line> = cells
        .iter()
        .map(|c| Line {
            scene: c.scene,
            setting: &c.setting,
            ms_per_step: c.ms_per_step,
            ms_median: c.ms_median,
            error: c.error,
            error_measure: c.error_name,
            reference_error: c.reference_error,
            deepest_penetration: c.deepest_penetration,
            energy_drift: c.energy_drift,
            nan: c.nan,
            on_front: on_front(c, cells),
        })
        .collect();
    super::to_csv(&lines)
}

/// The cells as a Markdown table, the front marked.
pub fn to_markdown(cells: &[Cell]) -> String {
    let mut t = Table::new([
        "scene",
        "setting",
        "mean ms/step (whole run)",
        "median",
        "error",
        "error measure",
        "against the reference (units)",
        "deepest penetration (units)",
        "worst energy change",
        "front",
    ]);
    for c in cells {
        t.row([
            c.scene.to_string(),
            c.setting.clone(),
            format!("{:.5}", c.ms_per_step),
            format!("{:.5}", c.ms_median),
            format!("{:.3e}{}", c.error, if c.nan { " NaN" } else { "" }),
            c.error_name.to_string(),
            format!("{:.2e}", c.reference_error),
            format!("{:.2e}", c.deepest_penetration),
            format!("{:.2e}", c.energy_drift),
            (if on_front(c, cells) { "yes" } else { "" }).to_string(),
        ]);
    }
    t.to_string()
}

/// The cells in one line each for the terminal, the front marked.
pub fn to_text(cells: &[Cell]) -> String {
    cells
        .iter()
        .map(|c| {
            format!(
                "{:<11} {:<34} {:>9.5} ms  error {:>10.3e}  reference {:>9.2e}  energy {:>9.2e}{}{}\n",
                c.scene,
                c.setting,
                c.ms_per_step,
                c.error,
                c.reference_error,
                c.energy_drift,
                if c.nan { "  NaN" } else { "" },
                if on_front(c, cells) { "  front" } else { "" }
            )
        })
        .collect()
}

/// Writes `out/tradeoff.csv`, `out/tradeoff.png` and, if `out/README.md` exists, the
/// table between its `tradeoff` markers, saying it was measured by `command`. Returns
/// the files written.
pub fn write(
    out: &Path,
    cells: &[Cell],
    references: &[(&str, String)],
    command: &str,
) -> Result<Vec<PathBuf>> {
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let (csv, png, readme) = (
        out.join("tradeoff.csv"),
        out.join("tradeoff.png"),
        out.join("README.md"),
    );
    std::fs::write(&csv, to_csv(cells)?)?;
    chart(cells, &png)?;
    let mut written = vec![csv, png];
    if readme.exists() {
        let references: String = references
            .iter()
            .map(|(scene, line)| format!("- {scene}: {line}\n"))
            .collect();
        super::splice(
            &readme,
            "tradeoff",
            &format!(
                "Measured by `{command}` on {}.\n\n{references}\n{}",
                super::machine(),
                to_markdown(cells)
            ),
        )?;
        written.push(readme);
    }
    Ok(written)
}

/// Whether a cell is on its scene's front: no other setting is both faster and more
/// accurate.
pub fn on_front(cell: &Cell, cells: &[Cell]) -> bool {
    !cell.nan
        && !cells.iter().any(|o| {
            o.scene == cell.scene
                && !o.nan
                && o.ms_per_step <= cell.ms_per_step
                && o.error <= cell.error
                && (o.ms_per_step < cell.ms_per_step || o.error < cell.error)
        })
}

/// Draws time against error per scene, the front in red, as a PNG.
pub fn chart(cells: &[Cell], path: &std::path::Path) -> anyhow::Result<()> {
    use plotters::prelude::*;
    register_font()?;
    // Every setting in the order first met (scenes try only what they need).
    let mut names: Vec<String> = Vec::new();
    for c in cells {
        if !names.contains(&c.setting) {
            names.push(c.setting.clone());
        }
    }
    write_png(path, (1500, 950), |root| {
        root.fill(&WHITE)?;
        let panels = root.split_evenly((2, 3));
        for (area, &(scene, ..)) in panels.iter().zip(SCENES) {
            let mine: Vec<&Cell> = cells
                .iter()
                .filter(|c| c.scene == scene && !c.nan)
                .collect();
            let Some(error_name) = mine.first().map(|c| c.error_name) else {
                continue;
            };
            let points: Vec<Point> = mine
                .iter()
                .map(|c| Point {
                    ms: c.ms_per_step,
                    error: c.error,
                    front: on_front(c, cells),
                    label: names.iter().position(|n| *n == c.setting).unwrap_or(0) + 1,
                })
                .collect();
            panel(area, scene, error_name, &points)?;
        }
        if let Some(legend) = panels.get(5) {
            legend.draw(&Text::new(
                "Settings (red: on the front)",
                (10, 20),
                ("sans-serif", 18),
            ))?;
            for (k, name) in names.iter().enumerate() {
                legend.draw(&Text::new(
                    format!("{}  {name}", k + 1),
                    // Two columns of 13.
                    (10 + 235 * (k / 13) as i32, 48 + 19 * (k % 13) as i32),
                    ("sans-serif", 13),
                ))?;
            }
        }
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cell(scene: &'static str, ms: f64, error: f64) -> Cell {
        Cell {
            scene,
            setting: String::new(),
            ms_per_step: ms,
            ms_median: ms,
            error,
            error_name: "",
            reference_error: error,
            deepest_penetration: 0.0,
            energy_drift: 0.0,
            nan: false,
        }
    }

    #[test]
    fn the_projectiles_closed_form_error_is_symplectic_eulers_lag() {
        // Symplectic Euler from v0 under g: p_n = p0 + v0 t + g dt² n(n+1)/2, so the error
        // against p0 + v0 t + g t²/2 is |g| dt t / 2: 10 x (1/60) x 2 / 2 = 1/6 after 2 s,
        // worst at the end; 4 sub-steps quarter it; exact flight leaves rounding.
        let report = measure(
            &subject("projectile"),
            None,
            &Options::default(),
            &indicatif::ProgressBar::hidden(),
        )
        .unwrap();
        let cells = cells("projectile", &report);
        let error = |name: &str| cells.iter().find(|c| c.setting == name).unwrap().error;
        assert!((error("symplectic, 1 sub-step") - 1.0 / 6.0).abs() < 1e-9);
        assert!((error("symplectic, 4 sub-steps") - 1.0 / 24.0).abs() < 1e-9);
        assert!(error("exact, 1 sub-step") < 1e-9);
    }

    #[test]
    fn the_front_keeps_only_settings_nothing_beats_on_both() {
        let cells = vec![
            cell("s", 1.0, 1.0),
            cell("s", 2.0, 0.5),
            cell("s", 3.0, 0.7),
            cell("t", 0.1, 9.0),
        ];
        let front: Vec<bool> = cells.iter().map(|c| on_front(c, &cells)).collect();
        assert_eq!(front, [true, true, false, true]);
    }
}
