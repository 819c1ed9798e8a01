//! Sleeping of bodies at rest (`sleeping`; on by default, off under the chapter's
//! relaxation).
//!
//! After each step, touching dynamic bodies are joined into islands. An island whose
//! bodies all moved slower than `sleep_speed` for `sleep_delay` seconds, none straying
//! further than that speed allows from its recent places (in its own sizes if it is
//! smaller than a unit) unless jammed (its overlaps opening no faster than twice that,
//! see [`rest`]), goes to sleep:
//! velocities zeroed, no integration, and the solvers see its bodies as static (their
//! inverse mass is set aside during a step). An island that nothing holds (no static body,
//! no sleeper, no gravity) must also have a still centre of mass: a free body keeps its
//! momentum. An island with a moving body in it (a body
//! that hit a sleeper joins its island) wakes whole, its sleepers keeping the time they
//! rested (the wake itself moved none of them). Bodies driven by a behaviour (hero,
//! minions, dye packs) never sleep; actions that move bodies or change the world's
//! parameters wake everything.

use super::body::{Body, Sleeper};
use crate::geometry::separation;
use glam::DVec2;

/// Sleepers become static for the step: their inverse mass is set aside.
pub fn freeze(bodies: &mut [Body], movers: &[u32]) {
    for &i in movers {
        let b = &mut bodies[i as usize];
        if b.asleep.is_some() {
            b.inv_mass = 0.0;
            b.vel = glam::DVec2::ZERO;
        }
    }
}

/// After the step: sleepers get their inverse mass back.
pub fn thaw(bodies: &mut [Body], movers: &[u32]) {
    for &i in movers {
        let b = &mut bodies[i as usize];
        if let Some(s) = b.asleep {
            b.inv_mass = s.inv_mass;
        }
    }
}

/// Wakes a body and starts its rest again (an action moved it or changed the world).
pub fn wake(body: &mut Body) {
    if let Some(s) = body.asleep.take() {
        body.inv_mass = s.inv_mass;
    }
    body.rest_time = 0.0;
}

/// The root of `i` in a union-find forest `parent` (each entry its parent, a root its
/// own), halving the path on the way.
pub(crate) fn find(parent: &mut [u32], mut i: u32) -> u32 {
    while parent[i as usize] != i {
        let p = parent[i as usize];
        parent[i as usize] = parent[p as usize];
        i = p;
    }
    i
}

