//! Speed against accuracy on any scene (`ricochet-server tradeoff --scene FILE`): the
//! scene runs under each candidate setting and under a converged reference, and each
//! candidate is reported with its cost (median ms per step and its spread, solver work)
//! and its error against the reference over the whole run.
//!
//! - **Candidates** are `[world]` overrides of the scene's own settings (`NAME=VALUE`, as
//!   `simulate --set` takes them). The default matrix holds only what the scene needs: a
//!   scene whose bodies never touch tries integrators and sub-steps, not solver passes.
//! - **The reference** is the scene under the impulse solver with split impulses, the exact
//!   integrator, and sub-steps and passes doubled until two refinements agree (worst body
//!   position difference over the run) within a tolerance, or a budget of refinements is
//!   spent; the report says how far the last two agreed. Errors below the reference's
//!   resolution (that agreement, or a floor of 1e-12 of the scene's size) cannot be told
//!   apart and are reported as the resolution.
//! - **Errors**: worst and RMS position error of the dynamic bodies over every frame
//!   (scene units), deepest penetration over the run, worst relative change of the
//!   bodies' energy (kinetic and potential) over the run, and where the scene has
//!   particles the worst and RMS particle position error at sampled frames.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context, Result};
use glam::DVec2;

use ricochet_engine::scene;
use ricochet_engine::world::{Limits, World};
use ricochet_protocol::command::TimedAction;

/// A setting measured: a name and the overrides of the scene's `[world]` it makes.
#[derive(Clone, Debug, PartialEq)]
pub struct Candidate {
    pub name: String,
    pub overrides: Vec<String>,
}

impl Candidate {
    pub fn new(name: &str, overrides: &[&str]) -> Candidate {
        Candidate {
            name: name.to_string(),
            overrides: overrides.iter().map(|s| s.to_string()).collect(),
        }
    }

    /// A candidate given on the command line: overrides separated by `;`
    /// (`solver=impulses;impulse_iterations=8`), named by themselves.
    pub fn parse(text: &str) -> Result<Candidate> {
        let overrides: Vec<String> = text
            .split(';')
            .map(str::trim)
            .filter(|s| !s.is_empty())
            .map(str::to_string)
            .collect();
        if overrides.is_empty() {
            bail!("candidate `{text}`: no NAME=VALUE overrides");
        }
        if let Some(bad) = overrides.iter().find(|o| !o.contains('=')) {
            bail!("candidate `{text}`: `{bad}` is not NAME=VALUE");
        }
        Ok(Candidate {
            name: overrides.join(", "),
            overrides,
        })
    }
}

/// What a scene holds and does, found by running it once under its own settings: what
/// the candidate matrix and the report need.
#[derive(Clone, Copy, Debug, Default)]
pub struct Features {
    pub dynamic: usize,
    pub statics: usize,
    /// Rigid contacts were resolved in some step.
    pub contacts: bool,
    /// Particles lived in some step.
    pub particles: bool,
    /// Some body moved more than a hundredth of the scene's size in a step: what
    /// continuous collision is for.
    pub fast: bool,
}

