//! The generated page and table: `peers.md` (the engines and their settings, one table
//! per scene, a summary) and `peers.csv` (one row per scene and engine).

use std::fmt::Write as _;
use std::path::Path;

use anyhow::{Context, Result};
use ricochet_engine::dynamics::WorldConfig;

use crate::engine::EngineKind;
use crate::run::Outcome;
use crate::scene::Scene;

/// Every criterion a scene may state, in the monitor's order (the CSV's columns).
const CRITERIA: [&str; 7] = [
    "inside",
    "drift",
    "overlap",
    "final_overlap",
    "speed",
    "final_speed",
    "energy_rise",
];

/// What the page says about the run besides the scenes' figures.
pub struct Setup {
    /// The command that wrote the page.
    pub command: String,
    pub rounds: usize,
    /// "2 cores, AMD EPYC".
    pub machine: String,
    /// The scenes' directory as the page names it (`assets/scenes/suite/`).
    pub scenes: String,
    pub box2d_version: String,
    pub boxdd_version: String,
    pub rapier_version: String,
    /// Ricochet's settings, as the suite's scenes get them (the default under
    /// `overrides`).
    pub ricochet: WorldConfig,
    /// The `--set` overrides Ricochet ran under (none: its default).
    pub overrides: Vec<String>,
    /// This machine's bandwidth and peak arithmetic, measured before the scenes ran.
    pub limits: crate::limit::Machine,
}

/// One scene's outcomes, engines in [`EngineKind::ALL`] order.
pub struct SceneResult {
    pub name: String,
    pub bodies: usize,
    pub dynamic: usize,
    pub steps: u64,
    pub outcomes: Vec<Outcome>,
}

impl SceneResult {
    pub fn new(scene: &Scene, outcomes: Vec<Outcome>) -> SceneResult {
        SceneResult {
            name: scene.name.clone(),
            bodies: scene.bodies().len(),
            dynamic: scene.dynamic_count(),
            steps: scene.steps(),
            outcomes,
        }
    }

    pub(crate) fn outcome(&self, engine: EngineKind) -> &Outcome {
        self.outcomes
            .iter()
            .find(|o| o.engine == engine)
            .expect("every engine ran")
    }

    /// Box2D's mean time over `engine`'s (above 1: `engine` is faster than Box2D).
    pub(crate) fn box2d_ratio(&self, engine: EngineKind) -> f64 {
        self.outcome(EngineKind::Box2d).mean_ms / self.outcome(engine).mean_ms
    }
}

/// Writes `dir/peers.md` and `dir/peers.csv`.
pub fn write(dir: &Path, ctx: &Setup, results: &[SceneResult]) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let md = dir.join("peers.md");
    std::fs::write(&md, page(ctx, results)).with_context(|| format!("writing {}", md.display()))?;
    let csv = dir.join("peers.csv");
    write_csv(&csv, ctx, results).with_context(|| format!("writing {}", csv.display()))?;
    Ok(())
}

