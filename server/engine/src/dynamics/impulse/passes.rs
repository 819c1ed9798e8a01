//! The stages of a sub-step, in the order the solver runs them (Box2D v3's
//! `b2IntegrateVelocitiesTask`, `b2WarmStartContactsTask`, `b2SolveContactsTask`,
//! `b2IntegratePositionsTask`, `b2RelaxContactsTask`, `b2ApplyRestitutionTask`,
//! `b2StoreImpulsesTask`), and the velocity pass they share.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Mutex;

use glam::DVec2;

use super::blocks::Bodies;
use super::load::SUPPORT_COS;
use super::split::{self, Shared};
use super::support::SWEEP_COS;
use super::team::Team;
use super::{Bias, Biases, Contact, ImpulseParams, ImpulseReport, Pair, SolverBody};
use crate::dynamics::body::Body;
use crate::dynamics::config::Integrator;

/// Gravity: every mover gains what it gains per second over `h`.
pub(super) fn integrate_velocities(sb: &mut [SolverBody], gain: &[DVec2], h: f64) {
    for (body, &g) in sb.iter_mut().zip(gain.iter()) {
        body.vel += g * h;
    }
}

/// Warm start: the impulses of the last sub-step (or frame) once more.
pub(super) fn warm_start(team: &Team, sb: &mut [SolverBody], buckets: &mut [Vec<Contact>]) {
    in_blocks(team, sb, buckets, |bodies, c| {
        if c.normal_impulse != 0.0 || c.tangent_impulse != 0.0 {
            let t = DVec2::new(-c.normal.y, c.normal.x);
            apply(
                bodies,
                c,
                c.normal * c.normal_impulse + t * c.tangent_impulse,
            );
        }
        0.0
    });
}

/// The split impulses the contacts pushed with last, applied again to the
/// pseudo-velocities (which start from nothing each sub-step): a contact's push starts
/// where its last sub-step left it (a share of it, [`super::prepare::WARM_PUSH_SHARE`], from
/// one step to the next), so pushes that a few passes cannot carry across a body at once
/// build up over the sub-steps. A row of 12 boxes a third into each other, pushed from
/// nothing each sub-step, opened from its two ends only: its middle boxes, pushed both ways
/// at once, stayed (the suite's `overlap-third` was still overlapped a third after 3.3 s;
/// apart in 1.4 s now). A contact no longer overlapping takes its push back in the
/// passes (to no more than parts it). Contacts of crowds held by their container
/// ([`super::free::spread_push_out`]) start from nothing.
pub(super) fn warm_push(team: &Team, sb: &mut [SolverBody], buckets: &mut [Vec<Contact>]) {
    in_blocks(team, sb, buckets, |bodies, c| {
        if c.pseudo_impulse > 0.0 {
            let p = c.normal * c.pseudo_impulse;
            let (a, b) = (c.a as usize, c.b as usize);
            let (ia, ib) = (bodies.get(a).inv_mass, bodies.get(b).inv_mass);
            bodies.update(a, |s| s.pseudo -= p * ia);
            bodies.update(b, |s| s.pseudo += p * ib);
        }
        0.0
    });
}

