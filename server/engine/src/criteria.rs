//! What a user of a scene expects of it, stated in the scene's `[criteria]` table, and the
//! [`Monitor`] that measures a run against it: the suite of scene kinds
//! (`assets/scenes/suite/`) holds each of its scenes to these, and any scene may state its
//! own.
//!
//! ```toml
//! [criteria]
//! steps = 600                  # the run judged (default 600)
//! inside = [[0, 0], [40, 80]]  # no dynamic body's centre ever leaves this box
//! drift = 0.02                 # no dynamic body ever further than this from where it was
//!                              # built, in its own sizes (its smaller side)
//! overlap = 0.01               # no two bodies that interact ever overlap deeper than this,
//!                              # in sizes of the smaller of the two
//! final_overlap = 0.01         # the same, at the end of the run only
//! speed = 5                    # no dynamic body ever faster than this (units/s)
//! final_speed = 0.05           # the same, over the last second of the run only
//! energy_rise = 0.01           # kinetic energy never rises more than this share of its
//!                              # start above an earlier low (worlds without gravity)
//! energy_change = 0.02         # kinetic energy at the end within this share of its start
//!                              # (elastic worlds: restitution 1, no friction, no gravity)
//! stopping = 0.02              # a body built sliding on another comes to rest within this
//!                              # share of v^2 / (2 mu g) of where it started
//! ```
//!
//! Every figure is the worst over the whole run (or over its stated end); a body that
//! leaves the world's numbers (NaN, infinity) fails every criterion.

use glam::DVec2;
use serde::{Deserialize, Serialize};

use crate::dynamics::body::{Body, GroupId};
use crate::geometry::{separation, Shape};
use crate::world::{Side, World};

/// A scene's expectations; each absent criterion is not judged.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Criteria {
    /// Steps the run is judged over.
    #[serde(default = "default_steps")]
    pub steps: u64,
    /// A box (lower-left, upper-right corners) no dynamic body's centre may leave: a
    /// container's inside, or the near side of a wall.
    #[serde(default)]
    #[schemars(with = "Option<[[f64; 2]; 2]>")]
    pub inside: Option<[DVec2; 2]>,
    /// Worst distance of a dynamic body from where it was built, in its own sizes.
    #[serde(default)]
    pub drift: Option<f64>,
    /// Worst overlap of two interacting bodies, in sizes of the smaller.
    #[serde(default)]
    pub overlap: Option<f64>,
    /// Worst overlap after the last step, in sizes of the smaller body of the pair.
    #[serde(default)]
    pub final_overlap: Option<f64>,
    /// Worst speed of a dynamic body (units/s): the larger of its velocity and how far it
    /// moved in a step over the step (a push that moves positions without velocity counts).
    #[serde(default)]
    pub speed: Option<f64>,
    /// Worst speed of a dynamic body over the last second of the run (units/s).
    #[serde(default)]
    pub final_speed: Option<f64>,
    /// Worst rise of the kinetic energy above its lowest value so far, as a share of its
    /// value at the start.
    #[serde(default)]
    pub energy_rise: Option<f64>,
    /// Largest share by which the kinetic energy at the end of the run differs from its
    /// value at the start, up or down (an elastic world keeps it).
    #[serde(default)]
    pub energy_change: Option<f64>,
    /// Worst error of a stopping distance at the end of the run, as a share of the
    /// distance Coulomb friction gives, `v^2 / (2 mu g)`: judged on each dynamic body built
    /// resting on a body it interacts with (touching it, under it along gravity) and moving
    /// across gravity at `v`; `mu` is the pair's friction (the square root of the product
    /// of the two), `g` the body's gravity. The distance is its travel along its starting
    /// velocity.
    #[serde(default)]
    pub stopping: Option<f64>,
}

fn default_steps() -> u64 {
    600
}

/// No criterion stated, over the default run.
impl Default for Criteria {
    fn default() -> Self {
        Criteria {
            steps: default_steps(),
            inside: None,
            drift: None,
            overlap: None,
            final_overlap: None,
            speed: None,
            final_speed: None,
            energy_rise: None,
            energy_change: None,
            stopping: None,
        }
    }
}