/// The default candidates for a scene with these features: only the knobs that act on it.
pub fn default_candidates(f: &Features) -> Vec<Candidate> {
    let c = Candidate::new;
    let mut out = vec![c("as the scene sets it", &[])];
    if !f.contacts {
        // Nothing touches: only the flight's integration and its step matter.
        for integrator in ["symplectic", "explicit", "exact"] {
            for substeps in [1, 2, 4] {
                out.push(Candidate {
                    name: format!(
                        "{integrator}, {substeps} sub-step{}",
                        if substeps > 1 { "s" } else { "" }
                    ),
                    overrides: vec![
                        format!("integrator={integrator}"),
                        format!("substeps={substeps}"),
                    ],
                });
            }
        }
        return out;
    }
    let relaxation = |n: u32| format!("relaxation_iterations={n}");
    for n in [5, 15, 50] {
        out.push(Candidate {
            name: format!("relaxation {n}"),
            overrides: vec![
                "solver=relaxation".into(),
                relaxation(n),
                "substeps=1".into(),
            ],
        });
    }
    out.push(c(
        "relaxation 15, 4 sub-steps",
        &[
            "solver=relaxation",
            "relaxation_iterations=15",
            "substeps=4",
        ],
    ));
    out.push(c(
        "relaxation 15, exact flight",
        &[
            "solver=relaxation",
            "relaxation_iterations=15",
            "substeps=1",
            "integrator=exact",
        ],
    ));
    for n in [4, 8, 16] {
        out.push(Candidate {
            name: format!("impulses {n} it"),
            overrides: vec![
                "solver=impulses".into(),
                format!("impulse_iterations={n}"),
                "substeps=1".into(),
            ],
        });
    }
    let impulses8 = ["solver=impulses", "impulse_iterations=8"];
    let with = |extra: &[&str]| -> Vec<String> {
        impulses8
            .iter()
            .chain(extra)
            .map(|s| s.to_string())
            .collect()
    };
    for (name, extra) in [
        ("impulses 8 it, 2 sub-steps", &["substeps=2"][..]),
        ("impulses 8 it, 4 sub-steps", &["substeps=4"]),
        (
            "impulses 8 it, split",
            &["substeps=1", "split_impulses=true"],
        ),
        (
            "impulses 8 it, exact flight",
            &["substeps=1", "integrator=exact"],
        ),
        (
            "impulses 8 it, no warm start",
            &["substeps=1", "warm_starting=false"],
        ),
        (
            "soft 1 it + 1 relax, 4 sub-steps",
            &[
                "impulse_iterations=1",
                "relax_iterations=1",
                "substeps=4",
                "contact_hertz=30",
            ],
        ),
    ] {
        out.push(Candidate {
            name: name.into(),
            overrides: with(extra),
        });
    }
    if f.fast {
        out.push(Candidate {
            name: "impulses 8 it, continuous collision".into(),
            overrides: with(&["substeps=1", "ccd=true"]),
        });
    }
    if f.dynamic >= 64 {
        out.push(Candidate {
            name: "impulses 8 it, grid".into(),
            overrides: with(&["substeps=1", "broad_phase=grid"]),
        });
        out.push(Candidate {
            name: "impulses 8 it, sleeping".into(),
            overrides: with(&["substeps=1", "sleeping=true"]),
        });
    }
    out
}

/// A closed form a scene's run can be checked against, besides the reference.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ClosedForm {
    /// The first dynamic body flies under its constant acceleration:
    /// `p0 + v0 t + a t² / 2` (the projectile).
    Flight,
    /// The first dynamic body keeps its velocity: `p0 + v0 t` (a frictionless slide).
    Coast,
    /// The bodies keep their energy (restitution 1): the error is the worst relative
    /// energy change over the run.
    Energy,
}

impl ClosedForm {
    /// What the closed-form error measures, for tables.
    pub fn measure(self) -> &'static str {
        match self {
            ClosedForm::Flight => "position against p0 + v0 t + a t²/2, worst over the run (units)",
            ClosedForm::Coast => "position against p0 + v0 t, worst over the run (units)",
            ClosedForm::Energy => "relative energy change, worst over the run",
        }
    }
}

/// A scene to measure: its text, where it came from, the steps to run and the inputs.
#[derive(Clone, Debug)]
pub struct Subject {
    pub path: PathBuf,
    pub text: String,
    pub steps: u64,
    pub inputs: Vec<TimedAction>,
    /// Overrides every run makes after the candidate's (the user's `--set`: theirs win).
    pub base: Vec<String>,
    /// The scene's closed form, if it has one.
    pub closed_form: Option<ClosedForm>,
}

impl Subject {
    pub fn read(path: &Path, steps: u64, inputs: Vec<TimedAction>) -> Result<Subject> {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("cannot read scene {}", path.display()))?;
        let subject = Subject {
            path: path.to_path_buf(),
            text,
            steps,
            inputs,
            base: Vec::new(),
            closed_form: None,
        };
        subject.world(&[])?;
        Ok(subject)
    }

    /// The scene under these overrides of its `[world]`.
    pub fn world(&self, overrides: &[String]) -> Result<World> {
        // Measuring is local work on the user's own scene: the ceiling on a step's cost
        // that protects a server from its peers does not apply.
        let limits = Limits::unbounded();
        let all: Vec<String> = overrides.iter().chain(&self.base).cloned().collect();
        Ok(scene::parse_with(&self.text, &self.path, &all, &limits)?)
    }

    /// The scene's length unit: the median size (larger side, or diameter) of its dynamic
    /// bodies, or a hundredth of its bounds' diagonal without any.
    pub fn length_unit(&self) -> Result<f64> {
        let w = self.world(&[])?;
        let mut sizes: Vec<f64> = w
            .bodies()
            .iter()
            .filter(|b| !b.is_static())
            .map(|b| b.shape.size().max_element())
            .collect();
        sizes.sort_by(f64::total_cmp);
        let [lo, hi] = w.config.bounds;
        Ok(match sizes.get(sizes.len() / 2) {
            Some(&s) if s > 0.0 => s,
            _ => ((hi - lo).length() / 100.0).max(1e-9),
        })
    }

    /// The diagonal of the scene's bounds.
    pub fn extent(&self) -> Result<f64> {
        let [lo, hi] = self.world(&[])?.config.bounds;
        Ok((hi - lo).length().max(1e-9))
    }
}

