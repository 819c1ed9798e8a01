//! Particle presets: named recipes for random particles ("Testing the Particle System":
//! the chapter's `_createParticle`, kept as data so designers tune it without code).
//!
//! Every number of a preset is a [`Sample`]: a constant, or `{ base, rand = [c1, c2, ..] }`
//! meaning `base + c1 * rand() + c2 * rand() + ..` with one fresh uniform draw in [0, 1)
//! per coefficient, drawn in the order the fields are listed below.

use std::collections::BTreeMap;

use glam::{Vec2, Vec4};
use rand::Rng;
use serde::Deserialize;

use super::system::ParticleDef;

/// A number drawn from the world's generator: `base + Σ cᵢ · randᵢ`.
#[derive(Clone, Debug, PartialEq, Deserialize, serde::Serialize, schemars::JsonSchema)]
#[serde(untagged)]
pub enum Sample {
    Constant(f32),
    Random {
        #[serde(default)]
        base: f32,
        #[serde(default)]
        rand: Vec<f32>,
    },
}

impl Sample {
    pub fn draw(&self, rng: &mut impl Rng) -> f32 {
        match self {
            Sample::Constant(v) => *v,
            Sample::Random { base, rand } => rand
                .iter()
                .fold(*base, |acc, c| acc + c * rng.random::<f32>()),
        }
    }

    /// How many random terms it draws.
    pub fn rand_terms(&self) -> usize {
        match self {
            Sample::Constant(_) => 0,
            Sample::Random { rand, .. } => rand.len(),
        }
    }

    fn is_finite(&self) -> bool {
        match self {
            Sample::Constant(v) => v.is_finite(),
            Sample::Random { base, rand } => base.is_finite() && rand.iter().all(|c| c.is_finite()),
        }
    }
}

/// A particle recipe. Positions are given when the preset is used.
#[derive(Clone, Debug, PartialEq, Deserialize, serde::Serialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ParticlePreset {
    /// Seconds a particle lives.
    pub life: Sample,
    /// Red, green, blue, alpha at birth, each from 0 to 1.
    pub color: [Sample; 4],
    /// Colour at the end of its life, blended over it.
    pub final_color: [Sample; 4],
    /// Size at birth (units).
    pub size: Sample,
    /// Factor on the size each frame.
    pub size_delta: Sample,
    /// Velocity at birth (units/s).
    pub vel: [Sample; 2],
    /// Factor on the velocity each frame (1: no drag).
    pub drag: Sample,
}

impl ParticlePreset {
    /// Draws one particle at `pos`.
    pub fn spawn(&self, pos: Vec2, rng: &mut impl Rng) -> ParticleDef {
        let life = self.life.draw(rng).max(0.0);
        let color = Vec4::from(self.color.each_ref().map(|s| s.draw(rng)));
        let final_color = Vec4::from(self.final_color.each_ref().map(|s| s.draw(rng)));
        let size = self.size.draw(rng).max(0.0);
        let size_delta = self.size_delta.draw(rng).max(0.0);
        let vel = Vec2::from(self.vel.each_ref().map(|s| s.draw(rng)));
        let drag = self.drag.draw(rng).max(0.0);
        ParticleDef {
            pos,
            vel,
            life,
            size,
            color,
            final_color,
            size_delta,
            drag,
            gravity: None,
        }
    }

    /// Every field's numbers, by field name.
    fn fields(&self) -> [(&'static str, Vec<&Sample>); 7] {
        [
            ("life", vec![&self.life]),
            ("color", self.color.iter().collect()),
            ("final_color", self.final_color.iter().collect()),
            ("size", vec![&self.size]),
            ("size_delta", vec![&self.size_delta]),
            ("vel", self.vel.iter().collect()),
            ("drag", vec![&self.drag]),
        ]
    }

    /// Names the first field holding a non-finite number.
    pub fn non_finite_field(&self) -> Option<&'static str> {
        self.fields()
            .into_iter()
            .find(|(_, samples)| samples.iter().any(|s| !s.is_finite()))
            .map(|(name, _)| name)
    }

    /// The first field with more than `max` random terms in one number, and its count.
    pub fn too_many_rand_terms(&self, max: usize) -> Option<(&'static str, usize)> {
        self.fields().into_iter().find_map(|(name, samples)| {
            let most = samples.iter().map(|s| s.rand_terms()).max().unwrap_or(0);
            (most > max).then_some((name, most))
        })
    }
}

/// The presets shipped in `assets/presets/`, built into the binary so a scene can name
/// them with nothing installed.
pub const BUILT_IN: &[(&str, &str)] =
    &[("fire", include_str!("../../../../assets/presets/fire.toml"))];

/// Presets by name. A scene's own `[preset.NAME]` tables add to or replace the built-ins.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PresetLibrary {
    presets: BTreeMap<String, ParticlePreset>,
}

impl PresetLibrary {
    /// The built-in presets.
    pub fn built_in() -> Self {
        let mut lib = PresetLibrary::default();
        for (name, text) in BUILT_IN {
            let preset: ParticlePreset = toml::from_str(text)
                .unwrap_or_else(|e| panic!("built-in preset {name} does not parse: {e}"));
            lib.insert(name, preset);
        }
        lib
    }

    pub fn insert(&mut self, name: &str, preset: ParticlePreset) {
        self.presets.insert(name.to_string(), preset);
    }

    pub fn get(&self, name: &str) -> Option<&ParticlePreset> {
        self.presets.get(name)
    }

    pub fn names(&self) -> impl Iterator<Item = &str> {
        self.presets.keys().map(String::as_str)
    }

    pub fn len(&self) -> usize {
        self.presets.len()
    }

    pub fn is_empty(&self) -> bool {
        self.presets.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn fire_stays_within_the_chapters_ranges() {
        let lib = PresetLibrary::built_in();
        let fire = lib.get("fire").expect("fire is built in");
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        for _ in 0..1000 {
            let p = fire.spawn(Vec2::new(5.0, 5.0), &mut rng);
            assert!((30.0..230.0).contains(&p.life), "life {}", p.life);
            assert_eq!(p.color, Vec4::new(1.0, 0.0, 0.0, 1.0));
            assert!((3.5..4.5).contains(&p.final_color.x));
            assert!((0.4..0.5).contains(&p.final_color.y));
            assert!((0.3..0.4).contains(&p.final_color.z));
            assert_eq!(p.final_color.w, 0.6);
            assert!((3.5..6.0).contains(&p.size));
            assert_eq!(p.size_delta, 0.98);
            assert!((-20.0..10.0).contains(&p.vel.x) && (0.0..10.0).contains(&p.vel.y));
            assert_eq!(p.drag, 0.95);
            assert_eq!(p.pos, Vec2::new(5.0, 5.0));
        }
    }

    #[test]
    fn samples_draw_one_uniform_per_coefficient() {
        let s: Sample =
            toml::from_str::<BTreeMap<String, Sample>>("v = { base = 1, rand = [2, -4] }")
                .unwrap()
                .remove("v")
                .unwrap();
        let mut a = ChaCha8Rng::seed_from_u64(3);
        let mut b = ChaCha8Rng::seed_from_u64(3);
        let (r1, r2): (f32, f32) = (b.random(), b.random());
        assert_eq!(s.draw(&mut a), 1.0 + 2.0 * r1 - 4.0 * r2);
    }
}
