//! Speed against accuracy on any scene (what the accuracy picker measures at start-up, and
//! `ricochet-lab tradeoff --scene FILE` reports): the scene runs under each candidate setting and under a converged reference, and each
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

use anyhow::{Context, Result};
use glam::DVec2;

use ricochet_engine::criteria::Criteria;
use ricochet_engine::scene;
use ricochet_engine::world::{Limits, World};
use ricochet_protocol::command::TimedAction;

mod candidates;
mod run;
#[cfg(test)]
mod tests;

pub use candidates::{default_candidates, Candidate, Features};
use run::{body_error, body_errors, particle_error, timed_run};
pub use run::{run, Run};

/// The `p` quantile (0 to 1) of `sorted` values, the nearest rank; NaN when empty.
pub fn percentile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    sorted[((sorted.len() - 1) as f64 * p).round() as usize]
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
        // The user's own file: its errors in the long form, with the line and a caret.
        scene::parse_with(&self.text, &self.path, &all, &limits)
            .map_err(|e| anyhow::anyhow!("{}", e.report(&self.text)))
    }

    /// The scene's own `[criteria]`, if it states any.
    pub fn criteria(&self) -> Result<Option<Criteria>> {
        scene::criteria(&self.text, &self.path)
            .map_err(|e| anyhow::anyhow!("{}", e.report(&self.text)))
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

/// One candidate's figures against the reference.
#[derive(Clone, Debug)]
pub struct Row {
    pub name: String,
    pub overrides: Vec<String>,
    /// Mean ms per step over every step of the run, the first included.
    pub ms_mean: f64,
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
    /// Per frame, the worst position error of anything that moves up to that frame, each
    /// no lower than what the reference resolves there ([`Reference::agreement_by_frame`]).
    pub errors: Vec<f64>,
    /// What the run failed of the criteria that stay meaningful whatever the trajectories
    /// do ([`failed_criteria`]); empty when it holds them all.
    pub fails: Vec<String>,
    /// The figures of the scene's stated criteria that are shares ([`SHARES`]), each the
    /// worst over the run: an accuracy target holds them tighter than the scene states.
    pub shares: Vec<(String, f64)>,
}

/// The stated criteria that are shares of a body's size, of the kinetic energy or of a
/// stopping distance: under an accuracy target `TOL` each is held to at most `TOL`, as a
/// share, however loosely the scene states it.
pub const SHARES: [&str; 3] = ["drift", "energy_change", "stopping"];

/// The figures of `verdict` that are [`SHARES`].
pub fn shares(verdict: &[ricochet_engine::criteria::Judgement]) -> Vec<(String, f64)> {
    verdict
        .iter()
        .filter(|j| SHARES.contains(&j.name))
        .map(|j| (j.name.to_string(), j.figure))
        .collect()
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
    /// Per frame, how far the last two refinements had differed up to that frame (worst
    /// body position difference; infinite where only one refinement ran). Where it grows
    /// to the size of a body the scene's trajectories diverge: refining the step changes
    /// where things go, and an error against the reference means nothing past there.
    pub agreement_by_frame: Vec<f64>,
    pub run: Run,
}

impl Reference {
    /// The frames from the start over which the reference is good to `within`.
    pub fn horizon(&self, within: f64) -> usize {
        self.agreement_by_frame
            .iter()
            .take_while(|&&a| a <= within)
            .count()
    }

    /// Whether the scene's trajectories diverge: the last two refinements end further
    /// apart than [`DIVERGED`] of the scene's length unit.
    pub fn diverges(&self, unit: f64) -> bool {
        self.agreement_by_frame
            .last()
            .is_some_and(|&a| a > DIVERGED * unit)
    }
}

/// Refinements that end further apart than this share of the scene's length unit: the
/// trajectories diverge (a smash, a crowd, a tumble), they do not converge.
pub const DIVERGED: f64 = 0.1;

/// The reference's settings at refinement `k` (0, 1, ...): sub-steps and passes double.
fn reference_overrides(k: u32, contacts: bool) -> (String, Vec<String>) {
    let substeps = 4u32 << k;
    let iterations = 8u32 << k;
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
    /// Seconds the whole measure may take: once spent, the candidates not yet run are
    /// left out (the report lists them). The candidates run in the order given.
    pub budget: Option<f64>,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            tolerance: 1e-6,
            max_refinements: 4,
            reference_budget: 300.0,
            budget: None,
        }
    }
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
    /// Candidates left out because the measure's budget was spent.
    pub skipped: Vec<String>,
    /// The scene states its own `[criteria]` (else the candidates are judged by
    /// [`failed_criteria`]'s generic ones).
    pub stated_criteria: bool,
}