/// The biased passes: `iterations` of them, the position bias pushing touching contacts
/// apart (into pseudo-velocities with split impulses), then up to `adaptive_iterations`
/// more while the last one changed a contact's normal velocity by more than `converged`.
/// In a still frame ([`super::still`]) each pass only pushes out.
/// With `deep_fixed` (a contact with a static body overlaps beyond its slop), each pass is
/// followed by the push-out of the contacts with static bodies ([`static_push_out`];
/// `gain` is what each mover gains per second).
/// The frame's last pass measures the residual when no relax pass follows it.
#[allow(clippy::too_many_arguments)]
pub(super) fn solve(
    team: &Team,
    sb: &mut [SolverBody],
    buckets: &mut [Vec<Contact>],
    params: &ImpulseParams,
    bias: Biases,
    h: f64,
    converged: f64,
    last_step: bool,
    deep_fixed: bool,
    still: bool,
    gain: &[DVec2],
    report: &mut ImpulseReport,
) {
    let adaptive = params.adaptive_iterations > 0;
    let most = params.iterations + params.adaptive_iterations;
    let residual = last_step && params.relax_iterations == 0;
    let mut k = 0;
    loop {
        report.passes += 1;
        let args = (bias.push, bias.push_fixed, 1.0 / h, params.split_impulses);
        let measure = k + 1 >= params.iterations && (adaptive || residual);
        let change = if still {
            super::still::push_pass(team, sb, buckets, bias.push.rate, bias.push_fixed.rate);
            measure.then_some(0.0)
        } else {
            velocity_pass(team, sb, buckets, args, measure)
        };
        if params.split_impulses && deep_fixed {
            static_push_out(team, sb, buckets, gain, bias.push_fixed.rate);
        }
        k += 1;
        if k < params.iterations {
            continue;
        }
        let done = !adaptive || k >= most || change.is_none_or(|c| c <= converged);
        if done {
            if let (true, Some(change)) = (residual, change) {
                report.residual = change * h;
            }
            return;
        }
    }
}

/// After the passes: no body pushed out faster than one body size a second
/// ([`super::MAX_PUSH_OUT`]; `cap`, its own size), however many contacts push it. Each
/// contact's push is capped so, but a body that several push at once, as in a crowd fuller
/// than its container, moved at the sum (2.1 units/s in a crowd of circles 1.8 across).
/// `unpushed` is each mover's pseudo-velocity before the passes (a bounce's share of the
/// sub-step, set by the collision stage, is left alone). Under gravity the support sweep
/// then caps what it pushes up the same way.
pub(super) fn cap_push_out(sb: &mut [SolverBody], unpushed: &[DVec2], cap: &[f64]) {
    for ((body, &from), &most) in sb.iter_mut().zip(unpushed).zip(cap) {
        let push = body.pseudo - from;
        let speed = push.length_squared();
        if speed > most * most {
            body.pseudo = from + push * (most / speed.sqrt());
        }
    }
}

/// Exact sliding, after the passes: a body that friction slows on what holds it up (a
/// contact within [`SWEEP_COS`] of `up`, against gravity) moves by its mean velocity over
/// the sub-step rather than by the velocity at its end. Symplectic Euler moves it by the
/// velocity friction left it, so a body sliding to rest under friction loses `a h^2 / 2`
/// of its path each sub-step (`a` the deceleration) and stops `v h / 2` short of
/// `v^2 / (2 a)`; friction that stops it within the sub-step moved it by nothing, where it
/// slid `u^2 / (2 a)` first.
///
/// Each contact gives its pair back a share of its friction impulse `jt` through the
/// pseudo-velocities (positions only): `-jt / 2` times the share of the sub-step the pair
/// slid, `min(1, |jt| / (mu jn))` (friction at its full force takes that long to give
/// `jt`). No body then moves further than the mean of its own velocities at the start
/// (`before`) and the end takes it beyond the end's (`moved` sums each body's share,
/// reused): a body that friction holds at rest (a pile, or a plank the ground holds while
/// a box slides along it) keeps its velocity and moves by it alone.
///
/// Friction against a wall, or between bodies that strike each other side on, is left
/// alone: its impulse is a blow's, not a steady force over the sub-step (moved as if it
/// were, the boxes a heavy body sweeps aside were driven into their neighbours).
pub(super) fn slide(
    team: &Team,
    sb: &mut [SolverBody],
    before: &[DVec2],
    moved: &mut Vec<DVec2>,
    buckets: &mut [Vec<Contact>],
    up: DVec2,
) {
    moved.clear();
    moved.resize(sb.len(), DVec2::ZERO);
    {
        let shares = Shared::new(moved);
        let sb = &*sb;
        // A block's contacts add to its own bodies' shares (bodies that do not move take
        // none): the same sums on any thread count.
        split::each_block(team, buckets, |c| {
            let jt = c.tangent_impulse;
            let most = c.friction * c.normal_impulse;
            if jt == 0.0 || most <= 0.0 || c.normal.dot(up).abs() <= SWEEP_COS {
                return;
            }
            let (a, b) = (c.a as usize, c.b as usize);
            let t = DVec2::new(-c.normal.y, c.normal.x);
            let slid = (jt.abs() / most).min(1.0);
            let p = t * (-0.5 * jt * slid);
            let (ia, ib) = (sb[a].inv_mass, sb[b].inv_mass);
            // SAFETY: a moving body's contacts are its block's and the boundary's, which
            // run on one member at a time (`split::each_block`).
            if ia != 0.0 {
                unsafe { *shares.at(a) -= p * ia };
            }
            if ib != 0.0 {
                unsafe { *shares.at(b) += p * ib };
            }
            // A pair friction stopped: what stopped it does not push again (warm-started,
            // it threw a box and the plank under it back the way the box came).
            let u = (before[b] - before[a]).dot(t).abs();
            if slid < 1.0 && u * c.mass > 0.1 * jt.abs() {
                c.tangent_impulse = 0.0;
            }
        });
    }
    let bodies = Shared::new(sb);
    let moved = &moved[..];
    split::each_range(team, moved.len(), |_, range| {
        for k in range {
            let Some(dir) = moved[k].try_normalize() else {
                continue;
            };
            // SAFETY: the ranges are disjoint.
            let s = unsafe { bodies.at(k) };
            // The mean velocity's lead over the end's, along the share.
            let most = ((before[k] - s.vel) * 0.5).dot(dir);
            s.pseudo += dir * most.clamp(0.0, moved[k].length());
        }
    });
}

