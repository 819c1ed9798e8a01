//! The pair set's tests: candidates against brute force, in frames at rest and moving.

use super::*;
use crate::geometry::Shape;
use proptest::prelude::*;

fn body(i: u32, x: f64, y: f64, w: f64, h: f64, inv_mass: f64, group: GroupId) -> Body {
    Body {
        key: super::super::body::BodyKey(i),
        group,
        ..Body::for_test(Shape::rect(w, h), DVec2::new(x, y), DVec2::ZERO, inv_mass)
    }
}

/// Every pair whose bodies' boxes overlap and that must be resolved.
fn touching(bodies: &[Body], resolving: &[(GroupId, GroupId)]) -> Vec<(u32, u32)> {
    let mut out = Vec::new();
    for i in 0..bodies.len() {
        for j in i + 1..bodies.len() {
            let (p, q) = (&bodies[i], &bodies[j]);
            let named = resolving
                .iter()
                .any(|&(a, b)| (a, b) == (p.group, q.group) || (b, a) == (p.group, q.group));
            let (bp, bq) = (Aabb::of(&p.shape, p.pos), Aabb::of(&q.shape, q.pos));
            let overlap = bp.min.x <= bq.max.x
                && bq.min.x <= bp.max.x
                && bp.min.y <= bq.max.y
                && bq.min.y <= bp.max.y;
            if named && overlap && !(p.is_static() && q.is_static()) {
                out.push((i as u32, j as u32));
            }
        }
    }
    out
}

proptest! {
    /// After any sequence of moves, every touching pair is a candidate, candidates are
    /// sorted and unique, and none joins two static bodies or groups no interaction
    /// names.
    #[test]
    fn kept_pairs_cover_every_touching_pair_after_moves(
        boxes in proptest::collection::vec(
            (0.0f64..60.0, 0.0f64..60.0, 0.2f64..6.0, 0.2f64..6.0, 0u8..4, 0u16..3), 2..60),
        moves in proptest::collection::vec((0usize..60, -8.0f64..8.0, -8.0f64..8.0), 0..40),
    ) {
        // A static floor far larger than the other bodies, too.
        let mut bodies = vec![body(0, 30.0, -1.0, 400.0, 2.0, 0.0, 0)];
        bodies.extend(boxes.iter().enumerate().map(|(k, &(x, y, w, h, s, g))| {
            body(k as u32 + 1, x, y, w, h, if s == 0 { 0.0 } else { 1.0 }, g)
        }));
        let resolving = [(0, 1), (1, 1)];
        let movers: Vec<u32> = (0..bodies.len() as u32)
            .filter(|&i| !bodies[i as usize].is_static())
            .collect();
        let (mut set, mut contacts) = (PairSet::default(), Contacts::default());
        let dt = 1.0 / 60.0;
        set.update(&mut contacts, &bodies, 1, &resolving, &movers, dt);
        for (k, dx, dy) in moves {
            if let Some(&i) = movers.get(k % movers.len().max(1)) {
                let b = &mut bodies[i as usize];
                b.vel = DVec2::new(dx, dy) * 30.0;
                b.pos += DVec2::new(dx, dy);
            }
            set.advance(dt);
            set.update(&mut contacts, &bodies, 1, &resolving, &movers, dt);
            let kept: Vec<(u32, u32)> = contacts.pairs.iter().map(|p| (p.a, p.b)).collect();
            prop_assert!(kept.windows(2).all(|w| w[0] < w[1]), "sorted, unique");
            for p in &contacts.pairs {
                let (a, b) = (&bodies[p.a as usize], &bodies[p.b as usize]);
                prop_assert!(!(a.is_static() && b.is_static()));
                prop_assert!(a.group != 2 && b.group != 2);
            }
            for t in touching(&bodies, &resolving) {
                prop_assert!(kept.binary_search(&t).is_ok(), "missing {:?}", t);
            }
        }
    }
}

