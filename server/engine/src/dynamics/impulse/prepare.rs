//! The frame's preparation: the solver's bodies (the movers first, then every other body a
//! pair touches), the blocks cut from where the movers are, and the contacts found from
//! the candidate pairs, each into its block's bucket (on several threads, in pair order).

use std::sync::Mutex;

use glam::DVec2;

use super::split::Shared;
use super::team::Team;
use super::{
    blocks, bounce_speed, Contact, ImpulseParams, Pair, SolverBody, SolverBuffers, UNSLOTTED,
};
use super::{CONTACT_PUSH_OUT, MAX_PUSH_OUT, SPECULATIVE_GAP, WARM_START_SPEED};
use crate::dynamics::body::Body;
use crate::geometry::separation;

/// The share of the split impulse a contact ended its last step with that it starts the
/// next with, while it still overlaps beyond twice its slop ([`super::passes::warm_push`]).
/// Whole, a bed of grains under heavy boxes never settled: the pushes it started from
/// fought each other in the few passes a step (6 of 300 fresh seeds of heavy-on-light
/// crept at up to 0.8 u/s). Half builds a row's push up over a few steps and lets a bed's
/// fade (all 300 held, 2 more than with none).
pub(crate) const WARM_PUSH_SHARE: f64 = 0.5;

/// A contact under gravity that held its bodies last step (a normal impulse), now apart by
/// more than the gap a resting contact holds ([`SPECULATIVE_GAP`] of its size) but by no
/// more than this many times it, was lifted there by a push-out (a grain squeezed between
/// two neighbours a little lower than it rises as their pushes add up): it may close back
/// to that gap only, a share of the way each sub-step ([`super::passes::closing`]), where a
/// contact found apart closes to touching. Closing to touching, the body fell freely
/// through the whole gap within a step, at three times `sleep_speed`, and the bed it was
/// part of restarted its rest every 8 to 15 steps: under two heavy boxes, heavy-on-light
/// seed 6 slept from frame 211, and from frame 78 now (docs/bench/engine-notes.md,
/// "Heavy-on-light beds").
pub(super) const DRIFT_BACK: f64 = 2.0;