/// The longest run a scene's criteria may ask for.
pub const MAX_STEPS: u64 = 1_000_000;

impl Criteria {
    /// Checks every number: the name of the first bad field and why.
    pub fn validate(&self) -> Result<(), (&'static str, String)> {
        if !(1..=MAX_STEPS).contains(&self.steps) {
            return Err(("steps", format!("{} must be 1 to {MAX_STEPS}", self.steps)));
        }
        if let Some([lo, hi]) = self.inside {
            if !(lo.is_finite() && hi.is_finite() && hi.x > lo.x && hi.y > lo.y) {
                return Err((
                    "inside",
                    "needs two finite corners [[x0, y0], [x1, y1]] with x1 > x0 and y1 > y0".into(),
                ));
            }
        }
        for (name, v) in [
            ("drift", self.drift),
            ("overlap", self.overlap),
            ("final_overlap", self.final_overlap),
            ("speed", self.speed),
            ("final_speed", self.final_speed),
            ("energy_rise", self.energy_rise),
            ("energy_change", self.energy_change),
            ("stopping", self.stopping),
        ] {
            if let Some(v) = v {
                if !(v.is_finite() && v >= 0.0) {
                    return Err((name, format!("{v} must be a finite number, 0 or above")));
                }
            }
        }
        Ok(())
    }
}

/// One criterion's verdict: the run's worst figure against the scene's limit.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Judgement {
    /// The criterion's name, as the scene spells it.
    pub name: &'static str,
    /// What the run measured (the worst over the run, or the count of bodies that left).
    pub figure: f64,
    pub limit: f64,
    pub pass: bool,
}

/// The worst figures of a run so far, measured after every step whatever the criteria
/// ask (a report shows them all), but for the overlaps: over the run only where
/// `overlap` is stated, at the end only where just `final_overlap` is.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Figures {
    /// Steps observed.
    pub steps: u64,
    /// Dynamic bodies whose centre was outside `inside` after some step.
    pub left: u64,
    pub drift: f64,
    pub overlap: f64,
    pub final_overlap: f64,
    pub speed: f64,
    pub final_speed: f64,
    pub energy_rise: f64,
    /// The kinetic energy after the last step observed against its start, as a share of
    /// the start (0 when the start had none).
    pub energy_change: f64,
    /// The worst stopping distance's error after the last step observed, as a share of the
    /// distance Coulomb friction gives (0 when no body slides as built).
    pub stopping: f64,
    /// A position or velocity stopped being a finite number.
    pub non_finite: bool,
}

/// Watches a run: [`Monitor::observe`] after every step, then [`Monitor::verdict`]. It
/// keeps its own copy of the bodies as built, so another engine's run of the same scene
/// can be judged the same way ([`Monitor::observe_dynamic`]).
#[derive(Clone, Debug)]
pub struct Monitor {
    criteria: Criteria,
    /// Every body as built; the dynamic ones are moved to where each step left them.
    bodies: Vec<Body>,
    /// The dynamic bodies' indices in `bodies` (and in the world's bodies).
    dynamic: Vec<u32>,
    /// Each dynamic body's place at the start and its size (its smaller side).
    built: Vec<(DVec2, f64)>,
    dt: f64,
    /// Which group pairs resolve (both orders), by group id.
    resolving: Vec<(GroupId, GroupId)>,
    /// Each dynamic body has left `inside` (same order as `dynamic`).
    left: Vec<bool>,
    energy: EnergyWatch,
    /// The kinetic energy as built.
    start_energy: f64,
    /// Steps in the run's last second, from the world's step.
    final_window: u64,
    /// The bodies built sliding on a support: index among the dynamic bodies, the
    /// direction of their start velocity and the distance Coulomb friction stops them in.
    sliders: Vec<Slider>,
    figures: Figures,
}

/// A body built sliding on a support, and where friction should stop it.
#[derive(Clone, Copy, Debug)]
struct Slider {
    /// Its index among the monitor's dynamic bodies.
    k: usize,
    dir: DVec2,
    distance: f64,
}

