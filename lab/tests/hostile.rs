//! `ricochet-lab hostile` runs its attacks against real servers and writes its table
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
        .filter(|l| {
            ["| a flood", "| four", "| one session"]
                .iter()
                .any(|s| l.starts_with(s))
        })
        .collect();
    assert_eq!(rows.len(), 3, "{text}");
    // Each row ends with two figures: a share of frames, bytes, queries a second.
    assert!(
        rows[0].ends_with("% |") && rows[1].ends_with("MiB |"),
        "{rows:?}"
    );
    let rate = |cell: &str| cell.trim().parse::<f64>().expect("queries a second");
    let cells: Vec<&str> = rows[2].trim_end_matches(" |").rsplitn(3, " | ").collect();
    let (defended, switched_off) = (rate(cells[1]), rate(cells[0]));
    // One sender's rate (50 a second, 100 at once) against twenty's.
    assert!(
        defended <= 160.0 && switched_off > 2.0 * defended,
        "made-up ids: {defended} answered a second with the defence, {switched_off} without"
    );
}
