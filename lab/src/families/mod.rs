//! Scene families: for each kind of scene, a generator that draws one from ranges with a
//! seed and writes it as a scene file whose `[criteria]` state the physical invariants the
//! engine must hold whatever the scene (`ricochet-lab families`). A failing seed is a file
//! anyone can run (`ricochet-server simulate --scene FILE`) and judge the same way.
//!
//! Sizes in the invariants are each body's own: a drift or an overlap is in sizes of the
//! body (the smaller of a pair), a final speed in the smallest body's sizes a second, a
//! stopping distance as a share of v^2 / (2 mu g).

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

mod draw;
mod motion;

use draw::*;
use motion::*;

/// A family of scenes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Family {
    /// Pyramids, columns and walls of boxes built at rest: sizes 0.05 to 20, aspect 0.25
    /// to 4, 2 to 100 levels (pyramids to 40), gaps 0 to 1% of a size, friction 0.1 to 1,
    /// masses 0.01 to 1000, up to 1e6 from the origin, steps of 1/240 to 1/15 s.
    Piles,
    /// A heavy box on a light one on the ground, or heavy boxes dropped on a bed of
    /// light circles: mass ratios 10 to 1e5.
    HeavyOnLight,
    /// Circles crowded into a closed box without gravity, from 50% to 110% of its area,
    /// its walls a tenth of a body to several bodies thick.
    Crowds,
    /// 100 to 5000 circles and boxes mixed, dropped into a bin from heights that make 5
    /// to 50 layers.
    Rains,
    /// A heavy body (mass ratios 10 to 1000) at 10 to 300 u/s into a block of light boxes
    /// or circles, without gravity; the heavy body 1 to 8 times their size.
    Impacts,
    /// Columns and pyramids of boxes started 10% to 50% overlapped.
    Overlaps,
    /// Restitution 1, friction 0, no gravity: gases of 50 to 1000 circles in a box, rows
    /// of touching and nearly touching balls, a ball into a pile of touching circles or
    /// boxes.
    Elastic,
    /// Bodies 0.01 to 0.1 at 100 to 2000 u/s against walls 0.02 to 0.5 thick.
    Bullets,
    /// Boxes and circles 0.05 to 20 across launched at 0.5 to 15 u/s along the ground or
    /// along a plank resting on it, sliding to rest under friction 0.1 to 1, gravity 2
    /// to 30: each must stop within 2% of v^2 / (2 mu g).
    Friction,
}

impl Family {
    pub const ALL: [Family; 9] = [
        Family::Piles,
        Family::HeavyOnLight,
        Family::Crowds,
        Family::Rains,
        Family::Impacts,
        Family::Overlaps,
        Family::Elastic,
        Family::Bullets,
        Family::Friction,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Family::Piles => "piles",
            Family::HeavyOnLight => "heavy-on-light",
            Family::Crowds => "crowds",
            Family::Rains => "rains",
            Family::Impacts => "impacts",
            Family::Overlaps => "overlaps",
            Family::Elastic => "elastic",
            Family::Bullets => "bullets",
            Family::Friction => "friction",
        }
    }

    /// The scene of `seed`, as a scene file's text (its first line says what was drawn).
    pub fn scene(self, seed: u64) -> String {
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ ((self as u64 + 1) << 48));
        let mut s = Scene::default();
        match self {
            Family::Piles => piles(&mut rng, &mut s),
            Family::HeavyOnLight => heavy_on_light(&mut rng, &mut s),
            Family::Crowds => crowds(&mut rng, &mut s),
            Family::Rains => rains(&mut rng, &mut s),
            Family::Impacts => impacts(&mut rng, &mut s),
            Family::Overlaps => overlaps(&mut rng, &mut s),
            Family::Elastic => elastic(&mut rng, &mut s),
            Family::Bullets => bullets(&mut rng, &mut s),
            Family::Friction => friction(&mut rng, &mut s),
        }
        format!("# {} seed {seed}: {}\n{}", self.name(), s.note, s.text)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_family_draws_scenes_that_load_and_state_criteria() {
        for family in Family::ALL {
            for seed in 0..8 {
                let text = family.scene(seed);
                let path = std::path::PathBuf::from(format!("{}-{seed}.toml", family.name()));
                ricochet_engine::scene::parse(&text, &path, &[])
                    .unwrap_or_else(|e| panic!("{text}\n{e}"));
                let criteria = ricochet_engine::scene::criteria(&text, &path)
                    .unwrap()
                    .unwrap_or_else(|| panic!("{} states no criteria", path.display()));
                assert!(criteria.steps > 0);
                // The same seed draws the same scene.
                assert_eq!(family.scene(seed), text);
            }
            assert_ne!(family.scene(1), family.scene(2));
        }
    }
}

