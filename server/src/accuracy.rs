//! An accuracy target instead of solver knobs (`[world] accuracy = TOL`, `run --accuracy`,
//! `simulate --accuracy`): the scene is measured under the candidate settings against a
//! converged reference ([`crate::report::scene_tradeoff`]), or the measure is read from a
//! cache keyed by the scene's content, and the cheapest candidate whose worst position
//! error meets the target is picked.
//!
//! "Cheapest" is the solver work the measure counted (solver passes times contacts, plus
//! sub-steps times dynamic bodies, summed over the run), not wall time: the same scene and
//! target pick the same setting on any machine, so runs stay reproducible.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use crate::report::scene_tradeoff::{judged_error, measure, Candidate, Options, Subject};

/// Steps of the measuring run, and the time the reference may take: start-up stays
/// bounded.
pub const MEASURE_STEPS: u64 = 120;
pub const MEASURE_BUDGET_S: f64 = 20.0;

/// The format of a cached measure; bumped when what it measures changes.
const CACHE_VERSION: u32 = 1;

/// One measured candidate, as cached.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Measured {
    pub name: String,
    pub overrides: Vec<String>,
    /// The worst position error over the run of anything that moves (bodies and
    /// particles), against the reference.
    pub worst_error: f64,
    pub work: u64,
    pub ms_median: f64,
    pub nan: bool,
}

/// What a measure found, as cached.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Measure {
    pub version: u32,
    pub steps: u64,
    pub reference: String,
    pub resolution: f64,
    pub candidates: Vec<Measured>,
}

/// The setting picked for a target, and why.
#[derive(Clone, Debug, PartialEq)]
pub struct Pick {
    pub target: f64,
    pub candidate: Measured,
    /// Whether it meets the target (when none does, the most accurate is picked).
    pub met: bool,
    /// How many candidates met the target.
    pub meeting: usize,
    pub measured: usize,
    pub from_cache: bool,
    pub reference: String,
    /// Errors below this are not resolved by the reference.
    pub resolution: f64,
    pub steps: u64,
}

impl Pick {
    /// Why this setting, in a sentence (for the log, the `info` reply and the viewer).
    pub fn reason(&self) -> String {
        let c = &self.candidate;
        let how = if self.from_cache {
            "cached measure"
        } else {
            "measured at start-up"
        };
        if self.met {
            format!(
                "accuracy {:e}: `{}` (worst position error {:.2e} over {} steps against {}, itself good to {:.1e}; the cheapest of {} of {} candidates that meet it, solver work {}; {how})",
                self.target, c.name, c.worst_error, self.steps, self.reference, self.resolution, self.meeting, self.measured, c.work
            )
        } else {
            format!(
                "accuracy {:e} is met by none of {} candidates: `{}` is the most accurate (worst position error {:.2e} over {} steps against {}, itself good to {:.1e}; {how})",
                self.target, self.measured, c.name, c.worst_error, self.steps, self.reference, self.resolution
            )
        }
    }
}

/// Picks from a measure: the least work among candidates that meet `target` (ties to the
/// first listed), else the most accurate.
pub fn pick_from(measure: &Measure, target: f64, from_cache: bool) -> Option<Pick> {
    let ok: Vec<&Measured> = measure
        .candidates
        .iter()
        .filter(|c| !c.nan && c.worst_error.is_finite())
        .collect();
    let meeting: Vec<&Measured> = ok
        .iter()
        .copied()
        .filter(|c| c.worst_error <= target)
        .collect();
    let (candidate, met) = match meeting.iter().copied().min_by_key(|c| c.work) {
        Some(c) => (c, true),
        None => (
            *ok.iter()
                .min_by(|a, b| a.worst_error.total_cmp(&b.worst_error))?,
            false,
        ),
    };
    Some(Pick {
        target,
        candidate: candidate.clone(),
        met,
        meeting: meeting.len(),
        measured: measure.candidates.len(),
        from_cache,
        reference: measure.reference.clone(),
        resolution: measure.resolution,
        steps: measure.steps,
    })
}

