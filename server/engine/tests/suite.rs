//! The suite of scene kinds (`assets/scenes/suite/`), each held to the criteria it states
//! (`[criteria]`: containment, drift, overlap, speed, energy made), under the default a
//! scene that names no solver gets. The figures are printed (`-- --nocapture`); the bounds
//! are the scenes' own, never times.

use std::path::{Path, PathBuf};

use ricochet_engine::criteria::Monitor;
use ricochet_engine::scene;

fn suite() -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/scenes/suite");
    let mut scenes: Vec<PathBuf> = std::fs::read_dir(&dir)
        .expect("assets/scenes/suite")
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    scenes.sort();
    scenes
}

/// Runs `path` under `overrides` for the steps its criteria ask; the failed criteria.
fn judge(path: &Path, overrides: &[&str]) -> Vec<String> {
    let text = std::fs::read_to_string(path).unwrap();
    let overrides: Vec<String> = overrides.iter().map(|s| s.to_string()).collect();
    let mut world = scene::parse(&text, path, &overrides).unwrap_or_else(|e| panic!("{e}"));
    let criteria = scene::criteria(&text, path)
        .unwrap()
        .unwrap_or_else(|| panic!("{} states no criteria", path.display()));
    let mut monitor = Monitor::new(&world, &criteria);
    for _ in 0..criteria.steps {
        world.step();
        monitor.observe(&world);
    }
    let name = path.file_stem().unwrap().to_string_lossy();
    let verdict = monitor.verdict();
    assert!(!verdict.is_empty(), "{name}: no criterion judged");
    let line: Vec<String> = verdict
        .iter()
        .map(|j| format!("{} {:.4} (limit {})", j.name, j.figure, j.limit))
        .collect();
    println!("{name}: {}", line.join(", "));
    verdict
        .iter()
        .filter(|j| !j.pass)
        .map(|j| format!("{name}: {} {} over {}", j.name, j.figure, j.limit))
        .collect()
}

#[test]
fn every_kind_of_scene_holds_its_criteria_under_the_default() {
    let scenes = suite();
    assert!(scenes.len() >= 10, "the suite has {} scenes", scenes.len());
    let failed: Vec<String> = scenes.iter().flat_map(|p| judge(p, &[])).collect();
    assert!(failed.is_empty(), "{}", failed.join("\n"));
}

/// The criteria can fail: the chapter's relaxation, which the default replaced, breaks
/// most of them (a column sinks through its ground, circles leave their box).
#[test]
fn the_chapters_relaxation_fails_the_suite() {
    let failed: Vec<String> = suite()
        .iter()
        .flat_map(|p| judge(p, &["solver=relaxation"]))
        .collect();
    for kind in ["column-60", "crowded-box", "rain", "bullets", "plank"] {
        assert!(
            failed.iter().any(|f| f.starts_with(kind)),
            "{kind} held under relaxation: {failed:?}"
        );
    }
}
