//! Free contacts: those between two moving bodies nothing accelerates, of a crowd its
//! container holds. Their push-out is spread over the crowd before each sub-step's passes
//! rather than solved in them, so a crowd squeezed evenly stays where it is.

use glam::DVec2;

use super::{Contact, SolverBody};

/// Keeps free only the contacts of crowds held in place: bodies joined through touching
/// contacts to a static body (a container's wall). A crowd pressed into its container
/// cannot spread; a block struck in open space can, and its contacts keep the push-out
/// of the passes, which opens it at once where spread pushes opened a compressed row from
/// its free end only, a body at a time. `parent` is scratch.
pub(super) fn hold_free(
    sb: &[SolverBody],
    buckets: &mut [Vec<Contact>],
    parent: &mut Vec<u32>,
    touching_fixed: bool,
) -> bool {
    use crate::dynamics::sleep::find;
    // Nothing static touched (`touching_fixed`, as the search found): no crowd is held,
    // and no contact stays free (a block struck in open space, as the suite's smash, pays
    // one look at its contacts, not the joins).
    if !touching_fixed {
        for c in buckets.iter_mut().flatten() {
            c.free = false;
        }
        return false;
    }
    let n = sb.len();
    // Slot `n` stands for every static body.
    parent.clear();
    parent.extend(0..=n as u32);
    let wall = n as u32;
    for c in buckets.iter().flatten() {
        if c.gap > 0.0 || !(c.free || c.fixed) {
            continue;
        }
        let (a, b) = if c.fixed {
            // The static body's slot is not shared: join the moving one to the wall.
            let moving = if sb[c.a as usize].inv_mass > 0.0 {
                c.a
            } else {
                c.b
            };
            (moving, wall)
        } else {
            (c.a, c.b)
        };
        let (ra, rb) = (find(parent, a), find(parent, b));
        if ra != rb {
            parent[ra.max(rb) as usize] = ra.min(rb);
        }
    }
    let root_wall = find(parent, wall);
    let mut any = false;
    for c in buckets.iter_mut().flatten() {
        if c.free {
            c.free = find(parent, c.a) == root_wall;
            any |= c.free;
        }
    }
    any
}

/// The push-out of the free contacts (two moving bodies nothing accelerates, of a crowd
/// its container holds: [`hold_free`]), before each sub-step's passes: each contact's push, `rate` times its depth beyond the slop (capped at its
/// `max_push`), shared between its bodies by inverse mass, and each body moved by the mean
/// of the pushes its contacts give it. Pushes that oppose each other cancel: a crowd
/// squeezed evenly stays where it is, where pushes solved one after the other moved it
/// by the order they came in.
pub(super) fn spread_push_out(
    sb: &mut [SolverBody],
    buckets: &[Vec<Contact>],
    rate: f64,
    spread: &mut Vec<(DVec2, u32)>,
) {
    spread.clear();
    spread.resize(sb.len(), (DVec2::ZERO, 0));
    for c in buckets.iter().flatten() {
        if !c.free {
            continue;
        }
        let (a, b) = (c.a as usize, c.b as usize);
        let gap = c.gap + (sb[b].delta - sb[a].delta).dot(c.normal);
        let pen = (-gap - c.slop).max(0.0);
        if pen <= 0.0 {
            continue;
        }
        let push = c.normal * (rate * pen).min(c.max_push) * c.mass;
        let (ia, ib) = (sb[a].inv_mass, sb[b].inv_mass);
        spread[a].0 -= push * ia;
        spread[a].1 += 1;
        spread[b].0 += push * ib;
        spread[b].1 += 1;
    }
    for (body, &(push, n)) in sb.iter_mut().zip(spread.iter()) {
        if n > 0 {
            body.pseudo += push / f64::from(n);
        }
    }
}