/// The cache file of a scene's measure: named by a hash of everything the measure
/// depends on (the scene's text, the overrides it runs under, the steps).
pub fn cache_path(dir: &Path, subject: &Subject) -> PathBuf {
    let mut h = Sha256::new();
    h.update(format!("ricochet accuracy v{CACHE_VERSION}\n").as_bytes());
    h.update(subject.text.as_bytes());
    for o in &subject.base {
        h.update(b"\n--set ");
        h.update(o.as_bytes());
    }
    h.update(format!("\nsteps {}\ninputs {}", subject.steps, subject.inputs.len()).as_bytes());
    for i in &subject.inputs {
        h.update(format!("\n{} {:?}", i.frame, i.action).as_bytes());
    }
    let hex: String = h.finalize().iter().map(|b| format!("{b:02x}")).collect();
    dir.join(format!("{hex}.json"))
}

/// Where measures are cached unless told: `$XDG_CACHE_HOME/ricochet/accuracy`, else
/// `~/.cache/ricochet/accuracy`.
pub fn default_cache_dir() -> Option<PathBuf> {
    let base = std::env::var_os("XDG_CACHE_HOME")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache")))?;
    Some(base.join("ricochet").join("accuracy"))
}

/// The accuracy target of a scene run under `overrides`: `flag` (`--accuracy`) if given,
/// else its `[world] accuracy`; and if there is one, the setting picked for it, whose
/// overrides go before `overrides` (the user's `--set` win).
pub fn for_scene(
    path: &Path,
    text: &str,
    overrides: &[String],
    flag: Option<f64>,
    cache: Option<&Path>,
) -> Result<Option<Pick>> {
    if let Some(t) = flag {
        if !(t.is_finite() && t > 0.0) {
            anyhow::bail!("--accuracy {t}: must be a length above 0, in scene units");
        }
    }
    let subject = Subject {
        path: path.to_path_buf(),
        text: text.to_string(),
        steps: MEASURE_STEPS,
        inputs: Vec::new(),
        base: overrides.to_vec(),
        closed_form: None,
    };
    let Some(target) = flag.or(subject.world(&[])?.config.accuracy) else {
        return Ok(None);
    };
    let cache = cache.map(Path::to_path_buf).or_else(default_cache_dir);
    pick(&subject, target, cache.as_deref()).map(Some)
}