fn page(ctx: &Setup, results: &[SceneResult]) -> String {
    let c = &ctx.ricochet;
    let mut s = String::new();
    let precision = if crate::box2d::DOUBLE_PRECISION {
        "positions in f64 (`--features double`)"
    } else {
        "positions in f32 (build with `--features double` for f64; the far pyramid at \
         (1e5, 1e5) ran in f32)"
    };
    let what = if ctx
        .scenes
        .trim_end_matches('/')
        .ends_with("assets/scenes/suite")
    {
        "the suite of scene kinds".to_string()
    } else {
        format!("the scenes of `{}`", ctx.scenes)
    };
    let _ = writeln!(
        s,
        "Written by `{}` (lab/peers/src/table.rs); do not edit by hand.\n\n\
         # Ricochet against Box2D v3 and rapier2d on {what}\n\n\
         Every scene of `{}` run in the three engines (Ricochet on one \
         thread and on two), alternated: each of {} rounds runs every engine once on a \
         fresh build of the scene, the order rotated every round. Each step is timed from the first (start-up included, no \
         warm-up); a run's mean and median ms a step are taken, then the median of each \
         over the rounds. After every step the dynamic bodies' positions and velocities \
         go to the scene's criteria monitor (`ricochet_engine::criteria::Monitor`), so \
         every engine is judged by the same code.\n\n\
         Machine: {}. Every engine on one thread; Ricochet on two as well (the row \
         \"Ricochet, 2 threads\": the same settings with `threads = 2`).\n\n\
         ## Engines\n\n\
         - **Ricochet**: the default (`WorldConfig::default`){}: solver {:?}, {} sub-steps of \
         {} passes, warm starting {}, resting load {}, split impulses {}, continuous \
         collision {}, sleeping {}, {} thread; f64.\n\
         - **Box2D v3** {} (the bundled C source of boxdd {}, compiled by cc with boxdd's \
         `simd-avx2`, AVX2): {} sub-steps a step, one worker and no task system, sleeping \
         as Ricochet's (world and bodies; its own tolerances, 0.05 units/s for 0.5 s), continuous collision on (its default: dynamic against \
         static), contact events off, speed cap raised from 400 to {} units/s (the bullets \
         fly at 600); {precision}. Every dynamic body has its rotation locked by the \
         motion lock and by mass data of rotational inertia 0 (mass 1/inv_mass, centre 0): \
         the lock alone only zeroes the angular velocity and stacks go soft.\n\
         - **rapier2d** {} (f32, one thread, no `parallel` feature): {} solver iterations, \
         sleeping as Ricochet's (its own thresholds), rotation locked, CCD on every dynamic body (as Box2D's \
         continuous collision; the bullets would cross the wall without it), speed cap \
         off (its default is 400 units/s).\n\n\
         Bodies: Ricochet's rectangles as boxes of the same half extents, circles of the \
         same radius, static bodies as static (fixed) bodies, the same positions, initial \
         velocities, masses (1/inv_mass) and gravity, `dt` = {:.6} s. Collision filters: \
         one bit per group of the scene; a group's mask holds each group an interaction \
         with `resolve = true` pairs it with (Box2D category and mask bits, rapier \
         interaction groups).\n\n\
         ## Materials\n\n\
         Ricochet combines a pair's materials as friction sqrt(fa * fb) and restitution \
         min(ea, eb). Box2D: its default friction mixing is already sqrt(fa * fb); its \
         default restitution mixing (the maximum, which would make the suite's static \
         bodies, left at restitution 0.8, bouncy) is replaced by a restitution callback \
         returning min(ea, eb). rapier: each collider carries its own friction and \
         restitution, with `CoefficientCombineRule::GeometricMean` for friction and \
         `CoefficientCombineRule::Min` for restitution. Every pair gets Ricochet's \
         coefficients in every engine, exactly.\n",
        ctx.command,
        ctx.scenes,
        ctx.rounds,
        ctx.machine,
        if ctx.overrides.is_empty() {
            String::new()
        } else {
            format!(" under `{}`", ctx.overrides.join(" "))
        },
        c.solver,
        c.substeps,
        c.impulse_iterations,
        on(c.warm_starting),
        on(c.rest_load),
        on(c.split_impulses),
        on(c.ccd),
        on(c.sleeping),
        c.threads,
        ctx.box2d_version,
        ctx.boxdd_version,
        crate::box2d::SUB_STEPS,
        crate::box2d::MAX_LINEAR_SPEED,
        ctx.rapier_version,
        crate::rapier::SOLVER_ITERATIONS,
        c.dt,
    );
    let _ = writeln!(s, "## Scenes\n");
    for r in results {
        scene_table(&mut s, r);
    }
    let names: Vec<&str> = EngineKind::ALL.iter().map(|e| e.name()).collect();
    let _ = writeln!(
        s,
        "## Summary\n\n\
         Holds: every criterion of the scene holds. Ratio: Box2D's mean time a step over \
         Ricochet's (above 1: Ricochet is faster).\n\n\
         | scene | holds: {} | Box2D / Ricochet mean time | Box2D / Ricochet on 2 threads |\n\
         |---|---|---:|---:|",
        names.join(" / ")
    );
    for r in results {
        let holds: Vec<&str> = EngineKind::ALL
            .iter()
            .map(|&e| yes_no(r.outcome(e).holds()))
            .collect();
        let _ = writeln!(
            s,
            "| {} | {} | {:.2} | {:.2} |",
            r.name,
            holds.join(" / "),
            r.box2d_ratio(EngineKind::Ricochet),
            r.box2d_ratio(EngineKind::Ricochet2)
        );
    }
    crate::families::table(&mut s, results);
    phases_table(&mut s, results);
    threads_table(&mut s, results);
    limit_table(&mut s, ctx, results);
    s
}

