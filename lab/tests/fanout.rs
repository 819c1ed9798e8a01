//! `ricochet-lab fanout` runs a server and viewers, directly and through a router, and
//! writes its table between the markers of a page: through a router the server sends each
//! frame once, directly once per viewer.

mod common;

use common::*;

/// A figure of a table cell such as `12.9 MB/s`.
fn number(cell: &str) -> f64 {
    cell.split_whitespace().next().unwrap().parse().unwrap()
}

#[test]
fn through_a_router_the_server_sends_each_frame_once() {
    let scenes = scene("");
    let text = report_page(
        "fanout",
        &[
            "fanout",
            "--viewers",
            "3",
            "--seconds",
            "3",
            "--scenes",
            &scenes,
        ],
    );
    let row = |mode: &str| -> Vec<String> {
        text.lines()
            .find(|l| l.starts_with(&format!("| {mode}")))
            .unwrap_or_else(|| panic!("no row {mode}: {text}"))
            .split('|')
            .map(|c| c.trim().to_string())
            .collect()
    };
    let (direct, routed) = (row("directly"), row("through a router"));
    // Columns: mode, CPU, sent, frames published, late steps, ...
    let (sent_direct, sent_routed) = (number(&direct[3]), number(&routed[3]));
    assert!(
        sent_routed * 2.0 < sent_direct,
        "three viewers: the server sent {sent_direct} MB/s directly, {sent_routed} through a router"
    );
    assert!(
        number(&direct[4]) > 60.0 && number(&routed[4]) > 60.0,
        "{text}"
    );
}
