//! What one world may hold and what one step may cost: the bound on everything a scene
//! file or a client can ask for, so that no input exhausts memory or freezes the clock.
//!
//! In: the defaults below, a ceiling set by whoever runs the engine (the server's
//! `--limit NAME=VALUE`), and a scene's `[limits]` table, which may lower the ceiling but
//! never raise it. Out: [`Limits`], checked by every way of adding to a world (scene
//! loading, actions, emitters) and by every change of setting ([`World::work_estimate`]).

use serde::{Deserialize, Serialize};

use crate::dynamics::broad_phase::BroadPhase;
use crate::dynamics::config::WorldConfig;

use super::{Side, World, PARTICLE_GRID_MIN_SHAPES};

/// A world's limits. Every count is a maximum; [`Limits::default`] gives the defaults
/// documented on each field, which every shipped scene fits.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct Limits {
    /// Rigid bodies, static ones included (default 100 000).
    pub bodies: u32,
    /// Particles alive plus particles still to come from emitters (default 2 000 000).
    pub particles: u32,
    /// Emitters running at once (default 1 000).
    pub emitters: u32,
    /// Groups of bodies (default 1 000; never more than 65 535).
    pub groups: u32,
    /// Declared interactions (default 1 000).
    pub interactions: u32,
    /// Particle presets (default 256).
    pub presets: u32,
    /// Random terms of one preset number, `rand = [c1, c2, ..]` (default 16).
    pub rand_terms: u32,
    /// Particles one action may spawn or one emitter may hold (default 100 000).
    pub particles_per_action: u32,
    /// Estimated work of one step, in pair tests (default 1e8, about a second of this
    /// machine's time at the solvers' measured cost per contact and pass); a setting or a
    /// scene whose estimate exceeds it is refused. See [`World::work_estimate`].
    pub step_work: f64,
    /// Bytes of one command from the network, `load` text included (default 65 536).
    pub command_bytes: u32,
}

impl Default for Limits {
    fn default() -> Self {
        Limits {
            bodies: 100_000,
            particles: 2_000_000,
            emitters: 1_000,
            groups: 1_000,
            interactions: 1_000,
            presets: 256,
            rand_terms: 16,
            particles_per_action: 100_000,
            step_work: 1e8,
            command_bytes: 65_536,
        }
    }
}

/// `step_work` of [`Limits::real_time`]: the estimate of a step that takes about one 60 Hz
/// frame (16.7 ms) on the reference machine (a 2 vCPU Xeon). The worst step of every
/// shipped scene whose estimate is above 10 000 units took 2 to 17 ns per unit of
/// estimate there (`step_work_against_measured_time` in `tests/limits.rs` prints them).
pub const REAL_TIME_STEP_WORK: f64 = 1e6;

/// A refused limit, or a world that would exceed one.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LimitError {
    #[error("limit `{name}`: {reason}")]
    Invalid { name: String, reason: String },
    #[error("over the world's limit of {limit} {what} (limits.{name})")]
    Exceeded {
        name: &'static str,
        what: &'static str,
        limit: f64,
    },
}

impl LimitError {
    pub fn exceeded(name: &'static str, what: &'static str, limit: impl Into<f64>) -> Self {
        LimitError::Exceeded {
            name,
            what,
            limit: limit.into(),
        }
    }
}

impl Limits {
    /// The names of the limits, as `[limits]` and `--limit` spell them: the fields of
    /// [`Limits`], in alphabetical order.
    pub fn names() -> Vec<String> {
        toml::Table::try_from(Limits::default())
            .expect("limits serialise")
            .keys()
            .cloned()
            .collect()
    }

    /// The limits of a world run against the clock: [`Limits::default`] with a step's
    /// estimated work at most about a frame's time ([`REAL_TIME_STEP_WORK`]), so no
    /// setting, scene or spawn accepted makes the world fall behind real time. Every
    /// shipped scene fits them.
    pub fn real_time() -> Limits {
        Limits {
            step_work: REAL_TIME_STEP_WORK,
            ..Limits::default()
        }
    }

    /// No limit worth the name: for trusted local measurement (benchmarks, trade-off
    /// reports), never for a world a network peer can reach.
    pub fn unbounded() -> Limits {
        Limits {
            bodies: u32::MAX,
            particles: u32::MAX,
            emitters: u32::MAX,
            groups: u16::MAX as u32,
            interactions: u32::MAX,
            presets: u32::MAX,
            rand_terms: u32::MAX,
            particles_per_action: u32::MAX,
            step_work: f64::INFINITY,
            command_bytes: u32::MAX,
        }
    }

