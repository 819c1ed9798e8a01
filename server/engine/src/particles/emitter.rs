//! Particle emitters ("Particle Emitters"): a budget of particles released over a few
//! updates, so an explosion persists instead of fizzling in one frame.

use glam::Vec2;
use rand::Rng;

/// Below this many particles left, an emitter releases all of them (`kMinToEmit`).
pub const MIN_TO_EMIT: u32 = 5;

/// An emitter at a point, releasing particles of one preset.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Emitter {
    pub pos: Vec2,
    /// Particles still to be released.
    pub remaining: u32,
    /// The preset's name (looked up in the world's library).
    pub preset: String,
}

impl Emitter {
    /// How many particles to release this update (the chapter's `emitParticles`): all that
    /// are left when fewer than [`MIN_TO_EMIT`] remain, otherwise a random share of up to
    /// 20% of what is left.
    ///
    /// The chapter emitted `ceil(x)` particles while subtracting the fractional `x`, so an
    /// emitter of N released a little more than N; here the count is whole, rounded up, so
    /// an emitter of N releases exactly N.
    pub fn take_batch(&mut self, rng: &mut impl Rng) -> u32 {
        let n = if self.remaining < MIN_TO_EMIT {
            self.remaining
        } else {
            let share = rng.random::<f64>() * 0.2 * self.remaining as f64;
            (share.ceil() as u32).min(self.remaining)
        };
        self.remaining -= n;
        n
    }

    pub fn expired(&self) -> bool {
        self.remaining == 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn an_emitter_releases_exactly_its_budget_then_expires() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        for budget in [0u32, 1, 4, 5, 200, 10_000] {
            let mut e = Emitter {
                pos: Vec2::ZERO,
                remaining: budget,
                preset: "fire".into(),
            };
            let mut total = 0;
            let mut updates = 0;
            while !e.expired() {
                let before = e.remaining;
                let n = e.take_batch(&mut rng);
                if before >= MIN_TO_EMIT {
                    assert!(n as f64 <= (0.2 * before as f64).ceil(), "{n} of {before}");
                } else {
                    assert_eq!(n, before);
                }
                total += n;
                updates += 1;
                assert!(updates < 100_000);
            }
            assert_eq!(total, budget);
        }
    }
}
