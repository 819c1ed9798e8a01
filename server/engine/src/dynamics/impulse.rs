//! The sequential-impulse contact solver (`solver = "impulses"`).
//!
//! Contacts are speculative: a pair still apart by a gap `s` gets the constraint "approach
//! at most `s / dt`", so bodies meet exactly instead of sinking in and being pushed back.
//!
//! Contacts of every resolving interaction are solved together: each velocity iteration
//! visits every contact once and applies the normal impulse that brings the bodies'
//! normal velocity to its target, accumulating it and clamping the sum at zero (contacts
//! push, never pull), then a Coulomb friction impulse clamped by `friction x normal
//! impulse`. The target is the restitution bounce for an approach faster than
//! [`RESTITUTION_SPEED`], plus a Baumgarte bias that removes `baumgarte` of the
//! penetration beyond the slop per sub-step. Impulses are kept between steps (keyed by the
//! pair of bodies) and applied first next step: warm starting, which lets stacks and
//! pyramids settle in a few iterations. Positions move only by velocity, after each
//! sub-step's solve.
//!
//! Shapes do not rotate, so one contact per pair carries all of it.
//!
//! Contacts are kept in blocks of neighbouring moving bodies ([`blocks`]): a pass solves
//! each block in the order its contacts were found, then the contacts between blocks, so
//! the blocks of a pass may run on several threads with the one-thread bits.

use glam::DVec2;

use self::blocks::Bodies;
use super::body::{Body, BodyKey};
pub use super::pairs::Pair;
use crate::geometry::separation;

/// The fastest the position bias pushes overlapping bodies apart, in body sizes per
/// second: a deep overlap (a spawn on top of another body, coincident centres) is undone
/// over a few frames instead of launching the bodies. The cap holds per contact, so a
/// stack of overlapped bodies adds its contacts' pushes up: the suite's `overlap-third`
/// (12 levels of boxes a third into each other) moved its top at 4.8 units/s with a cap
/// of 2, at 2.4 with 1.
pub const MAX_PUSH_OUT: f64 = 1.0;

/// A contact found with a larger gap than this (in body sizes) may close it and no more
/// (a falling body lands instead of stopping short); a nearer one holds, which keeps
/// stacks of touching bodies still.
pub const SPECULATIVE_GAP: f64 = 0.02;

/// Approaches slower than this (units/s) do not bounce: resting contacts stay at rest.
pub const RESTITUTION_SPEED: f64 = 1.0;

/// Contacts found approaching or separating faster than this (units/s) are impacts: they
/// start cold, not from the last step's impulse, which belonged to another state.
/// Warm-starting an impact pushes bodies apart again with the impulse that stopped them:
/// a heavy box driven into a block of small ones (the suite's `smash`) made 6.7% of its
/// kinetic energy that way at 4 sub-steps; resting contacts (slower) keep warm starting.
pub const WARM_START_SPEED: f64 = RESTITUTION_SPEED;

pub use crate::geometry::grid::KeyMap;

/// The solver's settings for one frame.
#[derive(Clone, Copy, Debug)]
pub struct ImpulseParams {
    /// Biased velocity iterations per sub-step.
    pub iterations: u32,
    /// Velocity iterations without position bias per sub-step, after the positions move
    /// (they take out the velocity the bias added, so pushing out does not launch).
    pub relax_iterations: u32,
    pub warm_starting: bool,
    /// Rigid contacts: share of the penetration beyond the slop removed per sub-step.
    pub baumgarte: f64,
    pub slop: f64,
    /// Soft contacts when above 0: the contact spring's frequency (Hz), capped at a
    /// quarter of the sub-step rate; contacts with a static body get twice it.
    pub contact_hertz: f64,
    /// The soft contact's damping ratio.
    pub contact_damping: f64,
    /// Push overlapping bodies apart with pseudo-velocities that move positions and are
    /// then forgotten (split impulses), instead of through their velocities: pushing out
    /// adds no momentum, so a deep pile does not bounce back.
    pub split_impulses: bool,
    /// The frame's time step.
    pub dt: f64,
    pub substeps: u32,
    /// How bodies no contact pushed in a sub-step move (`integrator`): symplectic Euler
    /// `p += v_new h`, explicit Euler `p += v_old h`, or the closed form of constant
    /// acceleration `p += v_old h + a h²/2`. A body a contact pushed moves by the velocity
    /// the contact left it (symplectic).
    pub flight: crate::dynamics::config::Integrator,
    /// Threads the passes may use (the result is the same for any count: see [`blocks`]).
    pub threads: u32,
    /// Start this frame's touching contacts from the load each carries at rest, against
    /// this direction (unit, against gravity): see [`load`]. None: as they are.
    pub rest_load: Option<DVec2>,
}

