//! The support sweep: shock propagation over the contacts that hold bodies up (after
//! Guendelman, Bridson and Fedkiw, "Nonconvex rigid bodies with stacking", 2003).
//!
//! A few sequential-impulse passes carry a pile's load down one contact a pass. Where the
//! pile was built at rest the resting load ([`super::load`]) starts it converged; where it
//! forms at run time (a column dropped box by box, a rain, heavy boxes landing on a bed of
//! light circles) the passes leave part of each impact's approach, every sub-step, and the
//! pile sinks into itself by it. After the passes, one sweep visits every contact whose
//! normal is within 45 degrees of gravity, from the lowest upper body to the highest, and
//! stops the upper body from approaching the lower one, the lower taken as fixed. A body
//! is visited after everything under it, so one sweep leaves no contact of a pile
//! approaching, however deep; what it takes out is what the passes had not yet carried
//! down, which a converged solve would have given the lower body instead.
//!
//! With split impulses, the same sweep carries the push-out: each upper body is pushed
//! out of its lower one at the contact's push-out speed on top of the lower body's, and
//! no body, however many contacts push it up or aside, faster than one contact may push
//! ([`super::MAX_PUSH_OUT`] sizes a second). A column started overlapped opens from the
//! ground up in a few seconds, where the passes, starting each sub-step's push-out from
//! nothing, opened only its top contacts; and a pyramid's top no longer moves at the
//! sum of the pushes of every contact under it.
//!
//! It changes only the velocities of upper bodies whose contact approaches, and only
//! straight up: a separating or sliding contact, a bounce the collision stage made, and
//! every contact without gravity are left alone. The impulse it gives is not kept for the
//! next step's warm start: kept, it pushed the lower bodies down again with what the sweep
//! had taken out, and heavy boxes on beds of circles were thrown about.

use glam::DVec2;

use super::load::SUPPORT_COS;
use super::{Contact, SolverBody};
use crate::dynamics::body::Body;

/// One supporting contact: where it is among the buckets, and which of its bodies is the
/// upper one.
#[derive(Clone, Copy, Debug)]
pub(super) struct Support {
    bucket: u32,
    index: u32,
    /// The contact's `b` is the upper body (its normal points up).
    upper_is_b: bool,
    /// How high the upper body is.
    height: f64,
}

/// Lists the contacts of `buckets` that hold a dynamic body up against `up` (unit,
/// against gravity) into `out`, in the order the sweep visits them: by the height of the
/// body they hold up, lowest first (ties in the contacts' order).
pub(super) fn order(
    buckets: &[Vec<Contact>],
    sb: &[SolverBody],
    bodies: &[Body],
    slotted: &[u32],
    up: DVec2,
    out: &mut Vec<Support>,
) {
    for (k, bucket) in buckets.iter().enumerate() {
        for (i, c) in bucket.iter().enumerate() {
            let cos = c.normal.dot(up);
            let (upper, upper_is_b) = if cos > SUPPORT_COS {
                (c.b, true)
            } else if cos < -SUPPORT_COS {
                (c.a, false)
            } else {
                continue;
            };
            if sb[upper as usize].inv_mass == 0.0 {
                continue;
            }
            let height = bodies[slotted[upper as usize] as usize].pos.dot(up);
            out.push(Support {
                bucket: k as u32,
                index: i as u32,
                upper_is_b,
                height,
            });
        }
    }
    // A stable sort: equal heights keep the contacts' order.
    out.sort_by(|x, y| x.height.total_cmp(&y.height));
}

/// One sweep over `supports` (as [`order`] left them against `up`) at the end of a
/// sub-step `h`'s passes: each upper body stops approaching its lower one (a contact found
/// apart may close its gap within the sub-step, no more); with `push` (split impulses: the
/// push-out rates against dynamic and static bodies), each is pushed out of it too.
pub(super) fn sweep(
    sb: &mut [SolverBody],
    buckets: &[Vec<Contact>],
    supports: &[Support],
    up: DVec2,
    h: f64,
    push: Option<(f64, f64)>,
) {
    for s in supports {
        let c = &buckets[s.bucket as usize][s.index as usize];
        let (upper, lower) = if s.upper_is_b { (c.b, c.a) } else { (c.a, c.b) };
        let (u, l) = (sb[upper as usize], sb[lower as usize]);
        let normal = if s.upper_is_b { c.normal } else { -c.normal };
        let gap = c.gap + (sb[c.b as usize].delta - sb[c.a as usize].delta).dot(c.normal);
        let target = if c.speculative && gap > 0.0 {
            -gap / h
        } else {
            0.0
        };
        let approach = (u.vel - l.vel).dot(normal);
        if approach < target {
            // Straight up (against gravity), not along the normal: a circle on a slope of
            // others is not pushed sideways.
            let cos = normal.dot(up);
            sb[upper as usize].vel += up * ((target - approach) / cos);
        }
        let Some((rate, rate_fixed)) = push else {
            continue;
        };
        if c.speculative && gap > 0.0 {
            continue;
        }
        let pen = (-gap - c.slop).max(0.0);
        let rate = if c.fixed { rate_fixed } else { rate };
        let target = (rate * pen).min(c.max_push);
        let (u, l) = (sb[upper as usize], sb[lower as usize]);
        let apart = (u.pseudo - l.pseudo).dot(normal);
        let cos = normal.dot(up);
        let mut pseudo = u.pseudo;
        if apart < target {
            pseudo += up * ((target - apart) / cos);
        }
        // However many contacts push it, up or aside, a body is pushed out no faster
        // than one of them may push.
        let speed = pseudo.length();
        if speed > c.max_push {
            pseudo *= c.max_push / speed;
        }
        sb[upper as usize].pseudo = pseudo;
    }
}
