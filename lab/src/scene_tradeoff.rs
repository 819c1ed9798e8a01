//! A measured scene as CSV, Markdown, a terminal table, a chart, and the index of several
//! (`ricochet-lab tradeoff --scene FILE`). The measure itself is the server's
//! ([`ricochet_server::accuracy::measure`]): the accuracy picker runs it at start-up.

use std::path::{Path, PathBuf};

use anyhow::{bail, Result};

use crate::chart::{panel, register_font, write_png, Point};
use crate::table::Table;
pub use ricochet_server::accuracy::measure::*;

/// A measured scene's pages.
pub trait ReportPages {
    /// The rows as CSV, a line each.
    fn to_csv(&self) -> Result<String>;
    /// What the reference is and how far it is to be trusted, in a line.
    fn reference_line(&self) -> String;
    /// The rows as a Markdown table.
    fn to_markdown(&self) -> String;
    /// The rows as a terminal table.
    fn to_text(&self) -> String;
    /// Time against error, the front marked, as a PNG at `path`.
    fn chart(&self, path: &Path) -> Result<()>;
    /// Writes `out/<stem>.csv`, `out/<stem>.png` and the page `out/<stem>.md`; returns the
    /// page's file name and the files written.
    fn write(&self, out: &Path, command: &str) -> Result<(String, [PathBuf; 3])>;
}