/// One body as the solver streams it.
#[derive(Clone, Copy, Debug)]
struct SolverBody {
    vel: DVec2,
    /// Push-out velocity of split impulses, applied to the position and dropped.
    pseudo: DVec2,
    /// Displacement since the start of the frame.
    delta: DVec2,
    inv_mass: f64,
}

/// One contact, as the inner loop reads it.
#[derive(Clone, Copy, Debug)]
struct Contact {
    /// The two bodies' places among the solver's bodies (not their indices in the world).
    a: u32,
    b: u32,
    normal: DVec2,
    /// 1 / (inv_a + inv_b).
    mass: f64,
    friction: f64,
    /// Separation at the start of the frame (negative: penetration).
    gap: f64,
    /// Penetration left alone.
    slop: f64,
    /// Normal velocity of the restitution bounce (0 for a resting contact).
    bounce: f64,
    /// Cap of the position bias velocity.
    max_push: f64,
    normal_impulse: f64,
    tangent_impulse: f64,
    /// Accumulated split impulse of the sub-step.
    pseudo_impulse: f64,
    /// Index of its pair.
    pair: u32,
    /// Found apart (beyond the slop): the bodies may close the gap, no more.
    speculative: bool,
    /// One of the two bodies is static (soft contacts are stiffer there).
    fixed: bool,
}

/// How one pass pushes touching contacts apart.
#[derive(Clone, Copy, Debug)]
struct Bias {
    /// Push-out velocity per unit of penetration (beyond the slop).
    rate: f64,
    /// Scales the impulse (soft contacts: below 1).
    mass_scale: f64,
    /// Share of the accumulated impulse taken back each pass (soft contacts).
    impulse_scale: f64,
}

impl Bias {
    const NONE: Bias = Bias {
        rate: 0.0,
        mass_scale: 1.0,
        impulse_scale: 0.0,
    };

    /// The soft-contact coefficients of a spring of `hertz` with damping ratio `zeta`
    /// integrated over `h` (Box2D v3's soft step).
    fn soft(hertz: f64, zeta: f64, h: f64) -> Bias {
        let omega = 2.0 * std::f64::consts::PI * hertz;
        let a1 = 2.0 * zeta + h * omega;
        let a2 = h * omega * a1;
        let a3 = 1.0 / (1.0 + a2);
        Bias {
            rate: omega / a1,
            mass_scale: a2 * a3,
            impulse_scale: a3,
        }
    }
}

/// Impulses of the last step, for warm starting, when pairs are not kept between steps
/// (the all-pairs and sweep broad phases).
#[derive(Clone, Debug, Default)]
pub struct ContactCache {
    impulses: KeyMap<(BodyKey, BodyKey), (DVec2, f64, f64)>,
}

impl ContactCache {
    pub fn clear(&mut self) {
        self.impulses.clear();
    }

    /// Pairs for `candidates` (a pair listed in both orders counts once) with last
    /// step's impulses.
    pub fn pairs(&self, bodies: &[Body], candidates: &mut Vec<(u32, u32)>, out: &mut Vec<Pair>) {
        for p in candidates.iter_mut() {
            if p.0 > p.1 {
                *p = (p.1, p.0);
            }
        }
        candidates.sort_unstable();
        candidates.dedup();
        out.clear();
        out.extend(candidates.iter().map(|&(a, b)| {
            let mut p = Pair::new(a, b);
            let key = (bodies[a as usize].key, bodies[b as usize].key);
            if let Some(&(n, jn, jt)) = self.impulses.get(&key) {
                p.normal = n;
                p.normal_impulse = jn;
                p.tangent_impulse = jt;
            }
            p
        }));
    }

