//! The measuring commands of `ricochet-server`: scenes and settings flow in; figures
//! (tables, CSV, charts) flow out. Nothing here is on the server's hot path.
//!
//! - [`bench`]: what a step costs, per case and setting;
//! - [`tradeoff`]: what each solver setting costs and buys in accuracy, on shipped scenes;
//! - [`scene_tradeoff`]: the same on any scene, against a converged reference;
//! - [`soak`]: a real server under floods, a stalled viewer and a kill, measured;
//! - [`suite`]: the suite of scene kinds under named settings, against their criteria;
//! - [`chart`]: the trade-off charts' font and their time-against-error panel;
//! - [`table`]: the one Markdown table writer;
//! - [`splice`]: how a run writes its table into a hand-written page;
//! - [`command_line`]: the command a report was measured by, for its page.

pub mod bench;
pub mod chart;
pub mod fanout;
pub mod hostile;
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

/// The `p` quantile (0 to 1) of `sorted` values, the nearest rank; NaN when empty.
pub fn percentile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    sorted[((sorted.len() - 1) as f64 * p).round() as usize]
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

/// The command this process was started with, as `ricochet-server ARGS...`: the command
/// a report says it was measured by.
pub fn command_line() -> String {
    std::iter::once("ricochet-server".to_string())
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
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|t| {
            t.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|m| m.trim().to_string())
        })
        .unwrap_or_else(|| "unknown CPU".into());
    let cores = std::thread::available_parallelism().map_or(0, |n| n.get());
    format!("{cores} cores ({cpu})")
}

#[cfg(test)]
mod tests {
    use super::*;

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