impl ReportPages for Report {
    /// The rows as CSV, a line each.
    fn to_csv(&self) -> Result<String> {
        #[derive(serde::Serialize)]
        struct Line<'a> {
            scene: String,
            setting: &'a str,
            overrides: String,
            ms_mean: f64,
            ms_median: f64,
            ms_p10: f64,
            ms_p90: f64,
            solver_work: u64,
            worst_error: f64,
            rms_error: f64,
            deepest_penetration: f64,
            worst_energy_change: f64,
            particle_worst_error: Option<f64>,
            particle_rms_error: Option<f64>,
            nan: bool,
            on_front: bool,
            fails: String,
        }
        let lines: Vec<Line> = self
            .rows
            .iter()
            .map(|r| Line {
                scene: self.scene.display().to_string(),
                setting: &r.name,
                overrides: r.overrides.join(";"),
                ms_mean: r.ms_mean,
                ms_median: r.ms_median,
                ms_p10: r.ms_spread.0,
                ms_p90: r.ms_spread.1,
                solver_work: r.work,
                worst_error: r.worst_error,
                rms_error: r.rms_error,
                deepest_penetration: r.deepest_penetration,
                worst_energy_change: r.worst_energy_change,
                particle_worst_error: r.particle_error.map(|e| e.0),
                particle_rms_error: r.particle_error.map(|e| e.1),
                nan: r.nan,
                on_front: r.on_front,
                fails: r.fails.join(";"),
            })
            .collect();
        crate::to_csv(&lines)
    }

    /// What the reference is and how far it is to be trusted, in one sentence.
    fn reference_line(&self) -> String {
        let r = &self.reference;
        let how = if r.converged {
            "converged".to_string()
        } else if r.stopped_by_budget {
            "not converged: the next refinement would have gone past the time budget".into()
        } else {
            "not converged within the refinements allowed".into()
        };
        let diverges = if r.diverges(self.unit) {
            format!(
                " The trajectories diverge: the refinements agree within a thousandth of the length unit over the first {} of {} steps only, and an error against the reference means nothing past there.",
                r.horizon(1e-3 * self.unit),
                self.steps
            )
        } else {
            String::new()
        };
        let judged = if self.stated_criteria {
            "Criteria: the scene's own `[criteria]`, over the measured steps."
        } else {
            "Criteria (the scene states none): escapes (`inside`), resting drift, penetration left at the end and, without gravity, energy made (and in an elastic world, energy lost), each against the reference's run."
        };
        let skipped = if self.skipped.is_empty() {
            String::new()
        } else {
            format!(" Left out by the time budget: {}.", self.skipped.join(", "))
        };
        format!(
            "Reference: {} ({} refinement{} of sub-steps and passes; the last two agree to {:.2e} units, worst over the run: {how}). Errors below {:.2e} are not resolved and show as that. The scene's length unit (median dynamic body size): {}.{diverges} {judged}{skipped}",
            r.name,
            r.refinements,
            if r.refinements == 1 { "" } else { "s" },
            r.agreement,
            r.resolution,
            self.unit,
        )
    }

    /// A Markdown table of the rows, the front marked.
    fn to_markdown(&self) -> String {
        let particles = self.features.particles;
        let mut header = vec![
            "setting",
            "mean ms/step (whole run)",
            "median (p10-p90)",
            "solver work",
            "worst error",
            "RMS error",
            "deepest penetration",
            "worst energy change",
        ];
        if particles {
            header.push("particle error worst / RMS");
        }
        header.extend(["fails", "front"]);
        let mut t = Table::new(header);
        for r in &self.rows {
            let mut cells = vec![
                r.name.clone(),
                format!("{:.5}", r.ms_mean),
                format!(
                    "{:.5} ({:.5}-{:.5})",
                    r.ms_median, r.ms_spread.0, r.ms_spread.1
                ),
                r.work.to_string(),
                format!("{:.2e}{}", r.worst_error, if r.nan { " NaN" } else { "" }),
                format!("{:.2e}", r.rms_error),
                format!("{:.2e}", r.deepest_penetration),
                format!("{:.2e}", r.worst_energy_change),
            ];
            if particles {
                let (w, rms) = r.particle_error.unwrap_or((0.0, 0.0));
                cells.push(format!("{w:.2e} / {rms:.2e}"));
            }
            cells.push(if r.fails.is_empty() {
                "none".to_string()
            } else {
                r.fails.join(", ")
            });
            cells.push((if r.on_front { "yes" } else { "" }).to_string());
            t.row(cells);
        }
        t.to_string()
    }

    /// A short table for the terminal.
    fn to_text(&self) -> String {
        let width = self
            .rows
            .iter()
            .map(|r| r.name.len())
            .max()
            .unwrap_or(7)
            .max(7);
        let mut out = format!(
            "{}: {} steps; {} dynamic, {} static bodies{}{}\n{}\n\n{:width$}  {:>10}  {:>10}  {:>10}  {:>10}  front\n",
            self.scene.display(),
            self.steps,
            self.features.dynamic,
            self.features.statics,
            if self.features.contacts { ", contacts" } else { ", no contacts" },
            if self.features.particles { ", particles" } else { "" },
            self.reference_line(),
            "setting",
            "mean ms",
            "worst err",
            "RMS err",
            "energy",
        );
        for r in &self.rows {
            out += &format!(
                "{:width$}  {:>10.5}  {:>10.2e}  {:>10.2e}  {:>10.2e}  {}\n",
                r.name,
                r.ms_mean,
                r.worst_error,
                r.rms_error,
                r.worst_energy_change,
                if r.nan {
                    "NaN"
                } else if r.on_front {
                    "*"
                } else {
                    ""
                },
            );
        }
        out
    }

    /// Time against error on log scales, the front in red, as a PNG.
    fn chart(&self, path: &Path) -> Result<()> {
        use plotters::prelude::*;
        register_font()?;
        let rows: Vec<&Row> = self.rows.iter().filter(|r| !r.nan).collect();
        if rows.is_empty() {
            bail!("every candidate gave NaN: nothing to chart");
        }
        write_png(path, (1100, 700), |root| {
            root.fill(&WHITE)?;
            let (plot, legend) = root.split_horizontally(700);
            let title = self
                .scene
                .file_name()
                .map_or("scene".into(), |n| n.to_string_lossy().into_owned());
            let points: Vec<Point> = self
                .rows
                .iter()
                .enumerate()
                .filter(|(_, r)| !r.nan)
                .map(|(k, r)| Point {
                    ms: r.ms_mean,
                    error: judged_error(r),
                    front: r.on_front,
                    label: k + 1,
                })
                .collect();
            panel(
                &plot,
                &title,
                "worst position error over the run (units)",
                &points,
            )?;
            legend.draw(&Text::new(
                "Settings (red: on the front)",
                (10, 20),
                ("sans-serif", 17),
            ))?;
            for (k, r) in self.rows.iter().enumerate() {
                legend.draw(&Text::new(
                    format!("{}  {}{}", k + 1, r.name, if r.nan { " (NaN)" } else { "" }),
                    (10, 48 + 22 * k as i32),
                    ("sans-serif", 14),
                ))?;
            }
            Ok(())
        })
    }

    /// Writes `out/<stem>.csv`, `out/<stem>.png` and the page `out/<stem>.md` (its table
    /// and chart, saying it was generated by `command`), where `stem` is the scene file's.
    /// Returns the page's file name and the files written.
    fn write(&self, out: &Path, command: &str) -> Result<(String, [PathBuf; 3])> {
        let stem = self
            .scene
            .file_stem()
            .map_or("scene".into(), |s| s.to_string_lossy().into_owned());
        let (csv, png, md) = (
            out.join(format!("{stem}.csv")),
            out.join(format!("{stem}.png")),
            out.join(format!("{stem}.md")),
        );
        std::fs::write(&csv, self.to_csv()?)?;
        self.chart(&png)?;
        std::fs::write(
            &md,
            format!(
                "# Speed against accuracy: `{}`\n\nGenerated by `{command}` on {}; not edited by hand.\n\n{}\n\n{}\n![time against error]({stem}.png)\n",
                self.scene.display(),
                crate::machine(),
                self.reference_line(),
                self.to_markdown(),
            ),
        )?;
        Ok((format!("{stem}.md"), [csv, png, md]))
    }
}