/// Every eligible pair whose fat boxes meet, by brute force over every pair: what the set
/// must hold, exactly.
fn overlapping_fat_boxes(set: &PairSet, bodies: &[Body]) -> Vec<(u32, u32)> {
    let mut out = Vec::new();
    for i in 0..bodies.len() as u32 {
        for j in i + 1..bodies.len() as u32 {
            let (p, q) = (&set.fat[i as usize], &set.fat[j as usize]);
            if p.placed
                && q.placed
                && meet(p, q)
                && eligible(&set.resolves, set.groups, bodies, i, j)
            {
                out.push((i, j));
            }
        }
    }
    out
}

proptest! {
    /// Boxes from 1e-2 to 1e2 across, moved, thrown fast, flown straight on, stopped,
    /// added and removed, a step apart: the kept pairs are exactly the eligible pairs
    /// whose fat boxes meet (standing or moving with their bodies), and they hold every
    /// pair whose boxes touch.
    #[test]
    fn kept_pairs_are_exactly_the_fat_boxes_that_meet_whatever_the_sizes(
        boxes in proptest::collection::vec(
            (-60.0f64..60.0, -60.0f64..60.0, -2.0f64..2.0, -2.0f64..2.0, 0u8..5, 0u16..3),
            2..50),
        ops in proptest::collection::vec(
            (0u8..7, 0usize..64, -1.0f64..1.0, -1.0f64..1.0, -2.0f64..2.0), 1..40),
    ) {
        // Sides of 10^-2 to 10^2, even in the logarithm.
        let make = |key: u32, x: f64, y: f64, w: f64, h: f64, s: u8, g: GroupId| {
            let inv_mass = if s == 0 { 0.0 } else { 1.0 };
            body(key, x, y, 10f64.powf(w), 10f64.powf(h), inv_mass, g)
        };
        let mut bodies: Vec<Body> = boxes
            .iter()
            .enumerate()
            .map(|(k, &(x, y, w, h, s, g))| make(k as u32, x, y, w, h, s, g))
            .collect();
        let mut key = bodies.len() as u32;
        let resolving = [(0, 1), (1, 1)];
        let movers = |bodies: &[Body]| -> Vec<u32> {
            (0..bodies.len() as u32)
                .filter(|&i| !bodies[i as usize].is_static())
                .collect()
        };
        let (mut set, mut contacts) = (PairSet::default(), Contacts::default());
        let (dt, mut revision) = (1.0 / 60.0, 1);
        set.update(&mut contacts, &bodies, revision, &resolving, &movers(&bodies), dt);
        for (op, k, dx, dy, e) in ops {
            let n = bodies.len();
            match op {
                // A move of up to 10^e, at the speed it takes in a step.
                0..=2 => {
                    let b = &mut bodies[k % n];
                    if !b.is_static() {
                        let d = DVec2::new(dx, dy) * 10f64.powf(e);
                        b.vel = d / dt;
                        b.pos += d;
                    }
                }
                // Every body flies a step straight on (boxes moving with their bodies
                // hold them).
                5 => {
                    for b in bodies.iter_mut().filter(|b| !b.is_static()) {
                        b.pos += b.vel * dt;
                    }
                }
                // A body stops dead.
                6 => bodies[k % n].vel = DVec2::ZERO,
                // A body added, of sides 10^e by 10^-e.
                3 => {
                    bodies.push(make(key, dx * 60.0, dy * 60.0, e, -e, k as u8 % 5, k as u16 % 3));
                    key += 1;
                    revision += 1;
                }
                // A body removed.
                _ => {
                    if n > 2 {
                        let mut removed = vec![false; n];
                        removed[k % n] = true;
                        bodies.remove(k % n);
                        contacts.remove_bodies(&removed);
                        revision += 1;
                    }
                }
            }
            set.advance(dt);
            set.update(&mut contacts, &bodies, revision, &resolving, &movers(&bodies), dt);
            let kept: Vec<(u32, u32)> = contacts.pairs.iter().map(|p| (p.a, p.b)).collect();
            prop_assert_eq!(&kept, &overlapping_fat_boxes(&set, &bodies));
            for t in touching(&bodies, &resolving) {
                prop_assert!(kept.binary_search(&t).is_ok(), "missing {:?}", t);
            }
        }
    }
}