/// Positions move by the velocities (and the pseudo-velocities, then dropped): a body a
/// contact pushed by symplectic Euler, one in flight as `flight` says. `pushed` is reused.
pub(super) fn integrate_positions(
    sb: &mut [SolverBody],
    gain: &[DVec2],
    buckets: &[Vec<Contact>],
    pushed: &mut Vec<bool>,
    flight: Integrator,
    h: f64,
    moving: usize,
) {
    if let Some(share) = flight.gravity_share() {
        pushed.clear();
        pushed.resize(sb.len(), false);
        for c in buckets.iter().flatten() {
            // A bounce moves its bodies in flight: the collision stage timed it.
            if c.normal_impulse > 0.0 || c.pseudo_impulse > 0.0 {
                pushed[c.a as usize] = true;
                pushed[c.b as usize] = true;
            }
        }
        // In flight: `p += v_old h + share g h²`, with `v_old = v - g h`.
        for (k, (body, &g)) in sb.iter_mut().zip(gain.iter()).enumerate() {
            body.delta += (body.vel + body.pseudo) * h;
            if !pushed[k] {
                body.delta -= g * ((1.0 - share) * h * h);
            }
            body.pseudo = DVec2::ZERO;
        }
    } else {
        for body in &mut sb[..moving] {
            body.delta += (body.vel + body.pseudo) * h;
            body.pseudo = DVec2::ZERO;
        }
    }
}

/// The relax passes: velocity passes without bias after the positions moved, taking back
/// the velocity the bias added. The frame's last measures the residual.
pub(super) fn relax(
    team: &Team,
    sb: &mut [SolverBody],
    buckets: &mut [Vec<Contact>],
    params: &ImpulseParams,
    h: f64,
    last_step: bool,
    report: &mut ImpulseReport,
) {
    for k in 0..params.relax_iterations {
        report.passes += 1;
        let args = (Bias::NONE, Bias::NONE, 1.0 / h, false);
        let last = last_step && k + 1 == params.relax_iterations;
        if let Some(change) = velocity_pass(team, sb, buckets, args, last) {
            report.residual = change * h;
        }
    }
}