/// Writes `out/index.md`: a line per scene page ([`index`]), saying it was generated by
/// `command`. Returns the file written.
pub fn write_index(out: &Path, pages: &[(String, Report)], command: &str) -> Result<PathBuf> {
    let file = out.join("index.md");
    std::fs::write(
        &file,
        format!(
            "# Speed against accuracy, scene by scene\n\nGenerated by `{command}` on {}; not edited by hand. Each scene's page has its full table and chart.\n\n{}",
            crate::machine(),
            index(pages),
        ),
    )?;
    Ok(file)
}

/// One line per scene: what it holds, how far its reference is to be trusted, and the
/// ends of its front (the fastest setting on it, and the most accurate).
pub fn index(pages: &[(String, Report)]) -> String {
    let mut t = Table::new([
        "scene",
        "bodies (dynamic / static)",
        "holds",
        "reference agrees to",
        "fastest on the front",
        "most accurate on the front",
    ]);
    for (page, r) in pages {
        let front: Vec<&Row> = r.rows.iter().filter(|row| row.on_front).collect();
        let fastest = front.iter().min_by(|a, b| a.ms_mean.total_cmp(&b.ms_mean));
        let finest = front
            .iter()
            .min_by(|a, b| judged_error(a).total_cmp(&judged_error(b)));
        let cell = |row: Option<&&Row>| {
            row.map_or("none".to_string(), |row| {
                format!(
                    "{}: {:.4} ms, {:.1e}",
                    row.name,
                    row.ms_mean,
                    judged_error(row)
                )
            })
        };
        let holds = [
            (r.features.contacts, "contacts"),
            (r.features.particles, "particles"),
        ]
        .iter()
        .filter(|(on, _)| *on)
        .map(|(_, what)| *what)
        .collect::<Vec<_>>()
        .join(", ");
        t.row([
            format!(
                "[{}]({page})",
                r.scene
                    .file_name()
                    .map_or(String::new(), |n| n.to_string_lossy().into_owned())
            ),
            format!("{} / {}", r.features.dynamic, r.features.statics),
            if holds.is_empty() {
                "flight only".into()
            } else {
                holds
            },
            format!(
                "{:.1e}{}",
                r.reference.agreement,
                if r.reference.converged {
                    ""
                } else {
                    " (not converged)"
                }
            ),
            cell(fastest),
            cell(finest),
        ]);
    }
    t.to_string()
}
