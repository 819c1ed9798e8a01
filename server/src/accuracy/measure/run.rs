//! One run of a scene under a setting, recorded for comparing (positions per frame,
//! particles at sampled frames, times and figures), and the differences of two runs.

use anyhow::Result;
use glam::DVec2;

use crate::wire::Replay;
use ricochet_engine::criteria::{Criteria, Figures, Judgement, Monitor};
use ricochet_engine::world::World;

use super::{Features, Subject};

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
    /// The worst figures of the run on the criteria's measures (drift, overlap at the end,
    /// speed, energy made), whatever the scene states.
    pub figures: Figures,
    /// The scene's own `[criteria]` judged over this run, if it states any.
    pub verdict: Vec<Judgement>,
    /// The box every dynamic body's centre stayed in over the run.
    pub extent: [DVec2; 2],
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
        figures: Figures::default(),
        verdict: Vec::new(),
        extent: [DVec2::ZERO; 2],
    };
    run.features.dynamic = run.dynamic.len();
    // The scene's criteria over the measured steps; the overlap at the end is measured
    // whether or not the scene asks for it (an infinite limit is not judged).
    let mut stated = subject.criteria()?;
    if let Some(c) = stated.as_mut().filter(|c| c.steps > subject.steps) {
        // A run shorter than the scene's is not at the scene's end: what the scene asks
        // of its end is judged by a run of its length (the accuracy pick's check).
        c.final_speed = None;
        c.final_overlap = None;
    }
    let criteria = Criteria {
        steps: subject.steps.max(1),
        final_overlap: Some(
            stated
                .as_ref()
                .and_then(|c| c.final_overlap)
                .unwrap_or(f64::INFINITY),
        ),
        ..stated.clone().unwrap_or_default()
    };
    let mut monitor = Monitor::new(&w, &criteria);
    let (watched, mut watching) = (w.bodies().len(), true);
    let mut extent = [DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY)];
    let mut particle_every = 1u64;
    let mut inputs = Replay::new(&subject.inputs);
    for _ in 0..subject.steps {
        // An action the world refuses is refused under every setting alike.
        let done = inputs.step(&mut w, |_, _| {});
        let acted = done.due > 0;
        run.ms.push(done.step_time.as_secs_f64() * 1e3);
        let s = w.stats();
        run.work += s.solver_passes.max(1) * s.contacts
            + u64::from(w.config.substeps) * run.dynamic.len() as u64;
        run.features.contacts |= s.contacts > 0;
        run.deepest_penetration = run.deepest_penetration.max(s.deepest_penetration);
        if !acted {
            // Inputs change the energy on purpose; a step without them should not.
            let e = energy(&w);
            run.worst_energy_change = run.worst_energy_change.max((e - e0).abs() / scale);
        }
        // Inputs that add or remove bodies end what the monitor can follow.
        watching &= w.bodies().len() == watched;
        if watching {
            monitor.observe(&w);
        }
        let bodies = w.bodies();
        for &i in &run.dynamic {
            let b = bodies.get(i);
            let p = b.map_or(DVec2::NAN, |b| b.pos);
            run.nan |= !p.is_finite();
            extent = [extent[0].min(p), extent[1].max(p)];
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
    run.figures = monitor.figures().clone();
    if stated.is_some() {
        run.verdict = monitor
            .verdict()
            .into_iter()
            .filter(|j| j.limit.is_finite())
            .collect();
    }
    run.extent = extent;
    Ok(run)
}

/// Short runs are repeated for their times (each step's fastest) until they have taken
/// this long, at most [`MAX_REPEATS`] times: a step of a microsecond is timed by many.
const TIMED_FOR_MS: f64 = 200.0;
const MAX_REPEATS: u32 = 20;

/// [`run`], repeated for its times while it is short.
pub(super) fn timed_run(
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

/// (worst, RMS) of the position differences of two runs, frame by frame.
pub(super) fn body_error(a: &Run, b: &Run) -> (f64, f64) {
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

/// The worst position difference of two runs' bodies at each frame (NaN where either is
/// not a number).
pub(super) fn body_errors(a: &Run, b: &Run) -> Vec<f64> {
    let n = a.dynamic.len();
    let frames = a.ms.len().min(b.ms.len());
    if n == 0 {
        return vec![0.0; frames];
    }
    a.bodies
        .chunks(n)
        .zip(b.bodies.chunks(n))
        .map(|(pa, pb)| {
            pa.iter()
                .zip(pb)
                .map(|(p, q)| (*p - *q).length())
                .fold(0.0, |w: f64, d| {
                    if d.is_nan() || w.is_nan() {
                        f64::NAN
                    } else {
                        w.max(d)
                    }
                })
        })
        .collect()
}

/// (worst, RMS, particles unmatched) of the particle differences at the frames both
/// sampled; each sampled frame's worst is also raised into `by_frame` (indexed by frame
/// minus one, as the bodies' are).
pub(super) fn particle_error(a: &Run, b: &Run, by_frame: &mut [f64]) -> (f64, f64, u64) {
    let (mut worst, mut sum, mut n, mut unmatched) = (0.0f64, 0.0, 0usize, 0u64);
    for (fa, pa) in &a.particles {
        let Some((_, pb)) = b.particles.iter().find(|(fb, _)| fb == fa) else {
            continue;
        };
        unmatched += pa.len().abs_diff(pb.len()) as u64;
        let mut here = 0.0_f64;
        for (p, q) in pa.iter().zip(pb) {
            let d = f64::from((p[0] - q[0]).hypot(p[1] - q[1]));
            worst = worst.max(d);
            here = here.max(d);
            sum += d * d;
            n += 1;
        }
        if let Some(slot) = (*fa as usize)
            .checked_sub(1)
            .and_then(|k| by_frame.get_mut(k))
        {
            *slot = slot.max(here);
        }
    }
    (
        worst,
        if n > 0 { (sum / n as f64).sqrt() } else { 0.0 },
        unmatched,
    )
}
