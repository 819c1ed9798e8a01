//! Generators of bodies: rows, grids, stacks and pyramids of one shape, as positions.

use glam::DVec2;

use super::raw::{GeneratorKind, RawGenerator};
use crate::geometry::Shape;

/// The largest number of bodies one generator may make.
pub(super) const MAX_GENERATED: u64 = 10_000_000;

/// The positions of a generator's bodies, at most `room` of them (what the world's
/// `bodies` limit leaves), checked before any is made.
pub(super) fn generate(
    g: &RawGenerator,
    shape: Shape,
    room: u64,
) -> Result<Vec<DVec2>, (&'static str, String)> {
    let need = |field: &'static str, v: Option<u32>| {
        v.ok_or((
            field,
            format!("a {:?} generator needs `{field}`", g.kind).to_lowercase(),
        ))
    };
    let size = shape.size();
    let finite = |field: &'static str, v: [f64; 2]| {
        if DVec2::from(v).is_finite() {
            Ok(DVec2::from(v))
        } else {
            Err((field, "is not finite".to_string()))
        }
    };
    if !g.gap.is_finite() {
        return Err(("gap", "is not finite".into()));
    }
    let count_check = |n: u64| {
        if n > MAX_GENERATED {
            Err(("count", format!("{n} bodies is more than {MAX_GENERATED}")))
        } else if n > room {
            Err((
                "count",
                format!(
                    "{n} bodies would exceed the world's limit (limits.bodies): room for {room}"
                ),
            ))
        } else {
            Ok(())
        }
    };
    let mut out = Vec::new();
    match g.kind {
        GeneratorKind::Row => {
            let (start, step) = (
                finite("start", g.start)?,
                finite(
                    "step",
                    g.step
                        .ok_or(("step", "a row generator needs `step`".to_string()))?,
                )?,
            );
            let n = need("count", g.count)?;
            count_check(n as u64)?;
            out.extend((0..n).map(|k| start + step * k as f64));
        }
        GeneratorKind::Grid => {
            let (start, step) = (
                finite("start", g.start)?,
                finite("step", g.step.unwrap_or([size.x, size.y]))?,
            );
            let (cols, rows) = (need("cols", g.cols)?, need("rows", g.rows)?);
            count_check(cols as u64 * rows as u64)?;
            for r in 0..rows {
                for c in 0..cols {
                    out.push(start + DVec2::new(c as f64 * step.x, r as f64 * step.y));
                }
            }
        }
        GeneratorKind::Stack => {
            let base = finite("base", g.base)?;
            let n = need("count", g.count)?;
            count_check(n as u64)?;
            out.extend(
                (0..n).map(|k| base + DVec2::new(0.0, size.y * 0.5 + k as f64 * (size.y + g.gap))),
            );
        }
        GeneratorKind::Pyramid => {
            let base = finite("base", g.base)?;
            let levels = need("levels", g.levels)?;
            count_check(levels as u64 * (levels as u64 + 1) / 2)?;
            for level in 0..levels {
                let n = levels - level;
                let y = base.y + size.y * 0.5 + level as f64 * (size.y + g.gap);
                for i in 0..n {
                    let x = base.x + (i as f64 - (n - 1) as f64 * 0.5) * (size.x + g.gap);
                    out.push(DVec2::new(x, y));
                }
            }
        }
    }
    Ok(out)
}