    /// Keeps the impulses the solver left on `pairs`.
    pub fn store(&mut self, bodies: &[Body], pairs: &[Pair]) {
        self.impulses.clear();
        for p in pairs {
            if p.normal_impulse != 0.0 || p.tangent_impulse != 0.0 {
                let key = (bodies[p.a as usize].key, bodies[p.b as usize].key);
                self.impulses
                    .insert(key, (p.normal, p.normal_impulse, p.tangent_impulse));
            }
        }
    }
}

/// What the solver did in one frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ImpulseReport {
    pub contacts: u64,
    pub deepest: f64,
    /// Velocity passes run over the contacts (biased and relax, every sub-step): counted
    /// as they run, not derived from the settings.
    pub passes: u64,
    /// The largest normal velocity change of the last pass times the sub-step (see
    /// [`crate::world::StepStats::residual`]).
    pub residual: f64,
}

/// No place among the solver's bodies.
const UNSLOTTED: u32 = u32::MAX;

/// Reusable buffers of the solver.
#[derive(Clone, Debug, Default)]
pub struct SolverBuffers {
    /// The bodies the frame moves (first, in the order of `movers`), then the others its
    /// contacts touch: a static body no contact touches costs nothing.
    bodies: Vec<SolverBody>,
    /// Each world body's place in `bodies`, [`UNSLOTTED`] if none: set for the frame and
    /// reset after it.
    slot: Vec<u32>,
    /// The world bodies given a place this frame.
    slotted: Vec<u32>,
    /// Velocity each body gains per second (gravity).
    accel: Vec<DVec2>,
    /// The contacts by block, then the boundary's (see [`blocks`]).
    buckets: Vec<Vec<Contact>>,
    /// Buckets of the runs of pairs after the first when contacts are found on several
    /// threads.
    found: Vec<Vec<Vec<Contact>>>,
    /// Each mover's block (see [`blocks::assign`]), the movers it was cut for, and the
    /// frames since: cut again when the movers change or every [`blocks::RECUT_FRAMES`].
    block_of: Vec<u16>,
    blocks_for: Vec<u32>,
    frames_since_cut: u32,
    places: Vec<DVec2>,
    cut_scratch: Vec<f64>,
    /// Bodies a contact pushed in the sub-step (exact flight only).
    pushed: Vec<bool>,
}

