//! The resting load: the normal impulses that hold a pile placed at rest, solved once in
//! one sweep from the top down instead of over many passes.
//!
//! A pile built at rest has no impulses to warm-start from. Sequential impulses carry its
//! weight down one contact per pass, so a few passes a frame take many frames to reach
//! the bottom of a tall pile or to balance a heavy body on a light one, and the pile sags
//! meanwhile (a 60-box column by a box and a half; a 10 000:1 plank crushes its legs).
//! With rotation locked and boxes on axes, a pile's vertical contacts form a directed
//! graph of supports, and the load each carries follows from the weights alone: every
//! body, from the highest down, passes its own weight and what it carries to the
//! contacts below it, split by the width each shares with it. The impulses so found
//! balance every body's weight exactly (rotation is locked, so no torque asks for another
//! split), so the first passes start where a converged solve would end.

use glam::DVec2;

use super::{Contact, SolverBody};
use crate::dynamics::body::Body;

/// Contacts whose normal is within about 45 degrees of the vertical carry load.
pub(super) const SUPPORT_COS: f64 = 0.7;

/// Sets the normal impulse of every touching contact that holds a body up to its share of
/// the load over one sub-step `h`; other contacts are left as they are. `up` points
/// against gravity (unit length); `gain` is what each moving body (the first
/// `gain.len()` solver bodies) gains per second; `bodies[slotted[s]]` is solver body `s`.
pub(super) fn rest(
    contacts: &mut [Vec<Contact>],
    sb: &[SolverBody],
    gain: &[DVec2],
    bodies: &[Body],
    slotted: &[u32],
    h: f64,
    up: DVec2,
) {
    // Each body's own weight over the sub-step, along -up.
    let mut load: Vec<f64> = vec![0.0; sb.len()];
    for (s, g) in gain.iter().enumerate() {
        if sb[s].inv_mass > 0.0 {
            load[s] = (-g.dot(up) * h / sb[s].inv_mass).max(0.0);
        }
    }
    // Every supporting contact, by the body it holds up: (upper, lower, bucket, index,
    // share of the upper body's width it carries, cosine of its normal to up), then
    // placed by upper body (in the order found: a count, then a place for each).
    let n = sb.len();
    let mut count = vec![0u32; n + 1];
    let mut found: Vec<(u32, u32, u32, u32, f64, f64)> = Vec::new();
    for (k, bucket) in contacts.iter().enumerate() {
        for (i, c) in bucket.iter().enumerate() {
            if c.speculative {
                continue;
            }
            let cos = c.normal.dot(up);
            let (upper, lower) = if cos > SUPPORT_COS {
                (c.b, c.a)
            } else if cos < -SUPPORT_COS {
                (c.a, c.b)
            } else {
                continue;
            };
            if sb[upper as usize].inv_mass == 0.0 {
                continue;
            }
            let (u, l) = (
                &bodies[slotted[upper as usize] as usize],
                &bodies[slotted[lower as usize] as usize],
            );
            let width = shared_width(u, l, up);
            count[upper as usize + 1] += 1;
            found.push((upper, lower, k as u32, i as u32, width, cos.abs()));
        }
    }
    // `count[s]..count[s + 1]`: where the supports of body `s` go.
    for s in 0..n {
        count[s + 1] += count[s];
    }
    let mut supports = found.clone();
    let mut at = count.clone();
    for t in &found {
        supports[at[t.0 as usize] as usize] = *t;
        at[t.0 as usize] += 1;
    }
    // The bodies that stand on something, highest first (ties in slot order).
    let height: Vec<f64> = slotted
        .iter()
        .map(|&i| bodies[i as usize].pos.dot(up))
        .collect();
    let mut order: Vec<u32> = (0..n as u32)
        .filter(|&s| count[s as usize + 1] > count[s as usize])
        .collect();
    order.sort_unstable_by(|&x, &y| {
        height[y as usize]
            .total_cmp(&height[x as usize])
            .then(x.cmp(&y))
    });
    for s in order {
        let held = &supports[count[s as usize] as usize..count[s as usize + 1] as usize];
        let total: f64 = held.iter().map(|t| t.4).sum();
        let carried = load[s as usize];
        if carried <= 0.0 {
            continue;
        }
        for &(_, lower, k, i, width, cos) in held {
            let share = if total > 0.0 {
                width / total
            } else {
                1.0 / held.len() as f64
            };
            let impulse = carried * share / cos;
            let c = &mut contacts[k as usize][i as usize];
            c.normal_impulse = impulse;
            c.tangent_impulse = 0.0;
            if sb[lower as usize].inv_mass > 0.0 {
                load[lower as usize] += impulse * cos;
            }
        }
    }
}

/// How much of the upper body's width (across `up`) lies over the lower body's.
fn shared_width(upper: &Body, lower: &Body, up: DVec2) -> f64 {
    let across = DVec2::new(up.y, -up.x);
    let (cu, cl) = (upper.pos.dot(across), lower.pos.dot(across));
    let half = |b: &Body| {
        let h = b.shape.half_extents();
        (h.x * across.x).abs() + (h.y * across.y).abs()
    };
    let (hu, hl) = (half(upper), half(lower));
    ((cu + hu).min(cl + hl) - (cu - hu).max(cl - hl)).max(0.0)
}