/// Fills `buffers` for the frame: the solver's bodies and what each mover gains per second
/// (`gains`), the blocks, and the contacts of `pairs` (each pair's impulses taken: the solver
/// leaves this frame's). Returns the touching contacts and the deepest penetration.
pub(super) fn prepare<G: Fn(&Body) -> DVec2 + Sync>(
    bodies: &[Body],
    pairs: &mut [Pair],
    params: ImpulseParams,
    buffers: &mut SolverBuffers,
    movers: &[u32],
    gains: &G,
    team: &Team,
) -> Found {
    let SolverBuffers {
        bodies: sb,
        slot,
        slotted,
        accel: gain,
        buckets,
        found,
        block_of,
        blocks_for,
        frames_since_cut,
        places,
        cut_scratch,
        pushed: _,
        met: _,
        before: _,
        moved: _,
        unpushed: _,
        push_cap: _,
        spread: _,
        held: _,
        pushing: _,
        live: _,
        island_moves: _,
        supports: _,
        impacts: _,
        crew: _,
        last_contacts: _,
        times: _,
        depths: _,
    } = buffers;
    if slot.len() < bodies.len() {
        slot.resize(bodies.len(), UNSLOTTED);
    }
    sb.clear();
    slotted.clear();
    // A body's place among the solver's bodies, given at its first use.
    let mut place = |i: u32, sb: &mut Vec<SolverBody>| -> u32 {
        let s = &mut slot[i as usize];
        if *s == UNSLOTTED {
            let b = &bodies[i as usize];
            *s = sb.len() as u32;
            sb.push(SolverBody {
                vel: b.vel,
                pseudo: DVec2::ZERO,
                delta: DVec2::ZERO,
                inv_mass: b.inv_mass,
            });
            slotted.push(i);
        }
        *s
    };
    // The movers first: mover k is solver body k.
    for &i in movers {
        place(i, sb);
    }
    gain.clear();
    gain.extend(movers.iter().map(|&i| gains(&bodies[i as usize])));

    let moving = movers.len();
    let block_count = blocks::block_count(moving);
    // The blocks, cut from where the movers are (not every frame: the cut costs about
    // as much as a tenth of a pass on the pyramid, and a pile hardly moves).
    *frames_since_cut += 1;
    if blocks_for.as_slice() != movers
        || block_of.len() != moving
        || *frames_since_cut >= blocks::RECUT_FRAMES
    {
        places.clear();
        places.extend(movers.iter().map(|&i| bodies[i as usize].pos));
        blocks::assign(places, block_count, block_of, cut_scratch);
        blocks_for.clear();
        blocks_for.extend_from_slice(movers);
        *frames_since_cut = 0;
    }
    buckets.resize_with(block_count + 1, Vec::new);
    buckets.truncate(block_count + 1);
    for bucket in buckets.iter_mut() {
        bucket.clear();
    }
    // Every body of a pair gets its place first (the movers have theirs), so that the
    // contacts can then be found on several threads, each pair on its own. Where every
    // body moves (a block struck in empty space), every one has its place already; where
    // the others are few beside the pairs (a crowd's four walls), each of them gets one,
    // in body order, without a pass over the pairs. A static body's place is only where
    // the solver reads it: which one it gets changes nothing.
    let others = bodies.len() - movers.len().min(bodies.len());
    if others > 0 && others * 8 <= pairs.len() {
        for i in 0..bodies.len() as u32 {
            place(i, sb);
        }
    } else if others > 0 {
        for pair in pairs.iter() {
            place(pair.a, sb);
            place(pair.b, sb);
        }
    }
    let find = Finder {
        bodies,
        slot,
        block_of,
        moving,
        block_count,
        params,
        gains,
    };
    // Contiguous runs of pairs, each filling its own buckets: the first run the solver's,
    // the others spares appended after it in order, so every bucket lists its contacts
    // in the order of the pairs whatever the thread count.
    let (runs, size) = crate::parallel::chunking(team.size() as u32, pairs.len());
    found.resize_with(runs.saturating_sub(1), Vec::new);
    for spare in found.iter_mut() {
        spare.resize_with(block_count + 1, Vec::new);
        spare.truncate(block_count + 1);
        spare.iter_mut().for_each(Vec::clear);
    }
    let outs = std::iter::once(&mut buckets[..]).chain(found.iter_mut().map(|f| &mut f[..]));
    let work: Vec<_> = pairs
        .chunks_mut(size.max(1))
        .enumerate()
        .zip(outs)
        .collect();
    // Run k on the team's member k: each takes its own run, then leaves its figures.
    let partial: Vec<Found> = if work.len() > 1 {
        let runs: Vec<Mutex<_>> = work.into_iter().map(|w| Mutex::new(Some(w))).collect();
        let figures: Vec<Mutex<Found>> = runs.iter().map(|_| Mutex::default()).collect();
        team.run(&|k| {
            let taken = runs.get(k).and_then(|r| r.lock().expect("a run").take());
            if let Some(((run, pairs), out)) = taken {
                *figures[k].lock().expect("figures") = find.contacts(pairs, run * size, out);
            }
            0.0
        });
        figures
            .into_iter()
            .map(|f| f.into_inner().expect("figures"))
            .collect()
    } else {
        work.into_iter()
            .map(|((run, pairs), out)| find.contacts(pairs, run * size, out))
            .collect()
    };
    // Each bucket takes the spares' contacts after its own. The helpers found them (they
    // are in the helpers' caches): the helpers copy, the buckets shared out among them.
    if !found.is_empty() {
        let count = buckets.len();
        let view = Shared::new(buckets);
        let found = &found[..];
        let helpers = team.size() - 1;
        team.run(&|k| {
            let (k, n) = if helpers == 0 {
                (0, 1)
            } else if k == 0 {
                return 0.0;
            } else {
                (k - 1, helpers)
            };
            for b in count * k / n..count * (k + 1) / n {
                // SAFETY: the members' runs of buckets are disjoint.
                let bucket = unsafe { view.at(b) };
                for spare in found {
                    bucket.extend_from_slice(&spare[b]);
                }
            }
            0.0
        });
    }
    partial.into_iter().fold(Found::default(), Found::and)
}

