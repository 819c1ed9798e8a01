//! The scene format described from its types: a JSON Schema for editors
//! (`docs/scene.schema.json`) and the reference tables of `docs/scenes.md`, both from the
//! schema `schemars` derives from [`super::raw::SceneFile`] and the engine's types it holds,
//! their doc comments included. `tests/scene_docs.rs` checks both files against these.

use serde_json::{Map, Value};

use super::raw::SceneFile;

/// The JSON Schema of a scene file (draft 2020-12), pretty-printed, ending in a newline.
pub fn json_schema() -> String {
    let schema = schemars::schema_for!(SceneFile);
    serde_json::to_string_pretty(&schema).expect("a schema serialises") + "\n"
}

/// The reference of every table and field of a scene: for each table its header as
/// written, what it is, and its fields with their type, default and meaning (units and
/// ranges are in the meaning). Markdown.
pub fn markdown() -> String {
    let schema = schemars::schema_for!(SceneFile);
    let root = schema.as_value();
    let defs = root
        .get("$defs")
        .and_then(Value::as_object)
        .cloned()
        .unwrap_or_default();
    let ctx = Defs(defs);
    let mut out = String::new();
    let properties = root["properties"].as_object().expect("a scene has tables");
    for (name, property) in properties {
        let (header, table) = match ctx.table_of(property) {
            Some(TableKind::Array(t)) => (format!("[[{name}]]"), t),
            Some(TableKind::Map(t)) => (format!("[{name}.NAME]"), t),
            Some(TableKind::One(t)) => (format!("[{name}]"), t),
            None => {
                // A top-level key (`groups`).
                out += &format!("### `{name}` (top-level key)\n\n");
                out += &format!(
                    "{}\n\nType: {}; before the first table.\n\n",
                    text(property.get("description")),
                    ctx.type_of(property)
                );
                continue;
            }
        };
        out += &format!("### `{header}`\n\n");
        // The scene's own word for the table, else its type's.
        let described = Some(text(property.get("description")))
            .filter(|d| !d.is_empty())
            .unwrap_or_else(|| text(table.get("description")));
        if !described.is_empty() {
            out += &format!("{described}\n\n");
        }
        out += "| field | type | default | meaning |\n|---|---|---|---|\n";
        let required: Vec<&str> = table
            .get("required")
            .and_then(Value::as_array)
            .map(|r| r.iter().filter_map(Value::as_str).collect())
            .unwrap_or_default();
        for (field, schema) in table["properties"].as_object().into_iter().flatten() {
            let default = match schema.get("default") {
                _ if required.contains(&field.as_str()) => "required".to_string(),
                Some(Value::Null) | None => "none".to_string(),
                Some(v) => format!("`{}`", toml_value(v)),
            };
            out += &format!(
                "| `{field}` | {} | {default} | {} |\n",
                ctx.type_of(schema),
                cell(&text(schema.get("description")))
            );
        }
        out.push('\n');
    }
    out
}