/// Updates rest times, before the islands. `may_sleep` says which bodies may rest at all
/// (the demo's steered bodies never do); `start` is each mover's place at the start of the
/// step (a body's rest begins there; one that strays from its recent places further than
/// `speed` allows over `delay` is not at rest, unless it is jammed: `depths` are the
/// movers' deepest overlaps of the step, in their order, and `accelerated` says which
/// bodies gravity pulls, which never are). Returns whether islands are needed: a body
/// sleeps, or has rested long enough to. If not, none can sleep or wake, and the caller
/// need not find the touching pairs.
#[allow(clippy::too_many_arguments)]
pub fn rest(
    bodies: &mut [Body],
    movers: &[u32],
    may_sleep: impl Fn(usize) -> bool,
    start: &[(u32, glam::DVec2)],
    depths: &[f64],
    accelerated: impl Fn(&Body) -> bool,
    dt: f64,
    speed: f64,
    delay: f64,
) -> bool {
    let mut islands_matter = false;
    let depths = if depths.len() == movers.len() {
        depths
    } else {
        &[]
    };
    for (k, &i) in movers.iter().enumerate() {
        let b = &mut bodies[i as usize];
        if b.asleep.is_some() {
            islands_matter = true;
            continue;
        }
        // Too fast to rest, or never to sleep: its rest starts again, and with it its
        // anchor and depth (set afresh the next step it is slow), so neither is kept up.
        if !(may_sleep(i as usize) && shorter(b.vel, speed)) {
            b.rest_time = 0.0;
            continue;
        }
        // At rest: slow, and near where it has been lately. Split impulses move
        // positions without velocity: the anchor follows the body's place, averaged over
        // `delay`, so a body they push on steadily faster than `speed` draws away from
        // it, and one they only shuffle in place (a crowd fuller than its container can
        // hold) stays near.
        let from = match start.get(k) {
            Some(&(j, p)) if j == i => Some(p),
            _ => None,
        };
        // The place is measured in the body's own size: one smaller than a unit must stay
        // within `speed` of its sizes a second (the push-out of a small box still
        // overlapped moves it slower than `speed` but not than that).
        let size = 2.0 * b.shape.half_extents().min_element();
        let reach = speed * size.min(1.0) * delay.max(dt);
        let depth = depths.get(k).copied().unwrap_or(0.0);
        if b.rest_time == 0.0 {
            b.rest_anchor = from.unwrap_or(b.pos);
            b.rest_depth = depth;
        }
        let follow = dt / delay.max(dt);
        b.rest_anchor += (b.pos - b.rest_anchor) * follow;
        b.rest_depth += (depth - b.rest_depth) * follow;
        // Jammed: overlapped deeper than `JAM_DEPTH` of its size, its overlaps opening no
        // faster than twice `speed` (its depth's lag behind its average, as its place's
        // behind the anchor; twice, as its deepest overlap drops at once when another
        // contact becomes its deepest), nothing accelerating it: a crowd packed past what
        // its container holds, whose push-out only moves its overlaps about. Such a body
        // rests wherever the push-out takes it; one whose overlaps the push-out opens does
        // not. (Looked at only for a body that strayed: most bodies at rest did not.)
        let jammed =
            || depth > JAM_DEPTH * size && b.rest_depth - depth < 2.0 * reach && !accelerated(b);
        let still = from.is_some() && (shorter(b.pos - b.rest_anchor, reach) || jammed());
        b.rest_time = if still { b.rest_time + dt } else { 0.0 };
        islands_matter |= rested(b.rest_time, delay, dt);
    }
    islands_matter
}

/// `v.length() < r`, to the bit, without the square root where the squares decide it
/// (unless `|v|²` is within a millionth of a millionth of `r²`, or out of the normal
/// range): each body's rest asks it twice a step, and its latency was a third of the
/// rest's time.
fn shorter(v: DVec2, r: f64) -> bool {
    let (l2, r2) = (v.length_squared(), r * r);
    if r > 0.0 && (1e-300..1e300).contains(&r2) {
        // The square root and `r²` are each off by half a rounding at most.
        if l2 < r2 * (1.0 - 1e-12) {
            return true;
        }
        if l2 > r2 * (1.0 + 1e-12) {
            return false;
        }
    }
    v.length() < r
}

/// Whether a body at rest for `rest_time`, summed a step `dt` at a time, has rested
/// `delay`: to within a millionth of a step, what the sum loses to rounding. Compared
/// exactly, thirty steps of 1/60 s summed to 0.49999999999999994 s, and every island
/// meant to sleep after half a second stayed awake a 31st step.
fn rested(rest_time: f64, delay: f64, dt: f64) -> bool {
    rest_time >= delay - 1e-6 * dt
}

/// Whether two bodies touch, for the islands: apart by at most 2% of the smaller one.
fn touching(a: &Body, b: &Body) -> bool {
    let size = a
        .shape
        .half_extents()
        .min_element()
        .min(b.shape.half_extents().min_element());
    separation(&a.shape, a.pos, &b.shape, b.pos).0 <= 0.02 * size
}

/// The share of `sleep_speed` below which an island that touches no static body counts as
/// not drifting (see [`islands`]).
pub const FREE_DRIFT: f64 = 0.01;

/// The depth of overlap, in a body's size, past which a body whose overlaps do not open is
/// jammed (see [`rest`]): a fifth of a percent, twenty times the push-out's slop. At a
/// hundredth, the bodies at the edge of a jammed crowd, overlapped 0.3% by the squeeze
/// their neighbours pass on and moved by it about as fast as `sleep_speed` allows, kept
/// starting their rest again (crowds seed 5 slept whole from frame 157, not 74).
pub const JAM_DEPTH: f64 = 0.002;

