//! The support sweep: shock propagation over the contacts that hold bodies up (after
//! Guendelman, Bridson and Fedkiw, "Nonconvex rigid bodies with stacking", 2003).
//!
//! A few sequential-impulse passes carry a pile's load down one contact a pass. Where the
//! pile was built at rest the resting load ([`super::load`]) starts it converged; where it
//! forms at run time (a column dropped box by box, a rain, heavy boxes landing on a bed of
//! light circles) the passes leave part of each impact's approach, every sub-step, and the
//! pile sinks into itself by it. After the passes, one sweep visits every contact whose
//! normal is within 72 degrees of gravity, from the lowest upper body to the highest, and
//! stops the upper body from approaching the lower one, the lower taken as fixed. A body
//! is visited after everything under it, so one sweep leaves no contact of a pile
//! approaching, however deep; what it takes out is what the passes had not yet carried
//! down, which a converged solve would have given the lower body instead.
//!
//! With split impulses, the same sweep carries the push-out: each upper body is pushed
//! out of its lower one at the contact's push-out speed on top of the lower body's, and
//! no body, however many contacts push it up or aside, faster than one of its own sizes a
//! second ([`super::MAX_PUSH_OUT`]), as after the passes. A column started overlapped opens from the
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

use super::split::{self, Shared};
use super::team::Team;
use super::{Contact, SolverBody};
use crate::dynamics::body::Body;

/// Contacts whose normal is within about 72 degrees of the vertical are swept: a grain
/// wedged steeply between others under a heavy box is held too (the heavy-on-light family
/// holds 78 seeds of 100 at this, 72 at the resting load's 45 degrees, 76 at 84).
pub(super) const SWEEP_COS: f64 = 0.3;

/// What the sweep reads of one supporting contact, laid out in the order it visits them
/// (one stream instead of a look into the buckets for each).
#[derive(Clone, Copy, Debug)]
struct Record {
    upper: u32,
    lower: u32,
    /// The contact's normal, from the lower body to the upper.
    normal: DVec2,
    /// Its cosine to `up`.
    cos: f64,
    /// Separation at the start of the frame.
    gap: f64,
    slop: f64,
    max_push: f64,
    /// The fastest the upper body may be pushed out, however many contacts push it
    /// ([`super::body_push_out`]).
    body_push: f64,
    speculative: bool,
    /// The gap a contact found apart may close to (`passes::closing`).
    keep: f64,
    fixed: bool,
}

/// The frame's supporting contacts in the order the sweep visits them: by the body they
/// hold up, those bodies lowest first. The bodies' order is kept from frame to frame and
/// sorted again from there: a pile's bodies keep their order, so sorting it again costs a
/// look at each. It is the order of (height, place) whatever it starts from, so the bits
/// do not depend on it.
#[derive(Clone, Debug, Default)]
pub(super) struct Sweep {
    /// The supporting contacts in the order the sweep visits them.
    records: Vec<Record>,
    /// Per solver body: how many contacts hold it up, then where its first goes.
    count: Vec<u32>,
    /// The solver bodies that stand on something, lowest first (ties by place).
    order: Vec<u32>,
    heights: Vec<f64>,
}