#[test]
fn a_restored_set_builds_its_tree_again_and_keeps_its_pairs() {
    let mut bodies: Vec<Body> = (0..30)
        .map(|k| body(k, (k % 6) as f64, (k / 6) as f64, 1.0, 1.0, 1.0, 1))
        .collect();
    bodies.push(body(30, 2.5, -40.0, 80.0, 78.0, 0.0, 0));
    let movers: Vec<u32> = (0..30).collect();
    let resolving = [(0, 1), (1, 1)];
    let (mut set, mut contacts) = (PairSet::default(), Contacts::default());
    let dt = 1.0 / 60.0;
    set.update(&mut contacts, &bodies, 1, &resolving, &movers, dt);
    let bytes = serde_json::to_vec(&set).unwrap();
    let mut restored: PairSet = serde_json::from_slice(&bytes).unwrap();
    let mut again = contacts.clone();
    for step in 0..20 {
        bodies[step % 30].pos += DVec2::new(3.0, 0.5);
        bodies[step % 30].vel = DVec2::new(180.0, 30.0);
        set.advance(dt);
        restored.advance(dt);
        set.update(&mut contacts, &bodies, 1, &resolving, &movers, dt);
        restored.update(&mut again, &bodies, 1, &resolving, &movers, dt);
        assert_eq!(contacts.pairs, again.pairs);
    }
    assert_eq!(restored.index.capacity(), 31);
    // The floor and the thrown bodies cover more cells than the grid keeps.
    assert!(restored.index.in_tree() > 1);
}

#[test]
fn bodies_at_rest_are_never_looked_at_again_and_impulses_survive_a_rebuild() {
    let mut bodies: Vec<Body> = (0..10)
        .map(|k| body(k, 0.0, 0.5 + k as f64, 1.0, 1.0, 1.0, 1))
        .collect();
    bodies.push(body(10, 0.0, -1.0, 100.0, 2.0, 0.0, 0));
    let movers: Vec<u32> = (0..10).collect();
    let resolving = [(0, 1), (1, 1)];
    let (mut set, mut contacts) = (PairSet::default(), Contacts::default());
    set.update(&mut contacts, &bodies, 1, &resolving, &movers, 1.0 / 60.0);
    // Nine box-on-box contacts and the bottom box on the floor.
    let kept: Vec<(u32, u32)> = contacts.pairs.iter().map(|p| (p.a, p.b)).collect();
    assert!(
        kept.contains(&(0, 10)) && kept.contains(&(8, 9)),
        "{kept:?}"
    );
    for _ in 0..100 {
        set.update(&mut contacts, &bodies, 1, &resolving, &movers, 1.0 / 60.0);
    }
    assert_eq!(set.reinserted, 0);
    // A new layout (a body removed in front) keeps the impulses by body key.
    contacts
        .pairs
        .iter_mut()
        .for_each(|p| p.normal_impulse = (p.a * 100 + p.b) as f64);
    // The floor's contact pushes its box out: only a split impulse left, kept too.
    let floor = contacts.pairs.iter_mut().find(|p| (p.a, p.b) == (0, 10));
    let floor = floor.expect("the floor's pair");
    floor.normal_impulse = 0.0;
    floor.pseudo_impulse = 0.25;
    let before: Vec<(u32, u32, f64)> = contacts
        .pairs
        .iter()
        .map(|p| {
            (
                bodies[p.a as usize].key.0,
                bodies[p.b as usize].key.0,
                p.normal_impulse,
            )
        })
        .collect();
    bodies.remove(5);
    let mut removed = vec![false; 11];
    removed[5] = true;
    contacts.remove_bodies(&removed);
    set.update(
        &mut contacts,
        &bodies,
        2,
        &resolving,
        &(0..9).collect::<Vec<_>>(),
        1.0 / 60.0,
    );
    for p in &contacts.pairs {
        let (ka, kb) = (bodies[p.a as usize].key.0, bodies[p.b as usize].key.0);
        if let Some(&(_, _, j)) = before.iter().find(|&&(a, b, _)| (a, b) == (ka, kb)) {
            assert_eq!(p.normal_impulse, j);
        }
    }
    assert!(contacts.pairs.iter().any(|p| p.normal_impulse > 0.0));
    let floor = contacts.pairs.iter().find(|p| (p.a, p.b) == (0, 9));
    assert_eq!(floor.map(|p| p.pseudo_impulse), Some(0.25));
}

