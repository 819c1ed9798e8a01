//! Scene files (TOML): a world's parameters, bodies, generators of bodies, particles,
//! emitters, presets and the interactions between groups. A bad scene is refused with
//! the file, line and field at fault.
//!
//! docs/scenes.md is the format's reference, written from these types ([`reference`]),
//! with an example of every table.
//!
//! ```toml
//! groups = ["dye_packs"]       # groups joined only at run time, before the first table
//!
//! [world]                      # every field optional
//! gravity = [0, -50]
//!
//! [[body]]
//! id = "floor"
//! group = "platforms"
//! shape = "rect"               # or "circle" with radius = r
//! size = [30, 3.75]
//! mass = 0                     # 0 = static
//!
//! [[interact]]                 # only groups a body, generator, template or `groups` names
//! a = "dye_packs"
//! b = "platforms"              # "particles" names the particle side
//!
//! [[template]]                 # a body `spawn` may name: {"do":"spawn","template":"ball","at":[x,y]}
//! name = "ball"
//! group = "dye_packs"
//! shape = "circle"
//! radius = 1
//! ```

use std::collections::BTreeSet;
use std::path::Path;

use glam::{DVec2, Vec2, Vec4};

use crate::behavior::{self, Behavior, Held};
use crate::criteria::Criteria;
use crate::dynamics::body::BodyDef;
use crate::dynamics::config::{Solver, WorldConfig};
use crate::geometry::Shape;
use crate::particles::ParticleDef;
use crate::world::{Limits, World, PARTICLES};

mod error;
mod generate;
mod raw;
pub mod reference;

pub use error::{Local, SceneError};

use error::{did_you_mean, Ctx};
use generate::generate;
use raw::*;

/// Reads and builds a scene file.
pub fn load(path: &Path) -> Result<World, SceneError> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| SceneError::unplaced(path, "file", e.to_string()))?;
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
        config.set_from_str(assignment).map_err(|e| {
            let name = assignment.split('=').next().unwrap_or(assignment).trim();
            SceneError::unplaced(Path::new("--set"), name, e.to_string())
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

    for (i, raw) in scene.template.iter().enumerate() {
        let table = format!("template[{i}]");
        let span = raw.span();
        let mut fields = raw.get_ref().clone();
        let name = match fields.remove("name") {
            Some(toml::Value::String(name)) => name,
            Some(_) => return Err(ctx.field_error(&table, span, "name", "must be a string")),
            None => {
                return Err(ctx.field_error(
                    &table,
                    span,
                    "name",
                    "is needed: the name `spawn` gives as `template`",
                ))
            }
        };
        plain_name(&name).map_err(|m| ctx.field_error(&table, span.clone(), "name", &m))?;
        if let Some(group) = fields.get("group").and_then(toml::Value::as_str) {
            plain_name(group).map_err(|m| ctx.field_error(&table, span.clone(), "group", &m))?;
        }
        let spec: crate::action::BodySpec =
            toml::Value::Table(fields)
                .try_into()
                .map_err(|e: toml::de::Error| {
                    let message = error::unquoted(e.message().trim());
                    let field = error::backticked(&message)
                        .filter(|k| error::is_name(k))
                        .unwrap_or("name")
                        .to_string();
                    ctx.field_error(&table, span.clone(), &field, &message)
                })?;
        world.add_template(&name, spec).map_err(|e| {
            let field = match &e {
                crate::action::ActionError::BadArgument { field, .. } => *field,
                _ => "name",
            };
            ctx.field_error(&table, span.clone(), field, &e.to_string())
        })?;
    }

    let groups = named_groups(&scene);
    for (i, raw) in scene.interact.iter().enumerate() {
        let it = raw.get_ref();
        for (side, name) in [("a", &it.a), ("b", &it.b)] {
            plain_name(name.get_ref())
                .map_err(|m| ctx.field_error(&format!("interact[{i}]"), raw.span(), side, &m))?;
            check_group(&ctx, format!("interact[{i}].{side}"), name, &groups)?;
        }
        world
            .add_interaction(it.a.get_ref(), it.b.get_ref(), it.resolve)
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

/// The groups an interaction may name: those the scene's bodies and generators belong
/// to, and those its `groups` list names for bodies that join them only at run time.
/// (`particles`, the particle side, is always there.)
fn named_groups(scene: &SceneFile) -> BTreeSet<&str> {
    let bodies = scene.body.iter().map(|b| b.get_ref().group.as_str());
    let generated = scene.generate.iter().map(|g| g.get_ref().group.as_str());
    let listed = scene.groups.iter().map(|g| g.get_ref().as_str());
    let templates = scene.template.iter().map(|t| {
        t.get_ref()
            .get("group")
            .and_then(toml::Value::as_str)
            .unwrap_or("default")
    });
    bodies
        .chain(generated)
        .chain(listed)
        .chain(templates)
        .collect()
}

/// Refuses an interaction's side that names a group no body will ever be in (a typo
/// there would turn a collision off without a word).
fn check_group(
    ctx: &Ctx,
    field: String,
    name: &toml::Spanned<String>,
    groups: &BTreeSet<&str>,
) -> Result<(), SceneError> {
    let group = name.get_ref().as_str();
    if group == PARTICLES || groups.contains(group) {
        return Ok(());
    }
    let mut e = ctx.error_at(
        name.span(),
        field,
        &format!(
            "no body or generator is in group `{}` and the scene's `groups` list does not name it",
            crate::world::short(group, 64)
        ),
    );
    e.local.help = did_you_mean(group, groups.iter().copied().chain([PARTICLES])).or_else(|| {
        Some("a group that bodies join only at run time goes in `groups = [...]`, at the top of the file".into())
    });
    Err(e)
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
