//! Where a step's time goes (`ricochet-lab profile`, docs/bench/README.md): scenes run
//! headless with the world's stage profile on ([`ricochet_engine::world::StepProfile`], as
//! Box2D's `b2Profile`), every stage's time summed over the whole run.
//!
//! In: scenes and a number of steps. Out: per scene, each stage's mean microseconds a
//! step over every step of the run (the first included) and its share of the step, beside
//! the step's mean and median.

use std::path::Path;
use std::time::Duration;

use anyhow::{Context, Result};
use ricochet_engine::scene;
use ricochet_engine::world::StepProfile;

use crate::table::Table;

/// The scenes the page's table is measured on: the pile the speed issues name, a rain of
/// boxes and circles, and the chapter's particles demo.
pub const SCENES: &[&str] = &["pyramid-100.toml", "suite/rain.toml", "emitters.toml"];

/// How a stage's time is read from a profile.
type Stage = fn(&StepProfile) -> Duration;

/// The stages of a profile, as the table names them, and how each is read.
const STAGES: &[(&str, Stage)] = &[
    ("game rules (behaviours)", |p| p.hooks),
    ("broad phase (impulse solver)", |p| p.broad_phase),
    ("rigid stage, in all", |p| p.rigid),
    ("- contact search and preparation", |p| p.solve.search),
    ("- velocities integrated", |p| p.solve.integrate_velocities),
    ("- warm start", |p| p.solve.warm_start),
    ("- velocity passes", |p| p.solve.passes),
    ("- positions integrated", |p| p.solve.integrate_positions),
    ("- relax passes", |p| p.solve.relax),
    ("- restitution", |p| p.solve.restitution),
    ("- stored back", |p| p.solve.store),
    ("particles moved, emitters", |p| p.particles_move),
    ("particles against shapes", |p| p.particle_interactions),
    ("sleeping", |p| p.sleep),
    ("energies (the step's figures)", |p| p.energy),
];

/// One scene's run.
pub struct Row {
    pub scene: String,
    /// Each stage's time summed over the run, in [`STAGES`]' order.
    pub stages: Vec<Duration>,
    /// Every step's time, in order.
    pub steps: Vec<Duration>,
}

impl Row {
    /// Mean microseconds a step of `total` over the run.
    fn mean_us(&self, total: Duration) -> f64 {
        total.as_secs_f64() * 1e6 / self.steps.len().max(1) as f64
    }

    fn step_total(&self) -> Duration {
        self.steps.iter().sum()
    }

    fn median_us(&self) -> f64 {
        let mut us: Vec<f64> = self.steps.iter().map(|d| d.as_secs_f64() * 1e6).collect();
        us.sort_by(f64::total_cmp);
        crate::percentile(&us, 0.5)
    }
}

/// The profile of `names` (under `scenes`), `steps` steps each.
pub struct ProfileReport {
    pub steps: u64,
    pub rows: Vec<Row>,
    /// The `[world]` overrides every scene ran under.
    pub set: Vec<String>,
    /// The most threads a scene's step could use (its `threads`, at most the cores).
    pub threads: usize,
}

/// Runs each scene for `steps` steps, profiled, under the `[world]` overrides `set`
/// (NAME=VALUE).
pub fn run(scenes: &Path, names: &[String], steps: u64, set: &[String]) -> Result<ProfileReport> {
    let mut rows = Vec::new();
    let mut threads = 1;
    for name in names {
        let path = scenes.join(name);
        let text = std::fs::read_to_string(&path)
            .with_context(|| format!("cannot read scene {}", path.display()))?;
        let mut world = scene::parse(&text, &path, set)?;
        world.set_profiling(true);
        threads = threads.max(ricochet_engine::parallel::effective(world.config.threads));
        let mut row = Row {
            scene: name.clone(),
            stages: vec![Duration::ZERO; STAGES.len()],
            steps: Vec::with_capacity(steps as usize),
        };
        for _ in 0..steps {
            world.step();
            let p = world.profile();
            for (total, (_, read)) in row.stages.iter_mut().zip(STAGES) {
                *total += read(p);
            }
            row.steps.push(p.step);
        }
        rows.push(row);
    }
    Ok(ProfileReport {
        steps,
        rows,
        set: set.to_vec(),
        threads,
    })
}

impl ProfileReport {
    /// The table, a column per scene: each stage's mean microseconds a step and its share
    /// of the step.
    pub fn to_markdown(&self) -> String {
        let mut header = vec!["stage".to_string()];
        header.extend(
            self.rows
                .iter()
                .map(|r| format!("{}: us a step (share)", r.scene)),
        );
        let mut t = Table::new(header);
        let mut step = vec!["whole step, mean (median)".to_string()];
        step.extend(
            self.rows
                .iter()
                .map(|r| format!("{:.1} ({:.1})", r.mean_us(r.step_total()), r.median_us())),
        );
        t.row(step);
        for (k, (name, _)) in STAGES.iter().enumerate() {
            let mut cells = vec![name.to_string()];
            cells.extend(self.rows.iter().map(|r| {
                let total = r.stages[k];
                let share = total.as_secs_f64() / r.step_total().as_secs_f64().max(1e-12);
                format!("{:.1} ({:.0}%)", r.mean_us(total), share * 100.0)
            }));
            t.row(cells);
        }
        format!(
            "Measured by `{}` ({} steps of each scene from its start, every stage of every \
             step timed by the world's profile, means over every step; the rigid stage's \
             lines marked `-` are the impulse solver's own stages within it, the rest of it \
             being the chapter's relaxation where a scene names it, and the time between the \
             solver's stages{}; on {}):\n\n{t}",
            crate::command_line(),
            self.steps,
            if self.set.is_empty() {
                String::new()
            } else {
                format!("; every scene under `{}`", self.set.join("`, `"))
            },
            if self.threads > 1 {
                format!("{}, {} threads used", crate::cpu(), self.threads)
            } else {
                crate::machine()
            },
        )
    }
}