/// Each engine's mean time a step in each part of the run, and Box2D's over Ricochet's:
/// where in a scene's run one engine gains on the other.
fn phases_table(s: &mut String, results: &[SceneResult]) {
    let parts = crate::run::PHASES;
    let _ = writeln!(
        s,
        "\n## Over the run\n\n\
         Each run cut into {parts} parts of equal step counts (the last takes the steps \
         left over), in order: the mean ms a step of each part (the median over the \
         rounds), for Ricochet on one thread and Box2D v3, and Box2D's over Ricochet's. \
         The whole run's ratio (the summary's) is the ratio of the parts' sums, not their \
         mean: a part that costs both engines more weighs more.\n\n\
         | scene | Ricochet ms/step, parts 1 to {parts} | Box2D ms/step | Box2D / Ricochet |\n\
         |---|---|---|---|"
    );
    let join = |xs: &[f64], digits: usize| {
        xs.iter()
            .map(|x| format!("{x:.digits$}"))
            .collect::<Vec<_>>()
            .join(" / ")
    };
    for r in results {
        let (ours, theirs) = (
            &r.outcome(EngineKind::Ricochet).phases,
            &r.outcome(EngineKind::Box2d).phases,
        );
        if ours.len() != parts || theirs.len() != parts {
            continue;
        }
        let ratios: Vec<f64> = theirs.iter().zip(ours).map(|(b, o)| b / o).collect();
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} |",
            r.name,
            join(ours, 3),
            join(theirs, 3),
            join(&ratios, 2)
        );
    }
}

/// Ricochet on two threads against one: the speed-up and whether the final states agree
/// bit for bit.
fn threads_table(s: &mut String, results: &[SceneResult]) {
    let _ = writeln!(
        s,
        "\n## Two threads\n\n\
         Ricochet's default with `threads = 2` against `threads = 1`, in the same rounds: \
         the mean time a step over the whole run, the speed-up (one thread's time over two \
         threads'), and whether the two runs end in the same state bit for bit (every \
         body's position and velocity). Work is split only where it splits without \
         changing a bit (blocks of contacts that share no moving body, chunks of at \
         least {} particles), so small scenes stay on one thread. Why the speed-up stays \
         under 1.7x on large piles too (the support sweep, the pile's order and the broad \
         phase run in sequence: about a third of their step) and what was measured: \
         docs/bench/engine-notes.md, \"Why two threads stay far from 1.7x\".\n\n\
         | scene | 1 thread ms/step | 2 threads ms/step | speed-up | same bits |\n\
         |---|---:|---:|---:|---|",
        ricochet_engine::parallel::MIN_SPLIT
    );
    for r in results {
        let one = r.outcome(EngineKind::Ricochet);
        let two = r.outcome(EngineKind::Ricochet2);
        let same = one.digest.is_some() && one.digest == two.digest;
        let _ = writeln!(
            s,
            "| {} | {:.3} | {:.3} | {:.2} | {} |",
            r.name,
            one.mean_ms,
            two.mean_ms,
            one.mean_ms / two.mean_ms,
            yes_no(same)
        );
    }
}

