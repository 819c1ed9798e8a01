//! An accuracy target instead of solver knobs (`[world] accuracy = TOL`, `run --accuracy`,
//! `simulate --accuracy`): the scene is measured under the candidate settings against a
//! converged reference ([`measure`]), or the measure is read from a
//! cache keyed by the scene's content, and a candidate is picked:
//!
//! 1. Only candidates that hold the criteria that stay meaningful on any scene are
//!    considered (the scene's own `[criteria]`, or escapes, resting drift, penetration,
//!    energy made, and in an elastic world energy lost, against the reference:
//!    [`failed_criteria`]); where none holds them all,
//!    those that fail the fewest.
//! 2. The position error is judged only over the frames where the reference is good to a
//!    quarter of the target: where a scene's trajectories diverge (a smash, a crowd, a
//!    tumble) refining the step changes where things go, and an error against the
//!    reference means nothing past that horizon. The pick says so.
//! 3. Among those, the cheapest that meets the target over the horizon; where none does,
//!    the most accurate; where the reference is good over no frame at all, the cheapest
//!    (the criteria are all that can be judged).
//!
//! "Cheapest" is the solver work the measure counted (solver passes times contacts, plus
//! sub-steps times dynamic bodies, summed over the run), not wall time: the same scene and
//! target pick the same setting on any machine, so runs stay reproducible. The measure
//! itself has a time budget ([`MEASURE_BUDGET_S`]): candidates it leaves out are named.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use ricochet_engine::criteria::Monitor;

pub mod measure;

use measure::{judged_error, measure, Candidate, Options, Subject, DIVERGED};

/// Steps of the measuring run, and the time the whole measure may take: start-up stays
/// bounded.
pub const MEASURE_STEPS: u64 = 120;
pub const MEASURE_BUDGET_S: f64 = 6.0;

/// The reference must be good to this share of a target over the frames judged.
pub const REFERENCE_MARGIN: f64 = 0.25;

/// The format of a cached measure; bumped when what it measures changes.
const CACHE_VERSION: u32 = 3;

/// One measured candidate, as cached.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Measured {
    pub name: String,
    pub overrides: Vec<String>,
    /// The worst position error over the run of anything that moves (bodies and
    /// particles), against the reference.
    pub worst_error: f64,
    /// Per frame, the worst position error up to it.
    pub errors: Vec<f64>,
    /// The criteria it failed (empty: it holds them all).
    pub fails: Vec<String>,
    /// It was run for the steps the scene's criteria state, beyond the measure's, and
    /// `fails` says how that run went.
    #[serde(default)]
    pub checked: bool,
    /// The figures of the scene's stated criteria that are shares ([`measure::SHARES`]),
    /// from the longest run: a target holds them to itself.
    #[serde(default)]
    pub shares: Vec<(String, f64)>,
    pub work: u64,
    pub ms_median: f64,
    pub nan: bool,
}

impl Measured {
    /// The criteria it fails under `target`: those it failed as the scene states them,
    /// then each share the scene states ([`measure::SHARES`]) whose figure is above the
    /// target (a target of 0.01 holds a drift, an energy change or a stopping distance
    /// the scene allows at 2% to 1%).
    pub fn fails_at(&self, target: f64) -> Vec<String> {
        let mut fails = self.fails.clone();
        for (name, figure) in &self.shares {
            // A figure that is not a number fails too.
            if (figure.is_nan() || *figure > target) && !fails.contains(name) {
                fails.push(name.clone());
            }
        }
        fails
    }
}

/// What a measure found, as cached.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Measure {
    pub version: u32,
    pub steps: u64,
    pub reference: String,
    pub resolution: f64,
    /// Per frame, how far the reference's last two refinements had differed up to it.
    pub agreement: Vec<f64>,
    /// The scene's length unit (the median dynamic body's size).
    pub unit: f64,
    /// The scene states its own `[criteria]`.
    pub stated_criteria: bool,
    pub candidates: Vec<Measured>,
    /// Candidates the measure's budget left out.
    pub skipped: Vec<String>,
}

