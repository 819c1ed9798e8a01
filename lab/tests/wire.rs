//! `ricochet-lab wire` runs the shipped scenes, encodes their frames as `run` sends
//! them, and writes its table between the markers of a page, leaving the rest as it was.

mod common;

use common::*;

#[test]
fn the_wire_report_writes_its_table_between_the_markers() {
    let scenes = scene("");
    let text = report_page("wire", &["wire", "--steps", "30", "--scenes", &scenes]);
    let rows: Vec<Vec<&str>> = text
        .lines()
        .filter(|l| l.starts_with("| ") && l.contains(".toml"))
        .map(|l| l.split('|').map(str::trim).collect())
        .collect();
    assert_eq!(rows.len(), 11, "{text}");
    for row in &rows {
        // Bodies and particles a frame, then bytes a frame: a resting world still sends
        // its header.
        let bytes: f64 = row[4].parse().unwrap();
        assert!(bytes >= 77.0, "{row:?}");
        let per: f64 = row[7].parse().unwrap();
        assert!(per > 0.0 && per.is_finite(), "{row:?}");
    }
    let pyramid = rows.iter().find(|r| r[1] == "pyramid-100.toml").unwrap();
    assert_eq!(pyramid[3], "5050", "{pyramid:?}");
    // A row run under a setting names it.
    assert!(
        rows.iter()
            .any(|r| r[1] == "suite/rain.toml `--set impulse_iterations=4`"),
        "{text}"
    );
}
