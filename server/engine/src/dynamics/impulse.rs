//! The sequential-impulse contact solver (`solver = "impulses"`).
//!
//! Contacts are speculative: a pair still apart by a gap `s` gets the constraint "approach
//! at most `s / dt`", so bodies meet exactly instead of sinking in and being pushed back.
//!
//! Contacts of every resolving interaction are solved together: each velocity iteration
//! visits every contact once and applies the normal impulse that brings the bodies'
//! normal velocity to its target, accumulating it and clamping the sum at zero (contacts
//! push, never pull), then a Coulomb friction impulse clamped by `friction x normal
//! impulse`. The target is a Baumgarte bias that removes `baumgarte` of the penetration
//! beyond the slop per sub-step. Impulses are kept between steps (on the pair
//! of bodies, in [`super::pairs::Contacts`]) and applied first next step: warm starting,
//! which lets stacks and pyramids settle in a few iterations. Positions move only by
//! velocity, after each sub-step's solve.
//!
//! Bouncing is a stage of its own, before the passes of each sub-step ([`collisions`]):
//! every contact of a bouncing pair that touches, or meets within the sub-step, and
//! approaches faster than its [`bounce_speed`], is a collision of two bodies, resolved
//! alone (`v_n' = -e v_n`), contact after contact, pass after pass, until none approaches
//! (in the manner of Guendelman, Bridson and Fedkiw's collision stage). A collision of
//! restitution 1 keeps the energy of its two bodies exactly, so a row of touching balls
//! hands its first ball's speed down to the last, and a gas of elastic circles keeps its
//! energy, where solving every contact at once shares the speed out and loses it.
//!
//! Shapes do not rotate, so one contact per pair carries all of it.
//!
//! Contacts are kept in blocks of neighbouring moving bodies ([`blocks`]): a pass solves
//! each block in the order its contacts were found, then the contacts between blocks, so
//! the blocks of a pass may run on several threads with the one-thread bits.

use std::time::{Duration, Instant};

use glam::DVec2;

use super::body::Body;
pub use super::pairs::Pair;

/// The fastest the position bias pushes overlapping bodies apart, in body sizes per
/// second: a deep overlap (a spawn on top of another body, coincident centres) is undone
/// over a few frames instead of launching the bodies. The cap holds per contact, so a
/// stack of overlapped bodies adds its contacts' pushes up: the suite's `overlap-third`
/// (12 levels of boxes a third into each other) moved its top at 4.8 units/s with a cap
/// of 2, at 2.4 with 1. Each body is also held to its own cap ([`body_push_out`]).
pub const MAX_PUSH_OUT: f64 = 1.0;

/// The fastest `body` is pushed out however many contacts push it (after the passes, and
/// in the support sweep): [`PUSH_OUT_SPEED`], but never less than [`MAX_PUSH_OUT`] of its
/// own size a second nor more than three times that. A box of 1 is pushed at up to 3 u/s,
/// so the suite's `overlap-third` rises its 3.7 units in 1.2 s (it took 3.7 s at one size
/// a second); a box of 5 keeps its 5 u/s (the overlaps family's limit, which a faster push
/// would break); grains of 0.2 at most 0.6 u/s.
fn body_push_out(body: &Body) -> f64 {
    let size = 2.0 * body.shape.half_extents().min_element();
    PUSH_OUT_SPEED.clamp(MAX_PUSH_OUT * size, 3.0 * MAX_PUSH_OUT * size)
}

/// The speed (units a second) a body is pushed out at when its size allows it
/// ([`body_push_out`]): Box2D v3's default `contactPushMaxVelocity`.
pub const PUSH_OUT_SPEED: f64 = 3.0;

