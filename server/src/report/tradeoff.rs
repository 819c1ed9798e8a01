//! Speed against accuracy, measured (`ricochet-server tradeoff`): a matrix of shipped
//! scenes (`assets/scenes/`, embedded at build time) and solver settings; per cell the median time per step and what the setting buys: error
//! against closed-form answers, penetration, drift of resting bodies, energy drift, NaN.

use std::time::Instant;

use glam::DVec2;

use ricochet_engine::dynamics::config::{Integrator, Solver, WorldConfig};
use ricochet_engine::dynamics::BroadPhase;
use ricochet_engine::world::World;

/// A setting of the matrix: a name and the knobs it turns.
#[derive(Clone, Debug)]
pub struct Setting {
    pub name: String,
    pub config: WorldConfig,
}

/// The settings measured.
/// `base` with the impulse solver, split impulses (baumgarte 0.5, slop 1e-4) and the grid
/// broad phase: the shipped pyramid-100 scene's solver.
fn split_setting(base: &WorldConfig, iterations: u32, substeps: u32) -> WorldConfig {
    WorldConfig {
        solver: Solver::Impulses,
        impulse_iterations: iterations,
        substeps,
        split_impulses: true,
        baumgarte: 0.5,
        slop: 0.0001,
        broad_phase: BroadPhase::Grid,
        ..base.clone()
    }
}

pub fn settings() -> Vec<Setting> {
    let base = WorldConfig {
        gravity: DVec2::new(0.0, -10.0),
        mass_scaled_acceleration: false,
        ..WorldConfig::default()
    };
    let s = |name: &str, f: &dyn Fn(&mut WorldConfig)| {
        let mut config = base.clone();
        f(&mut config);
        Setting {
            name: name.to_string(),
            config,
        }
    };
    vec![
        s("relaxation 15 (chapter), all pairs", &|c| {
            c.broad_phase = BroadPhase::AllPairs
        }),
        s("relaxation 15 (chapter)", &|_| {}),
        s("relaxation 15, explicit Euler", &|c| {
            c.integrator = Integrator::Explicit
        }),
        s("relaxation 15, exact flight", &|c| {
            c.integrator = Integrator::Exact
        }),
        s("relaxation 5", &|c| c.relaxation_iterations = 5),
        s("relaxation 50", &|c| c.relaxation_iterations = 50),
        s("relaxation 15, 4 sub-steps", &|c| c.substeps = 4),
        s("impulses 4 it", &|c| {
            c.solver = Solver::Impulses;
            c.impulse_iterations = 4;
        }),
        s("impulses 8 it", &|c| c.solver = Solver::Impulses),
        s("impulses 8 it, exact flight", &|c| {
            c.solver = Solver::Impulses;
            c.integrator = Integrator::Exact;
        }),
        s("impulses 8 it, 2 sub-steps", &|c| {
            c.solver = Solver::Impulses;
            c.substeps = 2;
        }),
        s("impulses 8 it, 4 sub-steps", &|c| {
            c.solver = Solver::Impulses;
            c.substeps = 4;
        }),
        s("impulses 8 it, no warm start", &|c| {
            c.solver = Solver::Impulses;
            c.warm_starting = false;
        }),
        s("impulses 6 it, split, grid", &|c| {
            *c = split_setting(c, 6, 1)
        }),
        s("impulses 4 it, 2 sub-steps, split, grid", &|c| {
            *c = split_setting(c, 4, 2)
        }),
        s("soft 1 it + 1 relax, 4 sub-steps, grid", &|c| {
            c.solver = Solver::Impulses;
            c.impulse_iterations = 1;
            c.relax_iterations = 1;
            c.substeps = 4;
            c.contact_hertz = 30.0;
            c.broad_phase = BroadPhase::Grid;
        }),
    ]
}

