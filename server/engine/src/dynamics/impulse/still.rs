//! Frames with nothing for the velocity passes to do: every body still, nothing
//! accelerating one, no impulse carried from the last frame. Under split impulses the
//! passes then only push out: each contact's velocity impulse would bring a normal
//! velocity of 0 to a target of 0 (a touching contact holds) or to an approach it allows
//! (a gap it may close), and friction a tangential velocity of 0 to 0, so every impulse
//! is 0 and every velocity stays 0. A crowd its container holds, packed past what fits,
//! spends its frames so: its circles move by the push-out alone (the crowds family: every
//! velocity 0 for the whole run), and the velocity passes were half of its step.

use glam::DVec2;

use super::blocks::Bodies;
use super::passes::{in_blocks, split_push};
use super::team::Team;
use super::{Contact, ImpulseParams, SolverBody};

/// Whether the frame is still: split impulses, no stage that moves a velocity without a
/// contact's impulse (the resting load, the support sweep and exact sliding act under
/// gravity), every body's velocity and gain 0, and no contact starting from an impulse
/// (`impulses`: the contact search found one). The bodies' velocities then stay 0
/// through every sub-step, and the collision stage, the warm start, the relax passes,
/// the velocity half of each pass and the impact sweep (no contact approaches or
/// presses) change nothing.
pub(super) fn frame(
    params: &ImpulseParams,
    sb: &[SolverBody],
    gain: &[DVec2],
    impulses: bool,
) -> bool {
    params.split_impulses
        && params.rest_load.is_none()
        && params.support.is_none()
        && params.exact_sliding.is_none()
        && !impulses
        && sb.iter().all(|s| s.vel == DVec2::ZERO)
        && gain.iter().all(|g| *g == DVec2::ZERO)
}

/// One pass of a still frame: the push-out half of each contact's share of a velocity
/// pass (the free contacts of a held crowd are pushed by [`super::free::spread_push_out`]
/// instead). `rate` and `rate_fixed`: the push-out per unit of depth against moving and
/// against static bodies.
pub(super) fn push_pass(
    team: &Team,
    sb: &mut [SolverBody],
    buckets: &mut [Vec<Contact>],
    rate: f64,
    rate_fixed: f64,
) {
    in_blocks(
        team,
        sb,
        buckets,
        #[inline(always)]
        |bodies: Bodies, c: &mut Contact| {
            if c.free {
                return 0.0;
            }
            let gap = c.gap
                + (bodies.get(c.b as usize).delta - bodies.get(c.a as usize).delta).dot(c.normal);
            let pen = (-gap - c.slop).max(0.0);
            split_push(bodies, c, if c.fixed { rate_fixed } else { rate }, pen);
            0.0
        },
    );
}

/// The contacts of a still frame that its passes push out: all but the free ones (a held
/// crowd's, pushed by the spread, whose rows the passes would only read), copied out by
/// bucket in their order, so each pass sweeps the few against the walls, not the crowd.
/// The bits are those of the full buckets: a free contact's pass changes nothing, and
/// the others come in the same order.
#[derive(Clone, Debug, Default)]
pub(super) struct Pushing {
    pub(super) buckets: Vec<Vec<Contact>>,
    /// Where each came from: its bucket and its place there, in the order copied.
    from: Vec<(u32, u32)>,
}

impl Pushing {
    /// Copies out the contacts of `buckets` that `keep` keeps (a still frame's: those
    /// not free).
    pub(super) fn gather(
        &mut self,
        buckets: &[Vec<Contact>],
        mut keep: impl FnMut(&Contact) -> bool,
    ) {
        self.buckets.resize_with(buckets.len(), Vec::new);
        self.from.clear();
        for (k, (bucket, out)) in buckets.iter().zip(self.buckets.iter_mut()).enumerate() {
            out.clear();
            for (i, c) in bucket.iter().enumerate() {
                if keep(c) {
                    out.push(*c);
                    self.from.push((k as u32, i as u32));
                }
            }
        }
    }

    /// Puts the contacts back where [`Pushing::gather`] took them.
    pub(super) fn scatter(&self, buckets: &mut [Vec<Contact>]) {
        let copied = self.buckets.iter().flatten();
        for (c, &(k, i)) in copied.zip(&self.from) {
            buckets[k as usize][i as usize] = *c;
        }
    }
}

/// Islands that cannot change this frame: bodies joined by contacts, none of them moving
/// (velocity and pseudo-velocity 0) or accelerated, and no contact among them carrying an
/// impulse, drifting back to a gap ([`Contact::keep`]) or overlapping beyond its slop.
/// What makes a frame still ([`frame`]) then holds for the island alone: every impulse
/// of its contacts stays 0 through every stage, and with it every velocity and place, so
/// its contacts are left out of the passes (a block at rest in open space that a heavy
/// body has not reached yet). A static body joins the islands it touches.
///
/// Returns whether a quarter of the contacts or more are in such islands (fewer are not
/// worth the copying); then a contact `c`'s island moves when `moving[find(parent, c.a)]`
/// (`parent` and `moving` are filled here).
pub(super) fn still_islands(
    params: &ImpulseParams,
    sb: &[SolverBody],
    gain: &[DVec2],
    buckets: &[Vec<Contact>],
    (movers, at_rest, contacts): (usize, usize, usize),
    parent: &mut Vec<u32>,
    moving: &mut Vec<bool>,
) -> bool {
    use crate::dynamics::sleep::find;
    // `at_rest` of the `contacts` join two bodies at rest that nothing accelerates (the
    // search counted them): a still island's are among them.
    if params.rest_load.is_some()
        || params.support.is_some()
        || params.exact_sliding.is_some()
        || at_rest * 4 < contacts.max(1)
    {
        return false;
    }
    let moves = |k: usize| {
        let s = &sb[k];
        s.vel != DVec2::ZERO
            || s.pseudo != DVec2::ZERO
            || gain.get(k).is_some_and(|g| *g != DVec2::ZERO)
    };
    // A static body never moves by itself: an island that cannot change has a mover at
    // rest.
    if (0..movers).all(moves) {
        return false;
    }
    let n = sb.len();
    parent.clear();
    parent.extend(0..n as u32);
    moving.clear();
    moving.extend((0..n).map(moves));
    for c in buckets.iter().flatten() {
        let (ra, rb) = (find(parent, c.a), find(parent, c.b));
        if ra != rb {
            parent[ra.max(rb) as usize] = ra.min(rb);
        }
        if c.normal_impulse != 0.0
            || c.tangent_impulse != 0.0
            || c.pseudo_impulse != 0.0
            || c.keep != 0.0
            || -c.gap - c.slop > 0.0
        {
            moving[c.a as usize] = true;
        }
    }
    // Each island's root (its lowest body) moves if any of its bodies does.
    for k in 0..n as u32 {
        if moving[k as usize] {
            let r = find(parent, k);
            moving[r as usize] = true;
        }
    }
    let still = buckets
        .iter()
        .flatten()
        .filter(|c| !moving[find(parent, c.a) as usize])
        .count();
    still * 4 >= contacts.max(1)
}
