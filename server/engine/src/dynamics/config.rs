//! Every world-wide knob in one place, documented field by field: the `[world]` table of a
//! scene, and through [`super::setting::Setting`] the `--set NAME=VALUE` overrides of a
//! headless run and the `set` action, all checked by [`WorldConfig::validate`].

use glam::DVec2;
use serde::{Deserialize, Serialize};

/// How positions and velocities advance over one step ("Movement").
#[derive(
    Clone,
    Copy,
    Debug,
    Default,
    PartialEq,
    Eq,
    Serialize,
    Deserialize,
    strum::IntoStaticStr,
    schemars::JsonSchema,
)]
#[serde(rename_all = "snake_case")]
#[strum(serialize_all = "snake_case")]
pub enum Integrator {
    /// Symplectic (semi-implicit) Euler: `v += a dt; p += v_new dt`. The chapter's choice.
    #[default]
    Symplectic,
    /// Explicit Euler: `p += v_old dt; v += a dt`. Kept for comparison: it gains energy.
    /// Under the impulse solver a body a contact pushed in the step moves as symplectic
    /// Euler (its contact set its velocity).
    Explicit,
    /// Exact for constant acceleration: `p += v_old dt + a dt²/2; v += a dt`. A body in
    /// flight follows the closed form to rounding; under the impulse solver a body that a
    /// contact pushed in the step moves as symplectic Euler (its contact set its velocity).
    Exact,
}

impl Integrator {
    /// The name scenes and settings use (as serde spells it).
    pub fn name(self) -> &'static str {
        self.into()
    }

    /// The share of `a h²` a step of `h` adds to the position beyond `v_old h`, for the
    /// integrators that are not symplectic Euler (which adds all of it): explicit Euler
    /// none, the closed form a half. None for symplectic Euler.
    pub fn gravity_share(self) -> Option<f64> {
        match self {
            Integrator::Symplectic => None,
            Integrator::Explicit => Some(0.0),
            Integrator::Exact => Some(0.5),
        }
    }
}

/// How rigid collisions are resolved.
#[derive(
    Clone,
    Copy,
    Debug,
    Default,
    PartialEq,
    Eq,
    Serialize,
    Deserialize,
    strum::IntoStaticStr,
    schemars::JsonSchema,
)]
#[serde(rename_all = "snake_case")]
#[strum(serialize_all = "snake_case")]
pub enum Solver {
    /// The chapter's relaxation: each interaction in turn runs up to
    /// `relaxation_iterations` passes of projection, friction and impulse.
    Relaxation,
    /// Sequential impulses over the contacts of every interaction at once, with
    /// accumulated, clamped impulses, Coulomb friction, warm starting from the previous
    /// step and a Baumgarte position bias (in the manner of Box2D's contact solver).
    #[default]
    Impulses,
}

impl Solver {
    /// The name scenes and settings use (as serde spells it).
    pub fn name(self) -> &'static str {
        self.into()
    }
}

/// The chapter's positional correction rate, used when a value outside (0, 1) is given.
pub const DEFAULT_CORRECTION_RATE: f64 = 0.8;
/// The chapter's relaxation count.
pub const DEFAULT_RELAXATION_ITERATIONS: u32 = 15;
/// The time step's range in seconds: below it a real-time server would step faster than
/// any clock can pace, above it a step is no longer a step.
pub const DT_RANGE: std::ops::RangeInclusive<f64> = 1e-5..=1.0;
/// Solver passes one step may run at most, all sub-steps together.
pub const MAX_PASSES_PER_STEP: u64 = 100_000;
/// Threads a world may step on at most.
pub const MAX_THREADS: u32 = 64;
/// The largest acceleration component a world accepts (units/s²).
pub const MAX_ACCELERATION: f64 = 1e9;