/// One cell of the matrix.
#[derive(Clone, Debug)]
pub struct Cell {
    pub scene: &'static str,
    pub setting: String,
    pub ms_per_step: f64,
    /// The scene's error against its closed form (projectile, bounce, slide), or the worst
    /// drift of a resting body (stack, pyramid), in units of the body's size.
    pub error: f64,
    pub error_name: &'static str,
    /// Deepest penetration over the run, in units of the smaller body's size.
    pub deepest_penetration: f64,
    /// Mean over steps of each step's deepest penetration, in body sizes.
    pub mean_penetration: f64,
    /// Relative change of total energy (kinetic + potential) from start to end.
    pub energy_drift: f64,
    pub nan: bool,
}

fn energy(w: &World) -> f64 {
    let g = -w.config.gravity.y;
    w.bodies()
        .iter()
        .filter(|b| !b.is_static())
        .map(|b| b.kinetic_energy() + b.mass() * g * b.pos.y)
        .sum()
}

/// The scenes of the matrix: (name, steps, builder).
type Builder = fn(WorldConfig) -> World;

/// A shipped scene (the file users run, embedded at build time) under the setting `c`
/// in place of its own `[world]` (the stack and pyramid scenes declare gravity -10,
/// unscaled acceleration and 15 relaxation passes, as the settings' base does).
fn shipped(name: &str, text: &str, c: WorldConfig) -> World {
    let path = std::path::Path::new("assets/scenes").join(name);
    let mut w = ricochet_engine::scene::parse(text, &path, &[])
        .unwrap_or_else(|e| panic!("the shipped scene {name} loads: {e}"));
    w.config = c;
    w
}

fn projectile(c: WorldConfig) -> World {
    shipped(
        "projectile.toml",
        include_str!("../../../assets/scenes/projectile.toml"),
        c,
    )
}

fn bounce(c: WorldConfig) -> World {
    shipped(
        "bounce.toml",
        include_str!("../../../assets/scenes/bounce.toml"),
        c,
    )
}

fn slide(c: WorldConfig) -> World {
    shipped(
        "slide.toml",
        include_str!("../../../assets/scenes/slide.toml"),
        c,
    )
}

fn stack(c: WorldConfig) -> World {
    shipped(
        "stack-20.toml",
        include_str!("../../../assets/scenes/stack-20.toml"),
        c,
    )
}

fn pyramid(c: WorldConfig) -> World {
    shipped(
        "pyramid-10.toml",
        include_str!("../../../assets/scenes/pyramid-10.toml"),
        c,
    )
}

/// The scenes: name, steps, builder, what the error measures.
pub const SCENES: &[(&str, u64, Builder, &str)] = &[
    (
        "projectile",
        120,
        projectile,
        "position error after 2 s (units)",
    ),
    (
        "bounce",
        600,
        bounce,
        "relative energy drift after 10 s (restitution 1)",
    ),
    (
        "slide",
        120,
        slide,
        "position error after 2 s, frictionless (units)",
    ),
    (
        "stack-20",
        600,
        stack,
        "worst drift of a box over the run (box sizes)",
    ),
    (
        "pyramid-10",
        300,
        pyramid,
        "worst drift of a box over the run (box sizes)",
    ),
];