/// What finding a frame's contacts found, besides the contacts.
#[derive(Clone, Copy, Debug)]
pub(super) struct Found {
    /// Contacts touching (within the speculative gap a resting contact holds),
    /// overlapping, or meeting within the frame.
    pub touching: u64,
    /// The deepest penetration among them.
    pub deepest: f64,
    /// The smallest body size a contact touches (infinite for none).
    pub smallest: f64,
    /// Whether a contact may bounce (its pair's restitution is above 0).
    pub bouncing: bool,
    /// Whether a contact with a static body overlaps beyond its slop.
    pub deep_fixed: bool,
    /// Whether a contact with a static body touches (a crowd may be held by it).
    pub touching_fixed: bool,
    /// Contacts between two bodies at rest that nothing accelerates (those of islands
    /// that cannot change are among them: [`super::still::still_islands`]).
    pub at_rest: usize,
    /// Whether a contact is free (its push-out spread).
    pub free: bool,
    /// Whether a contact starts from a share of its last push ([`WARM_PUSH_SHARE`]).
    pub warm_push: bool,
    /// Whether a contact starts from an impulse (warm-started from the last frame).
    pub impulses: bool,
}

impl Default for Found {
    fn default() -> Self {
        Found {
            touching: 0,
            deepest: 0.0,
            smallest: f64::INFINITY,
            bouncing: false,
            deep_fixed: false,
            touching_fixed: false,
            at_rest: 0,
            free: false,
            warm_push: false,
            impulses: false,
        }
    }
}

impl Found {
    /// Two runs' findings as one.
    fn and(self, other: Found) -> Found {
        Found {
            touching: self.touching + other.touching,
            deepest: self.deepest.max(other.deepest),
            smallest: self.smallest.min(other.smallest),
            bouncing: self.bouncing || other.bouncing,
            deep_fixed: self.deep_fixed || other.deep_fixed,
            touching_fixed: self.touching_fixed || other.touching_fixed,
            at_rest: self.at_rest + other.at_rest,
            free: self.free || other.free,
            warm_push: self.warm_push || other.warm_push,
            impulses: self.impulses || other.impulses,
        }
    }
}

/// What finding a frame's contacts reads: the bodies, their places among the solver's
/// bodies (all given), the blocks, the frame's settings and what each body gains per second.
struct Finder<'a, G> {
    bodies: &'a [Body],
    slot: &'a [u32],
    /// Each mover's block, by slot.
    block_of: &'a [u16],
    moving: usize,
    block_count: usize,
    params: ImpulseParams,
    gains: &'a G,
}

