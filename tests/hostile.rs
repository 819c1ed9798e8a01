//! `ricochet-server hostile` runs its attacks against real servers and writes its table
//! between the markers of a page, leaving the rest of the page as it was.

mod common;

use std::process::Command as Process;

use common::*;

#[test]
fn the_hostile_run_writes_its_table_between_the_markers() {
    let dir = temp_dir();
    let page = dir.path().join("page.md");
    std::fs::write(
        &page,
        "before\n<!-- hostile:begin -->\nold\n<!-- hostile:end -->\nafter\n",
    )
    .unwrap();
    let out = Process::new(bin("ricochet-server"))
        .args(["hostile", "--seconds", "1", "--scenes", &scene("")])
        .arg("--out")
        .arg(&page)
        .output()
        .unwrap();
    ok(&out);
    let text = std::fs::read_to_string(&page).unwrap();
    assert!(
        text.starts_with("before\n<!-- hostile:begin -->\nMeasured by `ricochet-server hostile"),
        "{text}"
    );
    assert!(
        text.ends_with("<!-- hostile:end -->\nafter\n") && !text.contains("old"),
        "{text}"
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