/// What [`islands`] did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Slept {
    /// Bodies asleep now.
    pub sleeping: u64,
    /// Whether a body put to sleep was stopped (its velocity was not zero): what the
    /// bodies look like changed after the pairs were found.
    pub stopped: bool,
    /// Whether a body asleep now is `accelerated` (frozen for the next step, it is swept
    /// there as a static body, not as the pairs found it).
    pub pulled: bool,
}

/// After [`rest`]: joins touching bodies into islands and puts resting islands to sleep
/// or wakes them. `pairs` are candidate pairs of the step (body indices); those touching
/// join islands. Says how many bodies sleep now, whether one put to sleep was stopped,
/// and whether a sleeper is accelerated.
///
/// A sleeping island stops where it stands. One that nothing holds must also not drift:
/// its centre of mass must move slower than [`FREE_DRIFT`] times `speed`, or stopping it
/// would take momentum that no contact took. Without gravity a block at rest sleeps, but
/// the slow pieces of an elastic rack struck gently keep flying (they stopped in
/// mid-flight: 4.5% of the rack's energy). An island is held when it touches a static body
/// or a sleeper (seen as static), or when a body of it is `accelerated` (under gravity, a
/// body slow for `delay` rests on something).
pub fn islands(
    bodies: &mut [Body],
    movers: &[u32],
    pairs: impl Iterator<Item = (u32, u32)> + Clone,
    accelerated: impl Fn(&Body) -> bool,
    speed: f64,
    delay: f64,
    dt: f64,
) -> Slept {
    let mut parent: Vec<u32> = (0..bodies.len() as u32).collect();
    // A body awake that has not rested long enough keeps its island awake. Joining two such
    // bodies changes no island's fate (both islands are restless already), so their pair
    // is not looked at: in a pile being pushed apart, most pairs.
    let restless = |b: &Body| b.asleep.is_none() && !rested(b.rest_time, delay, dt);
    // A pair already in one island changes nothing either: in a crowd packed tight, most
    // pairs close a loop, and whether they touch is not worth working out. (Each island's
    // root is its lowest body whatever order the pairs come in.)
    for (i, j) in pairs.clone() {
        let (a, b) = (&bodies[i as usize], &bodies[j as usize]);
        if a.is_static() || b.is_static() || (restless(a) && restless(b)) {
            continue;
        }
        let (ri, rj) = (find(&mut parent, i), find(&mut parent, j));
        if ri != rj && touching(a, b) {
            parent[ri.max(rj) as usize] = ri.min(rj);
        }
    }
    // An island rests when every body in it sleeps or has rested long enough.
    let mut unrested = vec![false; bodies.len()];
    for &i in movers {
        let b = &bodies[i as usize];
        if restless(b) {
            let root = find(&mut parent, i);
            unrested[root as usize] = true;
        }
    }
    // The momentum and mass of each island at rest (sleepers are still).
    // An island held has an infinite mass here.
    let mut momentum = vec![(glam::DVec2::ZERO, 0.0); bodies.len()];
    for &i in movers {
        let root = find(&mut parent, i) as usize;
        let b = &bodies[i as usize];
        if unrested[root] || momentum[root].1 == f64::INFINITY {
            continue;
        }
        if b.asleep.is_some() || accelerated(b) {
            momentum[root].1 = f64::INFINITY;
            continue;
        }
        let m = 1.0 / b.inv_mass;
        momentum[root].0 += b.vel * m;
        momentum[root].1 += m;
    }
    let mut drifting = vec![false; bodies.len()];
    let mut any_drift = false;
    let drift = FREE_DRIFT * speed;
    for &i in movers {
        let root = find(&mut parent, i) as usize;
        let (p, m) = momentum[root];
        if m > 0.0 && m < f64::INFINITY && p.length_squared() > (drift * m) * (drift * m) {
            drifting[root] = true;
            any_drift = true;
        }
    }
    if any_drift {
        for (i, j) in pairs {
            let (a, b) = (&bodies[i as usize], &bodies[j as usize]);
            let mover = match (a.is_static(), b.is_static()) {
                (true, false) => j,
                (false, true) => i,
                _ => continue,
            };
            let root = find(&mut parent, mover) as usize;
            if drifting[root] && touching(a, b) {
                drifting[root] = false;
            }
        }
        for (r, d) in unrested.iter_mut().zip(&drifting) {
            *r |= d;
        }
    }
    let (mut sleeping, mut stopped, mut pulled) = (0, false, false);
    for &i in movers {
        let root = find(&mut parent, i);
        let b = &mut bodies[i as usize];
        if unrested[root as usize] {
            // Woken because a restless body joined its island, a sleeper keeps its rest
            // time: it has not moved. If the wake moves it, `rest` starts its rest again;
            // if not, it sleeps again with its island as soon as the newcomer has rested.
            // (Started again on every wake, the sleepers at the edge of a jammed crowd
            // were woken by its shuffling neighbours faster than they could all rest
            // together: crowds seed 0 slept whole from frame 150, seed 2 never.)
            if let Some(s) = b.asleep.take() {
                b.inv_mass = s.inv_mass;
            }
        } else {
            if b.asleep.is_none() {
                b.asleep = Some(Sleeper {
                    inv_mass: b.inv_mass,
                });
                stopped |= b.vel != glam::DVec2::ZERO;
                b.vel = glam::DVec2::ZERO;
            }
            pulled = pulled || accelerated(b);
            sleeping += 1;
        }
    }
    Slept {
        sleeping,
        stopped,
        pulled,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Shape;
    use proptest::prelude::*;

    /// A row of three unit boxes side by side without gravity: the first two asleep, the
    /// third come to rest against them but not yet for `delay`. Its island wakes; the
    /// sleepers keep their rest, and the row sleeps whole as soon as the newcomer has
    /// rested, not `delay` after the wake.
    #[test]
    fn sleepers_woken_by_a_newcomer_keep_their_rest_and_sleep_again_with_it() {
        let (speed, delay, dt) = (0.05, 0.5, 1.0 / 60.0);
        let unit = Shape::Rect {
            half: DVec2::splat(0.5),
        };
        let mut bodies: Vec<Body> = (0..3)
            .map(|k| Body::for_test(unit, DVec2::new(k as f64, 0.0), DVec2::ZERO, 1.0))
            .collect();
        for b in &mut bodies[..2] {
            b.rest_time = delay + 4.0 * dt;
            b.asleep = Some(Sleeper { inv_mass: 1.0 });
        }
        let movers = [0, 1, 2];
        let pairs = [(0, 1), (1, 2)];
        let islands = |bodies: &mut [Body]| {
            islands(
                bodies,
                &movers,
                pairs.iter().copied(),
                |_| false,
                speed,
                delay,
                dt,
            )
        };
        assert_eq!(
            islands(&mut bodies).sleeping,
            0,
            "the newcomer wakes the row"
        );
        for b in &bodies[..2] {
            assert!(b.asleep.is_none() && b.inv_mass == 1.0);
            assert!(rested(b.rest_time, delay, dt), "rest kept: {}", b.rest_time);
        }
        bodies[2].rest_time = delay;
        let slept = islands(&mut bodies);
        assert_eq!(slept.sleeping, 3, "asleep as soon as the newcomer rested");
        assert!(bodies.iter().all(|b| b.asleep.is_some()));
        // An action that wakes a body starts its rest again.
        wake(&mut bodies[0]);
        assert_eq!(bodies[0].rest_time, 0.0);
    }

    proptest! {
        /// `shorter` answers as the square root does: on vectors and bounds of any scale,
        /// and on vectors a rounding or a few away from the bound (where the squares do
        /// not decide it).
        #[test]
        fn shorter_answers_as_the_length_does(
            x in -1e3f64..1e3, y in -1e3f64..1e3, scale in -200i32..200, r in 0.0f64..2e3,
            ulps in -4i64..4,
        ) {
            let k = 10f64.powi(scale);
            let v = DVec2::new(x, y) * k;
            for r in [r * k, -r * k, 0.0, f64::NAN, f64::INFINITY] {
                prop_assert_eq!(shorter(v, r), v.length() < r, "{} against {}", v, r);
            }
            // A bound at the vector's own length, moved by a few roundings.
            let l = v.length();
            let near = f64::from_bits((l.to_bits() as i64 + ulps).max(0) as u64);
            prop_assert_eq!(shorter(v, near), v.length() < near, "{} against {}", v, near);
        }
    }
}
