//! Scene files (TOML): a world's parameters, bodies, generators of bodies, particles,
//! emitters, presets and the interactions between groups. A bad scene is refused with
//! the file, line and field at fault.
//!
//! ```toml
//! [world]                      # every field optional; the chapter's defaults
//! gravity = [0, -50]
//! relaxation_iterations = 15
//!
//! [limits]                     # optional: lower the runner's limits for this world
//! bodies = 500
//!
//! [[body]]
//! id = "hero"
//! group = "hero"
//! shape = "rect"               # or "circle" with radius = r
//! size = [16, 22]
//! pos = [30, 30]
//! mass = 0.7                   # 0 = static
//! behavior = "hero"            # or "minion", "dumb_minion"
//!
//! [[generate]]                 # bodies "<id>/0", "<id>/1", ...
//! kind = "row"                 # "row", "grid", "stack" or "pyramid"
//! id = "floor"
//! group = "platforms"
//! size = [30, 3.75]
//! start = [-15, 2]
//! step = [30, 0]
//! count = 9
//! mass = 0
//!
//! [[interact]]
//! a = "hero"
//! b = "platforms"              # "particles" names the particle side
//! ```

use std::path::{Path, PathBuf};

use glam::{DVec2, Vec2, Vec4};

use crate::behavior::{self, Behavior, Held};
use crate::criteria::Criteria;
use crate::dynamics::body::BodyDef;
use crate::dynamics::config::{Solver, WorldConfig};
use crate::geometry::Shape;
use crate::particles::ParticleDef;
use crate::world::{Limits, World};

mod generate;
mod raw;

use generate::generate;
use raw::*;

/// A refused scene: where and why.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{}:{line}: {field}: {message}", file.display())]
pub struct SceneError {
    pub file: PathBuf,
    /// 1-based line of the offending field (or of its table when the field is missing).
    pub line: usize,
    /// The field at fault, with its table: `body[2].radius`, `world.dt`.
    pub field: String,
    pub message: String,
}

/// Reads and builds a scene file.
pub fn load(path: &Path) -> Result<World, SceneError> {
    let text = std::fs::read_to_string(path).map_err(|e| SceneError {
        file: path.to_path_buf(),
        line: 0,
        field: "file".into(),
        message: e.to_string(),
    })?;
    parse(&text, path, &[])
}

/// Builds a scene from its text under the default [`Limits`]; `file` names it in errors.
/// `overrides` are `NAME=VALUE` assignments to `[world]` fields applied after the file's
/// (the `--set` flag).
pub fn parse(text: &str, file: &Path, overrides: &[String]) -> Result<World, SceneError> {
    parse_with(text, file, overrides, &Limits::default())
}