#[test]
fn a_refill_keeps_the_impulses_of_the_pairs_found_again_and_removal_renumbers() {
    let mut contacts = Contacts::default();
    let mut kept = Vec::new();
    contacts.refill(&mut vec![(2, 1), (0, 3), (1, 2), (3, 4)], &mut kept);
    let found: Vec<(u32, u32)> = contacts.pairs.iter().map(|p| (p.a, p.b)).collect();
    assert_eq!(found, [(0, 3), (1, 2), (3, 4)]);
    for p in &mut contacts.pairs {
        p.normal = DVec2::Y;
        p.normal_impulse = (p.a * 10 + p.b) as f64;
    }
    // (0, 3) has no impulse left: it comes back cold, normal and all.
    contacts.pairs[0].normal_impulse = 0.0;
    // (3, 4) pushed its bodies apart last step: its split impulse comes back with it.
    contacts.pairs[2].pseudo_impulse = 0.5;
    contacts.refill(&mut vec![(4, 3), (0, 3), (2, 5), (1, 2)], &mut kept);
    let found: Vec<(u32, u32, f64, DVec2)> = contacts
        .pairs
        .iter()
        .map(|p| (p.a, p.b, p.normal_impulse, p.normal))
        .collect();
    assert_eq!(
        found,
        [
            (0, 3, 0.0, DVec2::ZERO),
            (1, 2, 12.0, DVec2::Y),
            (2, 5, 0.0, DVec2::ZERO),
            (3, 4, 34.0, DVec2::Y)
        ]
    );
    let pushes: Vec<f64> = contacts.pairs.iter().map(|p| p.pseudo_impulse).collect();
    assert_eq!(pushes, [0.0, 0.0, 0.0, 0.5]);
    contacts.remove_bodies(&[false, false, true, false, false, false]);
    let left: Vec<(u32, u32, f64)> = contacts
        .pairs
        .iter()
        .map(|p| (p.a, p.b, p.normal_impulse))
        .collect();
    assert_eq!(left, [(0, 2, 0.0), (2, 3, 34.0)]);
}

/// Every eligible pair whose bodies' boxes overlap at some moment of the coming step of
/// `dt`, their velocities held or either of them stopped (looked at in eight slices).
fn meeting(
    bodies: &[Body],
    resolving: &[(GroupId, GroupId)],
    dt: f64,
    stops: bool,
) -> Vec<(u32, u32)> {
    // Both bodies on their way, or (with `stops`, under gravity) either stopped dead within
    // the step (by a third body) while the other goes on: any two bodies differ in some bit
    // of their index, so stopping the bodies with that bit clear, then those with it set,
    // stops each of the two alone once.
    let ways = std::iter::once((0, false)).chain(
        (0..16)
            .filter(|_| stops)
            .flat_map(|bit| [(bit, false), (bit, true)]),
    );
    let mut out: Vec<(u32, u32)> = ways
        .enumerate()
        .flat_map(|(w, (bit, set))| {
            (0..=8).flat_map(move |k| {
                let t = dt * k as f64 / 8.0;
                let moved: Vec<Body> = bodies
                    .iter()
                    .enumerate()
                    .map(|(i, b)| {
                        let stopped = w > 0 && ((i >> bit) & 1 == 1) == set;
                        Body {
                            pos: b.pos + if stopped { DVec2::ZERO } else { b.vel * t },
                            ..*b
                        }
                    })
                    .collect();
                touching(&moved, resolving)
            })
        })
        .collect();
    out.sort_unstable();
    out.dedup();
    out
}