/// The collision stage of a sub-step, before its passes: every contact of a bouncing pair
/// that touches, or meets within the sub-step `h`, and approaches faster than its bounce
/// speed, is resolved as a collision of its two bodies alone: the normal velocity becomes
/// `-e` times the approach at impact (for a pair still apart, what it closes at under its
/// bodies' gains: `v_i^2 = v^2 - 2 a s`). Contact after contact, pass after pass until none
/// approaches or `most` passes ran (forward and backward in turn), each counted in
/// `report`; friction within the Coulomb
/// cone of the collision's impulse.
///
/// A collision has a time within the sub-step: when its pair meets, and no earlier than
/// the last collision of either body (`met`, reused: a row of balls passes the first one's
/// speed down at the time it arrived). A body's velocity changed at `t` moves it for
/// `h - t` only: the difference goes to its pseudo-velocity, so a ball that meets a wall
/// in mid-step ends where it would had it bounced there. With restitution 1 each collision
/// keeps its two bodies' energy. `flight`: the share of the gain bodies in flight move by
/// in closed form (exact 1/2, explicit 0: [`Integrator::gravity_share`]), from their
/// velocity before the sub-step's gain; `None`: by the velocity after it (symplectic).
#[allow(clippy::too_many_arguments)]
pub(super) fn collisions(
    sb: &mut [SolverBody],
    gain: &[DVec2],
    buckets: &mut [Vec<Contact>],
    met: &mut Vec<f64>,
    h: f64,
    most: u32,
    flight: Option<f64>,
    report: &mut ImpulseReport,
) {
    met.clear();
    met.resize(sb.len(), 0.0);
    let bodies = Bodies::new(sb);
    let gain_of = |k: usize| gain.get(k).copied().unwrap_or(DVec2::ZERO);
    for pass in 0..most.max(1) {
        report.passes += 1;
        let mut any = false;
        // Forward and backward in turn: a collision running down a row against the
        // contacts' order passes in one pass, not one contact a pass.
        let contacts = buckets.iter_mut().flat_map(|b| b.iter_mut());
        let contacts: Box<dyn Iterator<Item = &mut Contact>> = if pass % 2 == 0 {
            Box::new(contacts)
        } else {
            Box::new(contacts.rev())
        };
        for c in contacts {
            if c.restitution <= 0.0 {
                continue;
            }
            let (a, b) = (c.a as usize, c.b as usize);
            let (ba, bb) = (bodies.get(a), bodies.get(b));
            let vn = (bb.vel - ba.vel).dot(c.normal);
            let bounce = c.bounce_speed as f64;
            if vn >= -bounce {
                continue;
            }
            let gap = c.gap + (bb.delta - ba.delta).dot(c.normal);
            // The pair's relative acceleration along the normal, and the approach the
            // sub-step moves it by: under symplectic Euler the velocity after the gain
            // (taken from the velocity before it, a ball bouncing on the ground under
            // gravity lost `v g h / 2` of energy at every bounce); in exact or explicit
            // flight the velocity before it.
            let an = (gain_of(b) - gain_of(a)).dot(c.normal);
            let v0 = if flight.is_some() { vn - an * h } else { vn };
            // When within the sub-step it meets (0: touching), and how fast.
            let (free, impact) = if gap > 0.0 {
                let impact = -(v0 * v0 - 2.0 * an * gap).max(0.0).sqrt();
                // The root of `gap + v0 t + an t^2 / 2 = 0`, in the form that stays exact
                // when `an` is small (infinite when the pair never meets).
                (2.0 * gap / (-v0 - impact), impact)
            } else {
                (0.0, v0)
            };
            let t = free.max(met[a]).max(met[b]);
            // Where the sub-step's move leaves the pair without a collision: in flight
            // (`flight`'s closed form), or by the velocity after the gain.
            let rest = gap + vn * h - flight.map_or(0.0, |share| (1.0 - share) * an * h * h);
            // The passes let a pair found apart close its gap within the sub-step when its
            // velocity would carry it there: it meets within the sub-step then, at its end
            // if its flight falls short (by rounding, or by a gain that curves it away).
            // Left to the passes, it would land with the approach they clamp it to (less
            // by up to `an h / 2` in exact flight), and bounce with that.
            let closes = c.speculative && gap > 0.0 && -vn * h >= gap;
            let meets = t <= h || closes;
            // A pair the passes would let close its gap bounces in the sub-step it meets;
            // one too slow at impact does not bounce.
            if (c.speculative && gap > 0.0 && !meets)
                || (if meets { impact } else { vn }) >= -bounce
            {
                continue;
            }
            let e = c.restitution as f64;
            // Apart at `-e impact` from `t` on, under the pair's acceleration. A pair that
            // stays a hair apart (nearer than the passes let close) turns where it is.
            let (target, t) = if meets {
                let t = t.min(h);
                (-e * impact + an * (h - t), t)
            } else {
                (-e * vn, 0.0)
            };
            // Never pulling (a pair whose acceleration outruns its bounce).
            let jn = (c.mass * (target - vn)).max(0.0);
            // Friction within the Coulomb cone of the collision's impulse.
            let t_dir = DVec2::new(-c.normal.y, c.normal.x);
            let limit = c.friction * jn;
            let jt = (-c.mass * (bb.vel - ba.vel).dot(t_dir)).clamp(-limit, limit);
            let p = c.normal * jn + t_dir * jt;
            // The change moves each body from `t` on only. A pair whose path does not
            // meet within the sub-step (it meets at its end) ends it touching, as the
            // passes would have left it: its move takes the rest of its gap too.
            let late = t / h;
            let short = if meets && free > h {
                c.normal * (c.mass * rest / h)
            } else {
                DVec2::ZERO
            };
            bodies.update(a, |s| {
                s.vel -= p * ba.inv_mass;
                s.pseudo += (p * late + short) * ba.inv_mass;
            });
            bodies.update(b, |s| {
                s.vel += p * bb.inv_mass;
                s.pseudo -= (p * late + short) * bb.inv_mass;
            });
            // A static body's velocity never changes: its collisions set no time.
            if ba.inv_mass > 0.0 {
                met[a] = t;
            }
            if bb.inv_mass > 0.0 {
                met[b] = t;
            }
            c.bounced = true;
            any = true;
        }
        if !any {
            return;
        }
    }
}

