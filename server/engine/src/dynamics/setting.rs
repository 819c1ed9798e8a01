//! One world parameter as a typed value: what the `set` action, a headless run's
//! `--set NAME=VALUE` and a trade-off candidate change.
//!
//! [`Setting`] has one variant per field of [`WorldConfig`], named as the field and
//! holding its type, so a value of the wrong kind is refused when it is read, and
//! [`WorldConfig::set`] checks the range the way a scene's `[world]` table is checked.
//! In JSON and TOML a setting is `{"name": "gravity", "value": [0, -9.8]}`.

use glam::DVec2;
use serde::{Deserialize, Serialize};

use super::broad_phase::BroadPhase;
use super::config::{ConfigError, Integrator, Solver, WorldConfig};

/// How a setting's value becomes its field's (the identity but for the chapter's
/// relaxation count, read as any integer so that 0 or -3 get the chapter's clamp to 1).
trait IntoField<F> {
    fn into_field(self) -> F;
}

impl<T> IntoField<T> for T {
    fn into_field(self) -> T {
        self
    }
}

impl IntoField<u32> for i64 {
    fn into_field(self) -> u32 {
        self.clamp(1, u32::MAX as i64) as u32
    }
}

macro_rules! settings {
    ($( $variant:ident ( $ty:ty ) => $field:ident, )*) => {
        /// One world parameter and its value; each variant sets the [`WorldConfig`] field
        /// of the same name (documented there).
        #[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
        #[serde(tag = "name", content = "value", rename_all = "snake_case", deny_unknown_fields)]
        pub enum Setting {
            $( #[doc = concat!("[`WorldConfig::", stringify!($field), "`]")] $variant($ty), )*
        }

        impl Setting {
            /// Every setting's name, in [`WorldConfig`]'s order.
            pub const NAMES: &'static [&'static str] = &[$( stringify!($field), )*];

            /// The setting's name, as the field it sets.
            pub fn name(&self) -> &'static str {
                match self {
                    $( Setting::$variant(_) => stringify!($field), )*
                }
            }
        }

        impl WorldConfig {
            /// Writes the setting's value into its field, unchecked.
            fn assign(&mut self, setting: Setting) {
                match setting {
                    $( Setting::$variant(v) => self.$field = v.into_field(), )*
                }
            }

            /// `self`'s fields that `named` lists over `base`'s others (a scene's
            /// `[world]` over the defaults of the solver it names).
            pub fn named_over(&self, base: WorldConfig, named: &[&str]) -> WorldConfig {
                let mut out = base;
                for s in self.settings() {
                    if named.contains(&s.name()) {
                        out.assign(s);
                    }
                }
                out
            }

            /// Every parameter's current value, as settings.
            pub fn settings(&self) -> Vec<Setting> {
                vec![$( Setting::$variant(self.$field.clone().into()), )*]
            }
        }
    };
}

settings! {
    Gravity(DVec2) => gravity,
    ParticleGravity(DVec2) => particle_gravity,
    Dt(f64) => dt,
    RelaxationIterations(i64) => relaxation_iterations,
    CorrectionRate(f64) => correction_rate,
    Seed(u64) => seed,
    Integrator(Integrator) => integrator,
    MassScaledAcceleration(bool) => mass_scaled_acceleration,
    Bounds([DVec2; 2]) => bounds,
    Solver(Solver) => solver,
    BroadPhase(BroadPhase) => broad_phase,
    Substeps(u32) => substeps,
    ImpulseIterations(u32) => impulse_iterations,
    AdaptiveIterations(u32) => adaptive_iterations,
    WarmStarting(bool) => warm_starting,
    Baumgarte(f64) => baumgarte,
    Slop(f64) => slop,
    RelaxIterations(u32) => relax_iterations,
    SettleIterations(u32) => settle_iterations,
    StartIterations(u32) => start_iterations,
    StartFrames(u32) => start_frames,
    RestLoad(bool) => rest_load,
    ShockPropagation(bool) => shock_propagation,
    ImpactPropagation(bool) => impact_propagation,
    ExactSliding(bool) => exact_sliding,
    ContactHertz(f64) => contact_hertz,
    ContactDamping(f64) => contact_damping,
    SplitImpulses(bool) => split_impulses,
    Ccd(bool) => ccd,
    Sleeping(bool) => sleeping,
    SleepSpeed(f64) => sleep_speed,
    SleepDelay(f64) => sleep_delay,
    Threads(u32) => threads,
}

