//! The lab's test helpers: the end-to-end tests' own (binaries, scenes, servers killed
//! when dropped), and a report run against a page.
#![allow(dead_code)]

use std::process::Command as Process;

#[path = "../../../tests/common/mod.rs"]
mod shared;

pub use shared::*;

/// Runs `ricochet-lab ARGS --out PAGE` on a page whose `name` markers hold old text,
/// checks the report replaced only that text with its table (the command named first),
/// and returns the page.
pub fn report_page(name: &str, args: &[&str]) -> String {
    let dir = temp_dir();
    let page = dir.path().join("page.md");
    std::fs::write(
        &page,
        format!("before\n<!-- {name}:begin -->\nold\n<!-- {name}:end -->\nafter\n"),
    )
    .unwrap();
    let out = Process::new(bin("ricochet-lab"))
        .args(args)
        .arg("--out")
        .arg(&page)
        .output()
        .unwrap();
    ok(&out);
    let text = std::fs::read_to_string(&page).unwrap();
    assert!(
        text.starts_with(&format!(
            "before\n<!-- {name}:begin -->\nMeasured by `ricochet-lab {name}"
        )),
        "{text}"
    );
    assert!(
        text.ends_with(&format!("<!-- {name}:end -->\nafter\n")) && !text.contains("old"),
        "{text}"
    );
    text
}