/// World parameters. The default holds every kind of scene (see its `Default`);
/// [`WorldConfig::chapter`] is the chapter's relaxation.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct WorldConfig {
    /// Acceleration applied to rigid bodies that do not override it (units/s²).
    #[schemars(with = "[f64; 2]")]
    pub gravity: DVec2,
    /// Acceleration applied to particles that do not override it (units/s²).
    #[schemars(with = "[f64; 2]")]
    pub particle_gravity: DVec2,
    /// The fixed time step in seconds.
    pub dt: f64,
    /// Upper bound of relaxation iterations per interaction per step (at least 1).
    pub relaxation_iterations: u32,
    /// Fraction of the penetration depth removed per relaxation iteration, in (0, 1).
    pub correction_rate: f64,
    /// Seed of the world's one random generator.
    pub seed: u64,
    /// Movement integrator.
    pub integrator: Integrator,
    /// The chapter scales a body's acceleration by its inverse mass (a body of mass 2
    /// falls at half the rate). Physically classical scenes turn this off.
    pub mass_scaled_acceleration: bool,
    /// The world's extent, lower-left and upper-right corners: the viewer's camera.
    #[schemars(with = "[[f64; 2]; 2]")]
    pub bounds: [DVec2; 2],
    /// How rigid collisions are resolved. A scene whose `[world]` names `"relaxation"`
    /// gets the chapter's sub-steps and broad phase ([`WorldConfig::chapter`]) for the
    /// fields it does not name.
    pub solver: Solver,
    /// How interactions find their candidate pairs.
    pub broad_phase: super::broad_phase::BroadPhase,
    /// Rigid sub-steps per frame, each of `dt / substeps` (particles step once a frame).
    pub substeps: u32,
    /// Velocity iterations of the impulse solver per sub-step.
    pub impulse_iterations: u32,
    /// Biased passes a sub-step may add after its `impulse_iterations` while its last
    /// pass still changed a contact's normal velocity by more than
    /// [`crate::dynamics::impulse::CONVERGED_CHANGE`] body sizes a second (an impact
    /// travelling down a pile): resting scenes run none, and each added pass is counted.
    /// 0: always exactly `impulse_iterations`.
    pub adaptive_iterations: u32,
    /// Start the impulse solver from the previous step's impulses.
    pub warm_starting: bool,
    /// Share of the penetration (beyond `slop`) the impulse solver removes per second per
    /// `1 / dt` (Baumgarte factor), in [0, 1].
    pub baumgarte: f64,
    /// Penetration the impulse solver leaves alone, relative to the smaller body's size.
    pub slop: f64,
    /// Velocity passes of the impulse solver per sub-step without position bias, after
    /// the positions move: they take back the velocity the bias added (Box2D v3's relax
    /// iterations), so pushing out does not make bodies jump.
    pub relax_iterations: u32,
    /// Velocity passes the impulse solver spends, before the first step of a world
    /// (frame 0), on the impulses that hold the scene's resting contacts: one frame solved
    /// with this many iterations whose impulses are kept and whose motion is dropped, so the
    /// first step starts warm instead of letting a pile sag while warm starting catches up.
    /// 0: none.
    pub settle_iterations: u32,
    /// Velocity passes of the impulse solver per sub-step during the first `start_frames`
    /// frames of a world (from frame 0, after a load or reset), when more than
    /// `impulse_iterations` (0: none). A pile placed at rest has no impulses to warm-start
    /// from; a few passes a frame carry its load down only over many frames, and it sags
    /// meanwhile (the 100-level pyramid's apex by half a box). Solving the first frames to
    /// convergence costs those frames, not the run's.
    pub start_iterations: u32,
    /// Frames `start_iterations` lasts.
    pub start_frames: u32,
    /// The impulse solver starts the first frame of a world (frame 0) from the load each
    /// touching contact carries at rest: every body's weight passed down, from the highest
    /// body to the ground, through the contacts that hold it up, split by the width they
    /// share. A pile placed at rest then starts as a converged solve would leave it,
    /// whatever its height or mass ratios, in one sweep instead of many passes.
    pub rest_load: bool,
    /// Under gravity, the impulse solver ends each sub-step's passes with one sweep over
    /// the contacts that hold a body up, from the lowest body to the highest, each
    /// stopping its upper body from moving into its lower one, the lower taken as fixed
    /// (shock propagation, after Guendelman, Bridson and Fedkiw): what the passes left of
    /// a pile's approach does not sink it. A pile formed at run time (a column dropped
    /// box by box, a rain, a heavy box on a bed) then holds however deep.
    pub shock_propagation: bool,
    /// Without gravity, the impulse solver ends each sub-step's passes by moving the
    /// bodies a heavy body (100 times a body it strikes, or more) drives into each other
    /// on as one, along their momentum: the passes carry its push down a file of light
    /// bodies one contact a pass, halving it at each, and the file runs into itself.
    pub impact_propagation: bool,
    /// Under gravity, the impulse solver moves a body that friction slows on what holds it
    /// up by its mean velocity over the sub-step instead of the velocity at its end, and
    /// one that friction stops within the sub-step as far as it slides before it stops: a
    /// body sliding to rest stops at `v^2 / (2 mu g)`, where symplectic Euler alone stops
    /// it short by `v h / 2` (4% at 1 u/s, friction 0.5, the default step). A body friction
    /// holds at rest, and friction against walls and in blows, are left as they are.
    pub exact_sliding: bool,
    /// 0: rigid contacts pushed out by `baumgarte`. Above 0: soft contacts, springs of
    /// this frequency in Hz (capped at a quarter of the sub-step rate; twice it against
    /// static bodies), damped by `contact_damping` (Box2D v3's soft step).
    pub contact_hertz: f64,
    /// Damping ratio of soft contacts (above 1: no overshoot).
    pub contact_damping: f64,
    /// Rigid contacts push overlapping bodies apart through pseudo-velocities that move
    /// positions and are then dropped (split impulses), so pushing out adds no momentum.
    pub split_impulses: bool,
    /// Continuous collision for the relaxation solver: a body that moves more than half
    /// its size in a step is swept against the shapes of its interactions and stopped at
    /// the first it would pass through (the impulse solver's speculative contacts already
    /// do this).
    pub ccd: bool,
    /// Let bodies at rest sleep: an island of touching dynamic bodies that all moved slower
    /// than `sleep_speed` for `sleep_delay` seconds stops being integrated and is seen as
    /// static by the solvers until something moving touches it. An island that touches no
    /// static body and has no gravity sleeps only if its centre of mass is still (slower
    /// than a hundredth of `sleep_speed`): a body drifting freely keeps its momentum. On
    /// by default, off under the chapter's relaxation.
    pub sleeping: bool,
    /// Speed below which a body counts as at rest (units/s). A body at rest also stays
    /// within `sleep_speed * sleep_delay` of its recent places, measured in its own sizes
    /// if it is smaller than a unit, unless it is jammed: overlapped by more than a fifth
    /// of a percent of its size, its overlaps opening no faster than twice `sleep_speed`,
    /// nothing accelerating it (a crowd packed past what its container holds). A crowd
    /// whose overlaps open slower than that sleeps as overlapped as it is: lower
    /// `sleep_speed` to have it opened first.
    pub sleep_speed: f64,
    /// Seconds at rest before an island sleeps.
    pub sleep_delay: f64,
    /// Threads a step may use (1: the calling thread only). The particle passes (motion,
    /// and meeting the shapes) and, in worlds of 1024 moving bodies or more with 8192
    /// contacts or more, the impulse solver's contact search, its passes over contacts in
    /// blocks and the work around them (ordering the supports, exact sliding, storing) are
    /// split among them; the results are the same bits whatever the count (each particle is
    /// its own work; blocks touch disjoint bodies). The support and impact sweeps, the
    /// broad phase and the relaxation solver run on one.
    pub threads: u32,
    /// The accuracy the scene asks for instead of solver knobs: the worst position error
    /// of its dynamic bodies over a measured run against a converged reference, in scene
    /// units. The engine does not read it: `ricochet-server run` and `simulate` measure the
    /// scene under candidate settings and run it under the cheapest that meets it
    /// (docs/tradeoff/README.md).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub accuracy: Option<f64>,
}