impl<G: Fn(&Body) -> DVec2> Finder<'_, G> {
    /// The contacts of `pairs` (the run starting at pair `first`), each pushed to its
    /// bucket in `out`; each pair's impulses are taken (the solver leaves this frame's).
    /// Returns what it found besides the contacts.
    fn contacts(&self, pairs: &mut [Pair], first: usize, out: &mut [Vec<Contact>]) -> Found {
        let (bodies, params, gains) = (self.bodies, self.params, self.gains);
        let frame_dt = params.dt;
        let mut found = Found::default();
        for (k, pair) in pairs.iter_mut().enumerate() {
            let (i, j) = (pair.a, pair.b);
            let (a, b) = (&bodies[i as usize], &bodies[j as usize]);
            let (old_n, jn, jt) = (pair.normal, pair.normal_impulse, pair.tangent_impulse);
            let jp = pair.pseudo_impulse;
            pair.normal_impulse = 0.0;
            pair.tangent_impulse = 0.0;
            pair.pseudo_impulse = 0.0;
            if a.inv_mass + b.inv_mass == 0.0 {
                continue;
            }
            let rel = b.vel - a.vel;
            let (ha, hb) = (a.shape.half_extents(), b.shape.half_extents());
            let size = ha.min_element().min(hb.min_element()) * 2.0;
            // Too far apart to meet within the frame: no contact. A pair that gravity
            // pulls, or that moves and may bounce, may meet within a tenth of its size
            // whatever its speed (a body struck or turned back within the step); any other
            // pair only within the gap a resting contact holds. The tenth for every pair
            // made a contact of every neighbour of a calm crowd a few hundredths apart,
            // solved in every pass for nothing (the crowds ran 3 times slower awake); the
            // gap for every pair let rains sink a quarter of a size into each other within
            // a step, and struck circles of elastic gases overlap 2.7 times deeper
            // (docs/engine.md, "How near a pair becomes a contact").
            let accelerated = gains(a) != DVec2::ZERO || gains(b) != DVec2::ZERO;
            let moving = a.vel != DVec2::ZERO || b.vel != DVec2::ZERO;
            let near = accelerated || (moving && a.restitution > 0.0 && b.restitution > 0.0);
            let reach = if near { 0.1 } else { SPECULATIVE_GAP } * size;
            // How fast the pair may close: at its relative speed, or, under gravity, at
            // either body's own speed should the other be stopped within the frame (a box
            // of a falling column landing on a pile, the next box still falling onto it).
            // Without gravity the contacts this adds between bodies thrown together cost
            // the impacts family 2 seeds of 100 and a seventh of its time.
            let closing = if accelerated {
                rel.length_squared()
                    .max(a.vel.length_squared())
                    .max(b.vel.length_squared())
            } else {
                rel.length_squared()
            };
            if too_far(b.pos - a.pos, ha + hb, closing, reach, frame_dt) {
                continue;
            }
            let (gap, n) = separation(&a.shape, a.pos, &b.shape, b.pos);
            if gap > reach && gap > closing.sqrt() * frame_dt + reach {
                continue;
            }
            if gap <= 0.0 {
                found.deepest = found.deepest.max(-gap);
            }
            // The approach speed at impact: a pair found apart closes its gap under its
            // relative acceleration first, so it meets faster (or slower) than it was found
            // moving (`v_i² = v² - 2 a s`, energy along the normal). Bouncing with the
            // speed found would lose the energy gained over the gap at every bounce.
            let approach = rel.dot(n);
            let impact = if gap > 0.0 && approach < 0.0 {
                let closing = approach * approach - 2.0 * (gains(b) - gains(a)).dot(n) * gap;
                -closing.max(0.0).sqrt()
            } else {
                approach
            };
            // Touching: within the gap a resting contact holds (bodies at rest settle
            // anywhere in it, and a bounce leaves them apart, never overlapped), or
            // meeting within the frame.
            let band = SPECULATIVE_GAP * size;
            if gap <= band || (impact < 0.0 && gap <= -impact * frame_dt) {
                found.touching += 1;
            }
            let restitution = a.restitution.min(b.restitution).max(0.0);
            let bounce_speed = bounce_speed(accelerated, size);
            let bounces = restitution > 0.0 && impact < -bounce_speed;
            let slop = params.slop * size;
            // Only contacts that touch, and are no impact, start from their last impulses
            // (a pair about to bounce starts from none: the collision stage bounces it
            // with the approach it has). Where nothing accelerates the pair, only one
            // still closing does: nothing presses a contact there between steps, and
            // warm-starting one that has stopped closing pushes its bodies apart with
            // the impulse of a push that is over (a cluster a heavy body drove made up
            // to 10% of its energy that way).
            let warm = params.warm_starting
                && gap <= slop
                && old_n.dot(n) > 0.99
                && approach.abs() <= WARM_START_SPEED
                && !bounces
                && (accelerated || approach < 0.0);
            // Held last step and lifted just past the gap a resting contact holds: back to
            // that gap, not down to touching ([`DRIFT_BACK`]).
            let drifted = gap > band && gap <= DRIFT_BACK * band;
            let keep = if accelerated && jn > 0.0 && !bounces && drifted {
                band
            } else {
                0.0
            };
            let (sa, sb) = (self.slot[i as usize], self.slot[j as usize]);
            let bucket = blocks::bucket_of(
                sa,
                sb,
                self.block_count,
                // Moving: a mover (the first slots) that is not frozen for the step.
                |s| {
                    (s as usize) < self.moving
                        && if s == sa {
                            a.inv_mass != 0.0
                        } else {
                            b.inv_mass != 0.0
                        }
                },
                |s| self.block_of[s as usize] as usize,
            );
            found.smallest = found.smallest.min(size);
            found.bouncing |= restitution > 0.0;
            let fixed = a.inv_mass == 0.0 || b.inv_mass == 0.0;
            found.deep_fixed |= fixed && -gap > slop;
            found.touching_fixed |= fixed && gap <= 0.0;
            found.at_rest += usize::from(!moving && !accelerated);
            let free = !fixed && !accelerated && params.split_impulses;
            found.free |= free;
            let jp = if warm && !free && params.split_impulses && -gap > 2.0 * slop {
                WARM_PUSH_SHARE * jp
            } else {
                0.0
            };
            found.warm_push |= jp > 0.0;
            found.impulses |= warm && (jn != 0.0 || jt != 0.0);
            out[bucket].push(Contact {
                a: sa,
                b: sb,
                normal: n,
                mass: 1.0 / (a.inv_mass + b.inv_mass),
                friction: (a.friction * b.friction).sqrt(),
                gap,
                slop,
                restitution: restitution as f32,
                bounce_speed: bounce_speed as f32,
                max_push: if accelerated || !params.split_impulses {
                    MAX_PUSH_OUT * size
                } else {
                    CONTACT_PUSH_OUT * size
                },
                normal_impulse: if warm { jn } else { 0.0 },
                tangent_impulse: if warm { jt } else { 0.0 },
                pseudo_impulse: jp,
                pair: (first + k) as u32,
                keep: keep as f32,
                // A pair about to bounce may close its gap, however small: it bounces
                // where it meets, not short of it.
                speculative: gap > band || (bounces && gap > 0.0),
                fixed,
                free,
                bounced: false,
            });
        }
        found
    }
}

/// Whether two shapes whose centres are `d` apart and whose half extents add up to `half`
/// are sure to be too far apart to meet within `dt` closing at the speed whose square is
/// `closing` (the
/// test of [`Finder::contacts`], on the gap of their bounding boxes): without the exact
/// separation, nor a square root. The boxes' gap is never more than the shapes', and the
/// margins (a millionth of the reach and a few roundings of the distances, a millionth of
/// the squared travel) cover the rounding by which the two may differ, so a pair it
/// rejects the exact test rejects too:
/// the contacts found are the same, bit for bit. Most candidate pairs of a moving crowd
/// are rejected here (on the rain, the separation's square root and division were a third
/// of the search).
#[inline(always)]
fn too_far(d: DVec2, half: DVec2, closing: f64, reach: f64, dt: f64) -> bool {
    let room = (d.abs() - half).max_element() - reach;
    let rounding = 8.0 * f64::EPSILON * (d.abs().max_element() + half.max_element());
    room > 1e-6 * reach + rounding && room * room > closing * (dt * dt) * (1.0 + 1e-6)
}