proptest! {
    /// A crowd moving together at up to 300 u/s, each body with a velocity of its own
    /// besides, over a static floor, with gravity or without (where a fat box is swept
    /// along eight steps of travel, not two): at every step, every pair that meets within
    /// the step (both bodies going on, or under gravity either stopped by a third) is a
    /// candidate, whatever frame the set chose.
    #[test]
    fn a_moving_crowd_keeps_every_pair_that_meets_within_a_step(
        boxes in proptest::collection::vec(
            (0.0f64..40.0, 0.0f64..40.0, 0.2f64..3.0, 0.2f64..3.0, -5.0f64..5.0, -5.0f64..5.0),
            2..50),
        crowd in (-300.0f64..300.0, -300.0f64..300.0),
        steps in 1usize..40,
        kicks in proptest::collection::vec((0usize..50, -60.0f64..60.0, -60.0f64..60.0), 0..10),
        weightless in proptest::bool::ANY,
    ) {
        let mut bodies = vec![body(0, 20.0, -1.0, 400.0, 2.0, 0.0, 0)];
        bodies.extend(boxes.iter().enumerate().map(|(k, &(x, y, w, h, vx, vy))| Body {
            vel: DVec2::new(crowd.0 + vx, crowd.1 + vy),
            ..body(k as u32 + 1, x, y, w, h, 1.0, 1)
        }));
        let resolving = [(0, 1), (1, 1)];
        let movers: Vec<u32> = (1..bodies.len() as u32).collect();
        let (mut set, mut contacts) = (PairSet::default(), Contacts::default());
        // Under gravity, a body may be stopped within the step by a third one.
        let gravity = if weightless { DVec2::ZERO } else { DVec2::new(0.0, -10.0) };
        set.set_gravity(gravity);
        let dt = 1.0 / 60.0;
        for step in 0..steps {
            if let Some(&(k, dx, dy)) = kicks.get(step) {
                let i = movers[k % movers.len()] as usize;
                bodies[i].vel += DVec2::new(dx, dy);
            }
            set.update(&mut contacts, &bodies, 1, &resolving, &movers, dt);
            let kept: Vec<(u32, u32)> = contacts.pairs.iter().map(|p| (p.a, p.b)).collect();
            prop_assert!(kept.windows(2).all(|w| w[0] < w[1]), "sorted, unique");
            for pair in meeting(&bodies, &resolving, dt, !weightless) {
                prop_assert!(
                    kept.binary_search(&pair).is_ok(),
                    "step {step}: {pair:?} meets within the step but is no candidate (frame {:?})",
                    set.frame_velocity
                );
            }
            for b in &mut bodies[1..] {
                b.pos += b.vel * dt;
            }
            set.advance(dt);
        }
    }
}

/// A packed crowd of 400 boxes thrown at 100 u/s: the set moves its frame with the crowd,
/// so no box leaves its fat box and none is placed again step after step (a frame at rest
/// places every box again every other step). Under gravity the pairs kept are those a
/// body could meet should it or its neighbour be stopped, within the two steps of travel a
/// fat box covers; without it, those of the crowd at rest.
#[test]
fn a_crowd_moving_together_keeps_its_boxes() {
    let crowd = |vel: DVec2| -> Vec<Body> {
        (0..400u32)
            .map(|k| Body {
                vel,
                ..body(
                    k,
                    (k % 20) as f64 * 0.5,
                    (k / 20) as f64 * 0.5,
                    0.5,
                    0.5,
                    1.0,
                    0,
                )
            })
            .collect()
    };
    let dt = 1.0 / 60.0;
    let after = |mut bodies: Vec<Body>, gravity: DVec2| -> (usize, DVec2, u64) {
        let movers: Vec<u32> = (0..bodies.len() as u32).collect();
        let (mut set, mut contacts) = (PairSet::default(), Contacts::default());
        set.set_gravity(gravity);
        set.update(&mut contacts, &bodies, 1, &[(0, 0)], &movers, dt);
        let placed = set.reinserted;
        for _ in 0..30 {
            for b in &mut bodies {
                b.pos += b.vel * dt;
            }
            set.advance(dt);
            set.update(&mut contacts, &bodies, 1, &[(0, 0)], &movers, dt);
        }
        (
            contacts.pairs.len(),
            set.frame_velocity,
            set.reinserted - placed,
        )
    };
    let down = DVec2::new(0.0, -10.0);
    let (at_rest, still, _) = after(crowd(DVec2::ZERO), down);
    let (thrown, frame, placed_again) = after(crowd(DVec2::new(100.0, 0.0)), down);
    // Without gravity nothing stops a body of the crowd within the step: it keeps the
    // pairs of a crowd at rest.
    let (weightless, _, _) = after(crowd(DVec2::new(100.0, 0.0)), DVec2::ZERO);
    assert_eq!(weightless, at_rest);
    assert_eq!(still, DVec2::ZERO);
    assert_eq!(frame, DVec2::new(100.0, 0.0));
    assert_eq!(
        placed_again, 0,
        "boxes placed again in a frame moving with the crowd"
    );
    // Two steps of travel at 100 u/s is 3.3 units, about 7 boxes of the crowd's rows.
    let reach = |i: usize, j: usize| {
        let (di, dj) = ((i % 20) as i64, (j % 20) as i64);
        let (ri, rj) = ((i / 20) as i64, (j / 20) as i64);
        (ri - rj).abs() <= 1 && (di - dj).abs() <= 8
    };
    let within = (0..400)
        .flat_map(|i| (i + 1..400).map(move |j| (i, j)))
        .filter(|&(i, j)| reach(i, j))
        .count();
    assert!(
        at_rest < thrown && thrown <= within,
        "{thrown} pairs kept by the thrown crowd, {at_rest} at rest, {within} within its reach"
    );
}