impl WorldConfig {
    /// The chapter's solver: its relaxation, one step at a time, candidates by sweep (the
    /// chapter tests every pair; the sweep finds the same contacts in the same order),
    /// every body stepped (no sleeping).
    /// What a scene gets when its `[world]` names `solver = "relaxation"`: the fields it
    /// names over these.
    pub fn chapter() -> Self {
        WorldConfig {
            solver: Solver::Relaxation,
            broad_phase: super::broad_phase::BroadPhase::Sweep,
            substeps: 1,
            sleeping: false,
            ..WorldConfig::default()
        }
    }
}

/// The default holds every kind of scene of the suite (`assets/scenes/suite/`, each
/// against its criteria; docs/engine.md says why each part is there): the impulse solver
/// at 2 sub-steps of 2 passes, pushing overlaps out by split impulses, its first frame
/// started from the resting load, candidates from the persistent grid, islands at rest
/// asleep. The world's facts
/// (gravity, time step, bounds, the chapter's relaxation count and correction rate) are
/// the chapter's.
impl Default for WorldConfig {
    fn default() -> Self {
        WorldConfig {
            gravity: DVec2::new(0.0, -50.0),
            particle_gravity: DVec2::new(0.0, -50.0),
            dt: 1.0 / 60.0,
            relaxation_iterations: DEFAULT_RELAXATION_ITERATIONS,
            correction_rate: DEFAULT_CORRECTION_RATE,
            seed: 1,
            integrator: Integrator::Symplectic,
            mass_scaled_acceleration: true,
            bounds: [DVec2::ZERO, DVec2::new(200.0, 112.5)],
            solver: Solver::Impulses,
            broad_phase: super::broad_phase::BroadPhase::Grid,
            substeps: 2,
            impulse_iterations: 2,
            adaptive_iterations: 6,
            warm_starting: true,
            baumgarte: 0.2,
            // A pile formed by falling rests each contact this deep: 1e-3 left a dropped
            // box on a 20-box stack 0.021 low.
            slop: 0.0001,
            relax_iterations: 0,
            settle_iterations: 0,
            start_iterations: 0,
            start_frames: 20,
            rest_load: true,
            shock_propagation: true,
            impact_propagation: true,
            exact_sliding: true,
            contact_hertz: 0.0,
            contact_damping: 10.0,
            split_impulses: true,
            ccd: false,
            sleeping: true,
            sleep_speed: 0.05,
            sleep_delay: 0.5,
            threads: 1,
            accuracy: None,
        }
    }
}