/// How far Ricochet's one-thread step is from this machine's limits.
fn limit_table(s: &mut String, ctx: &Setup, results: &[SceneResult]) {
    use crate::limit::*;
    let m = &ctx.limits;
    let too_big: Vec<&str> = results
        .iter()
        .filter(|r| {
            let w = r.outcome(EngineKind::Ricochet).work;
            match (w, m.l2_cache) {
                (Some(w), Some(l2)) => w.working_set > l2,
                _ => false,
            }
        })
        .map(|r| r.name.as_str())
        .collect();
    let fit = match (m.l2_cache, too_big.is_empty()) {
        (None, _) => "The cache's size is not known here.".to_string(),
        (Some(_), true) => "Every scene's fits in the level-2 cache: the passes read \
            their bytes from the caches, not from memory."
            .to_string(),
        (Some(_), false) => format!(
            "Larger than the level-2 cache: {}; the others fit, and their passes read \
             their bytes from the caches, not from memory.",
            too_big.join(", ")
        ),
    };
    let l2 = match m.l2_cache {
        Some(b) => format!("{} KiB", b >> 10),
        None => "not reported".to_string(),
    };
    let _ = writeln!(
        s,
        "\n## Distance to the machine's limits\n\n\
         This machine on one core, measured by this run: memory bandwidth {:.1} GB/s (a \
         triad `a = b + s c` over three arrays of 64 MiB, the best of 5; reads and writes \
         counted), peak arithmetic {:.1} Gflop/s ({}, independent multiply-adds, the best \
         of 5). Level-2 cache of a core: {l2}.\n\n\
         Ricochet's work a step, from a model: the engine counts each step's contacts and \
         velocity passes as they run (`StepStats`), and the model prices a contact in a \
         pass at {} bytes (its {}-byte row read, its impulses written, both {}-byte \
         bodies read and their velocities written) and {} double operations (counted by \
         hand in `solve_contact`), and a moving body in a sub-step at {} bytes and {} \
         operations. The contact search and the rest of the step are not priced, so the \
         work and the fractions are lower bounds. The fractions: the work a step over \
         the measured mean time a step (whole run, one thread), over the machine's \
         figure. The working set is every contact row and moving body, at its largest \
         over the run. {fit} A share of bandwidth therefore compares the passes' traffic \
         with what memory alone could feed; a small share of peak arithmetic says the \
         passes wait on their data (each contact reads the bodies the one before it \
         wrote), not on arithmetic.\n\n\
         | scene | contacts a step | contact visits a step | working set KiB | MB a step | Mflop a step | mean ms/step | GB/s | share of bandwidth | Gflop/s | share of peak |\n\
         |---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
        m.bandwidth / 1e9,
        m.peak_flops / 1e9,
        m.peak_kind,
        BYTES_PER_CONTACT_PASS,
        ricochet_engine::dynamics::impulse::CONTACT_ROW_BYTES,
        ricochet_engine::dynamics::impulse::SOLVER_BODY_BYTES,
        FLOPS_PER_CONTACT_PASS,
        BYTES_PER_BODY_SUBSTEP,
        FLOPS_PER_BODY_SUBSTEP,
    );
    for r in results {
        let one = r.outcome(EngineKind::Ricochet);
        let Some(w) = one.work else { continue };
        let steps = w.steps.max(1) as f64;
        let seconds = one.mean_ms / 1e3;
        let bytes = w.bytes_per_step();
        let flops = w.flops_per_step();
        let _ = writeln!(
            s,
            "| {} | {:.0} | {:.0} | {:.0} | {:.3} | {:.3} | {:.3} | {:.2} | {:.1}% | {:.3} | {:.2}% |",
            r.name,
            w.contacts as f64 / steps,
            w.contact_passes as f64 / steps,
            w.working_set as f64 / 1024.0,
            bytes / 1e6,
            flops / 1e6,
            one.mean_ms,
            bytes / seconds / 1e9,
            100.0 * bytes / seconds / m.bandwidth,
            flops / seconds / 1e9,
            100.0 * flops / seconds / m.peak_flops,
        );
    }
}