/// The setting picked for a target, and why.
#[derive(Clone, Debug, PartialEq)]
pub struct Pick {
    pub target: f64,
    pub candidate: Measured,
    /// Whether it meets the target over the horizon (when none does, the most accurate
    /// is picked).
    pub met: bool,
    /// How many candidates met the target and held the criteria.
    pub meeting: usize,
    /// How many candidates held every criterion.
    pub holding: usize,
    pub measured: usize,
    pub skipped: usize,
    pub from_cache: bool,
    pub reference: String,
    /// Errors below this are not resolved by the reference.
    pub resolution: f64,
    pub steps: u64,
    /// The frames over which the position error was judged (the reference good to a
    /// quarter of the target there); below `steps` the trajectories diverge.
    pub horizon: u64,
    /// The reference's refinements end further apart than a tenth of a body.
    pub diverges: bool,
    /// The reference was refined at least once within the measure's budget (else it
    /// resolves nothing and only the criteria judge).
    pub refined: bool,
    pub stated_criteria: bool,
}

impl Pick {
    /// The error the pick was judged by: the worst up to the horizon.
    pub fn error(&self) -> Option<f64> {
        (self.horizon > 0).then(|| self.candidate.errors[self.horizon as usize - 1])
    }

    /// Why this setting, in a sentence (for the log, the `info` reply and the viewer).
    pub fn reason(&self) -> String {
        let c = &self.candidate;
        let how = if self.from_cache {
            "cached measure"
        } else {
            "measured at start-up"
        };
        let criteria = if !self.stated_criteria {
            "escapes, resting drift, penetration and energy made or lost against the reference"
        } else if c.shares.is_empty() {
            "the scene's criteria"
        } else {
            "the scene's criteria, its shares held to the target"
        };
        let held = if c.fails.is_empty() {
            format!(
                "holds {criteria}{} ({} of {} candidates do)",
                if c.checked {
                    ", checked over the whole run they state"
                } else {
                    ""
                },
                self.holding,
                self.measured
            )
        } else {
            format!(
                "fails {} of {criteria}, the fewest of {} candidates (none holds them all)",
                c.fails.join(", "),
                self.measured
            )
        };
        let skipped = if self.skipped > 0 {
            format!(
                "; {} more candidates left out by the measure's time budget",
                self.skipped
            )
        } else {
            String::new()
        };
        let window = if self.horizon >= self.steps {
            format!("over {} steps", self.steps)
        } else {
            format!(
                "over the first {} of {} steps: the scene's trajectories {} after that (the reference's refinements differ by more than a quarter of the target)",
                self.horizon,
                self.steps,
                if self.diverges { "diverge" } else { "are not resolved" },
            )
        };
        let Some(error) = self.error() else {
            let why = if self.refined {
                "its trajectories diverge from the start (the reference's refinements never agree within a quarter of it)"
            } else {
                "the reference could not be refined within the measure's time budget, so it resolves no error"
            };
            return format!(
                "accuracy {:e} cannot be judged on this scene: {why}; `{}` is the cheapest setting that {held} (solver work {}; {how}{skipped})",
                self.target, c.name, c.work
            );
        };
        if self.met {
            format!(
                "accuracy {:e}: `{}` (worst position error {:.2e} {window}, against {}; the cheapest of {} candidates that meet it; it {held}; solver work {}; {how}{skipped})",
                self.target, c.name, error, self.reference, self.meeting, c.work
            )
        } else {
            format!(
                "accuracy {:e} is met by none of {} candidates: `{}` is the most accurate of those that hold the criteria (worst position error {:.2e} {window}, against {}; it {held}; {how}{skipped})",
                self.target, self.measured, c.name, error, self.reference
            )
        }
    }
}

