//! The pair set's frame of reference (see the parent module's notes): how far a body's
//! box is swept in it over the coming steps, whether the frame should fall with the
//! bodies, and which velocity it should move at.

use glam::DVec2;

use super::PairSet;
use crate::dynamics::body::Body;
use crate::dynamics::integrate::acceleration_under;

/// How much a body's box swept along its travel during a step of `dt` (in a frame moving
/// at `frame`) is grown every way: a share of that travel and a tenth of its size. That
/// box must stay inside its fat box.
pub(super) fn reach(body: &Body, frame: DVec2, dt: f64) -> f64 {
    (velocity(body) - frame).length() * dt * SIDEWAYS
        + 0.1 * body.shape.half_extents().max_element()
}

/// How much of a body's travel its box is grown by every way, beside being swept along it:
/// room for a body turned aside within the step (by a bounce the collision stage resolves).
/// With none, a thrown crowd runs 10% faster and the impacts family holds 96 seeds of 100
/// instead of 97; with all of it (a box grown by its travel every way, as before the sweep),
/// a body's box meets every neighbour it could reach in any direction.
pub(super) const SIDEWAYS: f64 = 0.25;

/// How many steps of its travel a body's fat box is swept along: two for a body gravity
/// pulls (its path curves), eight for one nothing accelerates, which flies straight until
/// it meets something. A spray of bodies flying apart then moves a body in the index
/// every few steps instead of every other one: at four rather than two, the suite's
/// smash, awake, spent 65 us a step in the broad phase instead of 114, the elastic
/// family's mean step fell by a third and the impacts' by 8%; at eight rather than four,
/// the impacts' mean step fell by another 5% and the elastic family's by 8% (6, 12 and 16
/// were slower than 8). Under gravity the longer boxes made the rains 4% slower (more
/// pairs than moves saved). The pairs are still exactly the eligible pairs whose boxes
/// overlap; every digest, and the generated scenes, ran to the same bits.
const SWEPT_STEPS: f64 = 2.0;
const SWEPT_STEPS_FREE: f64 = 8.0;

/// How many steps a box moving with its body ([`super::fat`]) lasts at most: each lasts
/// twice as long as its body's last one did (eight steps at first), so a body flying
/// straight is placed again ever more rarely, one turned often as often as before. The
/// index holds a box's hull over its life, and two moving boxes are a pair only if they
/// meet at one time, so a long life costs a query the hulls it crosses, not the contact
/// search pairs. On impacts seed 5 (289 circles struck apart) every life fixed at 8, 32
/// or 64 steps gave 0.071, 0.068 and 0.062 ms a step (the same at 128); the suite's smash
/// 0.130, 0.120 and 0.115 (a throwaway stepping example, 5 alternated runs).
pub(super) const MOVING_STEPS: f64 = 64.0;

/// How many other boxes a body's box must have crossed when last placed (a moving box's
/// hull counted for the share of its life a standing box's sweep lasts) for the body to
/// get a box moving with it. A moving box prunes pairs of bodies flying apart, as in a
/// crowd struck apart, but is left at any turn, and its test in time costs more than an
/// overlap: in a gas, whose bodies fly every way, it saves no pair and costs a step 12 to
/// 20% (the elastic family's gases of 711 to 836 circles filling a sixth of their box).
/// Mean ms a step with every box fit to fly moving / at 4 or more crossed / standing only
/// (a throwaway stepping example, 3 alternated runs): impacts seed 5 0.057 / 0.058 /
/// 0.081, the smash 0.116 / 0.121 / 0.136, elastic seed 9 0.122 / 0.112 / 0.104, elastic
/// seed 1 0.144 / 0.141 / 0.130. At 6 the elastic seeds lose 3 to 6% and the smash gains
/// only 6%.
pub(super) const CROWDED: u16 = 4;

pub(super) fn swept_steps(body: &Body, gravity: DVec2) -> f64 {
    if pulled(body, gravity) {
        SWEPT_STEPS
    } else {
        SWEPT_STEPS_FREE
    }
}

/// How far a body's box swept along `steps` steps of its travel, `travel` a step, is grown
/// every way beside: [`SIDEWAYS`] of the travel of those steps, but of no more than two of
/// them where that is more than a quarter of the body's size. A body swept along eight (one
/// nothing accelerates) flies straight; turned aside, it leaves its box and is placed
/// again, and one step's room is all that the check that it stays inside asks for
/// ([`reach`]). Grown by four steps every way, the fast fragments of a block struck apart
/// overlapped dozens of boxes each: impacts seed 5 (289 circles struck by one 174 times
/// heavier at 88 u/s) held 12 200 pairs for its 290 bodies at the sixth step, 7 300 with
/// two steps' room (then swept along four). Slow bodies turned aside often (a block struck
/// at 15 u/s) keep the room of all their steps: with two for every body, impacts seed 2
/// ran about 5% slower, placed again more often. The pairs a body can meet within a step
/// are in the set either way (the same bits on every shipped scene); the others only cost
/// the contact search a look.
pub(super) fn sideways(body: &Body, steps: f64, travel: f64) -> f64 {
    let room = |steps: f64| steps * travel * SIDEWAYS;
    room(steps).min(room(steps.min(SWEPT_STEPS)).max(0.5 * body.shape.half_extents().max_element()))
}

/// A box swept by `d` and by `e`: the box, the box moved by either, and all between.
pub(super) fn swept_either(min: DVec2, max: DVec2, d: DVec2, e: DVec2) -> (DVec2, DVec2) {
    (
        min + d.min(e).min(DVec2::ZERO),
        max + d.max(e).max(DVec2::ZERO),
    )
}