/// The movers' velocities and moves back into the world, each pair's impulses kept, the
/// bodies a contact pushed flagged collided (in `flagged`), mover `k`'s deepest overlap at
/// the frame's start in `depths[k]`. `slotted` names each solver body's world body.
#[allow(clippy::too_many_arguments)]
pub(super) fn store(
    team: &Team,
    bodies: &mut [Body],
    pairs: &mut [Pair],
    movers: &[u32],
    sb: &[SolverBody],
    slotted: &[u32],
    buckets: &mut [Vec<Contact>],
    pushed: &mut Vec<bool>,
    flagged: &mut Vec<u32>,
    depths: &mut Vec<f64>,
) {
    {
        let world = Shared::new(bodies);
        split::each_range(team, movers.len(), |_, range| {
            for k in range {
                // SAFETY: the movers are distinct bodies, and the ranges disjoint.
                let body = unsafe { world.at(movers[k] as usize) };
                body.vel = sb[k].vel;
                body.pos += sb[k].delta;
            }
        });
    }
    // Which solver bodies a contact pushed, by slot (then each world body visited once).
    pushed.clear();
    pushed.resize(sb.len(), false);
    depths.clear();
    depths.resize(movers.len(), 0.0);
    // Whether any body of a contact sleeps (looked up per contact only then).
    let sleepers = slotted.iter().any(|&i| bodies[i as usize].asleep.is_some());
    {
        let bodies = &*bodies;
        let (depths, pairs) = (Shared::new(depths), Shared::new(pairs));
        // SAFETY: `AtomicBool` has the size, alignment and bit validity of `bool`, and
        // the flags are used only through the atomics until the borrow ends.
        let pushed: &[AtomicBool] =
            unsafe { &*(pushed.as_mut_slice() as *mut [bool] as *const [AtomicBool]) };
        split::each_block(team, buckets, |c| {
            if c.gap < 0.0 {
                for s in [c.a as usize, c.b as usize] {
                    if s < movers.len() && sb[s].inv_mass != 0.0 {
                        // SAFETY: a moving body's contacts run on one member at a time.
                        let d = unsafe { depths.at(s) };
                        *d = d.max(-c.gap);
                    }
                }
            }
            // SAFETY: one contact a pair.
            let pair = unsafe { pairs.at(c.pair as usize) };
            pair.normal = c.normal;
            // A sleeper is static to the step: what its contact took against it is not the
            // impulse its body will carry when it wakes. Warm-started with it, a grain a
            // heavy box landed on while it slept was launched at 400 u/s as it woke.
            let asleep = |k: u32| bodies[slotted[k as usize] as usize].asleep.is_some();
            let (jn, jt, jp) = if sleepers && (asleep(c.a) || asleep(c.b)) {
                (0.0, 0.0, 0.0)
            } else {
                (c.normal_impulse, c.tangent_impulse, c.pseudo_impulse)
            };
            pair.normal_impulse = jn;
            pair.tangent_impulse = jt;
            pair.pseudo_impulse = jp;
            if c.normal_impulse > 0.0 || c.bounced {
                // Bodies that do not move are marked from any member.
                pushed[c.a as usize].store(true, Ordering::Relaxed);
                pushed[c.b as usize].store(true, Ordering::Relaxed);
            }
        });
    }
    // A mover frozen for the step (asleep) is in no block: its depths are found after
    // (the deepest is the same in any order).
    if sb[..movers.len()].iter().any(|s| s.inv_mass == 0.0) {
        for c in buckets.iter().flatten().filter(|c| c.gap < 0.0) {
            for s in [c.a as usize, c.b as usize] {
                if s < movers.len() && sb[s].inv_mass == 0.0 {
                    depths[s] = depths[s].max(-c.gap);
                }
            }
        }
    }
    // The bodies newly collided, listed in slot order.
    if split::ranges(team, slotted.len()) == 1 {
        for (&i, _) in slotted.iter().zip(pushed.iter()).filter(|(_, &p)| p) {
            let body = &mut bodies[i as usize];
            if !body.collided {
                body.collided = true;
                flagged.push(i);
            }
        }
        return;
    }
    // On several threads each member lists its range's, joined in order.
    let lists: Vec<Mutex<Vec<u32>>> = (0..team.size()).map(|_| Mutex::default()).collect();
    let world = Shared::new(bodies);
    let ranges = split::each_range(team, slotted.len(), |k, range| {
        let mut list = lists[k].lock().expect("a list");
        for s in range.filter(|&s| pushed[s]) {
            let i = slotted[s];
            // SAFETY: the slotted bodies are distinct, and the ranges disjoint.
            let body = unsafe { world.at(i as usize) };
            if !body.collided {
                body.collided = true;
                list.push(i);
            }
        }
    });
    for list in &lists[..ranges] {
        flagged.extend_from_slice(&list.lock().expect("a list"));
    }
}