/// One frame of the impulse solver over the candidate `pairs` (body indices, `a < b`,
/// each carrying last step's impulses, which it leaves this step's in). Contacts are found
/// once; then `substeps` sub-steps of `dt / substeps` each run: gravity, warm start,
/// `iterations` biased passes, `p += v h` for the bodies listed in `movers`, and
/// `relax_iterations` passes without bias. Within the frame a contact's separation is
/// tracked from how far its two bodies moved along its normal, so detection runs once per
/// frame however many sub-steps there are (in the manner of Box2D v3's soft step).
/// Bodies whose contact pushed are flagged collided and listed in `flagged`.
#[allow(clippy::too_many_arguments)]
pub fn solve_frame(
    bodies: &mut [Body],
    pairs: &mut [Pair],
    params: ImpulseParams,
    buffers: &mut SolverBuffers,
    movers: &[u32],
    accel: impl Fn(&Body) -> DVec2 + Sync,
    flagged: &mut Vec<u32>,
) -> ImpulseReport {
    let frame_dt = params.dt;
    let substeps = params.substeps.max(1);
    let h = frame_dt / substeps as f64;
    let inv_h = 1.0 / h;
    let mut report = ImpulseReport::default();

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
        pushed,
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
    // What a body gains per second: static bodies gain nothing.
    let gains = |body: &Body| {
        if body.inv_mass > 0.0 {
            accel(body)
        } else {
            DVec2::ZERO
        }
    };
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
    // contacts can then be found on several threads, each pair on its own.
    for pair in pairs.iter() {
        place(pair.a, sb);
        place(pair.b, sb);
    }
    let find = Finder {
        bodies,
        slot,
        block_of,
        moving,
        block_count,
        params,
        gains: &gains,
    };
    // Contiguous runs of pairs, each filling its own buckets: the first run the solver's,
    // the others spares appended after it in order, so every bucket lists its contacts
    // in the order of the pairs whatever the thread count.
    let (runs, size) = crate::parallel::chunking(params.threads, pairs.len());
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
    let partial = crate::parallel::run(params.threads, work, |((run, pairs), out)| {
        find.contacts(pairs, run * size, out)
    });
    for (contacts, deepest) in partial {
        report.contacts += contacts;
        report.deepest = report.deepest.max(deepest);
    }
    for spare in found.iter_mut() {
        for (bucket, more) in buckets.iter_mut().zip(spare.iter()) {
            bucket.extend_from_slice(more);
        }
    }

    if let Some(up) = params.rest_load {
        load::rest(buckets, sb, gain, bodies, slotted, h, up);
    }

    let (push, push_fixed) = if params.contact_hertz > 0.0 {
        let hertz = params.contact_hertz.min(0.25 / h);
        (
            Bias::soft(hertz, params.contact_damping, h),
            Bias::soft(2.0 * hertz, params.contact_damping, h),
        )
    } else {
        let rigid = Bias {
            rate: params.baumgarte * inv_h,
            ..Bias::NONE
        };
        (rigid, rigid)
    };

    // One block has nothing to split: the frame stays on the calling thread (no hand-over
    // to the pool for a small world that asked for threads).
    let threads = if block_count > 1 { params.threads } else { 1 };
    let mut bouncing = buckets.iter().flatten().any(|c| c.bounce > 0.0);
    // The sub-steps run inside the pool, so each pass splits among threads already
    // running (one hand-over a frame, not one a pass).
    crate::parallel::install(threads, || {
        for step in 0..substeps {
            for (body, &g) in sb.iter_mut().zip(gain.iter()) {
                body.vel += g * h;
            }
            // Warm start: the impulses of the last sub-step (or frame) once more.
            if params.warm_starting || params.rest_load.is_some() || step > 0 {
                in_blocks(threads, sb, buckets, |bodies, c| {
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
            let last_step = step + 1 == substeps;
            for k in 0..params.iterations {
                // Split impulses start from nothing each sub-step.
                let fresh = params.split_impulses && k == 0;
                report.passes += 1;
                let args = (push, push_fixed, inv_h, params.split_impulses, fresh);
                let last = last_step && params.relax_iterations == 0 && k + 1 == params.iterations;
                if let Some(change) = velocity_pass(threads, sb, buckets, args, last) {
                    report.residual = change * h;
                }
            }
            if let Some(share) = params.flight.gravity_share() {
                pushed.clear();
                pushed.resize(sb.len(), false);
                for c in buckets.iter().flatten() {
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
                for body in &mut sb[..movers.len()] {
                    body.delta += (body.vel + body.pseudo) * h;
                    body.pseudo = DVec2::ZERO;
                }
            }
            for k in 0..params.relax_iterations {
                report.passes += 1;
                let args = (Bias::NONE, Bias::NONE, inv_h, false, false);
                let last = last_step && k + 1 == params.relax_iterations;
                if let Some(change) = velocity_pass(threads, sb, buckets, args, last) {
                    report.residual = change * h;
                }
            }
            // Restitution, once, for contacts that pushed: after the move, the normal velocity
            // becomes the bounce of the approach speed the contact was found with (as Box2D
            // applies it), so a contact that caught a body early still bounces it fully.
            if !bouncing {
                continue;
            }
            bouncing = false;
            let bodies = Bodies::new(sb);
            for c in buckets.iter_mut().flatten() {
                if c.bounce > 0.0 && c.normal_impulse > 0.0 {
                    let (a, b) = (c.a as usize, c.b as usize);
                    let vn = (bodies.get(b).vel - bodies.get(a).vel).dot(c.normal);
                    let total = (c.normal_impulse + c.mass * (c.bounce - vn)).max(0.0);
                    let p = c.normal * (total - c.normal_impulse);
                    c.normal_impulse = total;
                    apply(bodies, c, p);
                    c.bounce = 0.0;
                }
                bouncing |= c.bounce > 0.0;
            }
        }
    });

    for (&i, s) in movers.iter().zip(sb.iter()) {
        let body = &mut bodies[i as usize];
        body.vel = s.vel;
        body.pos += s.delta;
    }
    for c in buckets.iter().flatten() {
        let pair = &mut pairs[c.pair as usize];
        pair.normal = c.normal;
        pair.normal_impulse = c.normal_impulse;
        pair.tangent_impulse = c.tangent_impulse;
        if c.normal_impulse > 0.0 {
            for i in [pair.a, pair.b] {
                let body = &mut bodies[i as usize];
                if !body.collided {
                    body.collided = true;
                    flagged.push(i);
                }
            }
        }
    }
    for &i in slotted.iter() {
        slot[i as usize] = UNSLOTTED;
    }
    report
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
    /// Returns the touching contacts and the deepest penetration among them.
    fn contacts(&self, pairs: &mut [Pair], first: usize, out: &mut [Vec<Contact>]) -> (u64, f64) {
        let (bodies, params, gains) = (self.bodies, self.params, self.gains);
        let frame_dt = params.dt;
        let (mut touching, mut deepest) = (0, 0.0_f64);
        for (k, pair) in pairs.iter_mut().enumerate() {
            let (i, j) = (pair.a, pair.b);
            let (a, b) = (&bodies[i as usize], &bodies[j as usize]);
            let (old_n, jn, jt) = (pair.normal, pair.normal_impulse, pair.tangent_impulse);
            pair.normal_impulse = 0.0;
            pair.tangent_impulse = 0.0;
            if a.inv_mass + b.inv_mass == 0.0 {
                continue;
            }
            let (gap, n) = separation(&a.shape, a.pos, &b.shape, b.pos);
            let rel = b.vel - a.vel;
            let size = a
                .shape
                .half_extents()
                .min_element()
                .min(b.shape.half_extents().min_element())
                * 2.0;
            // Too far apart to meet within the frame: no contact.
            if gap > rel.length() * frame_dt + 0.1 * size {
                continue;
            }
            if gap <= 0.0 {
                touching += 1;
                deepest = deepest.max(-gap);
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
            let bounce = if impact < -RESTITUTION_SPEED {
                -a.restitution.min(b.restitution) * impact
            } else {
                0.0
            };
            let slop = params.slop * size;
            // Only contacts that touch, and are no impact, start from their last impulses.
            let warm = params.warm_starting
                && gap <= slop
                && old_n.dot(n) > 0.99
                && approach.abs() <= WARM_START_SPEED;
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
            out[bucket].push(Contact {
                a: sa,
                b: sb,
                normal: n,
                mass: 1.0 / (a.inv_mass + b.inv_mass),
                friction: (a.friction * b.friction).sqrt(),
                gap,
                slop,
                bounce,
                max_push: MAX_PUSH_OUT * size,
                normal_impulse: if warm { jn } else { 0.0 },
                tangent_impulse: if warm { jt } else { 0.0 },
                pseudo_impulse: 0.0,
                pair: (first + k) as u32,
                // A bouncing pair closes its gap, however small, before it bounces:
                // bouncing from short of the surface would give it the gap's height for
                // nothing.
                speculative: gap > SPECULATIVE_GAP * size || (bounce > 0.0 && gap > 0.0),
                fixed: a.inv_mass == 0.0 || b.inv_mass == 0.0,
            });
        }
        (touching, deepest)
    }
}

/// One contact's share of a velocity pass: the normal impulse that brings the normal
/// velocity to its target (never pulling), then friction within the Coulomb cone. With
/// `MEASURE`, returns the normal velocity change it made (0 otherwise).
/// `args`: the bias against dynamic and against static bodies, `1 / h`, split impulses,
/// and whether the split impulses start from nothing.
#[inline(always)]
fn solve_contact<const MEASURE: bool>(
    sb: Bodies,
    c: &mut Contact,
    args: (Bias, Bias, f64, bool, bool),
) -> f64 {
    let (push, push_fixed, inv_h, split, fresh) = args;
    {
        if fresh {
            c.pseudo_impulse = 0.0;
        }
        let (a, b) = (c.a as usize, c.b as usize);
        let (ba, bb) = (sb.get(a), sb.get(b));
        let dv = bb.vel - ba.vel;
        // Separation now: the frame's start plus how far the bodies moved since.
        let gap = c.gap + (bb.delta - ba.delta).dot(c.normal);
        let bias = if c.fixed { push_fixed } else { push };
        let (target, mass_scale, impulse_scale) = if c.speculative && gap > 0.0 {
            // Apart when found: close the gap within this sub-step, no further.
            (-gap * inv_h, 1.0, 0.0)
        } else {
            // Touching: hold, push out what exceeds the slop.
            let pen = (-gap - c.slop).max(0.0);
            if pen > 0.0 && split {
                // The push goes to the pseudo-velocities; the velocity only holds.
                let target = (bias.rate * pen).min(c.max_push);
                let pv = (bb.pseudo - ba.pseudo).dot(c.normal);
                let total = (c.pseudo_impulse + c.mass * (target - pv)).max(0.0);
                let p = c.normal * (total - c.pseudo_impulse);
                c.pseudo_impulse = total;
                sb.update(a, |s| s.pseudo -= p * ba.inv_mass);
                sb.update(b, |s| s.pseudo += p * bb.inv_mass);
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
            }
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

/// One velocity pass over every contact; with `measure` (the frame's last pass), the
/// largest normal velocity change it made.
fn velocity_pass(
    threads: u32,
    sb: &mut [SolverBody],
    buckets: &mut [Vec<Contact>],
    args: (Bias, Bias, f64, bool, bool),
    measure: bool,
) -> Option<f64> {
    if measure {
        Some(in_blocks(threads, sb, buckets, |b, c| {
            solve_contact::<true>(b, c, args)
        }))
    } else {
        in_blocks(threads, sb, buckets, |b, c| {
            solve_contact::<false>(b, c, args)
        });
        None
    }
}

fn apply(sb: Bodies, c: &Contact, impulse: DVec2) {
    let (a, b) = (c.a as usize, c.b as usize);
    let (ia, ib) = (sb.get(a).inv_mass, sb.get(b).inv_mass);
    sb.update(a, |s| s.vel -= impulse * ia);
    sb.update(b, |s| s.vel += impulse * ib);
}

/// Runs `work` on every contact of every block (at once on up to `threads` threads when
/// there are several blocks), then of the boundary; returns the largest of its results.
///
/// Two blocks a thread runs are interleaved, a contact of one then a contact of the
/// other: they touch different bodies, so the processor overlaps the two instead of
/// waiting on each contact's result for the next (consecutive contacts of one block
/// share a body). The bits are those of one block after the other (four-way interleaving
/// measured no faster).
#[inline(always)]
fn in_blocks(
    threads: u32,
    sb: &mut [SolverBody],
    buckets: &mut [Vec<Contact>],
    work: impl Fn(Bodies, &mut Contact) -> f64 + Sync + Send,
) -> f64 {
    let bodies = Bodies::new(sb);
    let (blocks, boundary) = buckets.split_at_mut(buckets.len() - 1);
    let n = crate::parallel::effective(threads).min(blocks.len());
    let run = |group: &mut [Vec<Contact>]| {
        let mut largest = 0.0_f64;
        for two in group.chunks_mut(2) {
            let (x, y) = match two {
                [x, y] => (x.as_mut_slice(), y.as_mut_slice()),
                [x] => (x.as_mut_slice(), &mut [][..]),
                _ => unreachable!("chunks of one or two"),
            };
            let common = x.len().min(y.len());
            let (x, x_rest) = x.split_at_mut(common);
            let (y, y_rest) = y.split_at_mut(common);
            for (p, q) in x.iter_mut().zip(y.iter_mut()) {
                largest = largest.max(work(bodies, p));
                largest = largest.max(work(bodies, q));
            }
            for c in x_rest.iter_mut().chain(y_rest.iter_mut()) {
                largest = largest.max(work(bodies, c));
            }
        }
        largest
    };
    let largest = if n > 1 {
        crate::parallel::run(threads, blocks::groups(blocks, n), run)
            .into_iter()
            .fold(0.0, f64::max)
    } else {
        run(blocks)
    };
    largest.max(run(boundary))
}

mod blocks;
mod load;
pub use blocks::{block_count, BLOCK_BODIES};

#[cfg(test)]
mod tests;