/// Where a body would be, against where it is, had it stopped dead within a step of `dt`
/// in a frame moving at `frame`: a body gravity accelerates may land on something within
/// the step (a box of a falling column on the pile) while its neighbour goes on. Without
/// gravity, none (a crowd thrown together keeps no pairs for it).
pub(super) fn stop(body: &Body, gravity: DVec2, frame: DVec2, dt: f64) -> DVec2 {
    if pulled(body, gravity) {
        -frame * dt
    } else {
        DVec2::ZERO
    }
}

/// Whether `gravity` accelerates `body` (a dynamic body it pulls).
pub(super) fn pulled(body: &Body, gravity: DVec2) -> bool {
    body.inv_mass > 0.0 && acceleration_under(body, gravity, false) != DVec2::ZERO
}

/// A body's velocity as the set sees it (a body static for good has none).
pub(super) fn velocity(body: &Body) -> DVec2 {
    if fixed(body) {
        DVec2::ZERO
    } else {
        body.vel
    }
}

/// A body that is static for good (a sleeper is only frozen for the step).
pub(super) fn fixed(body: &Body) -> bool {
    body.is_static() && body.asleep.is_none()
}

impl PairSet {
    /// A body's box `min..max` (in the frame) swept along where the body may be over the
    /// next `k` steps of `dt`: at its velocity, or, under gravity, stopped dead (by a
    /// third body) while its neighbour goes on ([`stop`]). In a falling frame, what its
    /// acceleration and the frame's differ by moves it too. The frame falls as the
    /// solver's sub-steps move a body gravity pulls ([`PairSet::fall_share`]); a body's own
    /// sub-steps may move it by anything from exact free fall (half its gain times the
    /// time squared, the `exact` integrator) to the whole of it, so a body gravity pulls
    /// is swept over that range, one it does not pull is left behind by the frame's fall,
    /// and one stopped dead by the frame's whole travel.
    pub(super) fn swept(
        &self,
        body: &Body,
        min: DVec2,
        max: DVec2,
        k: f64,
        dt: f64,
    ) -> (DVec2, DVec2) {
        let d = (velocity(body) - self.frame_velocity) * k * dt;
        if !self.falls {
            return swept_either(
                min,
                max,
                d,
                stop(body, self.gravity, self.frame_velocity, k * dt),
            );
        }
        // Over `k` steps a body gaining `a` a second moves `a dt^2` times this beside its
        // velocity, `c` its share of a step's gain (the velocity gains it step by step).
        let gain = |a: DVec2, c: f64| a * dt * dt * (k * c + k * (k - 1.0) / 2.0);
        let fall = gain(self.gravity, self.fall_share);
        // What the body gains this step: nothing if it is static to the step (a static
        // body, or a sleeper frozen for it, which the frame falls away from).
        let own = if body.inv_mass > 0.0 {
            acceleration_under(body, self.gravity, false)
        } else {
            DVec2::ZERO
        };
        let (lo, hi) = (d + gain(own, 0.5) - fall, d + gain(own, 1.0) - fall);
        let stopped = if pulled(body, self.gravity) {
            -self.frame_velocity * k * dt - fall
        } else {
            lo
        };
        let low = lo.min(hi).min(stopped).min(DVec2::ZERO);
        let high = lo.max(hi).max(stopped).max(DVec2::ZERO);
        (min + low, max + high)
    }

    /// Whether a frame moving at `frame`, the median velocity now, should fall: under
    /// plain gravity, when that median gained what gravity gives since the frame was
    /// chosen (within a quarter): the bodies fall freely, as a rain does, and a frame that
    /// falls with them keeps every box where it is until they land. A frame that does not
    /// fall left a rain's boxes behind every few steps and placed every body again (a rain
    /// of 3 700 spent a third of its first second in the broad phase).
    pub(super) fn free_fall(&self, frame: DVec2) -> bool {
        if !self.plain_gravity || self.gravity == DVec2::ZERO || self.since <= 0.0 {
            return false;
        }
        let expected = if self.falls {
            self.frame_velocity
        } else {
            self.frame_velocity + self.gravity * self.since
        };
        (frame - expected).length() <= 0.25 * self.gravity.length() * self.since
    }

    /// The median velocity of the placed bodies (those static for good at rest), when the
    /// travel summed over them in a frame moving at it is at most half what it is in the
    /// set's frame now; else none.
    pub(super) fn better_frame(&mut self, bodies: &[Body]) -> Option<DVec2> {
        let placed = || {
            self.fat
                .iter()
                .zip(bodies)
                .filter(|(f, _)| f.placed)
                .map(|(_, b)| velocity(b))
        };
        let travel = |frame: DVec2| placed().map(|v| (v - frame).length()).sum::<f64>();
        let now = travel(self.frame_velocity);
        if now.is_nan() || now <= 0.0 {
            return None;
        }
        let mut median = [0.0; 2];
        for (axis, m) in median.iter_mut().enumerate() {
            let mut speeds = std::mem::take(&mut self.speeds);
            speeds.clear();
            speeds.extend(placed().map(|v| v[axis]));
            let half = speeds.len() / 2;
            *m = *speeds.select_nth_unstable_by(half, f64::total_cmp).1;
            self.speeds = speeds;
        }
        let frame = DVec2::from(median);
        (frame.is_finite() && travel(frame) <= 0.5 * now).then_some(frame)
    }
}