/// [`parse`] under the limits `ceiling`: the scene's `[limits]` table may lower them,
/// never raise them, and the scene must fit them (bodies, particles, emitters, groups,
/// presets, and the estimated work of a step).
pub fn parse_with(
    text: &str,
    file: &Path,
    overrides: &[String],
    ceiling: &Limits,
) -> Result<World, SceneError> {
    let ctx = Ctx { text, file };
    let scene: SceneFile = toml::from_str(text).map_err(|e| ctx.parse_error(&e))?;

    let mut config = scene
        .world
        .as_ref()
        .map(|w| w.get_ref().clone())
        .unwrap_or_default();
    config.validate().map_err(|e| match &e {
        crate::dynamics::config::ConfigError::Invalid { name, .. } => {
            let span = scene.world.as_ref().map(|t| t.span()).unwrap_or(0..0);
            ctx.field_error("world", span, name, &e.to_string())
        }
        other => ctx.field_error("world", 0..0, "world", &other.to_string()),
    })?;
    for assignment in overrides {
        config.set_from_str(assignment).map_err(|e| SceneError {
            file: PathBuf::from("--set"),
            line: 0,
            field: assignment
                .split('=')
                .next()
                .unwrap_or(assignment)
                .trim()
                .to_string(),
            message: e.to_string(),
        })?;
    }
    if config.solver == Solver::Relaxation {
        // The chapter's relaxation keeps the chapter's sub-steps and broad phase unless
        // the table or an override names them.
        let table: toml::Table = toml::from_str(text).map_err(|e| ctx.parse_error(&e))?;
        let mut named: Vec<&str> = table
            .get("world")
            .and_then(|w| w.as_table())
            .map(|w| w.keys().map(String::as_str).collect())
            .unwrap_or_default();
        named.extend(
            overrides
                .iter()
                .filter_map(|o| o.split('=').next())
                .map(str::trim),
        );
        config = config.named_over(WorldConfig::chapter(), &named);
    }

    let limits = match &scene.limits {
        None => ceiling.clone(),
        Some(table) => read_limits(table, ceiling, &ctx)?,
    };
    let mut world = World::with_limits(config, limits);

    for (name, preset) in &scene.preset {
        let table = format!("preset.{}", name.escape_debug());
        plain_name(name).map_err(|m| ctx.field_error(&table, preset.span(), "name", &m))?;
        if let Some(field) = preset.get_ref().non_finite_field() {
            return Err(ctx.field_error(&table, preset.span(), field, "is not finite"));
        }
        world
            .add_preset(name, preset.get_ref().clone())
            .map_err(|e| ctx.field_error(&table, preset.span(), "rand", &e.to_string()))?;
    }

    for (i, raw) in scene.body.iter().enumerate() {
        let table = format!("body[{i}]");
        let span = raw.span();
        let raw = raw.get_ref();
        let id = raw.id.clone().unwrap_or_else(|| format!("body/{i}"));
        for (field, name) in [("id", &id), ("group", &raw.group)] {
            plain_name(name).map_err(|m| ctx.field_error(&table, span.clone(), field, &m))?;
        }
        let shape = shape_of(raw.shape, raw.size, raw.radius)
            .map_err(|(f, m)| ctx.field_error(&table, span.clone(), f, &m))?;
        let def = BodyDef {
            id,
            group: raw.group.clone(),
            shape,
            pos: DVec2::from(raw.pos),
            vel: DVec2::from(raw.vel),
            mass: raw.mass,
            restitution: raw.restitution,
            friction: raw.friction,
            gravity: raw.gravity.map(DVec2::from),
        };
        let behavior = behavior_of(raw.behavior, DVec2::from(raw.vel));
        add(&mut world, def, behavior, &ctx, &table, span)?;
    }

    for (i, raw) in scene.generate.iter().enumerate() {
        let table = format!("generate[{i}]");
        let span = raw.span();
        let g = raw.get_ref();
        for (field, name) in [("id", &g.id), ("group", &g.group)] {
            plain_name(name).map_err(|m| ctx.field_error(&table, span.clone(), field, &m))?;
        }
        let shape = shape_of(g.shape, g.size, g.radius)
            .map_err(|(f, m)| ctx.field_error(&table, span.clone(), f, &m))?;
        let positions = generate(g, shape, world.room_for_bodies())
            .map_err(|(f, m)| ctx.field_error(&table, span.clone(), f, &m))?;
        for (k, pos) in positions.into_iter().enumerate() {
            let def = BodyDef {
                id: format!("{}/{k}", g.id),
                group: g.group.clone(),
                shape,
                pos,
                vel: DVec2::from(g.vel),
                mass: g.mass,
                restitution: g.restitution,
                friction: g.friction,
                gravity: g.gravity.map(DVec2::from),
            };
            let behavior = behavior_of(g.behavior, DVec2::from(g.vel));
            add(&mut world, def, behavior, &ctx, &table, span.clone())?;
        }
    }

    for (i, raw) in scene.particle.iter().enumerate() {
        let p = raw.get_ref();
        let def = ParticleDef {
            pos: Vec2::from(p.pos),
            vel: Vec2::from(p.vel),
            life: p.life,
            size: p.size,
            color: Vec4::from(p.color),
            final_color: Vec4::from(p.final_color.unwrap_or(p.color)),
            size_delta: p.size_delta,
            drag: p.drag,
            gravity: p.gravity.map(Vec2::from),
        };
        def.validate().map_err(|e| {
            ctx.field_error(&format!("particle[{i}]"), raw.span(), e.field, &e.reason)
        })?;
        world.add_particle(&def).map_err(|e| {
            ctx.field_error(&format!("particle[{i}]"), raw.span(), "pos", &e.to_string())
        })?;
    }

    for (i, raw) in scene.emitter.iter().enumerate() {
        let e = raw.get_ref();
        let table = format!("emitter[{i}]");
        if world.presets().get(&e.preset).is_none() {
            let known = world.presets().names().collect::<Vec<_>>().join(", ");
            return Err(ctx.field_error(
                &table,
                raw.span(),
                "preset",
                &format!(
                    "unknown preset `{}` (known: {known})",
                    crate::world::short(&e.preset.escape_debug().to_string(), 64)
                ),
            ));
        }
        world
            .add_emitter(&e.preset, e.count, Vec2::from(e.pos))
            .map_err(|err| {
                let field = match err {
                    crate::world::WorldError::Limit(_) => "count",
                    _ => "pos",
                };
                ctx.field_error(&table, raw.span(), field, &err.to_string())
            })?;
    }

    for (i, raw) in scene.interact.iter().enumerate() {
        let it = raw.get_ref();
        for (field, name) in [("a", &it.a), ("b", &it.b)] {
            plain_name(name)
                .map_err(|m| ctx.field_error(&format!("interact[{i}]"), raw.span(), field, &m))?;
        }
        world
            .add_interaction(&it.a, &it.b, it.resolve)
            .map_err(|e| {
                ctx.field_error(&format!("interact[{i}]"), raw.span(), "b", &e.to_string())
            })?;
    }
    if let Some(criteria) = &scene.criteria {
        criteria
            .get_ref()
            .validate()
            .map_err(|(f, m)| ctx.field_error("criteria", criteria.span(), f, &m))?;
    }
    world.check_work(&world.config).map_err(|e| {
        let span = scene.world.as_ref().map(|t| t.span()).unwrap_or(0..0);
        ctx.field_error("world", span, "solver", &e.to_string())
    })?;
    Ok(world)
}