/// A spray of 400 boxes flying apart from a point at up to 14 u/s, no gravity: no frame
/// follows them all, so each box leaves its fat box in time. Moving with its body (a body
/// nothing accelerates flies straight), a box is placed again no more than every fourth
/// step (112 times in 30 steps), and two are a pair only if they meet at one time; under
/// gravity, swept along two steps and back to where it would stop, about every other step
/// (5 800).
#[test]
fn a_spray_without_gravity_places_its_boxes_again_every_few_steps() {
    let (weightless, ..) = spray(1.0, 1.0, DVec2::ZERO);
    let (falling, ..) = spray(1.0, 1.0, DVec2::new(0.0, -10.0));
    assert!(
        weightless * 4 <= 400 * SPRAY_STEPS,
        "{weightless} boxes placed again in {SPRAY_STEPS} steps of 400"
    );
    assert!(
        falling > 2 * weightless,
        "under gravity {falling}, without {weightless}"
    );
}

/// A block of 400 boxes 0.5 wide, 0.55 apart, struck apart (flying from its centre at up
/// to 74 u/s), no gravity: each box crosses a few others, so each fast body gets a box
/// moving with it, and only the pairs whose boxes meet at one time are kept, a tenth or
/// less of those whose boxes' hulls over their lives cross (20 of 4 720 after 30 steps;
/// standing boxes swept along as far would keep them all).
#[test]
fn a_block_struck_apart_keeps_only_the_pairs_whose_moving_boxes_meet() {
    let (_, kept, crossing) = spray(0.55, 10.0, DVec2::ZERO);
    assert!(
        kept * 10 <= crossing,
        "{kept} pairs kept, {crossing} whose boxes' hulls cross"
    );
}

const SPRAY_STEPS: u64 = 30;

/// 400 boxes 0.5 wide in a square `spacing` apart, each flying from the centre at
/// `speed` times its offset, moved straight on for [`SPRAY_STEPS`] under `gravity` (the
/// velocity left as it is): the boxes placed again, the pairs kept at the end, and the
/// pairs whose fat boxes' hulls cross then.
fn spray(spacing: f64, speed: f64, gravity: DVec2) -> (u64, usize, usize) {
    let dt = 1.0 / 60.0;
    let steps = SPRAY_STEPS;
    let spray: Vec<Body> = (0..400u32)
        .map(|k| {
            let at = DVec2::new((k % 20) as f64 - 9.5, (k / 20) as f64 - 9.5) * spacing;
            Body {
                vel: at * speed,
                ..body(k, at.x, at.y, 0.5, 0.5, 1.0, 0)
            }
        })
        .collect();
    {
        let mut bodies = spray.clone();
        let movers: Vec<u32> = (0..bodies.len() as u32).collect();
        let (mut set, mut contacts) = (PairSet::default(), Contacts::default());
        set.set_gravity(gravity);
        set.update(&mut contacts, &bodies, 1, &[(0, 0)], &movers, dt);
        let placed = set.reinserted;
        for _ in 0..steps {
            for b in &mut bodies {
                b.pos += b.vel * dt;
            }
            set.advance(dt);
            set.update(&mut contacts, &bodies, 1, &[(0, 0)], &movers, dt);
        }
        // The pairs whose boxes' hulls overlap, against those kept.
        let fat = &set.fat;
        let crossing = (0..fat.len())
            .flat_map(|i| (i + 1..fat.len()).map(move |j| (i, j)))
            .filter(|&(i, j)| fat::cross(&fat[i], &fat[j]))
            .count();
        (set.reinserted - placed, contacts.pairs.len(), crossing)
    }
}