/// One run of the scene: per frame (after each step) the dynamic bodies' positions, and
/// the particles' at sampled frames; its times and figures.
pub struct Run {
    /// Frame-major positions of the dynamic bodies (those dynamic at the start, by index).
    pub bodies: Vec<DVec2>,
    pub dynamic: Vec<usize>,
    /// (frame, positions) every `particle_every` frames.
    pub particles: Vec<(u64, Vec<[f32; 2]>)>,
    pub ms: Vec<f64>,
    /// Solver passes times contacts, plus sub-steps times dynamic bodies, summed over the
    /// run: the work the step did, counted (the same on any machine).
    pub work: u64,
    pub deepest_penetration: f64,
    pub worst_energy_change: f64,
    pub nan: bool,
    pub features: Features,
}

/// How many particle positions a run keeps at most (sampled frames times particles).
const PARTICLE_SAMPLES: usize = 4_000_000;

fn energy(w: &World) -> f64 {
    let g = w.config.gravity;
    w.bodies()
        .iter()
        .filter(|b| !b.is_static())
        .map(|b| b.kinetic_energy() - b.mass() * g.dot(b.pos))
        .sum()
}

/// Runs the scene under `overrides`, calling `tick` after each step.
pub fn run(subject: &Subject, overrides: &[String], mut tick: impl FnMut()) -> Result<Run> {
    let mut w = subject.world(overrides)?;
    let dynamic: Vec<usize> = (0..w.bodies().len())
        .filter(|&i| !w.bodies()[i].is_static())
        .collect();
    let statics = w.bodies().len() - dynamic.len();
    let [lo, hi] = w.config.bounds;
    let size = (hi - lo).length();
    let e0 = energy(&w);
    let scale = e0.abs().max(1e-12);
    let steps = subject.steps as usize;
    let mut run = Run {
        bodies: Vec::with_capacity(dynamic.len() * steps),
        dynamic,
        particles: Vec::new(),
        ms: Vec::with_capacity(steps),
        work: 0,
        deepest_penetration: 0.0,
        worst_energy_change: 0.0,
        nan: false,
        features: Features {
            statics,
            ..Features::default()
        },
    };
    run.features.dynamic = run.dynamic.len();
    let mut particle_every = 1u64;
    let mut inputs = subject.inputs.iter().peekable();
    for _ in 0..subject.steps {
        let mut acted = false;
        while let Some(input) = inputs.next_if(|a| a.frame <= w.frame()) {
            // An action the world refuses is refused under every setting alike.
            let _ = w.apply(&input.action);
            acted = true;
        }
        let t = Instant::now();
        w.step();
        run.ms.push(t.elapsed().as_secs_f64() * 1e3);
        let s = w.stats();
        run.work += s.relaxation_iterations.max(1) * s.contacts
            + u64::from(w.config.substeps) * run.dynamic.len() as u64;
        run.features.contacts |= s.contacts > 0;
        run.deepest_penetration = run.deepest_penetration.max(s.deepest_penetration);
        if !acted {
            // Inputs change the energy on purpose; a step without them should not.
            let e = energy(&w);
            run.worst_energy_change = run.worst_energy_change.max((e - e0).abs() / scale);
        }
        let bodies = w.bodies();
        for &i in &run.dynamic {
            let b = bodies.get(i);
            let p = b.map_or(DVec2::NAN, |b| b.pos);
            run.nan |= !p.is_finite();
            if let Some(b) = b {
                run.features.fast |= b.vel.length() * w.config.dt > 0.01 * size;
            }
            run.bodies.push(p);
        }
        let n = w.particles().len();
        run.features.particles |= n > 0;
        if n > 0 {
            if run.particles.is_empty() {
                particle_every = ((steps * n) / PARTICLE_SAMPLES).max(1) as u64;
            }
            if w.frame() % particle_every == 0 {
                let ps = w.particles();
                run.particles
                    .push((w.frame(), (0..n).map(|i| ps.pos(i).to_array()).collect()));
            }
        }
        tick();
    }
    Ok(run)
}

/// One candidate's figures against the reference.
#[derive(Clone, Debug)]
pub struct Row {
    pub name: String,
    pub overrides: Vec<String>,
    pub ms_median: f64,
    /// The 10th and 90th percentiles of ms per step.
    pub ms_spread: (f64, f64),
    pub work: u64,
    pub worst_error: f64,
    pub rms_error: f64,
    pub deepest_penetration: f64,
    pub worst_energy_change: f64,
    /// Worst and RMS particle position error at the sampled frames; `None` without
    /// particles.
    pub particle_error: Option<(f64, f64)>,
    /// Particles present in one run but not the other at a sampled frame.
    pub particle_count_mismatch: u64,
    /// The error against the scene's closed form ([`ClosedForm`]), if it has one.
    pub closed_form_error: Option<f64>,
    pub nan: bool,
    pub on_front: bool,
}