/// Runs one cell.
pub fn measure(
    scene: &'static str,
    steps: u64,
    build: Builder,
    error_name: &'static str,
    setting: &Setting,
) -> Cell {
    let mut w = build(setting.config.clone());
    let start: Vec<DVec2> = w.bodies().iter().map(|b| b.pos).collect();
    let v0: Vec<DVec2> = w.bodies().iter().map(|b| b.vel).collect();
    let e0 = energy(&w);
    let mut times = Vec::with_capacity(steps as usize);
    let (mut deepest, mut sum_deepest) = (0.0f64, 0.0);
    let mut nan = false;
    // The piles' error: the worst drift of any box over every step, not at the last.
    let pile = !matches!(scene, "projectile" | "slide" | "bounce");
    let mut worst_drift: f64 = 0.0;
    for _ in 0..steps {
        let t = Instant::now();
        w.step();
        times.push(t.elapsed().as_secs_f64() * 1e3);
        if pile {
            worst_drift = w
                .bodies()
                .iter()
                .zip(&start)
                .map(|(b, p)| (b.pos - *p).length())
                .fold(worst_drift, f64::max);
        }
        let d = w.stats().deepest_penetration;
        deepest = deepest.max(d);
        sum_deepest += d;
        nan |= w.bodies().iter().any(|b| !b.pos.is_finite());
    }
    times.sort_by(f64::total_cmp);
    let t = w.time();
    let g = w.config.gravity;
    let error = match scene {
        "projectile" => {
            let exact = start[0] + v0[0] * t + g * (0.5 * t * t);
            (w.bodies()[0].pos - exact).length()
        }
        "slide" => {
            let b = w.body("box").expect("box");
            (b.pos - (start[1] + v0[1] * t)).length()
        }
        "bounce" => ((energy(&w) - e0) / e0).abs(),
        _ => worst_drift,
    };
    Cell {
        scene,
        setting: setting.name.clone(),
        ms_per_step: times[times.len() / 2],
        error: if nan { f64::NAN } else { error },
        error_name,
        deepest_penetration: deepest,
        mean_penetration: sum_deepest / steps as f64,
        energy_drift: if e0 != 0.0 {
            (energy(&w) - e0) / e0.abs()
        } else {
            0.0
        },
        nan,
    }
}

/// The whole matrix.
pub fn run_matrix() -> Vec<Cell> {
    let mut cells = Vec::new();
    for &(scene, steps, build, error_name) in SCENES {
        for setting in settings() {
            cells.push(measure(scene, steps, build, error_name, &setting));
        }
    }
    cells
}

/// The cells as CSV.
pub fn to_csv(cells: &[Cell]) -> String {
    let mut out = String::from("scene,setting,ms_per_step,error,error_measure,deepest_penetration,mean_penetration,energy_drift,nan\n");
    for c in cells {
        out += &format!(
            "{},\"{}\",{:.6},{:.6e},\"{}\",{:.6e},{:.6e},{:.6e},{}\n",
            c.scene,
            c.setting,
            c.ms_per_step,
            c.error,
            c.error_name,
            c.deepest_penetration,
            c.mean_penetration,
            c.energy_drift,
            c.nan
        );
    }
    out
}