impl Monitor {
    /// Starts watching `world` as it is now (before its first step), for a run in which no
    /// body is added or removed.
    pub fn new(world: &World, criteria: &Criteria) -> Monitor {
        let bodies = world.bodies().to_vec();
        let dynamic: Vec<u32> = (0..bodies.len() as u32)
            .filter(|&i| bodies[i as usize].inv_mass > 0.0)
            .collect();
        let built = dynamic
            .iter()
            .map(|&i| {
                let b = &bodies[i as usize];
                (b.pos, b.shape.size().min_element())
            })
            .collect::<Vec<_>>();
        let mut resolving = Vec::new();
        for inter in world.interactions() {
            if let (Side::Group(a), Side::Group(b), true) = (inter.a, inter.b, inter.resolve) {
                resolving.push((a, b));
                resolving.push((b, a));
            }
        }
        let energy = world.kinetic_energy();
        let sliders = if criteria.stopping.is_some() {
            sliders(world, &dynamic, &resolving)
        } else {
            Vec::new()
        };
        let per_second = (1.0 / world.config.dt).round().max(1.0) as u64;
        Monitor {
            criteria: criteria.clone(),
            left: vec![false; built.len()],
            built,
            bodies,
            dynamic,
            dt: world.config.dt,
            resolving,
            energy: EnergyWatch::new(energy),
            start_energy: energy,
            final_window: per_second.min(criteria.steps),
            sliders,
            figures: Figures::default(),
        }
    }

    /// The dynamic bodies, as indices among the world's bodies: the order in which
    /// [`Monitor::observe_dynamic`] takes their states.
    pub fn dynamic(&self) -> &[u32] {
        &self.dynamic
    }

    /// Measures the world after a step.
    pub fn observe(&mut self, world: &World) {
        let bodies = world.bodies();
        let states: Vec<(DVec2, DVec2)> = self
            .dynamic
            .iter()
            .map(|&i| {
                let b = &bodies[i as usize];
                (b.pos, b.vel)
            })
            .collect();
        self.observe_dynamic(&states);
    }

    /// Measures a step from the dynamic bodies' positions and velocities, in the order of
    /// [`Monitor::dynamic`] (another engine's run of the scene is judged this way).
    pub fn observe_dynamic(&mut self, states: &[(DVec2, DVec2)]) {
        let f = &mut self.figures;
        f.steps += 1;
        let in_final = f.steps + self.final_window > self.criteria.steps;
        let mut energy = 0.0;
        for (k, (&(pos, vel), &i)) in states.iter().zip(&self.dynamic).enumerate() {
            let (start, size) = self.built[k];
            let body = &mut self.bodies[i as usize];
            if !(pos.is_finite() && vel.is_finite()) {
                f.non_finite = true;
                continue;
            }
            f.drift = f.drift.max((pos - start).length() / size);
            let speed = vel.length().max((pos - body.pos).length() / self.dt);
            body.pos = pos;
            body.vel = vel;
            energy += body.kinetic_energy();
            f.speed = f.speed.max(speed);
            if in_final {
                f.final_speed = f.final_speed.max(speed);
            }
            if let Some([lo, hi]) = self.criteria.inside {
                let out = pos.x < lo.x || pos.y < lo.y || pos.x > hi.x || pos.y > hi.y;
                if out && !self.left[k] {
                    self.left[k] = true;
                    f.left += 1;
                }
            }
        }
        f.energy_rise = self.energy.see(energy);
        f.energy_change = if self.start_energy > 0.0 {
            (energy - self.start_energy).abs() / self.start_energy
        } else {
            0.0
        };
        f.stopping = 0.0;
        for s in &self.sliders {
            let (start, _) = self.built[s.k];
            let pos = self.bodies[self.dynamic[s.k] as usize].pos;
            let travel = (pos - start).dot(s.dir);
            // A non-finite place fails through `non_finite`.
            let error = ((travel - s.distance) / s.distance).abs();
            if error.is_finite() {
                f.stopping = f.stopping.max(error);
            }
        }
        // The overlap costs a pass over the bodies: every step where it is judged over the
        // run, from the last stated step on where only its end is.
        let at_end = self.figures.steps >= self.criteria.steps;
        if self.criteria.overlap.is_some() || (self.criteria.final_overlap.is_some() && at_end) {
            let deepest = deepest_overlap(&self.bodies, &self.resolving);
            let f = &mut self.figures;
            f.overlap = f.overlap.max(deepest);
            f.final_overlap = deepest;
        }
    }