/// (worst, RMS) of the position differences of two runs, frame by frame.
fn body_error(a: &Run, b: &Run) -> (f64, f64) {
    let (mut worst, mut sum, mut n) = (0.0f64, 0.0, 0usize);
    for (p, q) in a.bodies.iter().zip(&b.bodies) {
        let d = (*p - *q).length();
        if d.is_nan() {
            return (f64::NAN, f64::NAN);
        }
        worst = worst.max(d);
        sum += d * d;
        n += 1;
    }
    (worst, if n > 0 { (sum / n as f64).sqrt() } else { 0.0 })
}

/// (worst, RMS, particles unmatched) of the particle differences at the frames both
/// sampled.
fn particle_error(a: &Run, b: &Run) -> (f64, f64, u64) {
    let (mut worst, mut sum, mut n, mut unmatched) = (0.0f64, 0.0, 0usize, 0u64);
    for (fa, pa) in &a.particles {
        let Some((_, pb)) = b.particles.iter().find(|(fb, _)| fb == fa) else {
            continue;
        };
        unmatched += pa.len().abs_diff(pb.len()) as u64;
        for (p, q) in pa.iter().zip(pb) {
            let d = f64::from((p[0] - q[0]).hypot(p[1] - q[1]));
            worst = worst.max(d);
            sum += d * d;
            n += 1;
        }
    }
    (
        worst,
        if n > 0 { (sum / n as f64).sqrt() } else { 0.0 },
        unmatched,
    )
}

/// A run's error against the scene's closed form.
pub fn closed_form_error(subject: &Subject, form: ClosedForm, run: &Run) -> f64 {
    if form == ClosedForm::Energy {
        return run.worst_energy_change;
    }
    let Ok(w) = subject.world(&[]) else {
        return f64::NAN;
    };
    let Some(&first) = run.dynamic.first() else {
        return f64::NAN;
    };
    let b = &w.bodies()[first];
    let a = match form {
        ClosedForm::Flight => ricochet_engine::dynamics::integrate::acceleration_under(
            b,
            w.config.gravity,
            w.config.mass_scaled_acceleration,
        ),
        _ => DVec2::ZERO,
    };
    let (p0, v0, dt, n) = (b.pos, b.vel, w.config.dt, run.dynamic.len());
    run.bodies
        .iter()
        .step_by(n)
        .enumerate()
        .map(|(k, p)| {
            let t = (k + 1) as f64 * dt;
            (*p - (p0 + v0 * t + a * (0.5 * t * t))).length()
        })
        .fold(0.0, f64::max)
}

fn percentile(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return 0.0;
    }
    sorted[((sorted.len() - 1) as f64 * q).round() as usize]
}

/// The converged reference: the settings, and how far its last two refinements agreed.
pub struct Reference {
    pub overrides: Vec<String>,
    pub name: String,
    /// Worst body position difference over the run between the last two refinements.
    pub agreement: f64,
    pub refinements: u32,
    /// The last two refinements agreed within the tolerance.
    pub converged: bool,
    /// Refining stopped because the next refinement would have gone past the budget.
    pub stopped_by_budget: bool,
    /// Errors below this are not resolved: max(agreement, 1e-12 of the scene's size).
    pub resolution: f64,
    pub run: Run,
}

/// The reference's settings at refinement `k` (0, 1, ...): sub-steps and passes double.
fn reference_overrides(k: u32, contacts: bool) -> (String, Vec<String>) {
    let substeps = 4u32 << k;
    let iterations = 16u32 << k;
    let mut o = vec![
        "integrator=exact".to_string(),
        format!("substeps={substeps}"),
    ];
    if contacts {
        o.extend([
            "solver=impulses".to_string(),
            format!("impulse_iterations={iterations}"),
            // Its own passes, from the first frame (the scene's start passes are a
            // candidate's knob).
            "start_iterations=0".to_string(),
            "split_impulses=true".to_string(),
            "warm_starting=true".to_string(),
            "relax_iterations=0".to_string(),
            "sleeping=false".to_string(),
        ]);
        (
            format!("impulses {iterations} it, {substeps} sub-steps, split, exact flight"),
            o,
        )
    } else {
        (format!("exact flight, {substeps} sub-steps"), o)
    }
}