/// One seed of one family under one setting, judged.
#[derive(Clone, Debug)]
pub struct Run {
    pub family: Family,
    pub seed: u64,
    pub setting: String,
    pub row: crate::suite::Row,
    /// Where its scene file was written.
    pub file: std::path::PathBuf,
    /// Under an accuracy target: the setting the target picked, and the seconds its
    /// measure took (a fresh one, as a server without a cache makes at start-up).
    pub picked: Option<(String, f64)>,
}

/// The invariants the families state at 2% (drift from where a pile was built, kinetic
/// energy kept, stopping distance) at 1%, the others as stated: what a run under
/// `accuracy = 0.01` is held to.
pub fn at_one_percent(
    mut c: ricochet_engine::criteria::Criteria,
) -> ricochet_engine::criteria::Criteria {
    for limit in [&mut c.drift, &mut c.energy_change, &mut c.stopping]
        .into_iter()
        .flatten()
    {
        if *limit >= 0.02 {
            *limit -= 0.01;
        }
    }
    c
}

/// Runs `seeds` of each of `families` under each setting (a label and `[world]`
/// overrides), and under `target` if given (an accuracy target and how many of the first
/// seeds to run under it: the setting the target picks for the scene, judged
/// [`at_one_percent`]), writing each scene to `dir` (`<family>-<seed>.toml`)
/// and judging it by its criteria; `progress` ticks once a run. `jobs` scenes run at once
/// (each on a thread of its own); the runs come back in the same order whatever `jobs`
/// is, and their figures are the same: only their times share the machine.
pub fn run(
    families: &[Family],
    seeds: std::ops::Range<u64>,
    settings: &[(String, Vec<String>)],
    target: Option<(f64, u64)>,
    dir: &std::path::Path,
    progress: &indicatif::ProgressBar,
    jobs: usize,
) -> anyhow::Result<Vec<Run>> {
    std::fs::create_dir_all(dir)?;
    let count = seeds.clone().count() as u64;
    let targeted = target.map_or(0, |(_, n)| n.min(count));
    progress.set_length(families.len() as u64 * (count * settings.len() as u64 + targeted));
    let tasks: Vec<(Family, u64)> = families
        .iter()
        .flat_map(|&f| seeds.clone().map(move |s| (f, s)))
        .collect();
    let scene = |family: Family, seed: u64| -> anyhow::Result<Vec<Run>> {
        let mut runs = Vec::new();
        let file = dir.join(format!("{}-{seed}.toml", family.name()));
        std::fs::write(&file, family.scene(seed))?;
        for (label, overrides) in settings {
            progress.set_message(format!("{} {seed} / {label}", family.name()));
            let overrides: Vec<&str> = overrides.iter().map(String::as_str).collect();
            let row = crate::suite::measure(&file, label, &overrides)?;
            runs.push(Run {
                family,
                seed,
                setting: label.clone(),
                row,
                file: file.clone(),
                picked: None,
            });
            progress.inc(1);
        }
        if let Some((target, _)) = target.filter(|_| seed - seeds.start < targeted) {
            progress.set_message(format!("{} {seed} / accuracy = {target}", family.name()));
            let t = crate::suite::under_target_judged(&file, target, at_one_percent)?;
            runs.push(Run {
                family,
                seed,
                setting: format!("accuracy = {target}, judged at 1%"),
                row: t.row,
                file: file.clone(),
                picked: Some((t.pick.candidate.name.clone(), t.measure_s)),
            });
            progress.inc(1);
        }
        Ok(runs)
    };
    // Each worker takes the next scene; results go back in the tasks' order.
    let next = std::sync::atomic::AtomicUsize::new(0);
    let done: std::sync::Mutex<Vec<Option<anyhow::Result<Vec<Run>>>>> =
        std::sync::Mutex::new((0..tasks.len()).map(|_| None).collect());
    std::thread::scope(|s| {
        for _ in 0..jobs.clamp(1, tasks.len().max(1)) {
            s.spawn(|| loop {
                let k = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                let Some(&(family, seed)) = tasks.get(k) else {
                    break;
                };
                let result = scene(family, seed);
                let failed = result.is_err();
                done.lock().unwrap()[k] = Some(result);
                if failed {
                    // Stop handing out scenes: the first error is the answer.
                    next.store(tasks.len(), std::sync::atomic::Ordering::Relaxed);
                }
            });
        }
    });
    let mut runs = Vec::new();
    for result in done.into_inner().unwrap().into_iter().flatten() {
        runs.extend(result?);
    }
    Ok(runs)
}