/// Where neither body of a pair is accelerated (no gravity), the fastest its contact's
/// split impulse pushes it apart, in sizes of the smaller body a second. Each body is
/// still pushed out no faster than [`MAX_PUSH_OUT`] of its own size, however many
/// contacts push it (after the passes, and in the support sweep); the contact's own cap
/// sits well above it, so that it pushes as hard as it is deep (`baumgarte` times its
/// depth). Capped at one size a second, a contact pushed with the same strength past
/// about 4% of a diameter: a crowd fuller than its container then lessened the sum of its
/// overlaps, not the sum of their squares, by pressing a few circles along its walls into
/// each other (the suite's crowded box after 20 s: 37 pairs past 30% of a diameter, the
/// worst 100%; with this cap, 1 pair, the worst 31.5%, and the crowd falls asleep). Under
/// gravity a contact keeps [`MAX_PUSH_OUT`]: there the support sweep carries a pile's
/// push-out, and beds of circles under heavy boxes, their grains pushed harder, crept
/// (2 more of 300 fresh seeds of heavy-on-light failed). Without split impulses the push
/// is velocity and every contact keeps [`MAX_PUSH_OUT`]. A crowd its container holds is
/// not pushed out in the passes at all but by the mean of its contacts' pushes
/// ([`free::spread_push_out`]), which keeps it evenly squeezed and still.
pub const CONTACT_PUSH_OUT: f64 = 10.0;

/// A contact found with a larger gap than this (in body sizes) may close it and no more
/// (a falling body lands instead of stopping short); a nearer one holds, which keeps
/// stacks of touching bodies still.
pub const SPECULATIVE_GAP: f64 = 0.02;

/// Approaches slower than this (units/s) do not bounce where a body of the pair is
/// accelerated (by gravity): a resting contact gains about `g h` of approach every
/// sub-step, and must stay at rest.
pub const RESTITUTION_SPEED: f64 = 1.0;

/// Where neither body of a pair is accelerated, approaches slower than this many sizes of
/// the smaller body a second do not bounce: nothing presses a resting contact there, and a
/// slow collision of an elastic gas keeps its energy.
pub const RESTING_BOUNCE: f64 = 1e-3;

/// The approach below which a pair does not bounce: [`RESTITUTION_SPEED`] when a body of
/// it is accelerated, [`RESTING_BOUNCE`] sizes a second otherwise.
pub fn bounce_speed(accelerated: bool, size: f64) -> f64 {
    if accelerated {
        RESTITUTION_SPEED
    } else {
        RESTING_BOUNCE * size
    }
}

/// Contacts found approaching or separating faster than this (units/s) are impacts: they
/// start cold, not from the last step's impulse, which belonged to another state.
/// Warm-starting an impact pushes bodies apart again with the impulse that stopped them:
/// a heavy box driven into a block of small ones (the suite's `smash`) made 6.7% of its
/// kinetic energy that way at 4 sub-steps; resting contacts (slower) keep warm starting.
pub const WARM_START_SPEED: f64 = RESTITUTION_SPEED;

/// A sub-step's passes have converged when its last one changed no contact's normal
/// velocity by more than this many body sizes a second (the smallest body a contact of
/// the frame touches): a resting pile, warm-started, changes far less; an impact still
/// travelling down a column far more. Past it, up to `adaptive_iterations` more passes run.
pub const CONVERGED_CHANGE: f64 = 1.0;

pub use crate::geometry::grid::KeyMap;

