//! docs/scenes.md and docs/scene.schema.json are generated from the scene's types, and
//! every example in docs/scenes.md loads. `RICOCHET_WRITE_DOCS=1 cargo test --release -p
//! ricochet-engine --test scene_docs` writes both after a change of the types.

use std::path::{Path, PathBuf};

use ricochet_engine::scene::{self, reference};

fn docs() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../docs")
}

const BEGIN: &str = "<!-- scene-reference:begin -->\n";
const END: &str = "<!-- scene-reference:end -->";

fn writing() -> bool {
    std::env::var_os("RICOCHET_WRITE_DOCS").is_some()
}

#[test]
fn the_scene_reference_is_generated_from_the_types() {
    let path = docs().join("scenes.md");
    let page = std::fs::read_to_string(&path).unwrap();
    let (a, b) = (
        page.find(BEGIN).expect("begin"),
        page.find(END).expect("end"),
    );
    let generated = reference::markdown();
    if writing() {
        let page = format!("{}{BEGIN}{generated}{}", &page[..a], &page[b..]);
        std::fs::write(&path, page).unwrap();
        return;
    }
    assert!(
        page[a + BEGIN.len()..b] == generated,
        "docs/scenes.md's reference is not the types' (RICOCHET_WRITE_DOCS=1 writes it):\n{generated}"
    );
    for table in [
        "[world]",
        "[[body]]",
        "[[interact]]",
        "[preset.NAME]",
        "`groups`",
    ] {
        assert!(generated.contains(table), "{table} is missing");
    }
}

#[test]
fn the_json_schema_is_generated_from_the_types() {
    let path = docs().join("scene.schema.json");
    let schema = reference::json_schema();
    if writing() {
        std::fs::write(&path, &schema).unwrap();
        return;
    }
    let committed = std::fs::read_to_string(&path).unwrap();
    assert!(
        committed == schema,
        "docs/scene.schema.json is not the types' (RICOCHET_WRITE_DOCS=1 writes it)"
    );
    let value: serde_json::Value = serde_json::from_str(&schema).unwrap();
    assert_eq!(
        value["additionalProperties"], false,
        "unknown tables refused"
    );
    assert!(value["properties"]["interact"].is_object());
}

/// The TOML examples of docs/scenes.md, with the line each starts on.
fn examples(page: &str) -> Vec<(usize, String)> {
    let mut out = Vec::new();
    let mut current: Option<(usize, String)> = None;
    for (n, line) in page.lines().enumerate() {
        match &mut current {
            None if line.trim() == "```toml" => current = Some((n + 2, String::new())),
            Some(_) if line.trim() == "```" => out.push(current.take().unwrap()),
            Some((_, text)) => {
                text.push_str(line);
                text.push('\n');
            }
            None => {}
        }
    }
    out
}

#[test]
fn every_example_in_the_scene_reference_loads() {
    let page = std::fs::read_to_string(docs().join("scenes.md")).unwrap();
    let examples = examples(&page);
    for (line, text) in &examples {
        let name = format!("docs/scenes.md, the example on line {line}");
        if let Err(e) = scene::parse(text, Path::new(&name), &[]) {
            panic!("the example at {name} is refused:\n{}", e.report(text));
        }
        scene::criteria(text, Path::new(&name)).unwrap();
    }
    // An example for every table, and the top-level `groups`.
    let schema: serde_json::Value = serde_json::from_str(&reference::json_schema()).unwrap();
    for table in schema["properties"].as_object().unwrap().keys() {
        let shown = examples.iter().any(|(_, text)| {
            text.lines().any(|l| {
                let l = l.trim();
                l == format!("[{table}]")
                    || l == format!("[[{table}]]")
                    || l.starts_with(&format!("[{table}."))
                    || l.starts_with(&format!("{table} ="))
            })
        });
        assert!(shown, "no example in docs/scenes.md shows `{table}`");
    }
}