/// A table per family and setting: seeds held of seeds run, the worst figure of each
/// invariant over every seed (`!` where some seed failed it), the mean ms/step over every
/// step of every seed, and the seeds that failed.
pub fn markdown(runs: &[Run]) -> String {
    let mut out = String::new();
    let mut keys: Vec<(Family, String)> = Vec::new();
    for r in runs {
        if !keys.contains(&(r.family, r.setting.clone())) {
            keys.push((r.family, r.setting.clone()));
        }
    }
    let mut table = crate::table::Table::new([
        "family",
        "setting",
        "held",
        "worst figures (limit)",
        "ms/step, mean",
        "failed seeds",
        "settings picked (measure s, mean)",
    ]);
    for (family, setting) in keys {
        let of: Vec<&Run> = runs
            .iter()
            .filter(|r| r.family == family && r.setting == setting)
            .collect();
        let held = of.iter().filter(|r| r.row.holds).count();
        let mut worst: Vec<(&'static str, f64, f64, bool)> = Vec::new();
        for r in &of {
            for j in &r.row.verdict {
                match worst.iter_mut().find(|w| w.0 == j.name) {
                    Some(w) => {
                        w.1 = w.1.max(j.figure);
                        w.3 &= j.pass;
                    }
                    None => worst.push((j.name, j.figure, j.limit, j.pass)),
                }
            }
        }
        let steps: u64 = of.iter().map(|r| r.row.steps).sum();
        let ms = of
            .iter()
            .map(|r| r.row.ms_mean * r.row.steps as f64)
            .sum::<f64>()
            / steps.max(1) as f64;
        let failed: Vec<String> = of
            .iter()
            .filter(|r| !r.row.holds)
            .map(|r| r.seed.to_string())
            .collect();
        let mut picks: Vec<(&str, usize)> = Vec::new();
        for (name, _) in of.iter().filter_map(|r| r.picked.as_ref()) {
            match picks.iter_mut().find(|p| p.0 == name) {
                Some(p) => p.1 += 1,
                None => picks.push((name, 1)),
            }
        }
        let measured: Vec<f64> = of
            .iter()
            .filter_map(|r| r.picked.as_ref())
            .map(|p| p.1)
            .collect();
        let picked = if measured.is_empty() {
            String::new()
        } else {
            format!(
                "{} ({:.1} s)",
                picks
                    .iter()
                    .map(|(name, n)| format!("{name}: {n}"))
                    .collect::<Vec<_>>()
                    .join(", "),
                measured.iter().sum::<f64>() / measured.len() as f64
            )
        };
        table.row(vec![
            family.name().to_string(),
            setting,
            format!("{held} of {}", of.len()),
            worst
                .iter()
                .map(|(name, figure, limit, pass)| {
                    format!(
                        "{}{name} {figure:.3e} ({})",
                        if *pass { "" } else { "!" },
                        // To six places: a limit judged at 1% prints as it reads.
                        (limit * 1e6).round() / 1e6
                    )
                })
                .collect::<Vec<_>>()
                .join(", "),
            format!("{ms:.3}"),
            if failed.len() > 12 {
                format!("{}, ... ({} in all)", failed[..12].join(", "), failed.len())
            } else {
                failed.join(", ")
            },
            picked,
        ]);
    }
    out.push_str(&table.to_string());
    out
}

#[cfg(test)]
mod held {
    use super::*;

    fn judged(families: &[Family], seeds: std::ops::Range<u64>) -> Vec<Run> {
        let dir = tempfile::tempdir().unwrap();
        let progress = indicatif::ProgressBar::hidden();
        run(
            families,
            seeds,
            &[("the default".to_string(), Vec::new())],
            None,
            dir.path(),
            &progress,
            2,
        )
        .unwrap()
    }

    /// Run at once or one by one, the same runs in the same order with the same figures.
    #[test]
    fn jobs_change_neither_the_order_nor_the_figures() {
        let families = [Family::Friction, Family::Bullets];
        let of = |jobs| {
            let dir = tempfile::tempdir().unwrap();
            let progress = indicatif::ProgressBar::hidden();
            let settings = [("the default".to_string(), Vec::new())];
            run(
                &families,
                0..6,
                &settings,
                None,
                dir.path(),
                &progress,
                jobs,
            )
            .unwrap()
            .into_iter()
            .map(|r| (r.family, r.seed, r.row.criteria, r.row.holds))
            .collect::<Vec<_>>()
        };
        let (one, three) = (of(1), of(3));
        assert_eq!(one.len(), 12);
        assert_eq!(one, three);
        assert_eq!(one[0].0, Family::Friction);
        assert_eq!(one[6].0, Family::Bullets);
    }

    /// Pyramids of boxes a fifth to a third of a unit wide, started a third to almost half
    /// overlapped: their last overlaps are pushed out slower than `sleep_speed` (0.05 u/s)
    /// but faster than that many of their sizes a second. They held none when a body at
    /// rest might stray `sleep_speed` units from its place whatever its size (they fell
    /// asleep 1.0% and 1.2% overlapped).
    #[test]
    fn small_boxes_started_overlapped_do_not_sleep_overlapped() {
        for seed in [1073, 1085] {
            let runs = judged(&[Family::Overlaps], seed..seed + 1);
            assert!(runs[0].row.holds, "seed {seed}: {}", runs[0].row.criteria);
        }
    }

    /// A bed of circles under heavy boxes sleeps soon after it settles: a grain squeezed
    /// between two neighbours a little lower than it, lifted by their push-out, closes back
    /// to the gap a resting contact holds instead of falling through that gap each time it
    /// passes it (`DRIFT_BACK` in the engine's contact preparation). Seed 6 slept whole
    /// from frame 211, seeds 2102 and 3288 crept to the end of their runs and failed.
    #[test]
    fn a_bed_under_heavy_boxes_sleeps_once_it_settles() {
        for seed in [2102, 3288] {
            let runs = judged(&[Family::HeavyOnLight], seed..seed + 1);
            assert!(runs[0].row.holds, "seed {seed}: {}", runs[0].row.criteria);
        }
        let text = Family::HeavyOnLight.scene(6);
        let file = std::path::Path::new("heavy-on-light-6.toml");
        let mut world = ricochet_engine::scene::parse(&text, file, &[]).unwrap();
        let dynamic = world.bodies().iter().filter(|b| b.inv_mass > 0.0).count() as u64;
        let asleep = (1..=480u32).find(|_| {
            world.step();
            world.stats().sleeping == dynamic
        });
        assert!(
            asleep.is_some_and(|frame| frame <= 120),
            "asleep whole from frame {asleep:?}"
        );
    }

    /// Every family, judged in full on seeds the published run (`docs/bench/families.md`,
    /// seeds 0 to 99) never drew.
    #[test]
    fn the_default_holds_every_family_on_unpublished_seeds() {
        let families = [
            Family::Piles,
            Family::HeavyOnLight,
            Family::Rains,
            Family::Impacts,
            Family::Overlaps,
            Family::Bullets,
            Family::Elastic,
            Family::Crowds,
            Family::Friction,
        ];
        let runs = judged(&families, 500..508);
        assert_eq!(runs.len(), 72);
        for r in &runs {
            assert!(r.row.holds, "{}: {}", r.file.display(), r.row.criteria);
        }
    }
}