/// Steps `bodies` (the dynamic ones) by `dt` under `gravity` as the solver's one sub-step
/// does (symplectic Euler: the velocity first).
fn fall(bodies: &mut [Body], gravity: DVec2, dt: f64) {
    for b in bodies.iter_mut().filter(|b| !b.is_static()) {
        b.vel += gravity * dt;
        b.pos += b.vel * dt;
    }
}

proptest! {
    /// A rain under gravity over a static floor and a few sleepers (frozen for the step:
    /// no mass, no velocity), its bodies accelerating as the solver's sub-steps make them,
    /// some stopped dead now and then (landing on something): at every step, every pair
    /// that meets within the step (both bodies falling on, or either stopped by a third)
    /// is a candidate, whether the frame falls with the rain or not.
    #[test]
    fn a_falling_rain_keeps_every_pair_that_meets_within_a_step(
        boxes in proptest::collection::vec(
            (0.0f64..40.0, 10.0f64..50.0, 0.2f64..3.0, 0.2f64..3.0, -3.0f64..3.0, -3.0f64..3.0),
            2..50),
        sleepers in proptest::collection::vec((0.0f64..40.0, 0.2f64..3.0, 0.2f64..3.0), 0..8),
        steps in 1usize..60,
        landings in proptest::collection::vec((0usize..50, 0usize..60), 0..10),
        dt in prop_oneof![Just(1.0 / 60.0), Just(1.0 / 15.0), Just(1.0 / 240.0)],
    ) {
        let mut bodies = vec![body(0, 20.0, -1.0, 400.0, 2.0, 0.0, 0)];
        bodies.extend(boxes.iter().enumerate().map(|(k, &(x, y, w, h, vx, vy))| Body {
            vel: DVec2::new(vx, vy),
            ..body(k as u32 + 1, x, y, w, h, 1.0, 1)
        }));
        let first = bodies.len() as u32;
        bodies.extend(sleepers.iter().enumerate().map(|(k, &(x, w, h))| Body {
            asleep: Some(super::super::body::Sleeper { inv_mass: 1.0 }),
            ..body(first + k as u32, x, h / 2.0, w, h, 0.0, 1)
        }));
        let resolving = [(0, 1), (1, 1)];
        let movers: Vec<u32> = (1..bodies.len() as u32).collect();
        let (mut set, mut contacts) = (PairSet::default(), Contacts::default());
        let gravity = DVec2::new(0.0, -10.0);
        set.set_gravity(gravity);
        for step in 0..steps {
            for &(k, at) in &landings {
                if at == step {
                    bodies[movers[k % movers.len()] as usize].vel = DVec2::ZERO;
                }
            }
            set.update(&mut contacts, &bodies, 1, &resolving, &movers, dt);
            let falling = set.falls;
            let kept: Vec<(u32, u32)> = contacts.pairs.iter().map(|p| (p.a, p.b)).collect();
            prop_assert!(kept.windows(2).all(|w| w[0] < w[1]), "sorted, unique");
            // Where each body goes this step: at its velocity after gravity's gain.
            let mut ahead = bodies.clone();
            for b in ahead.iter_mut().filter(|b| !b.is_static()) {
                b.vel += gravity * dt;
            }
            for pair in meeting(&ahead, &resolving, dt, true) {
                prop_assert!(
                    kept.binary_search(&pair).is_ok(),
                    "step {step}: {pair:?} meets within the step but is no candidate \
                     (frame {:?}, falling {falling})",
                    set.frame_velocity,
                );
            }
            fall(&mut bodies, gravity, dt);
            set.advance(dt);
        }
    }
}

