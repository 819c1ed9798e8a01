//! docs/commands.md is generated from the command types, and every command is in it.
//! `RICOCHET_WRITE_DOCS=1 cargo test --release -p ricochet-protocol --test command_docs`
//! writes it after a change of the types.

use std::path::Path;

use ricochet_protocol::command::{Action, SERVER_COMMANDS};

#[test]
fn the_command_reference_is_generated_from_the_types() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../docs/commands.md");
    let generated = ricochet_protocol::reference::markdown();
    if std::env::var_os("RICOCHET_WRITE_DOCS").is_some() {
        std::fs::write(&path, &generated).unwrap();
        return;
    }
    for name in SERVER_COMMANDS.iter().chain(Action::NAMES) {
        assert!(
            generated.contains(&format!("### `{name}`\n")),
            "`{name}` is missing from the reference"
        );
    }
    let committed = std::fs::read_to_string(&path).unwrap_or_default();
    assert!(
        committed == generated,
        "docs/commands.md is not the command types' (RICOCHET_WRITE_DOCS=1 writes it)"
    );
}