/// Measures `subject` (or reads its cached measure from `cache`) and picks for `target`.
pub fn pick(subject: &Subject, target: f64, cache: Option<&Path>) -> Result<Pick> {
    let file = cache.map(|dir| cache_path(dir, subject));
    if let Some(file) = &file {
        if let Ok(text) = std::fs::read_to_string(file) {
            match serde_json::from_str::<Measure>(&text) {
                Ok(m) if m.version == CACHE_VERSION => {
                    if let Some(p) = pick_from(&m, target, true) {
                        return Ok(p);
                    }
                }
                _ => {
                    tracing::warn!(file = %file.display(), "unreadable accuracy cache: measuring again")
                }
            }
        }
    }
    let opts = Options {
        reference_budget: MEASURE_BUDGET_S,
        ..Options::default()
    };
    let report = measure(
        subject,
        None::<Vec<Candidate>>,
        &opts,
        &indicatif::ProgressBar::hidden(),
    )
    .context("measuring the scene for its accuracy target")?;
    let m = Measure {
        version: CACHE_VERSION,
        steps: subject.steps,
        reference: report.reference.name.clone(),
        resolution: report.reference.resolution,
        candidates: report
            .rows
            .iter()
            .map(|r| Measured {
                name: r.name.clone(),
                overrides: r.overrides.clone(),
                worst_error: judged_error(r),
                work: r.work,
                ms_median: r.ms_median,
                nan: r.nan,
            })
            .collect(),
    };
    if let Some(file) = &file {
        // A cache that cannot be written costs a measure next time, nothing else.
        let written = file
            .parent()
            .map_or(Ok(()), std::fs::create_dir_all)
            .and_then(|()| {
                std::fs::write(file, serde_json::to_vec_pretty(&m).expect("serialises"))
            });
        if let Err(e) = written {
            tracing::warn!(file = %file.display(), "cannot cache the accuracy measure: {e}");
        }
    }
    pick_from(&m, target, false).context("every candidate setting gave NaN on this scene")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn measured(name: &str, error: f64, work: u64) -> Measured {
        Measured {
            name: name.into(),
            overrides: Vec::new(),
            worst_error: error,
            work,
            ms_median: 0.0,
            nan: false,
        }
    }

    #[test]
    fn the_least_work_that_meets_the_target_else_the_most_accurate() {
        let m = Measure {
            version: CACHE_VERSION,
            steps: 10,
            reference: "r".into(),
            resolution: 0.0,
            candidates: vec![
                measured("coarse", 1e-1, 10),
                measured("fine", 1e-3, 100),
                measured("finer but cheap", 1e-4, 50),
                measured("exact", 1e-6, 1000),
            ],
        };
        assert_eq!(pick_from(&m, 0.5, false).unwrap().candidate.name, "coarse");
        assert_eq!(
            pick_from(&m, 1e-2, false).unwrap().candidate.name,
            "finer but cheap"
        );
        let p = pick_from(&m, 1e-5, false).unwrap();
        assert_eq!(
            (p.candidate.name.as_str(), p.met, p.meeting),
            ("exact", true, 1)
        );
        let p = pick_from(&m, 1e-9, false).unwrap();
        assert_eq!((p.candidate.name.as_str(), p.met), ("exact", false));
        assert!(p.reason().contains("met by none"), "{}", p.reason());
    }

    #[test]
    fn two_targets_pick_two_settings_each_meeting_its_own_and_the_looser_costs_less() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/scenes/pyramid-10.toml");
        let text = std::fs::read_to_string(&path).unwrap();
        let cache = tempfile::tempdir().unwrap();
        // A cold pile (no resting load): how far it sags depends on the passes.
        let cold = ["rest_load=false".to_string()];
        let pick = |t| {
            for_scene(&path, &text, &cold, Some(t), Some(cache.path()))
                .unwrap()
                .unwrap()
        };
        let loose = pick(1e-2);
        assert!(!loose.from_cache, "the first target measures");
        let tight = pick(1e-3);
        assert!(
            tight.from_cache,
            "the second reads the measure the first cached"
        );
        for p in [&loose, &tight] {
            assert!(
                p.met && p.candidate.worst_error <= p.target,
                "{}",
                p.reason()
            );
        }
        assert_ne!(loose.candidate.name, tight.candidate.name);
        assert!(
            loose.candidate.work < tight.candidate.work,
            "{} against {}",
            loose.reason(),
            tight.reason()
        );
        // The user's own overrides are part of what was measured: another cache entry.
        let theirs = for_scene(
            &path,
            &text,
            &["gravity=[0,-5]".into()],
            Some(1e-2),
            Some(cache.path()),
        )
        .unwrap()
        .unwrap();
        assert!(!theirs.from_cache);
        // The scene's own `[world] accuracy` is a target too; the flag overrides it.
        let declared = text.replacen("[world]", "[world]\naccuracy = 0.01", 1);
        let own = for_scene(&path, &declared, &cold, None, Some(cache.path()))
            .unwrap()
            .unwrap();
        assert_eq!(
            (own.target, &own.candidate.overrides),
            (1e-2, &loose.candidate.overrides)
        );
        let flag = for_scene(&path, &declared, &cold, Some(1e-3), Some(cache.path()))
            .unwrap()
            .unwrap();
        assert_eq!(flag.candidate.overrides, tight.candidate.overrides);
        let bad = text.replacen("[world]", "[world]\naccuracy = -1", 1);
        let e = format!("{:#}", for_scene(&path, &bad, &[], None, None).unwrap_err());
        assert!(e.contains("accuracy"), "{e}");
        // A scene without a target picks nothing; a bad target is refused.
        assert!(for_scene(&path, &text, &[], None, Some(cache.path()))
            .unwrap()
            .is_none());
        let e = for_scene(&path, &text, &[], Some(-1.0), None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("--accuracy -1"), "{e}");
    }
}