/// The solver's settings for one frame.
#[derive(Clone, Copy, Debug)]
pub struct ImpulseParams {
    /// Biased velocity iterations per sub-step.
    pub iterations: u32,
    /// Biased passes a sub-step may add while the last one has not converged (see
    /// [`CONVERGED_CHANGE`]).
    pub adaptive_iterations: u32,
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
    /// End each sub-step's passes with the support sweep against this direction (unit,
    /// against gravity): see [`support`]. None: no sweep.
    pub support: Option<DVec2>,
    /// Move a body sliding under friction on what holds it up by its mean velocity over
    /// the sub-step, up being this direction (unit, against gravity): see
    /// [`passes::slide`]. None: by its velocity at the end.
    pub exact_sliding: Option<DVec2>,
    /// End each sub-step's passes with the impact sweep: see [`impact`].
    pub impact_propagation: bool,
    /// Run a frame in which every body is still as push-out only, and leave the islands
    /// that cannot change out of a frame's stages ([`still`]): the bits are those of the
    /// full passes, which `false` runs (to compare them).
    pub still_frames: bool,
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
    /// The pair's restitution (the smaller of the two; 0: the contact never bounces).
    restitution: f32,
    /// Approaches slower than this do not bounce (units/s; see [`bounce_speed`]).
    bounce_speed: f32,
    /// Cap of the position bias velocity.
    max_push: f64,
    normal_impulse: f64,
    tangent_impulse: f64,
    /// Accumulated split impulse of the sub-step.
    pseudo_impulse: f64,
    /// Index of its pair.
    pair: u32,
    /// The gap a speculative contact may close to (0: touching). A contact that held its
    /// bodies last step and was lifted just past the gap a resting contact holds (by a
    /// push-out that raised its upper body) may close back to that gap only
    /// ([`prepare::DRIFT_BACK`]).
    keep: f32,
    /// Found apart (beyond the slop): the bodies may close the gap, no more.
    speculative: bool,
    /// One of the two bodies is static (soft contacts are stiffer there).
    fixed: bool,
    /// Two moving bodies that nothing accelerates, under split impulses, of a crowd its
    /// container holds ([`free::hold_free`] keeps only those): its push-out is spread
    /// ([`free::spread_push_out`]), not solved in the passes.
    free: bool,
    /// It bounced in the frame (its bodies count as collided).
    bounced: bool,
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

/// Bytes of one contact row as the velocity passes stream it (a cost model's figure: each
/// pass reads every row and writes its impulses back).
pub const CONTACT_ROW_BYTES: usize = std::mem::size_of::<Contact>();

/// Bytes of one moving body as the velocity passes read it (velocity, split-impulse
/// velocity, displacement, inverse mass).
pub const SOLVER_BODY_BYTES: usize = std::mem::size_of::<SolverBody>();

/// What the solver did in one frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ImpulseReport {
    pub contacts: u64,
    pub deepest: f64,
    /// Velocity passes run over the contacts (biased and relax, every sub-step; a still
    /// frame's push-out passes count as biased ones): counted as they run, not derived
    /// from the settings.
    pub passes: u64,
    /// The largest normal velocity change of the last pass times the sub-step (see
    /// [`crate::world::StepStats::residual`]).
    pub residual: f64,
    /// Contacts left out of the frame's stages, in islands that could not change (see
    /// [`still::still_islands`]).
    pub parked: u64,
}

/// No place among the solver's bodies.
const UNSLOTTED: u32 = u32::MAX;