/// Picks from a measure (see the module's rules).
pub fn pick_from(measure: &Measure, target: f64, from_cache: bool) -> Option<Pick> {
    let ok: Vec<Measured> = measure
        .candidates
        .iter()
        // An error may be infinite (a reference of one refinement resolves nothing): the
        // criteria still judge it.
        .filter(|c| !c.nan && !c.worst_error.is_nan() && c.errors.len() == measure.agreement.len())
        .map(|c| Measured {
            fails: c.fails_at(target),
            ..c.clone()
        })
        .collect();
    let fewest = ok.iter().map(|c| c.fails.len()).min()?;
    let pool: Vec<&Measured> = ok.iter().filter(|c| c.fails.len() == fewest).collect();
    let horizon = measure
        .agreement
        .iter()
        .take_while(|&&a| a <= REFERENCE_MARGIN * target)
        .count();
    let error = |c: &Measured| c.errors[horizon - 1];
    let meeting: Vec<&Measured> = if horizon == 0 {
        Vec::new()
    } else {
        pool.iter()
            .copied()
            .filter(|c| error(c) <= target)
            .collect()
    };
    let (candidate, met) = match meeting.iter().copied().min_by_key(|c| c.work) {
        Some(c) => (c, true),
        None if horizon == 0 => (*pool.iter().min_by_key(|c| c.work)?, false),
        None => (
            *pool.iter().min_by(|a, b| error(a).total_cmp(&error(b)))?,
            false,
        ),
    };
    Some(Pick {
        target,
        candidate: candidate.clone(),
        met,
        meeting: meeting.len(),
        holding: ok.iter().filter(|c| c.fails.is_empty()).count(),
        measured: measure.candidates.len(),
        skipped: measure.skipped.len(),
        from_cache,
        reference: measure.reference.clone(),
        resolution: measure.resolution,
        steps: measure.steps,
        horizon: horizon as u64,
        diverges: measure
            .agreement
            .last()
            .is_some_and(|&a| a.is_finite() && a > DIVERGED * measure.unit),
        refined: measure.agreement.first().is_none_or(|a| a.is_finite()),
        stated_criteria: measure.stated_criteria,
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

/// [`for_scene`], the picked setting's overrides then put before `overrides` (the user's
/// `--set` win): the overrides a server or `simulate` runs the scene under. Returns the
/// pick, to say what was picked and why.
pub fn apply_to(
    path: &Path,
    text: &str,
    overrides: &mut Vec<String>,
    flag: Option<f64>,
    cache: Option<&Path>,
) -> Result<Option<Pick>> {
    let picked = for_scene(path, text, overrides, flag, cache)?;
    if let Some(pick) = &picked {
        *overrides = pick
            .candidate
            .overrides
            .iter()
            .chain(overrides.iter())
            .cloned()
            .collect();
    }
    Ok(picked)
}

/// Measures `subject` (or reads its cached measure from `cache`) and picks for `target`.
pub fn pick(subject: &Subject, target: f64, cache: Option<&Path>) -> Result<Pick> {
    let file = cache.map(|dir| cache_path(dir, subject));
    let cached = file.as_ref().and_then(|file| {
        let text = std::fs::read_to_string(file).ok()?;
        match serde_json::from_str::<Measure>(&text) {
            Ok(m) if m.version == CACHE_VERSION => Some(m),
            _ => {
                tracing::warn!(file = %file.display(), "unreadable accuracy cache: measuring again");
                None
            }
        }
    });
    let from_cache = cached.is_some();
    let mut m = match cached {
        Some(m) => m,
        None => measured(subject)?,
    };
    let checked = check_pick(subject, &mut m, target)?;
    if let (Some(file), true) = (&file, !from_cache || checked) {
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
    pick_from(&m, target, from_cache).context("every candidate setting gave NaN on this scene")
}

/// Measures `subject` under the default candidates within [`MEASURE_BUDGET_S`].
fn measured(subject: &Subject) -> Result<Measure> {
    let opts = Options {
        budget: Some(MEASURE_BUDGET_S),
        ..Options::default()
    };
    let report = measure(
        subject,
        None::<Vec<Candidate>>,
        &opts,
        &indicatif::ProgressBar::hidden(),
    )
    .context("measuring the scene for its accuracy target")?;
    Ok(Measure {
        version: CACHE_VERSION,
        steps: subject.steps,
        reference: report.reference.name.clone(),
        resolution: report.reference.resolution,
        agreement: report.reference.agreement_by_frame.clone(),
        unit: report.unit,
        stated_criteria: report.stated_criteria,
        candidates: report
            .rows
            .iter()
            .map(|r| Measured {
                name: r.name.clone(),
                overrides: r.overrides.clone(),
                worst_error: judged_error(r),
                errors: r.errors.clone(),
                fails: r.fails.clone(),
                checked: false,
                shares: r.shares.clone(),
                work: r.work,
                ms_median: r.ms_median,
                nan: r.nan,
            })
            .collect(),
        skipped: report.skipped.clone(),
    })
}

/// Where the scene's criteria state a run longer than the measure's, the pick is run for
/// that long before it is trusted: one that fails there is marked so and the next is
/// picked, until a pick holds or none is left that has not been run. Whether anything
/// was run (the measure then changed).
fn check_pick(subject: &Subject, m: &mut Measure, target: f64) -> Result<bool> {
    let Some(criteria) = subject.criteria()?.filter(|c| c.steps > m.steps) else {
        return Ok(false);
    };
    let mut ran = false;
    while let Some(p) = pick_from(m, target, false) {
        let Some(c) = m
            .candidates
            .iter_mut()
            .find(|c| c.name == p.candidate.name && !c.checked)
        else {
            break;
        };
        let mut world = subject.world(&c.overrides)?;
        let mut monitor = Monitor::new(&world, &criteria);
        for _ in 0..criteria.steps {
            world.step();
            monitor.observe(&world);
        }
        c.checked = true;
        ran = true;
        // The whole run judges every step the measure's did and the rest: its verdict
        // stands (a NaN the measure saw stays).
        let verdict = monitor.verdict();
        let mut fails: Vec<String> = verdict
            .iter()
            .filter(|j| !j.pass)
            .map(|j| j.name.to_string())
            .collect();
        if c.fails.iter().any(|f| f == "non_finite") && !fails.iter().any(|f| f == "non_finite") {
            fails.push("non_finite".into());
        }
        c.fails = fails;
        c.shares = measure::shares(
            &verdict
                .into_iter()
                .filter(|j| j.limit.is_finite())
                .collect::<Vec<_>>(),
        );
        if c.fails_at(target).is_empty() {
            break;
        }
    }
    Ok(ran)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn measured(name: &str, errors: &[f64], work: u64, fails: &[&str]) -> Measured {
        Measured {
            name: name.into(),
            overrides: Vec::new(),
            worst_error: *errors.last().unwrap(),
            errors: errors.to_vec(),
            fails: fails.iter().map(|f| f.to_string()).collect(),
            checked: false,
            shares: Vec::new(),
            work,
            ms_median: 0.0,
            nan: false,
        }
    }

    fn measure(agreement: &[f64], candidates: Vec<Measured>) -> Measure {
        Measure {
            version: CACHE_VERSION,
            steps: agreement.len() as u64,
            reference: "r".into(),
            resolution: 0.0,
            agreement: agreement.to_vec(),
            unit: 1.0,
            stated_criteria: false,
            candidates,
            skipped: Vec::new(),
        }
    }

    #[test]
    fn the_least_work_that_meets_the_target_else_the_most_accurate() {
        let m = measure(
            &[0.0],
            vec![
                measured("coarse", &[1e-1], 10, &[]),
                measured("fine", &[1e-3], 100, &[]),
                measured("finer but cheap", &[1e-4], 50, &[]),
                measured("exact", &[1e-6], 1000, &[]),
            ],
        );
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
    fn a_target_holds_the_scenes_stated_shares_to_itself() {
        let share = |mut m: Measured, figure: f64| {
            m.shares = vec![("stopping".into(), figure)];
            m
        };
        let mut m = measure(
            &[0.0],
            vec![
                // Both hold the scene's 2%; only the finer one holds 1%.
                share(measured("coarse", &[1e-3], 10, &[]), 0.015),
                share(measured("fine", &[1e-3], 40, &[]), 0.004),
            ],
        );
        m.stated_criteria = true;
        assert_eq!(pick_from(&m, 0.02, false).unwrap().candidate.name, "coarse");
        let p = pick_from(&m, 0.01, false).unwrap();
        assert_eq!((p.candidate.name.as_str(), p.holding), ("fine", 1));
        assert!(
            p.reason().contains("shares held to the target"),
            "{}",
            p.reason()
        );
        // Tighter than either: the closer one, said to fail it.
        let p = pick_from(&m, 0.001, false).unwrap();
        assert_eq!(p.candidate.fails, ["stopping"]);
        assert!(p.reason().contains("fails stopping"), "{}", p.reason());
        // A figure that is not a number holds no target.
        m.candidates[1].shares[0].1 = f64::NAN;
        assert_eq!(pick_from(&m, 0.01, false).unwrap().candidate.name, "coarse");
    }

    #[test]
    fn a_setting_that_fails_the_criteria_is_never_picked_while_another_holds_them() {
        let m = measure(
            &[0.0, 0.0],
            vec![
                measured("escapes", &[1e-4, 1e-4], 10, &["inside"]),
                measured("sinks", &[1e-5, 1e-5], 20, &["drift", "final_overlap"]),
                measured("holds", &[1e-3, 5e-3], 40, &[]),
            ],
        );
        // Both failing settings are cheaper and more accurate; the target is met by all.
        let p = pick_from(&m, 1e-2, false).unwrap();
        assert_eq!(
            (p.candidate.name.as_str(), p.met, p.holding),
            ("holds", true, 1)
        );
        // A target only the failing ones meet: still the one that holds, said not met.
        let p = pick_from(&m, 1e-4, false).unwrap();
        assert_eq!((p.candidate.name.as_str(), p.met), ("holds", false));
        assert!(p.reason().contains("holds escapes"), "{}", p.reason());
        // None holds them all: the fewest failed.
        let m = measure(
            &[0.0, 0.0],
            vec![
                measured("escapes", &[1e-4, 1e-4], 10, &["inside"]),
                measured("sinks", &[1e-5, 1e-5], 20, &["drift", "final_overlap"]),
            ],
        );
        let p = pick_from(&m, 1e-2, false).unwrap();
        assert_eq!(p.candidate.name, "escapes");
        assert!(p.reason().contains("fails inside"), "{}", p.reason());
    }

    #[test]
    fn where_the_trajectories_diverge_the_error_is_judged_only_before_they_do() {
        // The reference's refinements agree to 1e-4 for two frames, then part by a body.
        let m = measure(
            &[1e-5, 1e-4, 2.0, 3.0],
            vec![
                measured("cheap", &[1e-3, 2e-3, 0.5, 1.0], 10, &[]),
                measured("dear", &[1e-4, 2e-4, 0.4, 0.9], 90, &[]),
            ],
        );
        // Judged over the whole run, neither meets 0.01; before the parting both do.
        let p = pick_from(&m, 1e-2, false).unwrap();
        assert_eq!(
            (p.candidate.name.as_str(), p.met, p.horizon),
            ("cheap", true, 2)
        );
        assert!(p.diverges);
        assert!(p.reason().contains("first 2 of 4 steps"), "{}", p.reason());
        assert!(p.reason().contains("diverge"), "{}", p.reason());
        // A target tighter than the reference resolves anywhere: judged on the criteria
        // alone, the cheapest that holds them, and said so.
        let p = pick_from(&m, 1e-6, false).unwrap();
        assert_eq!(
            (p.candidate.name.as_str(), p.met, p.horizon),
            ("cheap", false, 0)
        );
        assert!(p.reason().contains("cannot be judged"), "{}", p.reason());
    }

    #[test]
    fn two_targets_pick_two_settings_each_meeting_its_own_and_the_looser_costs_less() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/scenes/pyramid-10.toml");
        let text = std::fs::read_to_string(&path).unwrap();
        let cache = tempfile::tempdir().unwrap();
        // A cold pile (no resting load, no support sweep): how far it sags depends on the
        // passes.
        let cold = [
            "rest_load=false".to_string(),
            "shock_propagation=false".to_string(),
        ];
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