/// A refused parameter: which one and why.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ConfigError {
    #[error("unknown world parameter `{0}` (known: {known})", known = super::setting::Setting::NAMES.join(", "))]
    UnknownName(String),
    #[error("world parameter `{name}`: {reason}")]
    Invalid { name: String, reason: String },
}

impl ConfigError {
    pub fn invalid(name: &str, reason: impl Into<String>) -> ConfigError {
        ConfigError::Invalid {
            name: name.to_string(),
            reason: reason.into(),
        }
    }
}

fn invalid(name: &str, reason: impl Into<String>) -> ConfigError {
    ConfigError::invalid(name, reason)
}

impl WorldConfig {
    /// The chapter's setter: a rate outside (0, 1) becomes 0.8. Non-finite is refused.
    pub fn set_correction_rate(&mut self, rate: f64) -> Result<(), ConfigError> {
        if !rate.is_finite() {
            return Err(invalid(
                "correction_rate",
                format!("{rate} is not a finite number"),
            ));
        }
        self.correction_rate = if rate <= 0.0 || rate >= 1.0 {
            tracing::warn!(
                rate,
                "correction_rate outside (0, 1): using 0.8, as the chapter does"
            );
            DEFAULT_CORRECTION_RATE
        } else {
            rate
        };
        Ok(())
    }

    /// The chapter's setter: a count below 1 becomes 1 (and above 10 000 is refused by
    /// [`WorldConfig::validate`]).
    pub fn set_relaxation_iterations(&mut self, count: i64) {
        self.relaxation_iterations = count.clamp(1, u32::MAX as i64) as u32;
    }

    /// Sets the time step; it must be a number in [`DT_RANGE`].
    pub fn set_dt(&mut self, dt: f64) -> Result<(), ConfigError> {
        if !DT_RANGE.contains(&dt) {
            return Err(invalid(
                "dt",
                format!(
                    "{dt} must be a number from {} to {} seconds",
                    DT_RANGE.start(),
                    DT_RANGE.end()
                ),
            ));
        }
        self.dt = dt;
        Ok(())
    }

    /// Solver passes one step runs at most: sub-steps times the passes of each. Under
    /// the impulse solver the first step also runs the settle solve (sub-steps times
    /// `settle_iterations`), so the worst step, and with it the work a scene or a
    /// setting is priced at, counts it.
    pub fn passes_per_step(&self) -> u64 {
        self.substeps as u64
            * match self.solver {
                Solver::Relaxation => self.relaxation_iterations as u64,
                Solver::Impulses => {
                    self.impulse_iterations.max(self.start_iterations) as u64
                        + self.adaptive_iterations as u64
                        + self.relax_iterations as u64
                        + self.settle_iterations as u64
                }
            }
    }