    /// The figures so far.
    pub fn figures(&self) -> &Figures {
        &self.figures
    }

    /// Each stated criterion against the run's figures.
    pub fn verdict(&self) -> Vec<Judgement> {
        let f = &self.figures;
        let c = &self.criteria;
        let bad = f.non_finite;
        let mut out = Vec::new();
        let mut judge = |name, figure: f64, limit: Option<f64>| {
            if let Some(limit) = limit {
                out.push(Judgement {
                    name,
                    figure,
                    limit,
                    pass: !bad && figure <= limit,
                });
            }
        };
        judge("inside", f.left as f64, c.inside.map(|_| 0.0));
        judge("drift", f.drift, c.drift);
        judge("overlap", f.overlap, c.overlap);
        judge("final_overlap", f.final_overlap, c.final_overlap);
        judge("speed", f.speed, c.speed);
        judge("final_speed", f.final_speed, c.final_speed);
        judge("energy_rise", f.energy_rise, c.energy_rise);
        judge("energy_change", f.energy_change, c.energy_change);
        judge("stopping", f.stopping, c.stopping);
        out
    }

    /// Whether every stated criterion holds.
    pub fn holds(&self) -> bool {
        self.verdict().iter().all(|j| j.pass)
    }
}

/// The deepest overlap among pairs of bodies whose groups resolve against each other, in
/// sizes of the smaller body of the pair (bodies binned in a grid of the largest
/// dynamic body's size, so the cost is near the number of bodies).
fn deepest_overlap(bodies: &[Body], resolving: &[(GroupId, GroupId)]) -> f64 {
    use std::collections::HashMap;
    let cell = bodies
        .iter()
        .filter(|b| b.inv_mass > 0.0)
        .map(|b| b.shape.size().max_element())
        .fold(0.0_f64, f64::max);
    if cell <= 0.0 || resolving.is_empty() {
        return 0.0;
    }
    let key = |p: DVec2| ((p.x / cell).floor() as i64, (p.y / cell).floor() as i64);
    // Dynamic bodies in the grid; each body (static ones too, whatever their size) then
    // looks up the cells its bounds cover.
    let mut grid: HashMap<(i64, i64), Vec<u32>> = HashMap::new();
    for (i, b) in bodies.iter().enumerate() {
        if b.inv_mass > 0.0 && b.pos.is_finite() {
            grid.entry(key(b.pos)).or_default().push(i as u32);
        }
    }
    let interacts = |a: GroupId, b: GroupId| resolving.contains(&(a, b));
    let mut deepest = 0.0_f64;
    for (i, a) in bodies.iter().enumerate() {
        if !a.pos.is_finite() {
            continue;
        }
        let h = a.shape.half_extents() + DVec2::splat(cell * 0.5);
        let (lo, hi) = (key(a.pos - h), key(a.pos + h));
        // A huge static body covering very many cells: walk the dynamic bodies instead.
        let cells = (hi.0 - lo.0 + 1).saturating_mul(hi.1 - lo.1 + 1);
        let mut visit = |j: u32| {
            let b = &bodies[j as usize];
            // Each dynamic pair once; a static body against every dynamic one.
            if (j as usize) <= i && a.inv_mass > 0.0 {
                return;
            }
            if !interacts(a.group, b.group) {
                return;
            }
            let (gap, _) = separation(&a.shape, a.pos, &b.shape, b.pos);
            if gap < 0.0 {
                deepest = deepest.max(-gap / smaller(&a.shape, &b.shape));
            }
        };
        if cells as usize > grid.len() {
            for js in grid.values() {
                js.iter().for_each(|&j| visit(j));
            }
        } else {
            for x in lo.0..=hi.0 {
                for y in lo.1..=hi.1 {
                    if let Some(js) = grid.get(&(x, y)) {
                        js.iter().for_each(|&j| visit(j));
                    }
                }
            }
        }
    }
    deepest
}

/// The worst rise of an energy above its lowest value before, as a share of its start.
#[derive(Clone, Copy, Debug)]
struct EnergyWatch {
    start: f64,
    low: f64,
    worst: f64,
}