/// The cells as a Markdown table, the front marked.
pub fn to_markdown(cells: &[Cell]) -> String {
    let mut out = String::from(
        "| scene | setting | median ms/step | error | error measure | deepest penetration (sizes) | energy drift | front |\n|---|---|---|---|---|---|---|---|\n",
    );
    for c in cells {
        out += &format!(
            "| {} | {} | {:.4} | {:.3e}{} | {} | {:.2e} | {:+.2e} | {} |\n",
            c.scene,
            c.setting,
            c.ms_per_step,
            c.error,
            if c.nan { " NaN" } else { "" },
            c.error_name,
            c.deepest_penetration,
            c.energy_drift,
            if on_front(c, cells) { "yes" } else { "" },
        );
    }
    out
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

/// Where the chart's font is looked for (Debian's fonts-dejavu-core).
pub const FONT: &str = "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf";

/// Registers [`FONT`] as the charts' sans-serif (once; later calls do nothing).
pub fn register_font() -> anyhow::Result<()> {
    static REGISTERED: std::sync::OnceLock<Result<(), String>> = std::sync::OnceLock::new();
    REGISTERED
        .get_or_init(|| {
            let font = std::fs::read(FONT).map_err(|e| {
                format!("the chart needs the font {FONT} (Debian: fonts-dejavu-core): {e}")
            })?;
            plotters::style::register_font(
                "sans-serif",
                plotters::style::FontStyle::Normal,
                Box::leak(font.into_boxed_slice()),
            )
            .map_err(|_| format!("{FONT} is not a usable font"))
        })
        .clone()
        .map_err(|e| anyhow::anyhow!(e))
}

/// Draws time against error per scene, the front in red, as a PNG.
pub fn chart(cells: &[Cell], path: &std::path::Path) -> anyhow::Result<()> {
    use plotters::prelude::*;
    register_font()?;
    let names: Vec<String> = settings().into_iter().map(|s| s.name).collect();
    let root = BitMapBackend::new(path, (1500, 950)).into_drawing_area();
    root.fill(&WHITE)?;
    let panels = root.split_evenly((2, 3));
    for (panel, &(scene, _, _, error_name)) in panels.iter().zip(SCENES) {
        let mine: Vec<&Cell> = cells
            .iter()
            .filter(|c| c.scene == scene && !c.nan)
            .collect();
        if mine.is_empty() {
            continue;
        }
        let floor = 1e-9;
        let (xs, ys): (Vec<f64>, Vec<f64>) = mine
            .iter()
            .map(|c| (c.ms_per_step.max(1e-6), c.error.max(floor)))
            .unzip();
        let (x0, x1) = (
            xs.iter().cloned().fold(f64::MAX, f64::min) / 1.5,
            xs.iter().cloned().fold(0.0, f64::max) * 1.5,
        );
        let (y0, y1) = (
            ys.iter().cloned().fold(f64::MAX, f64::min) / 3.0,
            ys.iter().cloned().fold(0.0, f64::max) * 3.0,
        );
        let mut chart = ChartBuilder::on(panel)
            .caption(scene, ("sans-serif", 22))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())?;
        chart
            .configure_mesh()
            .x_desc("median ms per step")
            .y_desc(error_name)
            .axis_desc_style(("sans-serif", 13))
            .x_label_formatter(&|v| format!("{v:.2e}"))
            .y_label_formatter(&|v| format!("{v:.0e}"))
            .x_labels(5)
            .label_style(("sans-serif", 12))
            .draw()?;
        let mut front: Vec<(f64, f64)> = mine
            .iter()
            .filter(|c| on_front(c, cells))
            .map(|c| (c.ms_per_step.max(1e-6), c.error.max(floor)))
            .collect();
        front.sort_by(|a, b| a.0.total_cmp(&b.0));
        chart.draw_series(LineSeries::new(front.clone(), RED.stroke_width(2)))?;
        for c in &mine {
            let at = (c.ms_per_step.max(1e-6), c.error.max(floor));
            let colour = if on_front(c, cells) { RED } else { BLUE };
            let index = names.iter().position(|n| *n == c.setting).unwrap_or(0) + 1;
            chart.draw_series(std::iter::once(
                EmptyElement::at(at)
                    + Circle::new((0, 0), 5, colour.filled())
                    + Text::new(format!("{index}"), (7, -7), ("sans-serif", 13)),
            ))?;
        }
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
                (10, 50 + 24 * k as i32),
                ("sans-serif", 15),
            ))?;
        }
    }
    root.present()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cell(scene: &'static str, ms: f64, error: f64) -> Cell {
        Cell {
            scene,
            setting: String::new(),
            ms_per_step: ms,
            error,
            error_name: "",
            deepest_penetration: 0.0,
            mean_penetration: 0.0,
            energy_drift: 0.0,
            nan: false,
        }
    }

    #[test]
    fn the_projectiles_error_is_symplectic_eulers_lag() {
        // Symplectic Euler from v0 under g: p_n = p0 + v0 t + g dt² n(n+1)/2, so the error
        // against p0 + v0 t + g t²/2 is |g| dt t / 2: 10 x (1/60) x 2 / 2 = 1/6 after 2 s.
        let setting = &settings()[1];
        let c = measure("projectile", 120, projectile, "", setting);
        assert!((c.error - 1.0 / 6.0).abs() < 1e-6, "{}", c.error);
        let sub4 = settings()
            .into_iter()
            .find(|s| s.config.substeps == 4 && s.config.solver == Solver::Relaxation)
            .unwrap();
        let c = measure("projectile", 120, projectile, "", &sub4);
        assert!(
            (c.error - 1.0 / 24.0).abs() < 1e-6,
            "4 sub-steps quarter the lag: {}",
            c.error
        );
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