/// A rain of 400 boxes in free fall for a second: the frame falls with it, and a box is
/// placed again only as the frame's speed outgrows the travel its box allowed a body
/// stopped dead (about as often as that speed doubles); a frame that moves at a fixed
/// velocity, as under the chapter's rule (acceleration scaled by inverse mass, where the
/// frame never falls), left every box behind every few steps and placed all of them again
/// (6 000 placements in 60 steps, 800 in a falling frame).
#[test]
fn a_rain_in_free_fall_keeps_its_boxes_in_a_falling_frame() {
    let dt = 1.0 / 60.0;
    let gravity = DVec2::new(0.0, -10.0);
    let placed_again = |mass_scaled: bool| -> (u64, bool) {
        let mut bodies: Vec<Body> = (0..400u32)
            .map(|k| {
                body(
                    k,
                    (k % 20) as f64 * 0.6,
                    (k / 20) as f64 * 0.6,
                    0.5,
                    0.5,
                    1.0,
                    0,
                )
            })
            .collect();
        let movers: Vec<u32> = (0..bodies.len() as u32).collect();
        let (mut set, mut contacts) = (PairSet::default(), Contacts::default());
        set.set_acceleration(gravity, mass_scaled, 1);
        set.update(&mut contacts, &bodies, 1, &[(0, 0)], &movers, dt);
        let placed = set.reinserted + set.placed_whole;
        let mut fell = false;
        for _ in 0..60 {
            fall(&mut bodies, gravity, dt);
            set.advance(dt);
            set.update(&mut contacts, &bodies, 1, &[(0, 0)], &movers, dt);
            fell |= set.falls;
        }
        (set.reinserted + set.placed_whole - placed, fell)
    };
    let (falling, fell) = placed_again(false);
    let (fixed, scaled_fell) = placed_again(true);
    assert!(fell, "the frame falls with the rain");
    assert!(!scaled_fell, "the frame falls under the chapter's rule");
    assert!(
        falling * 4 <= fixed,
        "{falling} boxes placed again in a falling frame, {fixed} in one that does not fall"
    );
}

/// A body nothing accelerates flies straight along its sweep of eight steps: a fast one's
/// box is grown every way by two steps' share of its travel, as a body gravity pulls
/// (turned aside, it leaves its box and is placed again); a slow one's, whose eight steps'
/// share is less than a quarter of its size, by eight.
#[test]
fn a_fast_body_flying_straight_gets_two_steps_room_sideways() {
    let dt = 1.0 / 60.0;
    let room = |gravity: DVec2, speed: f64| {
        // Two bodies at rest far off keep the frame at rest (the median velocity).
        let bodies = vec![
            Body {
                vel: DVec2::new(speed, 0.0),
                ..body(0, 0.0, 0.0, 0.5, 0.5, 1.0, 0)
            },
            body(1, 500.0, 0.0, 0.5, 0.5, 1.0, 0),
            body(2, -500.0, 0.0, 0.5, 0.5, 1.0, 0),
        ];
        let (mut set, mut contacts) = (PairSet::default(), Contacts::default());
        set.set_gravity(gravity);
        set.update(&mut contacts, &bodies, 1, &[(0, 0)], &[0, 1, 2], dt);
        assert_eq!(set.frame_velocity, DVec2::ZERO);
        // Behind the body (its sweep goes ahead): what it is grown by every way.
        -0.25 - set.fat[0].min.x
    };
    // A share of the travel of `steps` steps and a quarter of the half size.
    let grown = |steps: f64, speed: f64| steps * speed * dt * frame::SIDEWAYS + 0.25 * 0.25;
    let fast = room(DVec2::ZERO, 60.0);
    assert!((fast - grown(2.0, 60.0)).abs() < 1e-9, "grown by {fast}");
    let slow = room(DVec2::ZERO, 1.0);
    assert!(
        (slow - grown(8.0, 1.0)).abs() < 1e-9,
        "grown by {slow} at 1 u/s"
    );
    let pulled = room(DVec2::new(0.0, -10.0), 60.0);
    assert!(
        (pulled - grown(2.0, 60.0)).abs() < 1e-9,
        "grown by {pulled} under gravity"
    );
}