/// How far a contact found apart by `gap` may close within a sub-step: all of it, or, for
/// one lifted just past the gap a resting contact holds (`keep` above 0,
/// [`super::prepare::DRIFT_BACK`]), half of what it is past that gap.
pub(super) fn closing(gap: f64, keep: f64) -> f64 {
    if keep > 0.0 {
        DRIFT_BACK_SHARE * (gap - keep).max(0.0)
    } else {
        gap
    }
}

/// The share of its drift past the gap a resting contact holds that a contact lifted there
/// may close within a sub-step. Closing all of it, the body fell back at the speed the
/// push-out lifted it, up to 0.08 u/s against `sleep_speed`'s 0.05, and a bed under a
/// heavy box (heavy-on-light seed 3187) never slept; a quarter let another (3288) creep.
const DRIFT_BACK_SHARE: f64 = 0.5;

/// One contact's share of a velocity pass: the normal impulse that brings the normal
/// velocity to its target (never pulling), then friction within the Coulomb cone. With
/// `MEASURE`, returns the normal velocity change it made (0 otherwise).
/// `args`: the bias against dynamic and against static bodies, `1 / h`, split impulses.
#[inline(always)]
fn solve_contact<const MEASURE: bool>(
    sb: Bodies,
    c: &mut Contact,
    args: (Bias, Bias, f64, bool),
) -> f64 {
    let (push, push_fixed, inv_h, split) = args;
    {
        let (a, b) = (c.a as usize, c.b as usize);
        let (ba, bb) = (sb.get(a), sb.get(b));
        let dv = bb.vel - ba.vel;
        // Separation now: the frame's start plus how far the bodies moved since.
        let gap = c.gap + (bb.delta - ba.delta).dot(c.normal);
        let bias = if c.fixed { push_fixed } else { push };
        // Apart when found: close the gap within this sub-step, no further. Touching: hold,
        // push out what exceeds the slop.
        let apart = c.speculative && gap > 0.0;
        let pen = if apart { 0.0 } else { (-gap - c.slop).max(0.0) };
        if split && !c.free {
            // The push goes to the pseudo-velocities; the velocity only holds.
            split_push(sb, c, bias.rate, pen);
        }
        let (target, mass_scale, impulse_scale) = if apart {
            (-closing(gap, f64::from(c.keep)) * inv_h, 1.0, 0.0)
        } else if pen > 0.0 && split {
            // The velocity holds, as softly as the contact is (rigid: fully).
            (0.0, bias.mass_scale, bias.impulse_scale)
        } else if pen > 0.0 {
            (
                (bias.rate * pen).min(c.max_push),
                bias.mass_scale,
                bias.impulse_scale,
            )
        } else {
            (0.0, 1.0, 0.0)
        };
        let vn = dv.dot(c.normal);
        let total = (c.normal_impulse + mass_scale * c.mass * (target - vn)
            - impulse_scale * c.normal_impulse)
            .max(0.0);
        let dn = total - c.normal_impulse;
        c.normal_impulse = total;
        // Friction: stop the sliding, within the Coulomb cone of the normal impulse.
        // (The normal impulse does not change the tangential velocity.)
        let t = DVec2::new(-c.normal.y, c.normal.x);
        let vt = dv.dot(t);
        let limit = c.friction * c.normal_impulse;
        let total_t = (c.tangent_impulse - c.mass * vt).clamp(-limit, limit);
        let dt_imp = total_t - c.tangent_impulse;
        c.tangent_impulse = total_t;
        let p = c.normal * dn + t * dt_imp;
        sb.update(a, |s| s.vel -= p * ba.inv_mass);
        sb.update(b, |s| s.vel += p * bb.inv_mass);
        if MEASURE && c.mass > 0.0 {
            return dn.abs() / c.mass;
        }
    }
    0.0
}

