//! Timed runs: one engine's full fresh run of a scene, judged by the scene's criteria,
//! and the rounds of a scene (each engine once a round, the order rotated every round)
//! reduced to the figures the tables show.

use std::time::Instant;

use anyhow::{Context, Result};
use ricochet_engine::criteria::{Figures, Judgement, Monitor};

use crate::engine::EngineKind;
use crate::limit::Work;
use crate::scene::Scene;

/// One engine's run of a scene.
pub struct Run {
    /// Mean ms a step over the whole run (the first step included, no warm-up).
    pub mean_ms: f64,
    /// Median ms a step.
    pub median_ms: f64,
    /// Mean ms a step over each of [`PHASES`] equal parts of the run, in order.
    pub phases: Vec<f64>,
    pub verdict: Vec<Judgement>,
    pub figures: Figures,
    /// The final state's digest (Ricochet only).
    pub digest: Option<u64>,
    /// The solver's work over the run (Ricochet only).
    pub work: Option<Work>,
}

/// The parts a run is cut into for the time a step over the run ([`Run::phases`]): a
/// scene's first part (a block struck, a crowd pressed) may cost far more a step than its
/// last (the pieces flying apart, the crowd asleep), in one engine and not in another.
pub const PHASES: usize = 4;

/// The mean of each of [`PHASES`] consecutive parts of `times` (the last part takes what
/// does not divide evenly); empty for a run of fewer steps than parts.
fn phases(times: &[f64]) -> Vec<f64> {
    if times.len() < PHASES {
        return Vec::new();
    }
    let size = times.len() / PHASES;
    (0..PHASES)
        .map(|k| {
            let end = if k + 1 == PHASES {
                times.len()
            } else {
                (k + 1) * size
            };
            let part = &times[k * size..end];
            part.iter().sum::<f64>() / part.len() as f64
        })
        .collect()
}

/// Builds the scene fresh in `engine` (not timed), then steps it for the criteria's steps,
/// timing every step, the monitor watching after each.
pub fn run(engine: EngineKind, scene: &Scene) -> Result<Run> {
    let mut built = engine
        .build(scene)
        .with_context(|| format!("{}: building {}", scene.name, engine.name()))?;
    let mut monitor = Monitor::new(&scene.world, &scene.criteria);
    let steps = scene.steps() as usize;
    let mut times = Vec::with_capacity(steps);
    for k in 0..steps {
        let start = Instant::now();
        built
            .step()
            .with_context(|| format!("{}: {} step {k}", scene.name, engine.name()))?;
        times.push(start.elapsed().as_secs_f64() * 1e3);
        built.observe(&mut monitor)?;
    }
    let mean_ms = times.iter().sum::<f64>() / steps as f64;
    Ok(Run {
        mean_ms,
        phases: phases(&times),
        median_ms: median(&mut times),
        verdict: monitor.verdict(),
        figures: monitor.figures().clone(),
        digest: built.digest(),
        work: built.work(),
    })
}

/// An engine's figures for a scene over every round.
pub struct Outcome {
    pub engine: EngineKind,
    /// Median over the rounds of each run's mean ms a step.
    pub mean_ms: f64,
    /// Median over the rounds of each run's median ms a step.
    pub median_ms: f64,
    /// Median over the rounds of each run's mean ms a step in each part of the run
    /// ([`Run::phases`]).
    pub phases: Vec<f64>,
    /// The first round's verdict (each engine here is deterministic: every round's is the
    /// same, else `consistent` is false).
    pub verdict: Vec<Judgement>,
    pub consistent: bool,
    /// The first round's final-state digest (Ricochet only).
    pub digest: Option<u64>,
    /// The first round's solver work (Ricochet only).
    pub work: Option<Work>,
}

impl Outcome {
    /// Whether every criterion holds.
    pub fn holds(&self) -> bool {
        self.verdict.iter().all(|j| j.pass)
    }
}

/// Every engine's outcome on `scene` over `rounds` rounds, in [`EngineKind::ALL`] order.
/// Round r runs the engines starting from the r-th, so each engine takes every place of
/// the order in turn.
pub fn rounds(scene: &Scene, rounds: usize) -> Result<Vec<Outcome>> {
    let engines = EngineKind::ALL;
    let mut runs: Vec<Vec<Run>> = engines.iter().map(|_| Vec::new()).collect();
    for round in 0..rounds {
        for k in 0..engines.len() {
            let e = (round + k) % engines.len();
            let r = run(engines[e], scene)?;
            eprintln!(
                "{:<16} round {} {:<9} mean {:>8.3} ms  median {:>8.3} ms  {}",
                scene.name,
                round + 1,
                engines[e].name(),
                r.mean_ms,
                r.median_ms,
                if r.verdict.iter().all(|j| j.pass) {
                    "holds"
                } else {
                    "fails"
                },
            );
            runs[e].push(r);
        }
    }
    Ok(engines
        .iter()
        .zip(runs)
        .map(|(&engine, runs)| {
            let first = &runs[0];
            let consistent = runs
                .iter()
                .all(|r| r.figures == first.figures && r.digest == first.digest);
            Outcome {
                engine,
                mean_ms: median(&mut runs.iter().map(|r| r.mean_ms).collect::<Vec<_>>()),
                median_ms: median(&mut runs.iter().map(|r| r.median_ms).collect::<Vec<_>>()),
                phases: (0..first.phases.len())
                    .map(|k| median(&mut runs.iter().map(|r| r.phases[k]).collect::<Vec<_>>()))
                    .collect(),
                verdict: first.verdict.clone(),
                consistent,
                digest: first.digest,
                work: first.work,
            }
        })
        .collect())
}

/// The median (the mean of the middle two for an even count); NaN for none.
fn median(xs: &mut [f64]) -> f64 {
    if xs.is_empty() {
        return f64::NAN;
    }
    xs.sort_by(f64::total_cmp);
    let n = xs.len();
    if n % 2 == 1 {
        xs[n / 2]
    } else {
        (xs[n / 2 - 1] + xs[n / 2]) / 2.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_run_is_cut_into_equal_parts_the_last_taking_the_rest() {
        let times: Vec<f64> = (1..=10).map(f64::from).collect();
        // Parts of 2, 2, 2 and 4 steps.
        assert_eq!(phases(&times), vec![1.5, 3.5, 5.5, 8.5]);
        let even: Vec<f64> = (1..=8).map(f64::from).collect();
        assert_eq!(phases(&even), vec![1.5, 3.5, 5.5, 7.5]);
        assert!(phases(&[1.0, 2.0, 3.0]).is_empty());
    }
}
