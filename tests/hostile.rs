//! `ricochet-server hostile` runs its attacks against real servers and writes its table
//! between the markers of a page, leaving the rest of the page as it was.

mod common;

use common::*;

#[test]
fn the_hostile_run_writes_its_table_between_the_markers() {
    let scenes = scene("");
    let text = report_page(
        "hostile",
        &["hostile", "--seconds", "1", "--scenes", &scenes],
    );
    let rows: Vec<&str> = text
        .lines()
        .filter(|l| l.starts_with("| a flood") || l.starts_with("| four"))
        .collect();
    assert_eq!(rows.len(), 2, "{text}");
    // Each row ends with two figures: a share of frames, then bytes.
    assert!(
        rows[0].ends_with("% |") && rows[1].ends_with("MiB |"),
        "{rows:?}"
    );
}