/// The scene's `[criteria]` (see [`crate::criteria`]), if it states any; a bad table is
/// refused as [`parse`] refuses it.
pub fn criteria(text: &str, file: &Path) -> Result<Option<Criteria>, SceneError> {
    let ctx = Ctx { text, file };
    let scene: SceneFile = toml::from_str(text).map_err(|e| ctx.parse_error(&e))?;
    let Some(criteria) = scene.criteria else {
        return Ok(None);
    };
    criteria
        .get_ref()
        .validate()
        .map_err(|(f, m)| ctx.field_error("criteria", criteria.span(), f, &m))?;
    Ok(Some(criteria.into_inner()))
}

/// The scene's `[limits]` over `ceiling`: each named value must be valid and no higher.
fn read_limits(
    table: &toml::Spanned<toml::Table>,
    ceiling: &Limits,
    ctx: &Ctx,
) -> Result<Limits, SceneError> {
    let err =
        |field: &str, message: String| ctx.field_error("limits", table.span(), field, &message);
    let assignments: Vec<String> = table
        .get_ref()
        .iter()
        .map(|(k, v)| format!("{k}={v}"))
        .collect();
    let limits = ceiling.with(&assignments).map_err(|e| match &e {
        crate::world::LimitError::Invalid { name, .. } => err(name, e.to_string()),
        other => err("limits", other.to_string()),
    })?;
    if let Some((name, asked, max)) = limits.above(ceiling) {
        return Err(err(
            name,
            format!("{asked} is above the runner's limit of {max}; a scene may only lower it"),
        ));
    }
    Ok(limits)
}

fn add(
    world: &mut World,
    def: BodyDef,
    behavior: Behavior,
    ctx: &Ctx,
    table: &str,
    span: std::ops::Range<usize>,
) -> Result<(), SceneError> {
    let id = def.id.clone();
    world
        .add_actor(def, behavior)
        .map(|_| ())
        .map_err(|e| match e {
            crate::world::WorldError::Body { source, .. } => ctx.field_error(
                table,
                span,
                source.field,
                &format!("body `{id}`: {}", source.reason),
            ),
            other => ctx.field_error(table, span, "id", &other.to_string()),
        })
}

fn shape_of(
    kind: ShapeKind,
    size: Option<[f64; 2]>,
    radius: Option<f64>,
) -> Result<Shape, (&'static str, String)> {
    match (kind, size, radius) {
        (ShapeKind::Rect, Some([w, h]), None) => Ok(Shape::rect(w, h)),
        (ShapeKind::Circle, None, Some(r)) => Ok(Shape::circle(r)),
        (ShapeKind::Rect, None, _) => Err(("size", "a rect needs size = [width, height]".into())),
        (ShapeKind::Rect, Some(_), Some(_)) => {
            Err(("radius", "a rect has a size, not a radius".into()))
        }
        (ShapeKind::Circle, _, None) => Err(("radius", "a circle needs radius = r".into())),
        (ShapeKind::Circle, Some(_), Some(_)) => {
            Err(("size", "a circle has a radius, not a size".into()))
        }
    }
}

fn behavior_of(kind: Option<BehaviorKind>, vel: DVec2) -> Behavior {
    match kind {
        None | Some(BehaviorKind::None) => Behavior::None,
        Some(BehaviorKind::Hero) => Behavior::Hero {
            held: Held::default(),
        },
        Some(BehaviorKind::Minion) => Behavior::Patrol {
            speed: if vel.x != 0.0 {
                vel.x.abs()
            } else {
                behavior::MINION_SPEED
            },
            dir: if vel.x < 0.0 { -1.0 } else { 1.0 },
        },
        Some(BehaviorKind::DumbMinion) => Behavior::DumbMinion,
    }
}

/// Refuses a name (a body's id, a group's, a preset's) holding a control character: names
/// reach `info` replies, frames, dumps and viewers' labels and terminals, where an escape
/// sequence or a newline would be read as something else than a name.
fn plain_name(name: &str) -> Result<(), String> {
    match name.chars().find(|c| c.is_control()) {
        Some(c) => Err(format!(
            "holds the control character U+{:04X}: a name may not",
            c as u32
        )),
        None => Ok(()),
    }
}