enum TableKind<'a> {
    /// `[[name]]`, repeated.
    Array(&'a Map<String, Value>),
    /// `[name.KEY]`, by key.
    Map(&'a Map<String, Value>),
    /// `[name]`, once.
    One(&'a Map<String, Value>),
}

/// The schema's definitions, by name.
struct Defs(Map<String, Value>);

impl Defs {
    /// The definition `schema` refers to, or `schema` itself.
    fn resolve<'a>(&'a self, schema: &'a Value) -> &'a Value {
        match schema.get("$ref").and_then(Value::as_str) {
            Some(r) => self
                .0
                .get(r.trim_start_matches("#/$defs/"))
                .unwrap_or(schema),
            None => schema,
        }
    }

    /// A schema with its `null` alternative (an `Option`) taken out.
    fn some<'a>(&'a self, schema: &'a Value) -> &'a Value {
        if let Some(any) = schema.get("anyOf").and_then(Value::as_array) {
            let not_null: Vec<&Value> = any.iter().filter(|s| s["type"] != "null").collect();
            if let [one] = not_null[..] {
                return self.resolve(one);
            }
        }
        self.resolve(schema)
    }

    fn table_of<'a>(&'a self, property: &'a Value) -> Option<TableKind<'a>> {
        let p = self.some(property);
        let object = |s: &'a Value| {
            let s = self.resolve(s);
            s.get("properties")
                .is_some()
                .then(|| s.as_object())
                .flatten()
        };
        if let Some(items) = p.get("items") {
            return object(items).map(TableKind::Array);
        }
        if let Some(values) = p.get("additionalProperties").filter(|v| v.is_object()) {
            return object(values).map(TableKind::Map);
        }
        object(p).map(TableKind::One)
    }

    /// A field's type as a reader writes it in TOML.
    fn type_of(&self, schema: &Value) -> String {
        let optional = schema
            .get("anyOf")
            .and_then(Value::as_array)
            .is_some_and(|a| a.iter().any(|s| s["type"] == "null"))
            || schema["type"]
                .as_array()
                .is_some_and(|t| t.iter().any(|t| t == "null"));
        let s = self.some(schema);
        let shown = if let Some(values) = s.get("enum").and_then(Value::as_array) {
            values
                .iter()
                .map(|v| format!("`{}`", toml_value(v)))
                .collect::<Vec<_>>()
                .join(", ")
        } else if let Some(one_of) = s.get("oneOf").and_then(Value::as_array) {
            one_of
                .iter()
                .map(|v| match v.get("const") {
                    Some(c) => format!("`{}`", toml_value(c)),
                    None => self.type_of(v),
                })
                .collect::<Vec<_>>()
                .join(", ")
        } else if let Some(any) = s.get("anyOf").and_then(Value::as_array) {
            any.iter()
                .map(|v| self.type_of(v))
                .collect::<Vec<_>>()
                .join(" or ")
        } else if let Some(items) = s.get("items") {
            let item = self.type_of(items);
            match (s.get("minItems"), s.get("maxItems")) {
                (Some(a), Some(b)) if a == b => format!("[{item}; {a}]"),
                _ => format!("[{item}, ...]"),
            }
        } else if let Some(props) = s.get("properties").and_then(Value::as_object) {
            let keys: Vec<&str> = props.keys().map(String::as_str).collect();
            format!("{{ {} }}", keys.join(", "))
        } else {
            let ty = match &s["type"] {
                Value::Array(types) => types
                    .iter()
                    .filter(|t| *t != "null")
                    .filter_map(Value::as_str)
                    .next()
                    .unwrap_or("any"),
                t => t.as_str().unwrap_or("any"),
            };
            let min = s.get("minimum").and_then(Value::as_f64);
            match (ty, min) {
                ("integer", Some(m)) => format!("integer ≥ {m}"),
                (ty, _) => ty.to_string(),
            }
        };
        if optional {
            format!("{shown} (optional)")
        } else {
            shown
        }
    }
}

/// A value as TOML writes it (strings quoted, arrays in brackets).
fn toml_value(v: &Value) -> String {
    match v {
        Value::String(s) => format!("\"{s}\""),
        Value::Array(a) => format!(
            "[{}]",
            a.iter().map(toml_value).collect::<Vec<_>>().join(", ")
        ),
        Value::Object(o) => format!(
            "{{ {} }}",
            o.iter()
                .map(|(k, v)| format!("{k} = {}", toml_value(v)))
                .collect::<Vec<_>>()
                .join(", ")
        ),
        // A number read as f32 shows as the f32 it is (`0.95`, not `0.949999988079071`).
        Value::Number(n) => match n.as_f64() {
            Some(f) if n.is_f64() && f64::from(f as f32) == f => format!("{}", f as f32),
            Some(f) if n.is_f64() => format!("{f}"),
            _ => n.to_string(),
        },
        other => other.to_string(),
    }
}

/// A doc comment as one paragraph, without the rustdoc links' brackets.
fn text(description: Option<&Value>) -> String {
    let Some(d) = description.and_then(Value::as_str) else {
        return String::new();
    };
    let mut one = d.split_whitespace().collect::<Vec<_>>().join(" ");
    // `[`World::step`]` and `[x](y)` read as their text.
    while let Some(a) = one.find("[`") {
        let Some(b) = one[a..].find("`]") else { break };
        let inner = one[a + 1..a + b + 1].to_string();
        let mut end = a + b + 2;
        if one[end..].starts_with('(') {
            end += one[end..].find(')').map_or(0, |c| c + 1);
        }
        one.replace_range(a..end, &inner);
    }
    one
}

/// Text that stays inside one cell of a Markdown table.
fn cell(text: &str) -> String {
    text.replace('|', "\\|")
}