/// A contact's push-out in a pass under split impulses: at `rate` times `pen`, its depth
/// beyond the slop; or, pushed apart before and no longer overlapping, the push it
/// started from taken back as far as it now parts its bodies.
#[inline(always)]
pub(super) fn split_push(sb: Bodies, c: &mut Contact, rate: f64, pen: f64) {
    if pen > 0.0 {
        push_out(sb, c, rate * pen);
    } else if c.pseudo_impulse > 0.0 {
        push_out(sb, c, 0.0);
    }
}

/// The split impulse of one contact: its bodies' pseudo-velocities apart at `target` along
/// its normal (capped at its `max_push`), the accumulated impulse never pulling.
#[inline(always)]
fn push_out(sb: Bodies, c: &mut Contact, target: f64) {
    let (a, b) = (c.a as usize, c.b as usize);
    let (ba, bb) = (sb.get(a), sb.get(b));
    let target = target.min(c.max_push);
    let pv = (bb.pseudo - ba.pseudo).dot(c.normal);
    let total = (c.pseudo_impulse + c.mass * (target - pv)).max(0.0);
    let p = c.normal * (total - c.pseudo_impulse);
    c.pseudo_impulse = total;
    sb.update(a, |s| s.pseudo -= p * ba.inv_mass);
    sb.update(b, |s| s.pseudo += p * bb.inv_mass);
}