/// The scene's text and name, for locating errors.
struct Ctx<'a> {
    text: &'a str,
    file: &'a Path,
}

impl Ctx<'_> {
    fn line_of(&self, offset: usize) -> usize {
        let offset = offset.min(self.text.len());
        self.text[..offset].bytes().filter(|&b| b == b'\n').count() + 1
    }

    /// The line of `field = ...` inside the span of a table, or the table's first line.
    fn field_line(&self, span: &std::ops::Range<usize>, field: &str) -> usize {
        let (start, end) = (
            span.start.min(self.text.len()),
            span.end.min(self.text.len()),
        );
        let mut offset = start;
        for line in self.text[start..end].split_inclusive('\n') {
            let trimmed = line.trim_start();
            if let Some(rest) = trimmed.strip_prefix(field) {
                if rest.trim_start().starts_with('=') {
                    return self.line_of(offset);
                }
            }
            offset += line.len();
        }
        // A field left out: point at the table's header, the line before its body.
        let line = self.line_of(start);
        let header = self.text[..start]
            .trim_end()
            .rfind('\n')
            .map_or(1, |i| self.line_of(i + 1));
        if self.text[..start].trim_end().ends_with(']') {
            header
        } else {
            line
        }
    }

    fn field_error(
        &self,
        table: &str,
        span: std::ops::Range<usize>,
        field: &str,
        message: &str,
    ) -> SceneError {
        SceneError {
            file: self.file.to_path_buf(),
            line: self.field_line(&span, field),
            field: format!("{table}.{field}"),
            message: message.to_string(),
        }
    }

    fn parse_error(&self, e: &toml::de::Error) -> SceneError {
        let (line, field) = match e.span() {
            Some(span) => {
                let line = self.line_of(span.start);
                let text_line = self.text.lines().nth(line - 1).unwrap_or("");
                let key = text_line
                    .split_once('=')
                    .map(|(k, _)| k.trim().to_string())
                    .filter(|k| is_name(k));
                // A table header as written (`[[body]`), where its name has a name's form.
                let header = Some(text_line.trim())
                    .filter(|l| l.starts_with('[') && l.len() <= 68)
                    .filter(|l| is_name(l.trim_matches(['[', ']'])))
                    .map(str::to_string);
                let field = key
                    .or(header)
                    .or_else(|| {
                        backticked(e.message())
                            .filter(|k| is_name(k))
                            .map(str::to_string)
                    })
                    .unwrap_or_else(|| "scene".to_string());
                (line, field)
            }
            None => (
                0,
                backticked(e.message())
                    .filter(|k| is_name(k))
                    .unwrap_or("scene")
                    .to_string(),
            ),
        };
        // No text of the file is quoted (a file that is not a scene may hold secrets):
        // a field only where it has the form of a name, and the message with every quoted
        // value taken out.
        SceneError {
            file: self.file.to_path_buf(),
            line,
            field,
            message: crate::world::short(&unquoted(e.message().trim()), 300),
        }
    }
}

/// Whether `s` has the form of a TOML key or table name (letters, digits, `_`, `-`,
/// `.`; at most 64 bytes): only such a piece of a file is named in an error.
fn is_name(s: &str) -> bool {
    !s.is_empty()
        && s.len() <= 64
        && s.bytes()
            .all(|b| b.is_ascii_alphanumeric() || matches!(b, b'_' | b'-' | b'.'))
}

/// A parser's message with what it quotes of the file taken out: text in double quotes
/// becomes `"…"`, and a backticked piece `` `…` `` unless it is what the parser
/// expected (names and tokens such as `` `=` ``) or an unknown field's name.
fn unquoted(message: &str) -> String {
    let mut out = String::with_capacity(message.len());
    let mut rest = message;
    while let Some(k) = rest.find(['"', '`']) {
        let q = rest[k..].chars().next().expect("found");
        out.push_str(&rest[..k]);
        let after = &rest[k + 1..];
        let Some(end) = after.find(q) else {
            out.push(q);
            out.push('…');
            return out;
        };
        let inner = &after[..end];
        // Kept: the parser's alternatives (after "expected") and an unknown field's name;
        // a value it quotes (an unknown variant, a number of the wrong type) is not.
        let told = out.contains("expected") || out.ends_with("field ");
        let keep =
            q == '`' && told && (is_name(inner) || inner.bytes().all(|b| b.is_ascii_punctuation()));
        out.push(q);
        out.push_str(if keep { inner } else { "…" });
        out.push(q);
        rest = &after[end + 1..];
    }
    out.push_str(rest);
    out
}

/// The first `name` in backticks of a serde message ("unknown field `siz`").
fn backticked(message: &str) -> Option<&str> {
    let start = message.find('`')? + 1;
    let len = message[start..].find('`')?;
    Some(&message[start..start + len])
}