fn scene_table(s: &mut String, r: &SceneResult) {
    let judged: Vec<&str> = r.outcomes[0].verdict.iter().map(|j| j.name).collect();
    let _ = writeln!(
        s,
        "### {}\n\n{} bodies ({} dynamic), {} steps.\n",
        r.name, r.bodies, r.dynamic, r.steps
    );
    let mut head = String::from(
        "| engine | mean ms/step (whole run) | median ms/step | Box2D time / this engine's time | holds |",
    );
    let mut rule = String::from("|---|---:|---:|---:|---|");
    for name in &judged {
        let _ = write!(head, " {name} (figure / limit) |");
        rule.push_str("---:|");
    }
    let _ = writeln!(s, "{head}\n{rule}");
    for o in &r.outcomes {
        let mut row = format!(
            "| {} | {:.3} | {:.3} | {:.2} | {}{} |",
            o.engine.name(),
            o.mean_ms,
            o.median_ms,
            r.box2d_ratio(o.engine),
            yes_no(o.holds()),
            if o.consistent { "" } else { " (rounds differ)" },
        );
        for j in &o.verdict {
            let _ = write!(row, " {} / {} |", figure(j.figure), figure(j.limit));
        }
        let _ = writeln!(s, "{row}");
    }
    let _ = writeln!(s);
}

fn write_csv(path: &Path, ctx: &Setup, results: &[SceneResult]) -> Result<()> {
    let mut w = csv::Writer::from_path(path)?;
    let mut head: Vec<String> = [
        "scene",
        "engine",
        "bodies",
        "dynamic",
        "steps",
        "rounds",
        "mean_ms",
        "median_ms",
        "box2d_over_engine",
        "holds",
        "rounds_agree",
        "contacts_per_step",
        "model_bytes_per_step",
        "model_flops_per_step",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    for name in CRITERIA {
        head.push(name.to_string());
        head.push(format!("{name}_limit"));
    }
    head.extend((1..=crate::run::PHASES).map(|k| format!("part{k}_mean_ms")));
    w.write_record(&head)?;
    for r in results {
        for o in &r.outcomes {
            let mut row = vec![
                r.name.clone(),
                o.engine.name().to_string(),
                r.bodies.to_string(),
                r.dynamic.to_string(),
                r.steps.to_string(),
                ctx.rounds.to_string(),
                format!("{:.6}", o.mean_ms),
                format!("{:.6}", o.median_ms),
                format!("{:.4}", r.box2d_ratio(o.engine)),
                o.holds().to_string(),
                o.consistent.to_string(),
            ];
            match o.work {
                Some(w) => row.extend([
                    format!("{:.1}", w.contacts as f64 / w.steps.max(1) as f64),
                    format!("{:.0}", w.bytes_per_step()),
                    format!("{:.0}", w.flops_per_step()),
                ]),
                None => row.extend([String::new(), String::new(), String::new()]),
            }
            for name in CRITERIA {
                match o.verdict.iter().find(|j| j.name == name) {
                    Some(j) => {
                        row.push(format!("{}", j.figure));
                        row.push(format!("{}", j.limit));
                    }
                    None => row.extend([String::new(), String::new()]),
                }
            }
            row.extend(
                (0..crate::run::PHASES)
                    .map(|k| o.phases.get(k).map_or(String::new(), |x| format!("{x:.6}"))),
            );
            w.write_record(&row)?;
        }
    }
    w.flush()?;
    Ok(())
}

fn on(b: bool) -> &'static str {
    if b {
        "on"
    } else {
        "off"
    }
}

fn yes_no(b: bool) -> &'static str {
    if b {
        "yes"
    } else {
        "no"
    }
}

/// A figure in three significant digits (0 as 0; very large or small ones with an exponent).
fn figure(x: f64) -> String {
    if x == 0.0 || !x.is_finite() {
        return format!("{x}");
    }
    let a = x.abs();
    if a.fract() == 0.0 && a < 1e6 {
        return format!("{x}");
    }
    if !(1e-3..1e4).contains(&a) {
        return format!("{x:.2e}");
    }
    let digits = (2 - a.log10().floor() as i32).max(0) as usize;
    format!("{x:.digits$}")
}