    /// Checks the values: every count at least 1 (`groups` at most 65 535), the work a
    /// positive number.
    pub fn validate(&self) -> Result<(), LimitError> {
        let invalid = |name: &str, reason: String| {
            Err(LimitError::Invalid {
                name: name.to_string(),
                reason,
            })
        };
        if self.step_work.is_nan() || self.step_work <= 0.0 {
            return invalid("step_work", format!("{} must be above 0", self.step_work));
        }
        if !(1..=u16::MAX as u32).contains(&self.groups) {
            return invalid("groups", format!("{} must be 1 to 65535", self.groups));
        }
        for (name, v) in [
            ("bodies", self.bodies),
            ("particles", self.particles),
            ("emitters", self.emitters),
            ("interactions", self.interactions),
            ("presets", self.presets),
            ("rand_terms", self.rand_terms),
            ("particles_per_action", self.particles_per_action),
            ("command_bytes", self.command_bytes),
        ] {
            if v == 0 {
                return invalid(name, "must be at least 1".into());
            }
        }
        Ok(())
    }

    /// The first limit of `self` above `ceiling`'s, if any: (name, asked, ceiling).
    pub fn above(&self, ceiling: &Limits) -> Option<(&'static str, f64, f64)> {
        let pairs = [
            ("bodies", self.bodies as f64, ceiling.bodies as f64),
            ("particles", self.particles as f64, ceiling.particles as f64),
            ("emitters", self.emitters as f64, ceiling.emitters as f64),
            ("groups", self.groups as f64, ceiling.groups as f64),
            (
                "interactions",
                self.interactions as f64,
                ceiling.interactions as f64,
            ),
            ("presets", self.presets as f64, ceiling.presets as f64),
            (
                "rand_terms",
                self.rand_terms as f64,
                ceiling.rand_terms as f64,
            ),
            (
                "particles_per_action",
                self.particles_per_action as f64,
                ceiling.particles_per_action as f64,
            ),
            ("step_work", self.step_work, ceiling.step_work),
            (
                "command_bytes",
                self.command_bytes as f64,
                ceiling.command_bytes as f64,
            ),
        ];
        pairs.into_iter().find(|(_, asked, max)| asked > max)
    }

    /// Applies `NAME=VALUE` assignments (the server's `--limit`), each checked and named
    /// when refused.
    pub fn with(&self, assignments: &[String]) -> Result<Limits, LimitError> {
        let mut limits = self.clone();
        for assignment in assignments {
            let (name, value) = assignment
                .split_once('=')
                .ok_or_else(|| LimitError::Invalid {
                    name: short(assignment, 64),
                    reason: "expected NAME=VALUE".into(),
                })?;
            let (name, value) = (name.trim(), value.trim());
            let invalid = |reason: String| LimitError::Invalid {
                name: short(name, 64),
                reason,
            };
            let names = Limits::names();
            if !names.iter().any(|n| n == name) {
                return Err(invalid(format!("unknown (known: {})", names.join(", "))));
            }
            let value: toml::Value = format!("v = {value}")
                .parse::<toml::Table>()
                .ok()
                .and_then(|mut t| t.remove("v"))
                .ok_or_else(|| invalid(format!("`{}` is not a number", short(value, 64))))?;
            let mut table = toml::Table::try_from(&limits).expect("limits serialise");
            table.insert(name.to_string(), value);
            limits = toml::Value::Table(table)
                .try_into()
                .map_err(|e: toml::de::Error| invalid(e.message().to_string()))?;
        }
        limits.validate()?;
        Ok(limits)
    }
}

/// Pair tests a broad phase is expected to hand over per body: the grid and the sweep
/// find each body's neighbours, a handful in a pile.
const NEIGHBOURS_PER_BODY: f64 = 4.0;

impl World {
    /// The estimated work of one step under `config`, in pair tests: for each declared
    /// interaction, the candidate pairs its broad phase yields (every pair for the
    /// chapter's all-pairs test, a few per body for the sweep and the grid, never more
    /// than every pair) times the
    /// solver's passes over them (all sub-steps), plus every particle against the shapes
    /// it may touch, plus one unit per body and particle moved. An upper estimate used to
    /// refuse settings and scenes that would stall the world, not a measured figure.
    pub fn work_estimate(&self, config: &WorldConfig) -> f64 {
        self.work_with(config, 0.0)
    }