/// Measures `candidates` (or the default matrix for the scene) on `subject`; `progress`
/// is told each step of every run.
pub fn measure(
    subject: &Subject,
    candidates: Option<Vec<Candidate>>,
    opts: &Options,
    progress: &indicatif::ProgressBar,
) -> Result<Report> {
    let measuring = Instant::now();
    let unit = subject.length_unit()?;
    let stated_criteria = subject.criteria()?.is_some();
    // The scene's own setting first: its features choose the matrix.
    progress.set_message("the scene's own setting");
    progress.set_length(0);
    let own = timed_run(subject, &[], progress)?;
    let features = own.features;
    let candidates = candidates.unwrap_or_else(|| default_candidates(&features));

    // The reference: refined until two refinements agree, or the budget is spent.
    let reference_budget = opts.budget.map_or(opts.reference_budget, |b| {
        opts.reference_budget.min(b / 2.0)
    });
    let started = Instant::now();
    let mut k = 0;
    let (mut name, mut overrides) = reference_overrides(k, features.contacts);
    progress.set_message(format!("reference: {name}"));
    progress.inc_length(subject.steps);
    let mut took = Instant::now();
    let mut last = run(subject, &overrides, || progress.inc(1))?;
    let mut last_took = took.elapsed().as_secs_f64();
    let mut agreement_by_frame = vec![f64::INFINITY; subject.steps as usize];
    let mut stopped_by_budget = false;
    while k < opts.max_refinements {
        if started.elapsed().as_secs_f64() + 4.0 * last_took > reference_budget {
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
        agreement_by_frame = running_worst(&body_errors(&last, &next), None);
        (name, overrides, last) = (next_name, next_overrides, next);
        if agreement_by_frame
            .last()
            .is_some_and(|&a| a <= opts.tolerance * unit)
        {
            break;
        }
    }
    if features.dynamic == 0 {
        // No bodies: nothing for the solver to refine; particles follow the integrator.
        agreement_by_frame.fill(0.0);
    }
    let agreement = agreement_by_frame.last().copied().unwrap_or(0.0);
    let floor_at = 1e-12 * subject.extent()?;
    let resolution = agreement.max(floor_at);
    let resolved_by_frame: Vec<f64> = agreement_by_frame.iter().map(|a| a.max(floor_at)).collect();
    let reference = Reference {
        overrides,
        name,
        agreement,
        refinements: k,
        resolution,
        converged: agreement <= opts.tolerance * unit,
        stopped_by_budget,
        agreement_by_frame,
        run: last,
    };
    let built = subject.world(&[])?;
    let free = built.config.gravity == DVec2::ZERO;
    // Elastic: nothing takes energy out (no gravity, restitution 1 and no friction on
    // every body), so a run must keep what the reference keeps.
    let elastic = free
        && built
            .bodies()
            .iter()
            .all(|b| b.restitution >= 1.0 && b.friction == 0.0);
    let world = Kind { free, elastic };

    let mut rows = Vec::with_capacity(candidates.len());
    let mut skipped = Vec::new();
    for candidate in &candidates {
        if opts
            .budget
            .is_some_and(|b| measuring.elapsed().as_secs_f64() > b)
        {
            skipped.push(candidate.name.clone());
            continue;
        }
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
        let mut by_frame = body_errors(r, &reference.run);
        let (particle_error, mismatch) = if features.particles {
            let (w, rms, unmatched) = particle_error(r, &reference.run, &mut by_frame);
            (Some((floor(w), floor(rms))), unmatched)
        } else {
            (None, 0)
        };
        rows.push(Row {
            name: candidate.name.clone(),
            overrides: candidate.overrides.clone(),
            ms_mean: ms.iter().sum::<f64>() / ms.len().max(1) as f64,
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
            errors: running_worst(&by_frame, Some(&resolved_by_frame)),
            fails: failed_criteria(r, &reference.run, stated_criteria, unit, world),
            shares: shares(&r.verdict),
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
        skipped,
        stated_criteria,
    })
}

/// The running worst of per-frame figures, each no lower than `floor`'s figure at its
/// frame; a NaN stays NaN from its frame on.
fn running_worst(by_frame: &[f64], floor: Option<&[f64]>) -> Vec<f64> {
    let mut worst = 0.0_f64;
    by_frame
        .iter()
        .enumerate()
        .map(|(f, &e)| {
            let e = floor.map_or(e, |fl| e.max(fl.get(f).copied().unwrap_or(0.0)));
            worst = if e.is_nan() || worst.is_nan() {
                f64::NAN
            } else {
                worst.max(e)
            };
            worst
        })
        .collect()
}

/// Drift this small (in body sizes) is a pile at rest: a candidate must keep it so.
const AT_REST: f64 = 0.02;
/// Overlap left at the end beyond this (in sizes of the smaller body) is penetration.
const PENETRATION: f64 = 0.01;
/// Kinetic energy made (or, in an elastic world, lost) beyond the reference's, as a
/// share of its start.
const ENERGY_MADE: f64 = 0.01;

/// What a scene's world is, for the criteria judged against the reference.
#[derive(Clone, Copy, Debug, Default)]
pub struct Kind {
    /// Without gravity.
    pub free: bool,
    /// Without gravity, every body of restitution 1 and friction 0: energy is kept.
    pub elastic: bool,
}

/// What a run fails of the criteria that stay meaningful on any scene, whether or not
/// its trajectories diverge (named as the scene's `[criteria]` fields):
///
/// - where the scene states `[criteria]`, those, over the measured steps;
/// - else, against the reference's run: `inside` (a body went further than a unit, or a
///   tenth of the reference's reach, beyond every place the reference's bodies went: it
///   escaped or tunnelled), `drift` (the reference's bodies rest within 0.02 of their
///   sizes; the run's drift more than that or twice the reference's), `final_overlap`
///   (more than 0.01 of a body's size, or twice the reference's, left at the end),
///   `energy_rise` (without gravity: kinetic energy made beyond the reference's by 1% of
///   its start), `energy_change` (in an elastic world: the kinetic energy at the end
///   further from its start than the reference's by 1% of it: energy lost counts as
///   much as energy made);
/// - and always `non_finite`, when a number left the finite.
///
/// Momentum is not judged: contacts with static bodies change it on purpose.
pub fn failed_criteria(
    run: &Run,
    reference: &Run,
    stated: bool,
    unit: f64,
    world: Kind,
) -> Vec<String> {
    let mut out = Vec::new();
    if run.nan || run.figures.non_finite {
        out.push("non_finite".to_string());
    }
    if stated {
        out.extend(
            run.verdict
                .iter()
                .filter(|j| !j.pass)
                .map(|j| j.name.to_string()),
        );
        return out;
    }
    let (f, r) = (&run.figures, &reference.figures);
    let [lo, hi] = reference.extent;
    if lo.is_finite() && hi.is_finite() {
        let margin = unit.max(0.1 * (hi - lo).length());
        let [a, b] = run.extent;
        if a.cmplt(lo - margin).any() || b.cmpgt(hi + margin).any() {
            out.push("inside".into());
        }
    }
    if r.drift <= AT_REST && f.drift > AT_REST.max(2.0 * r.drift) {
        out.push("drift".into());
    }
    if f.final_overlap > PENETRATION.max(2.0 * r.final_overlap) {
        out.push("final_overlap".into());
    }
    if world.free && f.energy_rise > r.energy_rise + ENERGY_MADE {
        out.push("energy_rise".into());
    }
    if world.elastic && f.energy_change > r.energy_change + ENERGY_MADE {
        out.push("energy_change".into());
    }
    out
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

/// On the front: no other row both as fast (whole-run mean) and as accurate, and better
/// at one.
pub fn on_front(row: &Row, rows: &[Row]) -> bool {
    !row.nan
        && !rows.iter().any(|o| {
            !o.nan
                && o.ms_mean <= row.ms_mean
                && judged_error(o) <= judged_error(row)
                && (o.ms_mean < row.ms_mean || judged_error(o) < judged_error(row))
        })
}