/// The split impulses of the contacts with a static body that do not hold a body up once
/// more, after a pass: a body its neighbours pushed into a wall ends the pass pushed out of
/// it. Solved only in their place among the others, a crowd squeezed between circles
/// pushed its outer circles through walls a tenth of a circle thick. Supports (a normal
/// within 45 degrees of the body's gain, gravity) are left to the pass: pushing a pile's
/// bottom row out of the ground harder than the overlaps above push it in left piles
/// started overlapped still overlapped. Velocities are left as the pass left them.
fn static_push_out(
    team: &Team,
    sb: &mut [SolverBody],
    buckets: &mut [Vec<Contact>],
    gain: &[DVec2],
    rate: f64,
) {
    in_blocks(team, sb, buckets, |bodies, c| {
        if !c.fixed {
            return 0.0;
        }
        let (a, b) = (c.a as usize, c.b as usize);
        let moving = if bodies.get(a).inv_mass > 0.0 { a } else { b };
        let g = gain.get(moving).copied().unwrap_or(DVec2::ZERO);
        if g.dot(c.normal).abs() > SUPPORT_COS * g.length() && g != DVec2::ZERO {
            return 0.0;
        }
        let gap = c.gap + (bodies.get(b).delta - bodies.get(a).delta).dot(c.normal);
        let pen = (-gap - c.slop).max(0.0);
        if pen > 0.0 {
            push_out(bodies, c, rate * pen);
        }
        0.0
    });
}

/// One velocity pass over every contact; with `measure` (the frame's last pass), the
/// largest normal velocity change it made.
fn velocity_pass(
    team: &Team,
    sb: &mut [SolverBody],
    buckets: &mut [Vec<Contact>],
    args: (Bias, Bias, f64, bool),
    measure: bool,
) -> Option<f64> {
    if measure {
        Some(in_blocks(
            team,
            sb,
            buckets,
            #[inline(always)]
            |b, c| solve_contact::<true>(b, c, args),
        ))
    } else {
        in_blocks(
            team,
            sb,
            buckets,
            #[inline(always)]
            |b, c| solve_contact::<false>(b, c, args),
        );
        None
    }
}

fn apply(sb: Bodies, c: &Contact, impulse: DVec2) {
    let (a, b) = (c.a as usize, c.b as usize);
    let (ia, ib) = (sb.get(a).inv_mass, sb.get(b).inv_mass);
    sb.update(a, |s| s.vel -= impulse * ia);
    sb.update(b, |s| s.vel += impulse * ib);
}

/// Runs `work` on every contact of every block (at once on the team's threads when there
/// are several blocks, a group of neighbouring blocks each), then of the boundary;
/// returns the largest of its results.
///
/// Four blocks a thread runs are interleaved, a contact of each in turn (two when the
/// thread has two or three): they touch different bodies, so the processor overlaps them
/// instead of waiting on each contact's result for the next (consecutive contacts of one
/// block share a body). The bits are those of one block after the other. Why four, not
/// two or eight: docs/bench/engine-notes.md.
#[inline(always)]
pub(super) fn in_blocks(
    team: &Team,
    sb: &mut [SolverBody],
    buckets: &mut [Vec<Contact>],
    work: impl Fn(Bodies, &mut Contact) -> f64 + Sync + Send,
) -> f64 {
    let bodies = Bodies::new(sb);
    let (blocks, boundary) = buckets.split_at_mut(buckets.len() - 1);
    let run = |group: &mut [Vec<Contact>]| {
        let mut largest = 0.0_f64;
        let mut solve = |c: &mut Contact| largest = largest.max(work(bodies, c));
        for chunk in group.chunks_mut(4) {
            // The rows that four blocks (or two of three) all have, interleaved; then the
            // rest of each block.
            let ways = match chunk.len() {
                4 => 4,
                2 | 3 => 2,
                _ => 0,
            };
            let common = chunk[..ways].iter().map(Vec::len).min().unwrap_or(0);
            match chunk {
                [w, x, y, z] => {
                    let rows = w[..common]
                        .iter_mut()
                        .zip(x[..common].iter_mut())
                        .zip(y[..common].iter_mut().zip(z[..common].iter_mut()));
                    for ((p, q), (r, s)) in rows {
                        solve(p);
                        solve(q);
                        solve(r);
                        solve(s);
                    }
                }
                [x, y, ..] => {
                    for (p, q) in x[..common].iter_mut().zip(y[..common].iter_mut()) {
                        solve(p);
                        solve(q);
                    }
                }
                _ => {}
            }
            for (k, block) in chunk.iter_mut().enumerate() {
                let done = if k < ways { common } else { 0 };
                block[done..].iter_mut().for_each(&mut solve);
            }
        }
        largest
    };
    let largest = split::on_groups(team, blocks, run);
    largest.max(run(boundary))
}