/// What the measuring needs to be told.
#[derive(Clone, Debug)]
pub struct Options {
    /// The reference is converged when two refinements agree within this many of the
    /// scene's length units ([`Subject::length_unit`]), worst over the run.
    pub tolerance: f64,
    /// Refinements at most.
    pub max_refinements: u32,
    /// Seconds the reference may take: a refinement expected to go past it (four times
    /// the one before) is not run, and the report says how far the last two agreed.
    pub reference_budget: f64,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            tolerance: 1e-6,
            max_refinements: 4,
            reference_budget: 300.0,
        }
    }
}

/// Short runs are repeated for their times (each step's fastest) until they have taken
/// this long, at most [`MAX_REPEATS`] times: a step of a microsecond is timed by many.
const TIMED_FOR_MS: f64 = 200.0;
const MAX_REPEATS: u32 = 20;

/// [`run`], repeated for its times while it is short.
fn timed_run(
    subject: &Subject,
    overrides: &[String],
    progress: &indicatif::ProgressBar,
) -> Result<Run> {
    progress.inc_length(subject.steps);
    let mut r = run(subject, overrides, || progress.inc(1))?;
    let mut spent: f64 = r.ms.iter().sum();
    let mut repeats = 1;
    while spent < TIMED_FOR_MS && repeats < MAX_REPEATS {
        let again = run(subject, overrides, || {})?;
        spent += again.ms.iter().sum::<f64>();
        for (a, b) in r.ms.iter_mut().zip(&again.ms) {
            *a = a.min(*b);
        }
        repeats += 1;
    }
    Ok(r)
}

/// The whole measurement of a scene.
pub struct Report {
    pub scene: PathBuf,
    pub steps: u64,
    pub features: Features,
    /// The scene's length unit ([`Subject::length_unit`]).
    pub unit: f64,
    pub reference: Reference,
    pub rows: Vec<Row>,
}

/// Measures `candidates` (or the default matrix for the scene) on `subject`; `progress`
/// is told each step of every run.
pub fn measure(
    subject: &Subject,
    candidates: Option<Vec<Candidate>>,
    opts: &Options,
    progress: &indicatif::ProgressBar,
) -> Result<Report> {
    let unit = subject.length_unit()?;
    // The scene's own setting first: its features choose the matrix.
    progress.set_message("the scene's own setting");
    progress.set_length(0);
    let own = timed_run(subject, &[], progress)?;
    let features = own.features;
    let candidates = candidates.unwrap_or_else(|| default_candidates(&features));

    // The reference: refined until two refinements agree, or the budget is spent.
    let started = Instant::now();
    let mut k = 0;
    let (mut name, mut overrides) = reference_overrides(k, features.contacts);
    progress.set_message(format!("reference: {name}"));
    progress.inc_length(subject.steps);
    let mut took = Instant::now();
    let mut last = run(subject, &overrides, || progress.inc(1))?;
    let mut last_took = took.elapsed().as_secs_f64();
    let mut agreement = f64::INFINITY;
    let mut stopped_by_budget = false;
    while k < opts.max_refinements {
        if started.elapsed().as_secs_f64() + 4.0 * last_took > opts.reference_budget {
            stopped_by_budget = true;
            break;
        }
        k += 1;
        let (next_name, next_overrides) = reference_overrides(k, features.contacts);
        progress.set_message(format!("reference: {next_name}"));
        progress.inc_length(subject.steps);
        took = Instant::now();
        let next = run(subject, &next_overrides, || progress.inc(1))?;
        last_took = took.elapsed().as_secs_f64();
        agreement = body_error(&last, &next).0;
        (name, overrides, last) = (next_name, next_overrides, next);
        if agreement <= opts.tolerance * unit {
            break;
        }
    }
    if features.dynamic == 0 {
        // No bodies: nothing for the solver to refine; particles follow the integrator.
        agreement = 0.0;
    }
    let resolution = agreement.max(1e-12 * subject.extent()?);
    let reference = Reference {
        overrides,
        name,
        agreement,
        refinements: k,
        resolution,
        converged: agreement <= opts.tolerance * unit,
        stopped_by_budget,
        run: last,
    };

    let mut rows = Vec::with_capacity(candidates.len());
    for candidate in &candidates {
        progress.set_message(candidate.name.clone());
        let r = if candidate.overrides.is_empty() {
            None
        } else {
            Some(timed_run(subject, &candidate.overrides, progress)?)
        };
        let r = r.as_ref().unwrap_or(&own);
        let mut ms = r.ms.clone();
        ms.sort_by(f64::total_cmp);
        let floor = |e: f64| if e.is_nan() { e } else { e.max(resolution) };
        let (worst, rms) = body_error(r, &reference.run);
        let (particle_error, mismatch) = if features.particles {
            let (w, rms, unmatched) = particle_error(r, &reference.run);
            (Some((floor(w), floor(rms))), unmatched)
        } else {
            (None, 0)
        };
        rows.push(Row {
            name: candidate.name.clone(),
            overrides: candidate.overrides.clone(),
            ms_median: percentile(&ms, 0.5),
            ms_spread: (percentile(&ms, 0.1), percentile(&ms, 0.9)),
            work: r.work,
            worst_error: floor(worst),
            rms_error: floor(rms),
            deepest_penetration: r.deepest_penetration,
            worst_energy_change: r.worst_energy_change,
            particle_error,
            particle_count_mismatch: mismatch,
            closed_form_error: subject
                .closed_form
                .map(|f| closed_form_error(subject, f, r)),
            nan: r.nan,
            on_front: false,
        });
    }
    let fronts: Vec<bool> = rows.iter().map(|r| on_front(r, &rows)).collect();
    for (row, front) in rows.iter_mut().zip(fronts) {
        row.on_front = front;
    }
    Ok(Report {
        scene: subject.path.clone(),
        steps: subject.steps,
        features,
        unit,
        reference,
        rows,
    })
}