    /// The impulse solver's biased passes per sub-step at `frame`.
    pub fn impulse_iterations_at(&self, frame: u64) -> u32 {
        if frame < u64::from(self.start_frames) {
            self.impulse_iterations.max(self.start_iterations)
        } else {
            self.impulse_iterations
        }
    }

    /// Checks a whole configuration (after deserialising a scene) and applies the
    /// chapter's clamps. Returns the name of the first bad field with the reason.
    pub fn validate(&mut self) -> Result<(), ConfigError> {
        for (name, v) in [
            ("gravity", self.gravity),
            ("particle_gravity", self.particle_gravity),
        ] {
            if !(v.is_finite() && v.abs().max_element() <= MAX_ACCELERATION) {
                return Err(invalid(
                    name,
                    format!("{v} must be finite, each component within ±{MAX_ACCELERATION:e}"),
                ));
            }
        }
        self.set_dt(self.dt)?;
        self.set_correction_rate(self.correction_rate)?;
        self.set_relaxation_iterations(self.relaxation_iterations as i64);
        if self.relaxation_iterations > 10_000 {
            return Err(invalid(
                "relaxation_iterations",
                format!("{} must be at most 10000", self.relaxation_iterations),
            ));
        }
        if !(1..=1000).contains(&self.substeps) {
            return Err(invalid(
                "substeps",
                format!("{} must be 1 to 1000", self.substeps),
            ));
        }
        if !(1..=10_000).contains(&self.impulse_iterations) {
            return Err(invalid(
                "impulse_iterations",
                format!("{} must be 1 to 10000", self.impulse_iterations),
            ));
        }
        if self.adaptive_iterations > 10_000 {
            return Err(invalid(
                "adaptive_iterations",
                format!("{} must be 0 to 10000", self.adaptive_iterations),
            ));
        }
        if self.start_iterations > 100_000 || self.start_frames > 1_000_000 {
            return Err(invalid(
                "start_iterations",
                format!(
                    "{} passes for {} frames: at most 100000 passes for 1000000 frames",
                    self.start_iterations, self.start_frames
                ),
            ));
        }
        if self.settle_iterations > 100_000 {
            return Err(invalid(
                "settle_iterations",
                format!("{} must be 0 to 100000", self.settle_iterations),
            ));
        }
        if self.relax_iterations > 10_000 {
            return Err(invalid(
                "relax_iterations",
                format!("{} must be 0 to 10000", self.relax_iterations),
            ));
        }
        for (name, v) in [
            ("contact_hertz", self.contact_hertz),
            ("contact_damping", self.contact_damping),
        ] {
            if !(v.is_finite() && (0.0..=1e6).contains(&v)) {
                return Err(invalid(name, format!("{v} must be a number from 0 to 1e6")));
            }
        }
        if !(0.0..=1.0).contains(&self.baumgarte) {
            return Err(invalid(
                "baumgarte",
                format!("{} must be in [0, 1]", self.baumgarte),
            ));
        }
        let passes = self.passes_per_step();
        if passes > MAX_PASSES_PER_STEP {
            let name = match self.solver {
                Solver::Relaxation => "relaxation_iterations",
                Solver::Impulses if self.settle_iterations > self.impulse_iterations => {
                    "settle_iterations"
                }
                Solver::Impulses => "impulse_iterations",
            };
            return Err(invalid(
                name,
                format!(
                    "{passes} solver passes a step (sub-steps times passes, the first step's settle solve included) is over {MAX_PASSES_PER_STEP}"
                ),
            ));
        }
        for (name, v) in [
            ("sleep_speed", self.sleep_speed),
            ("sleep_delay", self.sleep_delay),
        ] {
            if !(v.is_finite() && (0.0..=crate::dynamics::body::MAX_COORDINATE).contains(&v)) {
                return Err(invalid(
                    name,
                    format!(
                        "{v} must be a number from 0 to {:e}",
                        crate::dynamics::body::MAX_COORDINATE
                    ),
                ));
            }
        }
        if !(1..=MAX_THREADS).contains(&self.threads) {
            return Err(invalid(
                "threads",
                format!("{} must be 1 to {MAX_THREADS}", self.threads),
            ));
        }
        if let Some(a) = self.accuracy {
            if !(a.is_finite() && a > 0.0 && a <= crate::dynamics::body::MAX_COORDINATE) {
                return Err(invalid(
                    "accuracy",
                    format!(
                        "{a} must be above 0 and at most {:e} (scene units)",
                        crate::dynamics::body::MAX_COORDINATE
                    ),
                ));
            }
        }
        if !(0.0..=1.0).contains(&self.slop) {
            return Err(invalid("slop", format!("{} must be in [0, 1]", self.slop)));
        }
        let [lo, hi] = self.bounds;
        let within = |v: DVec2| {
            v.is_finite() && v.abs().max_element() <= crate::dynamics::body::MAX_COORDINATE
        };
        if !(within(lo) && within(hi) && hi.x > lo.x && hi.y > lo.y) {
            return Err(invalid(
                "bounds",
                format!(
                    "needs two corners [[x0, y0], [x1, y1]] within ±{:e}, with x1 > x0 and y1 > y0",
                    crate::dynamics::body::MAX_COORDINATE
                ),
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_chapters_solver_has_the_chapters_defaults() {
        let c = WorldConfig::chapter();
        assert_eq!(c.solver, Solver::Relaxation);
        assert_eq!(c.substeps, 1);
        assert_eq!(c.gravity, DVec2::new(0.0, -50.0));
        assert_eq!(c.relaxation_iterations, 15);
        assert_eq!(c.correction_rate, 0.8);
        assert!((c.dt - 1.0 / 60.0).abs() < 1e-15);
        assert!(c.mass_scaled_acceleration);
    }

    #[test]
    fn setter_clamps_follow_the_chapter() {
        let mut c = WorldConfig::default();
        c.set_from_str("correction_rate=0.5").unwrap();
        assert_eq!(c.correction_rate, 0.5);
        c.set_from_str("correction_rate=1.0").unwrap();
        assert_eq!(c.correction_rate, 0.8);
        c.set_from_str("correction_rate=-2").unwrap();
        assert_eq!(c.correction_rate, 0.8);
        c.set_from_str("relaxation_iterations=0").unwrap();
        assert_eq!(c.relaxation_iterations, 1);
        c.set_from_str("relaxation_iterations=-7").unwrap();
        assert_eq!(c.relaxation_iterations, 1);
        c.set_from_str("relaxation_iterations=40").unwrap();
        assert_eq!(c.relaxation_iterations, 40);
    }

    #[test]
    fn set_parses_vectors_and_enums() {
        let mut c = WorldConfig::default();
        c.set_from_str("gravity=[0, -9.81]").unwrap();
        assert_eq!(c.gravity, DVec2::new(0.0, -9.81));
        c.set_from_str("integrator=explicit").unwrap();
        assert_eq!(c.integrator, Integrator::Explicit);
        c.set_from_str("integrator=\"symplectic\"").unwrap();
        assert_eq!(c.integrator, Integrator::Symplectic);
        c.set_from_str("mass_scaled_acceleration=false").unwrap();
        assert!(!c.mass_scaled_acceleration);
    }

    #[test]
    fn bad_values_are_refused_by_name_and_change_nothing() {
        let mut c = WorldConfig::chapter();
        let before = c.clone();
        for bad in [
            "dt=0",
            "dt=-1",
            "dt=nan",
            "dt=1e-300",
            "dt=1e300",
            "relaxation_iterations=4000000000",
            "gravity=[0, -1e300]",
            "sleep_delay=1e300",
            "gravity=[0]",
            "gravity=[inf, 0]",
            "integrator=verlet",
            "nope=1",
            "dt",
        ] {
            let e = c.set_from_str(bad).unwrap_err().to_string();
            let name = bad.split('=').next().unwrap();
            assert!(e.contains(name), "error for {bad} should name {name}: {e}");
        }
        assert_eq!(c, before);
        // Sub-steps times passes is bounded as a whole.
        c.set_from_str("substeps=1000").unwrap();
        let e = c.set_from_str("relaxation_iterations=200").unwrap_err();
        assert!(e.to_string().contains("passes"), "{e}");
        assert_eq!(c.relaxation_iterations, 15);
    }
}
