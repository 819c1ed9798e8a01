//! The command reference (`docs/commands.md`), from the command types: every server
//! command and world action, what it does and its arguments, taken from the JSON Schema
//! `schemars` derives from [`ServerCommand`] and [`Action`] (their doc comments
//! included). `tests/command_docs.rs` checks the committed page against it.

use serde_json::{Map, Value};

use crate::command::{Action, ServerCommand};

/// The whole page, Markdown.
pub fn markdown() -> String {
    let mut out = String::from(
        "# Commands\n\n\
         Every command a world takes, generated from the command types \
         (`protocol/src/command.rs`, `protocol/src/action.rs`). \
         `RICOCHET_WRITE_DOCS=1 cargo test --release -p ricochet-protocol --test command_docs` \
         writes it.\n\n\
         A command is JSON whose `do` field names it: `{\"do\": \"impulse\", \"body\": \"ball\", \
         \"impulse\": [5, 0]}`. On the command line it is the name, then `NAME=VALUE` \
         arguments whose values are JSON (a bare word is a string):\n\n\
         ```sh\nricochet --world mine send impulse body=ball impulse=[5,0]\n```\n\n\
         Send one with `ricochet send`, a timed list of them with `ricochet script`, or from \
         any zenoh program on `ricochet/<world>/cmd` (`rpc` for a reply). A point is \
         `[x, y]` in the scene's units.\n\n",
    );
    out += "## Server commands\n\nThey steer the server's clock and the world's time.\n\n";
    out += &commands(schemars::schema_for!(ServerCommand).as_value());
    out += "## World actions\n\nThe engine applies them at the next frame boundary.\n\n";
    out += &commands(schemars::schema_for!(Action).as_value());
    out
}

/// A section per variant of a `do`-tagged enum's schema.
fn commands(root: &Value) -> String {
    let defs = root
        .get("$defs")
        .and_then(Value::as_object)
        .cloned()
        .unwrap_or_default();
    let mut out = String::new();
    for variant in root["oneOf"].as_array().expect("a tagged enum") {
        let properties = variant["properties"].as_object().expect("fields");
        let name = properties["do"]["const"]
            .as_str()
            .expect("every variant names its `do`");
        out += &format!("### `{name}`\n\n{}\n\n", text(&variant["description"]));
        let required: Vec<&str> = variant["required"]
            .as_array()
            .map(|r| r.iter().filter_map(Value::as_str).collect())
            .unwrap_or_default();
        let fields: Vec<(&String, &Value)> =
            properties.iter().filter(|(k, _)| *k != "do").collect();
        let mut example = format!("ricochet send {name}");
        if !fields.is_empty() {
            out += "| argument | type | |\n|---|---|---|\n";
            for (field, schema) in &fields {
                let needed = if required.contains(&field.as_str()) {
                    "required".to_string()
                } else {
                    match schema.get("default") {
                        Some(d) if !d.is_null() => format!("default `{d}`"),
                        _ => "optional".to_string(),
                    }
                };
                out += &format!("| `{field}` | {} | {needed} |\n", type_of(schema, &defs));
                if required.contains(&field.as_str()) {
                    example += &format!(" {field}={}", placeholder(schema, &defs));
                }
            }
            out += "\n";
        }
        out += &format!("```sh\n{example}\n```\n\n");
    }
    out
}

/// A description on one line, rustdoc's links (`` [`NAME`] ``) as plain code.
fn text(description: &Value) -> String {
    description
        .as_str()
        .unwrap_or("")
        .split_whitespace()
        .collect::<Vec<_>>()
        .join(" ")
        .replace("[`", "`")
        .replace("`]", "`")
}

/// The schema a `$ref` (or an `anyOf` of one and null, an `Option`) points at.
fn resolve<'a>(schema: &'a Value, defs: &'a Map<String, Value>) -> (&'a Value, Option<&'a str>) {
    if let Some(options) = schema.get("anyOf").and_then(Value::as_array) {
        if let Some(inner) = options
            .iter()
            .find(|o| o.get("type") != Some(&"null".into()))
        {
            return resolve(inner, defs);
        }
    }
    match schema.get("$ref").and_then(Value::as_str) {
        Some(r) => {
            let name = r.rsplit('/').next().unwrap_or(r);
            (defs.get(name).unwrap_or(schema), Some(name))
        }
        None => (schema, None),
    }
}

/// A field's type as a reader writes it.
fn type_of(schema: &Value, defs: &Map<String, Value>) -> String {
    let (schema, name) = resolve(schema, defs);
    if let Some(values) = enum_values(schema) {
        return values
            .iter()
            .map(|v| format!("`{v}`"))
            .collect::<Vec<_>>()
            .join(", ");
    }
    if name == Some("BodySpec") {
        return "a table of a scene's `[[body]]` fields (`shape` required; `id`, `group`, \
                `size`, `radius`, `pos`, `vel`, `mass`, `restitution`, `friction`, \
                `gravity`)"
            .to_string();
    }
    let types: Vec<&str> = match &schema["type"] {
        Value::String(t) => vec![t.as_str()],
        Value::Array(ts) => ts.iter().filter_map(Value::as_str).collect(),
        _ => Vec::new(),
    };
    match types.iter().find(|t| **t != "null") {
        Some(&"array") if schema["items"]["type"] == "number" => "point `[x, y]`".into(),
        Some(&"array") => match schema.get("prefixItems").or(schema.get("items")) {
            Some(items) if items.is_array() => "two points `[[x0, y0], [x1, y1]]`".into(),
            Some(items) => format!("list of {}", type_of(items, defs)),
            None => "list".into(),
        },
        Some(&"integer") => "integer".into(),
        Some(&"number") => "number".into(),
        Some(&"string") => "string".into(),
        Some(&"boolean") => "`true` or `false`".into(),
        Some(&"object") => "JSON object".into(),
        _ => "any JSON value".into(),
    }
}

/// The values of a string enum (`Direction`'s `up`, `down`, ...).
fn enum_values(schema: &Value) -> Option<Vec<String>> {
    if let Some(values) = schema.get("enum").and_then(Value::as_array) {
        return Some(
            values
                .iter()
                .filter_map(|v| v.as_str().map(String::from))
                .collect(),
        );
    }
    let options = schema.get("oneOf").and_then(Value::as_array)?;
    options
        .iter()
        .map(|o| o.get("const").and_then(Value::as_str).map(String::from))
        .collect()
}

/// An argument's value in the example command line.
fn placeholder(schema: &Value, defs: &Map<String, Value>) -> String {
    let kind = type_of(schema, defs);
    if let Some(values) = enum_values(resolve(schema, defs).0) {
        return values[0].clone();
    }
    match kind.as_str() {
        "point `[x, y]`" => "[0,0]".into(),
        "integer" | "number" => "1".into(),
        "string" => "NAME".into(),
        "`true` or `false`" => "true".into(),
        k if k.starts_with("a table") => "'{\"shape\":\"circle\",\"radius\":1}'".into(),
        _ => "VALUE".into(),
    }
}