impl Sweep {
    /// Finds the contacts of `buckets` that hold a dynamic body up against `up` (unit,
    /// against gravity) and orders them for the sweep. `push_cap`: each mover's push-out
    /// cap ([`super::body_push_out`]), by slot.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn order(
        &mut self,
        team: &Team,
        buckets: &mut [Vec<Contact>],
        sb: &[SolverBody],
        bodies: &[Body],
        slotted: &[u32],
        push_cap: &[f64],
        up: DVec2,
    ) {
        let n = sb.len();
        self.count.clear();
        self.count.resize(n, 0);
        // The contact's upper and lower body and its normal from the lower to the upper,
        // if it holds a dynamic body up.
        let support = |c: &Contact| {
            let cos = c.normal.dot(up);
            let (upper, lower, normal) = if cos > SWEEP_COS {
                (c.b, c.a, c.normal)
            } else if cos < -SWEEP_COS {
                (c.a, c.b, -c.normal)
            } else {
                return None;
            };
            (sb[upper as usize].inv_mass != 0.0).then_some((upper, lower, normal, cos.abs()))
        };
        // How many contacts hold each body up. An upper body moves, so a block's
        // contacts count its own bodies only (`split`).
        {
            let count = Shared::new(&mut self.count);
            split::each_block(team, buckets, |c| {
                if let Some((upper, ..)) = support(c) {
                    // SAFETY: a moving body's contacts run on one member at a time.
                    unsafe { *count.at(upper as usize) += 1 };
                }
            });
        }
        // The bodies that stand on something, by height: last frame's order kept where
        // it still holds, bodies newly standing after it, then sorted (a stable sort that
        // finds the runs already in order; on a first frame, with no order to keep, an
        // unstable one: every key differs, so either gives the same order).
        self.heights.clear();
        self.heights.resize(slotted.len(), 0.0);
        let heights = Shared::new(&mut self.heights);
        split::each_range(team, slotted.len(), |_, range| {
            for s in range {
                // SAFETY: the ranges are disjoint.
                unsafe { *heights.at(s) = bodies[slotted[s] as usize].pos.dot(up) };
            }
        });
        let count = &mut self.count;
        let fresh = self.order.is_empty();
        self.order
            .retain(|&s| (s as usize) < n && count[s as usize] > 0);
        // Marked (the top bit) while listed, so none is listed twice.
        const LISTED: u32 = 1 << 31;
        for &s in &self.order {
            count[s as usize] |= LISTED;
        }
        for (s, k) in count.iter().enumerate() {
            if *k > 0 && *k & LISTED == 0 {
                self.order.push(s as u32);
            }
        }
        let heights = &self.heights;
        let by_height = |&x: &u32, &y: &u32| {
            heights[x as usize]
                .total_cmp(&heights[y as usize])
                .then(x.cmp(&y))
        };
        if fresh {
            self.order.sort_unstable_by(by_height);
        } else {
            self.order.sort_by(by_height);
        }
        // Where each body's contacts go, then each placed there, in the order found.
        let mut at = 0;
        for &s in &self.order {
            let k = count[s as usize] & !LISTED;
            count[s as usize] = at;
            at += k;
        }
        let blank = Record {
            upper: 0,
            lower: 0,
            normal: DVec2::ZERO,
            cos: 0.0,
            gap: 0.0,
            slop: 0.0,
            max_push: 0.0,
            body_push: 0.0,
            speculative: false,
            keep: 0.0,
            fixed: false,
        };
        self.records.clear();
        self.records.resize(at as usize, blank);
        // Each upper body's records in the order its contacts come (its block's, then the
        // boundary's), at places no other body's take.
        let records = Shared::new(&mut self.records);
        let place = Shared::new(count);
        split::each_block(team, buckets, |c| {
            let Some((upper, lower, normal, cos)) = support(c) else {
                return;
            };
            // SAFETY: a moving body's contacts run on one member at a time, and its
            // records' places are its own.
            let place = unsafe { place.at(upper as usize) };
            let record = unsafe { records.at(*place as usize) };
            *record = Record {
                upper,
                lower,
                normal,
                cos,
                gap: c.gap,
                slop: c.slop,
                max_push: c.max_push,
                body_push: push_cap[upper as usize],
                speculative: c.speculative,
                keep: f64::from(c.keep),
                fixed: c.fixed,
            };
            *place += 1;
        });
    }

    /// One sweep over the supporting contacts (as [`Sweep::order`] left them against `up`) at the end of a
    /// sub-step `h`'s passes: each upper body stops approaching its lower one (a contact found
    /// apart may close its gap within the sub-step, no more); with `push` (split impulses: the
    /// push-out rates against dynamic and static bodies), each is pushed out of it too.
    pub(super) fn sweep(&self, sb: &mut [SolverBody], up: DVec2, h: f64, push: Option<(f64, f64)>) {
        for r in &self.records {
            let (upper, lower) = (r.upper as usize, r.lower as usize);
            let (u, l) = (sb[upper], sb[lower]);
            let gap = r.gap + (u.delta - l.delta).dot(r.normal);
            let apart = r.speculative && gap > 0.0;
            let target = if apart {
                -super::passes::closing(gap, r.keep) / h
            } else {
                0.0
            };
            let approach = (u.vel - l.vel).dot(r.normal);
            if approach < target {
                // Straight up (against gravity), not along the normal: a circle on a
                // slope of others is not pushed sideways.
                sb[upper].vel += up * ((target - approach) / r.cos);
            }
            let Some((rate, rate_fixed)) = push else {
                continue;
            };
            if apart {
                continue;
            }
            let pen = (-gap - r.slop).max(0.0);
            let rate = if r.fixed { rate_fixed } else { rate };
            let target = (rate * pen).min(r.max_push);
            let apart = (u.pseudo - l.pseudo).dot(r.normal);
            let mut pseudo = u.pseudo;
            if apart < target {
                pseudo += up * ((target - apart) / r.cos);
            }
            // However many contacts push it, up or aside, a body is pushed out no faster
            // than its own cap (as after the passes).
            let speed = pseudo.length_squared();
            if speed > r.body_push * r.body_push {
                pseudo *= r.body_push / speed.sqrt();
            } else if apart >= target {
                continue;
            }
            sb[upper].pseudo = pseudo;
        }
    }
}