/// The error a row is judged by (the front, the chart, accuracy targets): the worst
/// position error over the run of anything that moves, bodies and particles alike.
pub fn judged_error(row: &Row) -> f64 {
    match row.particle_error {
        Some((worst, _)) if row.worst_error.is_nan() || worst.is_nan() => f64::NAN,
        Some((worst, _)) => row.worst_error.max(worst),
        None => row.worst_error,
    }
}

/// On the front: no other row both as fast and as accurate, and better at one.
pub fn on_front(row: &Row, rows: &[Row]) -> bool {
    !row.nan
        && !rows.iter().any(|o| {
            !o.nan
                && o.ms_median <= row.ms_median
                && judged_error(o) <= judged_error(row)
                && (o.ms_median < row.ms_median || judged_error(o) < judged_error(row))
        })
}

impl Report {
    pub fn to_csv(&self) -> String {
        let mut out = String::from(
            "scene,setting,overrides,ms_median,ms_p10,ms_p90,solver_work,worst_error,rms_error,deepest_penetration,worst_energy_change,particle_worst_error,particle_rms_error,nan,on_front\n",
        );
        for r in &self.rows {
            let (pw, pr) = r
                .particle_error
                .map_or((String::new(), String::new()), |(w, rms)| {
                    (format!("{w:.6e}"), format!("{rms:.6e}"))
                });
            out += &format!(
                "{},\"{}\",\"{}\",{:.6},{:.6},{:.6},{},{:.6e},{:.6e},{:.6e},{:.6e},{pw},{pr},{},{}\n",
                self.scene.display(),
                r.name,
                r.overrides.join(";"),
                r.ms_median,
                r.ms_spread.0,
                r.ms_spread.1,
                r.work,
                r.worst_error,
                r.rms_error,
                r.deepest_penetration,
                r.worst_energy_change,
                r.nan,
                r.on_front
            );
        }
        out
    }

    /// What the reference is and how far it is to be trusted, in one sentence.
    pub fn reference_line(&self) -> String {
        let r = &self.reference;
        let how = if r.converged {
            "converged".to_string()
        } else if r.stopped_by_budget {
            "not converged: the next refinement would have gone past the time budget".into()
        } else {
            "not converged within the refinements allowed".into()
        };
        format!(
            "Reference: {} ({} refinement{} of sub-steps and passes; the last two agree to {:.2e} units, worst over the run: {how}). Errors below {:.2e} are not resolved and show as that. The scene's length unit (median dynamic body size): {}.",
            r.name,
            r.refinements,
            if r.refinements == 1 { "" } else { "s" },
            r.agreement,
            r.resolution,
            self.unit,
        )
    }

    /// A Markdown table of the rows, the front marked.
    pub fn to_markdown(&self) -> String {
        let particles = self.features.particles;
        let mut out = String::from(
            "| setting | median ms/step (p10-p90) | solver work | worst error | RMS error | deepest penetration | worst energy change |",
        );
        if particles {
            out += " particle error worst / RMS |";
        }
        out += " front |\n|---|---|---|---|---|---|---|";
        if particles {
            out += "---|";
        }
        out += "---|\n";
        for r in &self.rows {
            out += &format!(
                "| {} | {:.5} ({:.5}-{:.5}) | {} | {:.2e}{} | {:.2e} | {:.2e} | {:.2e} |",
                r.name,
                r.ms_median,
                r.ms_spread.0,
                r.ms_spread.1,
                r.work,
                r.worst_error,
                if r.nan { " NaN" } else { "" },
                r.rms_error,
                r.deepest_penetration,
                r.worst_energy_change,
            );
            if particles {
                let (w, rms) = r.particle_error.unwrap_or((0.0, 0.0));
                out += &format!(" {w:.2e} / {rms:.2e} |");
            }
            out += &format!(" {} |\n", if r.on_front { "yes" } else { "" });
        }
        out
    }