impl EnergyWatch {
    fn new(start: f64) -> EnergyWatch {
        EnergyWatch {
            start,
            low: start,
            worst: 0.0,
        }
    }

    /// Takes the next value; returns the worst rise so far (infinite for a non-finite value).
    fn see(&mut self, energy: f64) -> f64 {
        if !energy.is_finite() {
            self.worst = f64::INFINITY;
        } else if self.start > 0.0 {
            self.worst = self.worst.max((energy - self.low) / self.start);
        }
        self.low = self.low.min(energy);
        self.worst
    }
}

/// The dynamic bodies (`dynamic`, the world's indices) built moving across their gravity
/// while resting on a body they resolve against: touching it (within a millionth of the
/// smaller's size) on its side against gravity. Each slides `v^2 / (2 mu g)` before it
/// stops, `mu` the pair's friction as the impulse solver mixes it.
fn sliders(world: &World, dynamic: &[u32], resolving: &[(GroupId, GroupId)]) -> Vec<Slider> {
    let bodies = world.bodies();
    let config = &world.config;
    let mut out = Vec::new();
    for (k, &i) in dynamic.iter().enumerate() {
        let b = &bodies[i as usize];
        let g = crate::dynamics::integrate::acceleration_under(
            b,
            config.gravity,
            config.mass_scaled_acceleration,
        );
        let Some(down) = g.try_normalize() else {
            continue;
        };
        let across = b.vel - down * b.vel.dot(down);
        let Some(dir) = across.try_normalize() else {
            continue;
        };
        let support = bodies.iter().enumerate().find(|&(j, s)| {
            if j == i as usize || !resolving.contains(&(b.group, s.group)) {
                return false;
            }
            // The normal from the support to the body points against gravity.
            let (gap, normal) = separation(&s.shape, s.pos, &b.shape, b.pos);
            gap.abs() <= 1e-6 * smaller(&s.shape, &b.shape) && normal.dot(-down) > 0.999
        });
        let Some((_, support)) = support else {
            continue;
        };
        let mu = (b.friction * support.friction).sqrt();
        if mu > 0.0 {
            out.push(Slider {
                k,
                dir,
                distance: across.length_squared() / (2.0 * mu * g.length()),
            });
        }
    }
    out
}

