//! Ricochet's lab: what measures the server and its engine, apart from what serves. Scenes
//! and settings flow in; figures (tables, CSV, charts) flow out. The server never depends
//! on this crate: `ricochet-lab` -> `ricochet-server` -> `ricochet-protocol` ->
//! `ricochet-engine`. Its command, `ricochet-lab`, starts real servers from the
//! `ricochet-server` binary beside it (or `--server PATH`).
//!
//! - [`bench`]: what a step costs, per case and setting;
//! - [`tradeoff`]: what each solver setting costs and buys in accuracy, on shipped scenes;
//! - [`scene_tradeoff`]: the same on any scene, against a converged reference (measured by
//!   the server's [`ricochet_server::accuracy::measure`], written here);
//! - [`soak`]: a real server under floods, a stalled viewer and a kill, measured;
//! - [`suite`]: the suite of scene kinds under named settings, against their criteria;
//! - [`families`]: scene families drawn from ranges by seed, judged by physical invariants;
//! - [`hostile`]: attacks on real servers, each with its defence on and off;
//! - [`profile`]: where a step's time goes, stage by stage;
//! - [`wire`]: bytes on the wire per scene; [`fanout`]: one server, many viewers;
//! - [`chart`]: the trade-off charts' font and their time-against-error panel;
//! - [`table`]: the one Markdown table writer;
//! - [`splice`]: how a run writes its table into a hand-written page;
//! - [`command_line`]: the command a report was measured by, for its page.

pub mod bench;
pub mod chart;
pub mod families;
pub mod fanout;
pub mod hostile;
pub mod profile;
pub mod scaling;
pub mod scene_tradeoff;
pub mod soak;
pub mod suite;
pub mod table;
pub mod tradeoff;
pub mod wire;

use std::path::Path;

use anyhow::{Context, Result};

/// `rows` as CSV, a header of their field names then a line each.
pub fn to_csv<T: serde::Serialize>(rows: &[T]) -> Result<String> {
    let mut out = csv::Writer::from_writer(Vec::new());
    for r in rows {
        out.serialize(r)?;
    }
    Ok(String::from_utf8(out.into_inner()?)?)
}

pub use ricochet_server::accuracy::measure::percentile;

/// The `ricochet-server` binary the lab starts (`--server`), set once at start-up.
static SERVER_BINARY: std::sync::OnceLock<std::path::PathBuf> = std::sync::OnceLock::new();

/// Starts servers from `path` rather than the `ricochet-server` beside `ricochet-lab`.
pub fn use_server_binary(path: std::path::PathBuf) {
    let _ = SERVER_BINARY.set(path);
}

/// The `ricochet-server` binary to start: `--server`, else the one beside this program
/// (Cargo builds both into the same directory).
pub fn server_binary() -> Result<std::path::PathBuf> {
    if let Some(path) = SERVER_BINARY.get() {
        return Ok(path.clone());
    }
    let exe = std::env::current_exe().context("where this program is")?;
    let beside = exe.with_file_name(format!("ricochet-server{}", std::env::consts::EXE_SUFFIX));
    anyhow::ensure!(
        beside.is_file(),
        "no {} (build it with `cargo build --release -p ricochet-server`, or name one with --server)",
        beside.display()
    );
    Ok(beside)
}

/// Replaces what lies between `<!-- NAME:begin -->` and `<!-- NAME:end -->` in the file
/// at `path` by `content`: the generated part of a hand-written page.
pub fn splice(path: &Path, name: &str, content: &str) -> Result<()> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    let (begin, end) = (
        format!("<!-- {name}:begin -->"),
        format!("<!-- {name}:end -->"),
    );
    let (Some(a), Some(b)) = (text.find(&begin), text.find(&end)) else {
        anyhow::bail!("{} has no {begin} ... {end} markers", path.display());
    };
    anyhow::ensure!(a < b, "{}: {end} comes before {begin}", path.display());
    let spliced = format!("{}{begin}\n{content}{}", &text[..a], &text[b..]);
    std::fs::write(path, spliced).with_context(|| format!("cannot write {}", path.display()))
}

/// The command this process was started with, as `ricochet-lab ARGS...`: the command a
/// report says it was measured by.
pub fn command_line() -> String {
    std::iter::once("ricochet-lab".to_string())
        .chain(std::env::args().skip(1))
        .collect::<Vec<_>>()
        .join(" ")
}

/// The machine the figures were taken on, in one line.
pub fn machine() -> String {
    format!("{}, one thread used", cpu())
}

/// The machine's cores and CPU model.
pub fn cpu() -> String {
    let system = sysinfo::System::new_with_specifics(
        sysinfo::RefreshKind::nothing().with_cpu(sysinfo::CpuRefreshKind::nothing()),
    );
    let cpu = system
        .cpus()
        .first()
        .map(|c| c.brand().trim())
        .filter(|b| !b.is_empty())
        .unwrap_or("unknown CPU");
    let cores = std::thread::available_parallelism().map_or(0, |n| n.get());
    format!("{cores} cores ({cpu})")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_machine_names_its_cpu() {
        let cpu = cpu();
        assert!(
            !cpu.contains("unknown CPU") && !cpu.starts_with("0 cores"),
            "{cpu}"
        );
    }

    #[test]
    fn splice_replaces_only_between_the_markers() {
        let dir = tempfile::tempdir().unwrap();
        let page = dir.path().join("page.md");
        std::fs::write(
            &page,
            "intro\n<!-- t:begin -->\nold\n<!-- t:end -->\noutro\n",
        )
        .unwrap();
        splice(&page, "t", "new\n").unwrap();
        assert_eq!(
            std::fs::read_to_string(&page).unwrap(),
            "intro\n<!-- t:begin -->\nnew\n<!-- t:end -->\noutro\n"
        );
        assert!(splice(&page, "u", "x").is_err());
    }
}