    /// [`World::work_estimate`] with `more_particles` particles besides the world's.
    fn work_with(&self, config: &WorldConfig, more_particles: f64) -> f64 {
        let passes = config.passes_per_step() as f64;
        let size = |side: Side| match side {
            Side::Group(g) => self.groups[g as usize].members.len() as f64,
            Side::Particles => 0.0,
        };
        let particles = more_particles
            + self.particles.len() as f64
            + self
                .emitters
                .iter()
                .map(|e| e.remaining as f64)
                .sum::<f64>();
        let mut work = self.bodies.len() as f64 + particles;
        for inter in &self.interactions {
            match (inter.a, inter.b) {
                (Side::Particles, other) | (other, Side::Particles) => {
                    let shapes = size(other);
                    let per_particle = if shapes >= PARTICLE_GRID_MIN_SHAPES as f64 {
                        NEIGHBOURS_PER_BODY
                    } else {
                        shapes
                    };
                    work += particles * per_particle;
                }
                (a, b) => {
                    let (na, nb) = (size(a), size(b));
                    let all = if a == b {
                        na * (na - 1.0).max(0.0) / 2.0
                    } else {
                        na * nb
                    };
                    let pairs = match config.broad_phase {
                        BroadPhase::AllPairs => all,
                        _ if a == b => all.min(na * NEIGHBOURS_PER_BODY),
                        _ => all.min((na + nb) * NEIGHBOURS_PER_BODY),
                    };
                    work += pairs * if inter.resolve { passes } else { 1.0 };
                }
            }
        }
        work
    }

    /// Refuses `config` if a step under it would cost more than the world's work limit.
    pub fn check_work(&self, config: &WorldConfig) -> Result<(), LimitError> {
        self.check_work_with(config, 0)
    }

    /// Refuses `n` more particles (a spawn's, an emitter's to come) if a step with them
    /// would cost more than the world's work limit: particles are priced like settings.
    pub(super) fn check_work_with(
        &self,
        config: &WorldConfig,
        more_particles: u64,
    ) -> Result<(), LimitError> {
        let work = self.work_with(config, more_particles as f64);
        if work > self.limits.step_work {
            return Err(LimitError::Invalid {
                name: "step_work".into(),
                reason: format!(
                    "a step would cost about {work:.3e} pair tests, over the world's limit of {:.3e}",
                    self.limits.step_work
                ),
            });
        }
        Ok(())
    }
}

/// `text` with its control characters escaped (ESC as `\u{1b}`, a newline as `\n`), cut
/// to at most `max` bytes (on a character boundary), with "…" when cut: how refused
/// input and names are echoed in replies, events and logs, so none can move a
/// terminal's cursor or forge a log line.
pub fn short(text: &str, max: usize) -> String {
    let escaped;
    let text = if text.chars().any(char::is_control) {
        escaped = text
            .chars()
            .map(|c| {
                if c.is_control() {
                    c.escape_default().to_string()
                } else {
                    c.to_string()
                }
            })
            .collect::<String>();
        escaped.as_str()
    } else {
        text
    };
    if text.len() <= max {
        return text.to_string();
    }
    let mut end = max;
    while !text.is_char_boundary(end) {
        end -= 1;
    }
    format!("{}…", &text[..end])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn assignments_set_limits_by_name_and_refuse_nonsense() {
        let l = Limits::default()
            .with(&["bodies=10".into(), "step_work=2e6".into()])
            .unwrap();
        assert_eq!(l.bodies, 10);
        assert_eq!(l.step_work, 2e6);
        assert_eq!(l.particles, Limits::default().particles);
        for bad in ["bodies=0", "nope=3", "bodies=-1", "groups=70000", "bodies"] {
            let e = Limits::default()
                .with(&[bad.into()])
                .unwrap_err()
                .to_string();
            let name = bad.split('=').next().unwrap();
            assert!(e.contains(name), "{bad}: {e}");
        }
        // The names are the fields: each one can be set, and an unknown one lists them.
        let names = Limits::names();
        assert_eq!(names.len(), 10, "{names:?}");
        for name in &names {
            Limits::default()
                .with(&[format!("{name}=7")])
                .unwrap_or_else(|e| panic!("{name}: {e}"));
        }
        let e = Limits::default().with(&["nope=1".into()]).unwrap_err();
        assert!(e.to_string().contains(&names.join(", ")), "{e}");
    }

    #[test]
    fn a_limit_above_the_ceiling_is_named() {
        let ceiling = Limits::default();
        let mut asked = ceiling.clone();
        assert_eq!(asked.above(&ceiling), None);
        asked.emitters = ceiling.emitters + 1;
        assert_eq!(asked.above(&ceiling).map(|a| a.0), Some("emitters"));
    }

    #[test]
    fn short_cuts_on_a_character_boundary() {
        assert_eq!(short("abc", 5), "abc");
        assert_eq!(short("abcdef", 3), "abc…");
        assert_eq!(short("ééé", 3), "é…");
    }

    #[test]
    fn short_escapes_control_characters() {
        assert_eq!(short("a\x1b[2Jb\r\nc", 64), "a\\u{1b}[2Jb\\r\\nc");
        assert!(!short("\x1b]0;owned\x07", 64).chars().any(char::is_control));
    }
}