fn smaller(a: &Shape, b: &Shape) -> f64 {
    a.size().min_element().min(b.size().min_element())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dynamics::BodyDef;
    use crate::dynamics::WorldConfig;

    fn world(bodies: &[(DVec2, DVec2, f64)]) -> World {
        let mut w = World::new(WorldConfig {
            gravity: DVec2::ZERO,
            ..WorldConfig::default()
        });
        for (k, &(pos, vel, mass)) in bodies.iter().enumerate() {
            w.add_body(BodyDef {
                id: format!("b{k}"),
                group: "all".into(),
                pos,
                vel,
                mass,
                ..BodyDef::default()
            })
            .unwrap();
        }
        w.add_interaction("all", "all", true).unwrap();
        w
    }

    #[test]
    fn overlap_is_measured_in_sizes_of_the_smaller_body() {
        // Two unit boxes a quarter into each other, and one far away.
        let w = world(&[
            (DVec2::ZERO, DVec2::ZERO, 1.0),
            (DVec2::new(0.75, 0.0), DVec2::ZERO, 1.0),
            (DVec2::new(50.0, 0.0), DVec2::ZERO, 0.0),
        ]);
        let m = Monitor::new(&w, &Criteria::for_test());
        let d = deepest_overlap(w.bodies(), &m.resolving);
        assert!((d - 0.25).abs() < 1e-12, "{d}");
    }

    #[test]
    fn a_body_that_leaves_or_speeds_fails_and_is_counted_once() {
        let mut w = world(&[
            (DVec2::ZERO, DVec2::new(60.0, 0.0), 1.0),
            (DVec2::new(0.0, 5.0), DVec2::ZERO, 1.0),
        ]);
        let criteria = Criteria {
            steps: 30,
            inside: Some([DVec2::splat(-10.0), DVec2::splat(10.0)]),
            speed: Some(50.0),
            drift: Some(100.0),
            ..Criteria::for_test()
        };
        let mut m = Monitor::new(&w, &criteria);
        for _ in 0..30 {
            w.step();
            m.observe(&w);
        }
        let v = m.verdict();
        let get = |n| v.iter().find(|j| j.name == n).unwrap().clone();
        assert_eq!(get("inside").figure, 1.0);
        assert!(!get("inside").pass);
        assert!(!get("speed").pass);
        assert!(get("drift").pass, "{:?}", get("drift"));
        assert!(!m.holds());
    }

    /// `energy_change` is the end's kinetic energy against the start's, up or down: a
    /// body that keeps its speed holds it, one stopped by a wall loses it all.
    #[test]
    fn energy_change_compares_the_end_with_the_start() {
        let criteria = Criteria {
            steps: 60,
            energy_change: Some(0.02),
            overlap: None,
            ..Criteria::for_test()
        };
        let run = |w: &mut World| {
            let mut m = Monitor::new(w, &criteria);
            for _ in 0..60 {
                w.step();
                m.observe(w);
            }
            m
        };
        let mut free = world(&[(DVec2::ZERO, DVec2::new(3.0, 0.0), 1.0)]);
        let kept = run(&mut free);
        assert!(kept.figures().energy_change < 1e-9, "{:?}", kept.figures());
        assert!(kept.holds());
        // Into a static wall, with no bounce: stopped.
        let mut stopped = World::new(WorldConfig {
            gravity: DVec2::ZERO,
            ..WorldConfig::default()
        });
        for (id, pos, vel, mass) in [
            ("ball", DVec2::ZERO, DVec2::new(3.0, 0.0), 1.0),
            ("wall", DVec2::new(2.0, 0.0), DVec2::ZERO, 0.0),
        ] {
            stopped
                .add_body(BodyDef {
                    id: id.into(),
                    group: "all".into(),
                    pos,
                    vel,
                    mass,
                    restitution: 0.0,
                    ..BodyDef::default()
                })
                .unwrap();
        }
        stopped.add_interaction("all", "all", true).unwrap();
        let lost = run(&mut stopped);
        assert!(lost.figures().energy_change > 0.9, "{:?}", lost.figures());
        assert!(!lost.holds());
    }

    #[test]
    fn another_engines_states_are_judged_as_the_worlds() {
        let mut w = world(&[
            (DVec2::ZERO, DVec2::new(3.0, 0.0), 1.0),
            (DVec2::new(5.0, 0.0), DVec2::ZERO, 0.0),
            (DVec2::new(0.0, 5.0), DVec2::new(0.0, -1.0), 2.0),
        ]);
        let criteria = Criteria {
            speed: Some(10.0),
            drift: Some(1.0),
            ..Criteria::for_test()
        };
        let (mut mine, mut theirs) = (Monitor::new(&w, &criteria), Monitor::new(&w, &criteria));
        assert_eq!(mine.dynamic(), &[0, 2]);
        for _ in 0..60 {
            w.step();
            mine.observe(&w);
            let states: Vec<(DVec2, DVec2)> = theirs
                .dynamic()
                .iter()
                .map(|&i| (w.bodies()[i as usize].pos, w.bodies()[i as usize].vel))
                .collect();
            theirs.observe_dynamic(&states);
        }
        assert_eq!(mine.figures(), theirs.figures());
        assert!(mine.figures().drift > 0.5, "{:?}", mine.figures());
    }

    #[test]
    fn energy_rise_is_measured_above_the_low_so_far() {
        let mut e = EnergyWatch::new(4.0);
        assert_eq!(e.see(3.0), 0.0);
        assert_eq!(e.see(1.0), 0.0);
        // Back up from the low of 1 to 4: three quarters of the start.
        assert_eq!(e.see(4.0), 0.75);
        assert_eq!(e.see(2.0), 0.75);
        assert_eq!(e.see(f64::NAN), f64::INFINITY);
    }

    impl Criteria {
        fn for_test() -> Criteria {
            Criteria {
                steps: 600,
                inside: None,
                drift: None,
                overlap: Some(1.0),
                final_overlap: None,
                speed: None,
                final_speed: None,
                energy_rise: None,
                energy_change: None,
                stopping: None,
            }
        }
    }
}