/// Reusable buffers of the solver.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct SolverBuffers {
    /// The bodies the frame moves (first, in the order of `movers`), then the others its
    /// contacts touch: a static body no contact touches costs nothing.
    #[serde(skip)]
    bodies: Vec<SolverBody>,
    /// Each world body's place in `bodies`, [`UNSLOTTED`] if none: set for the frame and
    /// reset after it.
    #[serde(skip)]
    slot: Vec<u32>,
    /// The world bodies given a place this frame.
    #[serde(skip)]
    slotted: Vec<u32>,
    /// Velocity each body gains per second (gravity).
    #[serde(skip)]
    accel: Vec<DVec2>,
    /// The contacts by block, then the boundary's (see [`blocks`]).
    #[serde(skip)]
    buckets: Vec<Vec<Contact>>,
    /// Each mover's deepest penetration among the last frame's contacts, at its start
    /// (in the order of the frame's movers; 0 for none).
    #[serde(skip)]
    depths: Vec<f64>,
    /// The helper threads of the passes, kept from frame to frame (see [`team`]).
    #[serde(skip)]
    crew: team::Crew,
    /// Contacts of the last frame (0 after a restore: the bits do not depend on it).
    #[serde(skip)]
    last_contacts: usize,
    /// Buckets of the runs of pairs after the first when contacts are found on several
    /// threads.
    #[serde(skip)]
    found: Vec<Vec<Vec<Contact>>>,
    /// Each mover's block (see [`blocks::assign`]), the movers it was cut for, and the
    /// frames since: cut again when the movers change or every [`blocks::RECUT_FRAMES`].
    block_of: Vec<u16>,
    blocks_for: Vec<u32>,
    frames_since_cut: u32,
    #[serde(skip)]
    places: Vec<DVec2>,
    #[serde(skip)]
    cut_scratch: Vec<f64>,
    /// Bodies a contact pushed in the sub-step (exact flight only).
    #[serde(skip)]
    pushed: Vec<bool>,
    /// When in the sub-step each body last collided (the collision stage's).
    #[serde(skip)]
    met: Vec<f64>,
    /// Each body's velocity at the start of the sub-step, and how far exact sliding moves
    /// it (exact sliding only).
    #[serde(skip)]
    before: Vec<DVec2>,
    #[serde(skip)]
    moved: Vec<DVec2>,
    /// Each mover's pseudo-velocity before the sub-step's passes, and the most they may
    /// push it out (split impulses only).
    #[serde(skip)]
    unpushed: Vec<DVec2>,
    #[serde(skip)]
    push_cap: Vec<f64>,
    /// Each body's spread push-out and how many contacts gave it (see
    /// [`free::spread_push_out`]).
    #[serde(skip)]
    spread: Vec<(DVec2, u32)>,
    /// Union-find scratch of [`free::hold_free`].
    #[serde(skip)]
    held: Vec<u32>,
    /// The contacts a still frame pushes out in its passes (see [`still::Pushing`]).
    #[serde(skip)]
    pushing: still::Pushing,
    /// The contacts of the islands that may change this frame, when others cannot (see
    /// [`still::still_islands`]), and which islands move.
    #[serde(skip)]
    live: still::Pushing,
    #[serde(skip)]
    island_moves: Vec<bool>,
    /// The frame's supporting contacts, by the body they hold up, lowest first (see
    /// [`support`]).
    #[serde(skip)]
    supports: support::Sweep,
    #[serde(skip)]
    impacts: impact::Sweep,
    /// Where the frame's time went, stage by stage, when the world is profiled (`None`:
    /// no clock is read).
    #[serde(skip)]
    pub times: Option<SolveTimes>,
}

impl SolverBuffers {
    /// Each mover's deepest penetration among the last frame's contacts, at the frame's
    /// start, in the order of the movers the frame was given (empty before a frame).
    pub fn depths(&self) -> &[f64] {
        &self.depths
    }

    /// Checks buffers read back from a checkpoint against the world's `movers`: blocks
    /// kept for them (not cut again at the next frame) name blocks that exist. Names what
    /// is wrong.
    pub fn check(&self, movers: &[u32]) -> Result<(), (String, String)> {
        if self.blocks_for.as_slice() != movers || self.block_of.len() != movers.len() {
            return Ok(());
        }
        let blocks = blocks::block_count(movers.len());
        match self.block_of.iter().position(|&b| b as usize >= blocks) {
            Some(k) => Err((
                format!("solver_buffers.block_of[{k}]"),
                format!("block {} of {blocks}", self.block_of[k]),
            )),
            None => Ok(()),
        }
    }
}

/// The wall-clock time of each stage of one frame of the impulse solver, summed over its
/// sub-steps: where a step's rigid stage goes (a world's profile, as Box2D's `b2Profile`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SolveTimes {
    /// Contacts found among the candidate pairs and prepared (and the resting load).
    pub search: Duration,
    /// Gravity added to the velocities.
    pub integrate_velocities: Duration,
    /// Last frame's impulses applied again.
    pub warm_start: Duration,
    /// The biased velocity passes.
    pub passes: Duration,
    /// Positions moved by the velocities.
    pub integrate_positions: Duration,
    /// The unbiased (relax) passes.
    pub relax: Duration,
    /// The collisions of the contacts that bounce.
    pub restitution: Duration,
    /// Impulses, velocities and positions stored back in the world's bodies.
    pub store: Duration,
}

/// Adds the time since its last reading to a stage's total, or reads no clock at all.
struct Stopwatch(Option<Instant>);

impl Stopwatch {
    fn new(on: bool) -> Stopwatch {
        Stopwatch(on.then(Instant::now))
    }

    fn lap(&mut self, total: Option<&mut Duration>) {
        if let (Some(last), Some(total)) = (self.0.as_mut(), total) {
            let now = Instant::now();
            *total += now - *last;
            *last = now;
        }
    }
}