    /// A short table for the terminal.
    pub fn to_text(&self) -> String {
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
            "ms/step",
            "worst err",
            "RMS err",
            "energy",
        );
        for r in &self.rows {
            out += &format!(
                "{:width$}  {:>10.5}  {:>10.2e}  {:>10.2e}  {:>10.2e}  {}\n",
                r.name,
                r.ms_median,
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
    pub fn chart(&self, path: &Path) -> Result<()> {
        use plotters::prelude::*;
        super::tradeoff::register_font()?;
        let rows: Vec<&Row> = self.rows.iter().filter(|r| !r.nan).collect();
        if rows.is_empty() {
            bail!("every candidate gave NaN: nothing to chart");
        }
        let root = BitMapBackend::new(path, (1100, 700)).into_drawing_area();
        root.fill(&WHITE)?;
        let (plot, legend) = root.split_horizontally(700);
        let at = |r: &Row| (r.ms_median.max(1e-6), judged_error(r).max(1e-15));
        let (xs, ys): (Vec<f64>, Vec<f64>) = rows.iter().map(|r| at(r)).unzip();
        let x0 = xs.iter().cloned().fold(f64::MAX, f64::min) / 1.5;
        let x1 = xs.iter().cloned().fold(0.0, f64::max) * 1.5;
        let y0 = ys.iter().cloned().fold(f64::MAX, f64::min) / 3.0;
        let y1 = ys.iter().cloned().fold(0.0, f64::max) * 3.0;
        let title = self
            .scene
            .file_name()
            .map_or("scene".into(), |n| n.to_string_lossy().into_owned());
        let mut chart = ChartBuilder::on(&plot)
            .caption(title, ("sans-serif", 22))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())?;
        chart
            .configure_mesh()
            .x_desc("median ms per step")
            .y_desc("worst position error over the run (units)")
            .axis_desc_style(("sans-serif", 13))
            .x_label_formatter(&|v| format!("{v:.2e}"))
            .y_label_formatter(&|v| format!("{v:.0e}"))
            .x_labels(5)
            .label_style(("sans-serif", 12))
            .draw()?;
        let mut front: Vec<(f64, f64)> =
            rows.iter().filter(|r| r.on_front).map(|r| at(r)).collect();
        front.sort_by(|a, b| a.0.total_cmp(&b.0));
        chart.draw_series(LineSeries::new(front, RED.stroke_width(2)))?;
        for (k, r) in self.rows.iter().enumerate().filter(|(_, r)| !r.nan) {
            let colour = if r.on_front { RED } else { BLUE };
            chart.draw_series(std::iter::once(
                EmptyElement::at(at(r))
                    + Circle::new((0, 0), 5, colour.filled())
                    + Text::new(format!("{}", k + 1), (7, -7), ("sans-serif", 13)),
            ))?;
        }
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
        root.present()?;
        Ok(())
    }
}

/// One line per scene: what it holds, how far its reference is to be trusted, and the
/// ends of its front (the fastest setting on it, and the most accurate).
pub fn index(pages: &[(String, Report)]) -> String {
    let mut out = String::from(
        "| scene | bodies (dynamic / static) | holds | reference agrees to | fastest on the front | most accurate on the front |\n|---|---|---|---|---|---|\n",
    );
    for (page, r) in pages {
        let front: Vec<&Row> = r.rows.iter().filter(|row| row.on_front).collect();
        let fastest = front
            .iter()
            .min_by(|a, b| a.ms_median.total_cmp(&b.ms_median));
        let finest = front
            .iter()
            .min_by(|a, b| judged_error(a).total_cmp(&judged_error(b)));
        let cell = |row: Option<&&Row>| {
            row.map_or("none".to_string(), |row| {
                format!(
                    "{}: {:.4} ms, {:.1e}",
                    row.name,
                    row.ms_median,
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
        out += &format!(
            "| [{}]({page}) | {} / {} | {} | {:.1e}{} | {} | {} |\n",
            r.scene
                .file_name()
                .map_or(String::new(), |n| n.to_string_lossy().into_owned()),
            r.features.dynamic,
            r.features.statics,
            if holds.is_empty() {
                "flight only".into()
            } else {
                holds
            },
            r.reference.agreement,
            if r.reference.converged {
                ""
            } else {
                " (not converged)"
            },
            cell(fastest),
            cell(finest),
        );
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_candidate_is_overrides_separated_by_semicolons() {
        let c = Candidate::parse("solver=impulses; impulse_iterations=8").unwrap();
        assert_eq!(c.overrides, ["solver=impulses", "impulse_iterations=8"]);
        assert!(Candidate::parse(" ; ").is_err());
        let e = Candidate::parse("solver=impulses;fast")
            .unwrap_err()
            .to_string();
        assert!(e.contains("`fast` is not NAME=VALUE"), "{e}");
    }

    #[test]
    fn a_scene_without_contacts_tries_no_solver_passes() {
        let free = default_candidates(&Features {
            dynamic: 1,
            ..Features::default()
        });
        assert!(free
            .iter()
            .all(|c| !c.overrides.iter().any(|o| o.contains("iterations"))));
        let touching = default_candidates(&Features {
            dynamic: 1,
            contacts: true,
            ..Features::default()
        });
        assert!(touching
            .iter()
            .any(|c| c.overrides.iter().any(|o| o.contains("impulse_iterations"))));
        assert!(touching.len() > free.len());
    }

    fn shipped(name: &str, steps: u64) -> Subject {
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../assets/scenes")
            .join(name);
        Subject::read(&path, steps, Vec::new()).unwrap()
    }

    /// The reference's worst error over the run against a closed form of the first
    /// dynamic body's position at time t.
    fn reference_error(report: &Report, dt: f64, exact: impl Fn(f64) -> DVec2) -> f64 {
        report
            .reference
            .run
            .bodies
            .iter()
            .enumerate()
            .map(|(k, p)| (*p - exact((k + 1) as f64 * dt)).length())
            .fold(0.0, f64::max)
    }

    #[test]
    fn the_reference_beats_every_candidate_against_a_closed_form() {
        let hidden = indicatif::ProgressBar::hidden();
        // The projectile: p0 + v0 t + g t²/2.
        let subject = shipped("projectile.toml", 120);
        let w = subject.world(&[]).unwrap();
        let (b, g, dt) = (&w.bodies()[0], w.config.gravity, w.config.dt);
        let (p0, v0) = (b.pos, b.vel);
        let report = measure(&subject, None, &Options::default(), &hidden).unwrap();
        let error = reference_error(&report, dt, |t| p0 + v0 * t + g * (0.5 * t * t));
        let best = report
            .rows
            .iter()
            .map(|r| r.worst_error)
            .fold(f64::INFINITY, f64::min);
        assert!(error < best, "reference {error:e}, best candidate {best:e}");
        // Symplectic Euler lags the closed form by |g| dt t / 2, worst at the end: 1/6
        // after 2 s at 1/60 under gravity 10.
        let symplectic = report
            .rows
            .iter()
            .find(|r| r.name == "symplectic, 1 sub-step")
            .unwrap();
        let lag = g.length() * dt * 2.0 / 2.0;
        assert!(
            (symplectic.worst_error - lag).abs() < 1e-9,
            "{}",
            symplectic.worst_error
        );
        assert!(!report.features.contacts);

        // The slide: p0 + v0 t on frictionless ground.
        let subject = shipped("slide.toml", 120);
        let w = subject.world(&[]).unwrap();
        let b = w.body("box").unwrap();
        let (p0, v0, dt) = (b.pos, b.vel, w.config.dt);
        let report = measure(&subject, None, &Options::default(), &hidden).unwrap();
        assert!(report.features.contacts);
        let error = reference_error(&report, dt, |t| p0 + v0 * t);
        let best = report
            .rows
            .iter()
            .map(|r| r.worst_error)
            .fold(f64::INFINITY, f64::min);
        assert!(error < best, "reference {error:e}, best candidate {best:e}");
    }

    #[test]
    fn a_pile_against_its_reference_gains_from_more_passes_and_sub_steps() {
        let hidden = indicatif::ProgressBar::hidden();
        let subject = shipped("pyramid-10.toml", 60);
        let candidates = [
            "solver=impulses;impulse_iterations=2",
            "solver=impulses;impulse_iterations=8;substeps=4",
        ]
        .map(|c| Candidate::parse(c).unwrap())
        .to_vec();
        let opts = Options {
            max_refinements: 2,
            ..Options::default()
        };
        let report = measure(&subject, Some(candidates), &opts, &hidden).unwrap();
        let [few, many] = [&report.rows[0], &report.rows[1]];
        assert!(
            many.worst_error < few.worst_error / 4.0,
            "{:e} against {:e}",
            many.worst_error,
            few.worst_error
        );
        assert!(many.work > few.work, "the solver work counts passes");
        assert!(many.worst_error >= report.reference.resolution);
        assert!(
            !report.features.particles && report.rows.iter().all(|r| r.particle_error.is_none())
        );
    }
}