impl WorldConfig {
    /// Applies one setting, checked as a scene's `[world]` table is (the chapter's clamps
    /// included). A refused setting changes nothing and names the field.
    pub fn set(&mut self, setting: Setting) -> Result<(), ConfigError> {
        let mut next = self.clone();
        next.assign(setting);
        next.validate()?;
        *self = next;
        Ok(())
    }

    /// Parses `NAME=VALUE` (a headless run's `--set`; the value in the scene file's
    /// syntax: `[0, -9.8]`, `0.5`, `"explicit"` or `explicit`, `true`) and applies it.
    pub fn set_from_str(&mut self, assignment: &str) -> Result<(), ConfigError> {
        self.set(Setting::parse(assignment)?)
    }
}

impl Setting {
    /// Reads `NAME=VALUE`, the value in the scene file's syntax.
    pub fn parse(assignment: &str) -> Result<Setting, ConfigError> {
        let (name, value) = assignment
            .split_once('=')
            .ok_or_else(|| ConfigError::invalid(assignment, "expected NAME=VALUE"))?;
        let name = name.trim();
        if !Self::NAMES.contains(&name) {
            return Err(ConfigError::UnknownName(name.to_string()));
        }
        let value = parse_toml_value(value.trim()).map_err(|r| ConfigError::invalid(name, r))?;
        let mut table = toml::Table::new();
        table.insert("name".into(), toml::Value::String(name.to_string()));
        table.insert("value".into(), value);
        toml::Value::Table(table)
            .try_into()
            .map_err(|e: toml::de::Error| ConfigError::invalid(name, e.message()))
    }
}

/// Parses a lone TOML value (`0.5`, `[0, -9.8]`, `"explicit"`). A bare word that is not
/// valid TOML is taken as a string, so `--set integrator=explicit` works unquoted.
fn parse_toml_value(text: &str) -> Result<toml::Value, String> {
    let doc = format!("v = {text}");
    match doc.parse::<toml::Table>() {
        Ok(mut t) => Ok(t.remove("v").expect("key v was written above")),
        Err(_)
            if !text.is_empty() && text.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') =>
        {
            Ok(toml::Value::String(text.to_string()))
        }
        Err(e) => Err(format!("`{text}` is not a value: {}", e.message())),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn enum_names_are_serdes_names() {
        let json = |v: &dyn erased::Named| v.json();
        for (name, text) in [
            (BroadPhase::AllPairs.name(), json(&BroadPhase::AllPairs)),
            (BroadPhase::Sweep.name(), json(&BroadPhase::Sweep)),
            (BroadPhase::Grid.name(), json(&BroadPhase::Grid)),
            (Solver::Relaxation.name(), json(&Solver::Relaxation)),
            (Solver::Impulses.name(), json(&Solver::Impulses)),
            (Integrator::Symplectic.name(), json(&Integrator::Symplectic)),
            (Integrator::Explicit.name(), json(&Integrator::Explicit)),
            (Integrator::Exact.name(), json(&Integrator::Exact)),
        ] {
            assert_eq!(format!("\"{name}\""), text);
        }
    }

    mod erased {
        pub trait Named {
            fn json(&self) -> String;
        }
        impl<T: serde::Serialize> Named for T {
            fn json(&self) -> String {
                serde_json::to_string(self).unwrap()
            }
        }
    }

    #[test]
    fn every_field_has_a_setting_that_reads_back() {
        let config = WorldConfig::default();
        let settings = config.settings();
        assert_eq!(settings.len(), Setting::NAMES.len());
        let table = toml::Table::try_from(&config).unwrap();
        assert_eq!(table.len(), Setting::NAMES.len(), "a field has no setting");
        for s in settings {
            assert!(table.contains_key(s.name()), "{} is no field", s.name());
            let json = serde_json::to_string(&s).unwrap();
            assert_eq!(serde_json::from_str::<Setting>(&json).unwrap(), s, "{json}");
            let mut c = WorldConfig::default();
            c.set(s).unwrap();
            assert_eq!(c, config);
        }
    }

    #[test]
    fn a_refused_setting_changes_nothing() {
        let mut c = WorldConfig::default();
        let before = c.clone();
        assert!(c.set(Setting::Dt(0.0)).is_err());
        assert!(c.set(Setting::Baumgarte(2.0)).is_err());
        assert!(c.set(Setting::Substeps(0)).is_err());
        assert_eq!(c, before);
    }
}