/// How the biased passes push touching contacts apart, against dynamic bodies and against
/// static ones.
#[derive(Clone, Copy, Debug)]
struct Biases {
    push: Bias,
    push_fixed: Bias,
}

impl Biases {
    /// Soft contacts (springs, twice as stiff against static bodies) when
    /// `contact_hertz` is above 0, else the rigid Baumgarte rate.
    fn of(params: &ImpulseParams, h: f64) -> Biases {
        if params.contact_hertz > 0.0 {
            let hertz = params.contact_hertz.min(0.25 / h);
            Biases {
                push: Bias::soft(hertz, params.contact_damping, h),
                push_fixed: Bias::soft(2.0 * hertz, params.contact_damping, h),
            }
        } else {
            let rigid = Bias {
                rate: params.baumgarte / h,
                ..Bias::NONE
            };
            Biases {
                push: rigid,
                push_fixed: rigid,
            }
        }
    }
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
    let substeps = params.substeps.max(1);
    let h = params.dt / substeps as f64;
    let mut report = ImpulseReport::default();
    // What a body gains per second: static bodies gain nothing.
    let gains = |body: &Body| {
        if body.inv_mass > 0.0 {
            accel(body)
        } else {
            DVec2::ZERO
        }
    };
    // One block has nothing to split: the frame stays on the calling thread. Otherwise
    // the world's crew of threads (see [`team`]) takes the contact search when there are
    // `parallel::MIN_SPLIT` candidate pairs and last frame's contacts, the passes when
    // this frame has as many contacts: below that the hand-over costs more than the work
    // (docs/bench/engine-notes.md). The crew is kept: starting threads costs more than a
    // frame.
    let members = match blocks::block_count(movers.len()) {
        1 => 1,
        blocks => crate::parallel::effective(params.threads).min(blocks),
    };
    let crew = buffers.crew.team(members);
    let split = |work: usize| {
        if work < crate::parallel::MIN_SPLIT {
            team::Team::alone()
        } else {
            &*crew
        }
    };
    let mut times = buffers.times.take();
    let mut clock = Stopwatch::new(times.is_some());
    {
        let searching = split(pairs.len().min(buffers.last_contacts));
        let found = prepare::prepare(bodies, pairs, params, buffers, movers, &gains, searching);
        (report.contacts, report.deepest) = (found.touching, found.deepest);
        let contacts = buffers.buckets.iter().map(Vec::len).sum();
        buffers.last_contacts = contacts;
        let team = split(buffers.last_contacts);
        let SolverBuffers {
            bodies: sb,
            accel: gain,
            buckets,
            pushed,
            slotted,
            met,
            supports,
            impacts,
            unpushed,
            push_cap,
            before,
            moved,
            spread,
            held,
            pushing,
            live,
            island_moves,
            ..
        } = &mut *buffers;
        if let Some(up) = params.rest_load {
            load::rest(buckets, sb, gain, bodies, slotted, h, up);
        }
        // Each mover's push-out cap, read by the support sweep's records and after every
        // sub-step's passes.
        if params.split_impulses || params.support.is_some() {
            push_cap.clear();
            push_cap.extend(movers.iter().map(|&i| body_push_out(&bodies[i as usize])));
        }
        if let Some(up) = params.support {
            supports.order(team, buckets, sb, bodies, slotted, push_cap, up);
        }
        clock.lap(times.as_mut().map(|t| &mut t.search));
        let bias = Biases::of(&params, h);
        let found_free = found.free && free::hold_free(sb, buckets, held, found.touching_fixed);
        // The change under which a pass has converged, in the units of the smallest
        // contact.
        let converged = CONVERGED_CHANGE * found.smallest;
        // Every body still and nothing to move one: the passes only push out.
        let still = params.still_frames && still::frame(&params, sb, gain, found.impulses);
        // A still crowd's passes push out only the contacts its spread does not: those
        // alone are swept (the others would change nothing), and put back after.
        let gathered = still && found_free;
        if gathered {
            pushing.gather(buckets, |c| !c.free);
        }
        // The islands that cannot change this frame sit its stages out: the others' contacts
        // are swept alone, and put back after.
        let parked = params.still_frames
            && !still
            && still::still_islands(
                &params,
                sb,
                gain,
                buckets,
                (movers.len(), found.at_rest, contacts),
                held,
                island_moves,
            );
        if parked {
            use crate::dynamics::sleep::find;
            live.gather(buckets, |c| island_moves[find(held, c.a) as usize]);
            report.parked = (contacts - live.buckets.iter().map(Vec::len).sum::<usize>()) as u64;
            std::mem::swap(buckets, &mut live.buckets);
        }
        for step in 0..substeps {
            let last_step = step + 1 == substeps;
            if params.exact_sliding.is_some() {
                before.clear();
                before.extend(sb.iter().map(|s| s.vel));
            }
            if !still {
                passes::integrate_velocities(sb, gain, h);
            }
            clock.lap(times.as_mut().map(|t| &mut t.integrate_velocities));
            if !still && (params.warm_starting || params.rest_load.is_some() || step > 0) {
                passes::warm_start(team, sb, buckets);
            }
            clock.lap(times.as_mut().map(|t| &mut t.warm_start));
            if found.bouncing && !still {
                let most = params.iterations + params.adaptive_iterations;
                let flight = params.flight.gravity_share();
                passes::collisions(sb, gain, buckets, met, h, most, flight, &mut report);
            }
            clock.lap(times.as_mut().map(|t| &mut t.restitution));
            if params.split_impulses {
                unpushed.clear();
                unpushed.extend(sb[..movers.len()].iter().map(|b| b.pseudo));
                // Before a step's first sub-step only the contacts found with a share
                // of their last push have one; after it, any contact that pushed.
                if step > 0 || found.warm_push {
                    let work = if gathered {
                        &mut pushing.buckets
                    } else {
                        &mut *buckets
                    };
                    passes::warm_push(team, sb, work);
                }
                if found_free {
                    free::spread_push_out(sb, buckets, bias.push.rate, spread);
                }
            }
            passes::solve(
                team,
                sb,
                if gathered {
                    &mut pushing.buckets
                } else {
                    &mut *buckets
                },
                &params,
                bias,
                h,
                converged,
                last_step,
                found.deep_fixed,
                still,
                gain,
                &mut report,
            );
            if params.split_impulses {
                passes::cap_push_out(sb, unpushed, push_cap);
            }
            if params.impact_propagation && !still {
                impacts.sweep(sb, buckets, gain, h);
            }
            if let Some(up) = params.support {
                let push = params
                    .split_impulses
                    .then_some((bias.push.rate, bias.push_fixed.rate));
                supports.sweep(sb, up, h, push);
            }
            if let Some(up) = params.exact_sliding {
                passes::slide(team, sb, before, moved, buckets, up);
            }
            clock.lap(times.as_mut().map(|t| &mut t.passes));
            passes::integrate_positions(sb, gain, buckets, pushed, params.flight, h, movers.len());
            clock.lap(times.as_mut().map(|t| &mut t.integrate_positions));
            if !still {
                passes::relax(team, sb, buckets, &params, h, last_step, &mut report);
            }
        }
        if gathered {
            pushing.scatter(buckets);
            clock.lap(times.as_mut().map(|t| &mut t.relax));
        }
        if parked {
            std::mem::swap(buckets, &mut live.buckets);
            live.scatter(buckets);
        }
    }
    let team = split(buffers.last_contacts);
    let SolverBuffers {
        bodies: sb,
        slot,
        slotted,
        buckets,
        pushed,
        depths,
        ..
    } = &mut *buffers;
    passes::store(
        team, bodies, pairs, movers, sb, slotted, buckets, pushed, flagged, depths,
    );
    for &i in slotted.iter() {
        slot[i as usize] = UNSLOTTED;
    }
    clock.lap(times.as_mut().map(|t| &mut t.store));
    buffers.times = times;
    report
}

mod blocks;
mod free;
mod impact;
mod load;
mod passes;
mod prepare;
mod split;
mod still;
mod support;
mod team;
pub use blocks::{block_count, BLOCK_BODIES};

#[cfg(test)]
mod tests;
