//! The families' summary: scenes named `<family>-<seed>` (as `ricochet-lab families
//! --scenes-out DIR` writes them) grouped by family, so a claim about the engines holds on
//! every seed drawn, not on one scene.

use std::collections::BTreeMap;
use std::fmt::Write as _;

use crate::engine::EngineKind;
use crate::table::SceneResult;

/// The family of a scene named `<family>-<seed>`.
fn family(name: &str) -> Option<&str> {
    let (family, seed) = name.rsplit_once('-')?;
    (!family.is_empty() && !seed.is_empty() && seed.bytes().all(|b| b.is_ascii_digit()))
        .then_some(family)
}

fn median(mut v: Vec<f64>) -> Option<f64> {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    match n {
        0 => None,
        _ if n % 2 == 1 => Some(v[n / 2]),
        _ => Some((v[n / 2 - 1] + v[n / 2]) / 2.0),
    }
}

fn ratio(x: Option<f64>) -> String {
    x.map_or_else(|| "-".into(), |x| format!("{x:.2}"))
}

/// Writes the section when any scene is named as a family's seed.
pub fn table(s: &mut String, results: &[SceneResult]) {
    let mut by_family: BTreeMap<&str, Vec<&SceneResult>> = BTreeMap::new();
    for r in results {
        if let Some(f) = family(&r.name) {
            by_family.entry(f).or_default().push(r);
        }
    }
    if by_family.is_empty() {
        return;
    }
    let names: Vec<&str> = EngineKind::ALL.iter().map(|e| e.name()).collect();
    let _ = writeln!(
        s,
        "\n## Families\n\n\
         The scenes grouped by family (`<family>-<seed>`). Held: seeds whose every criterion \
         holds, per engine. Speed: Box2D's mean time a step over Ricochet's (one thread), \
         the median and the lowest over the seeds; \"where it holds\" counts only the seeds \
         Ricochet holds, and the last column the seeds Ricochet both holds and runs at least \
         1.5 times Box2D's speed (a seed it fails counts against it).\n\n\
         | family | seeds | held: {} | speed, median | speed, lowest | speed where Ricochet holds, median | held and at least 1.5x |\n\
         |---|---:|---|---:|---:|---:|---:|",
        names.join(" / ")
    );
    for (family, scenes) in &by_family {
        let held: Vec<String> = EngineKind::ALL
            .iter()
            .map(|&e| {
                scenes
                    .iter()
                    .filter(|r| r.outcome(e).holds())
                    .count()
                    .to_string()
            })
            .collect();
        let ratios: Vec<f64> = scenes
            .iter()
            .map(|r| r.box2d_ratio(EngineKind::Ricochet))
            .collect();
        let holding: Vec<f64> = scenes
            .iter()
            .filter(|r| r.outcome(EngineKind::Ricochet).holds())
            .map(|r| r.box2d_ratio(EngineKind::Ricochet))
            .collect();
        let good = holding.iter().filter(|&&x| x >= 1.5).count();
        let lowest = ratios.iter().copied().reduce(f64::min);
        let _ = writeln!(
            s,
            "| {family} | {} | {} | {} | {} | {} | {good} of {} |",
            scenes.len(),
            held.join(" / "),
            ratio(median(ratios)),
            ratio(lowest),
            ratio(median(holding)),
            scenes.len(),
        );
    }
    let _ = writeln!(s);
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_family_is_the_name_before_a_numeric_seed() {
        assert_eq!(super::family("heavy-on-light-12"), Some("heavy-on-light"));
        assert_eq!(super::family("piles-0"), Some("piles"));
        assert_eq!(super::family("pyramid-100"), Some("pyramid"));
        assert_eq!(super::family("crowded-box"), None);
        assert_eq!(super::family("-3"), None);
        assert_eq!(super::median(vec![3.0, 1.0, 2.0]), Some(2.0));
        assert_eq!(super::median(vec![4.0, 1.0]), Some(2.5));
    }
}
