//! How far a step is from this machine's physical limits: the solver's work per step (its
//! passes over the contact rows, counted by the engine as they run) priced in bytes and
//! double-precision operations by a model of the pass, set against this machine's memory
//! bandwidth and peak arithmetic, both measured here on one core.
//!
//! The model prices only the velocity passes and the per-body integration of the
//! sub-steps; the contact search (broad and narrow phase) and the rest of the step are not
//! counted, so the work and the fractions below are lower bounds.

use std::hint::black_box;
use std::time::Instant;

use ricochet_engine::dynamics::impulse::{CONTACT_ROW_BYTES, SOLVER_BODY_BYTES};
use ricochet_engine::world::World;

/// Double-precision operations of one contact in one velocity pass (a resting contact
/// with the position bias, `solve_contact` in `server/engine/src/dynamics/impulse/passes.rs`,
/// counted by hand: relative velocity 2, current gap 6, penetration 2, bias target 2,
/// normal velocity 3, normal impulse and clamp 8, tangent 1, tangent velocity 3, friction
/// limit and clamp 5, impulse vector 6, the two bodies' velocity changes 8). The split
/// impulse's extra work (about 20 more) is not counted.
pub const FLOPS_PER_CONTACT_PASS: u64 = 46;

/// Bytes one contact moves in one velocity pass: its row read, its three impulses written,
/// both bodies read and their velocities written.
pub const BYTES_PER_CONTACT_PASS: u64 =
    (CONTACT_ROW_BYTES + 3 * 8 + 2 * SOLVER_BODY_BYTES + 2 * 16) as u64;

/// Double-precision operations of one moving body in one sub-step: gravity into the
/// velocity (2), the position's move by velocity and split velocity (6).
pub const FLOPS_PER_BODY_SUBSTEP: u64 = 8;

/// Bytes one moving body moves in one sub-step: read and written by both integrations.
pub const BYTES_PER_BODY_SUBSTEP: u64 = 4 * SOLVER_BODY_BYTES as u64;

/// What the solver did over a run, summed from each step's figures.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Work {
    pub steps: u64,
    /// Contacts summed over the steps.
    pub contacts: u64,
    /// Contact visits of the velocity passes: each step's contacts times its passes.
    pub contact_passes: u64,
    /// Moving bodies times sub-steps, summed over the steps.
    pub body_substeps: u64,
    /// The largest over the steps of the bytes the passes stream: every contact row and
    /// every moving body.
    pub working_set: u64,
}

impl Work {
    /// Adds the step `world` just took.
    pub fn add(&mut self, world: &World) {
        let stats = world.stats();
        let moving = world.bodies().iter().filter(|b| b.inv_mass > 0.0).count() as u64;
        self.steps += 1;
        self.contacts += stats.contacts;
        self.contact_passes += stats.contacts * stats.solver_passes;
        self.body_substeps += moving * u64::from(world.config.substeps.max(1));
        let set = stats.contacts * CONTACT_ROW_BYTES as u64 + moving * SOLVER_BODY_BYTES as u64;
        self.working_set = self.working_set.max(set);
    }

    /// Bytes the model prices a step at, on average over the run.
    pub fn bytes_per_step(&self) -> f64 {
        (self.contact_passes * BYTES_PER_CONTACT_PASS + self.body_substeps * BYTES_PER_BODY_SUBSTEP)
            as f64
            / self.steps.max(1) as f64
    }

    /// Double-precision operations the model prices a step at, on average over the run.
    pub fn flops_per_step(&self) -> f64 {
        (self.contact_passes * FLOPS_PER_CONTACT_PASS + self.body_substeps * FLOPS_PER_BODY_SUBSTEP)
            as f64
            / self.steps.max(1) as f64
    }
}

/// This machine's limits on one core, measured.
#[derive(Clone, Debug)]
pub struct Machine {
    /// Bytes a second of a triad `a = b + s c` over arrays far larger than the caches (the
    /// best of several runs; reads and writes counted, the write's cache fill not).
    pub bandwidth: f64,
    /// Double-precision operations a second of independent multiply-adds (the best of
    /// several runs).
    pub peak_flops: f64,
    /// How the peak was reached ("AVX2 FMA, 4 lanes" or "scalar").
    pub peak_kind: &'static str,
    /// One core's level-2 cache in bytes, as the system reports it (None: not reported).
    pub l2_cache: Option<u64>,
}

impl Machine {
    pub fn measure() -> Machine {
        let (peak_flops, peak_kind) = peak_flops();
        Machine {
            bandwidth: bandwidth(),
            peak_flops,
            peak_kind,
            l2_cache: l2_cache(),
        }
    }
}

/// The level-2 cache of cpu0 from Linux's sysfs (`4096K`), in bytes.
fn l2_cache() -> Option<u64> {
    let text = std::fs::read_to_string("/sys/devices/system/cpu/cpu0/cache/index2/size").ok()?;
    let text = text.trim();
    let (digits, unit) = text.split_at(text.find(|c: char| !c.is_ascii_digit())?);
    let n: u64 = digits.parse().ok()?;
    Some(match unit {
        "K" => n << 10,
        "M" => n << 20,
        _ => return None,
    })
}

/// The best triad rate over 5 runs on three arrays of 64 MiB each.
fn bandwidth() -> f64 {
    const N: usize = 8 << 20;
    let mut a = vec![0.0_f64; N];
    let b: Vec<f64> = (0..N).map(|i| i as f64).collect();
    let c: Vec<f64> = (0..N).map(|i| (N - i) as f64).collect();
    let s = black_box(0.5);
    let mut best = f64::INFINITY;
    for _ in 0..5 {
        let start = Instant::now();
        for ((x, y), z) in a.iter_mut().zip(&b).zip(&c) {
            *x = y + s * z;
        }
        black_box(&mut a);
        best = best.min(start.elapsed().as_secs_f64());
    }
    (3 * 8 * N) as f64 / best
}

/// The best rate of independent multiply-adds over 5 runs: AVX2 FMA on 4 lanes when the
/// processor has it, else scalar.
fn peak_flops() -> (f64, &'static str) {
    #[cfg(target_arch = "x86_64")]
    if is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma") {
        let mut best = f64::INFINITY;
        const ITERS: u64 = 20_000_000;
        for _ in 0..5 {
            let start = Instant::now();
            // SAFETY: the processor has AVX2 and FMA (checked above).
            black_box(unsafe { fma_kernel(ITERS) });
            best = best.min(start.elapsed().as_secs_f64());
        }
        // 10 accumulators of 4 lanes, 2 operations a multiply-add.
        return ((ITERS * 10 * 4 * 2) as f64 / best, "AVX2 FMA on 4 lanes");
    }
    let mut best = f64::INFINITY;
    const ITERS: u64 = 20_000_000;
    for _ in 0..5 {
        let start = Instant::now();
        black_box(scalar_kernel(ITERS));
        best = best.min(start.elapsed().as_secs_f64());
    }
    ((ITERS * 8 * 2) as f64 / best, "scalar multiply-adds")
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn fma_kernel(iters: u64) -> f64 {
    use std::arch::x86_64::*;
    let m = _mm256_set1_pd(black_box(0.999_999));
    let k = _mm256_set1_pd(black_box(1e-9));
    let mut acc = [_mm256_set1_pd(1.0); 10];
    for _ in 0..iters {
        for a in acc.iter_mut() {
            *a = _mm256_fmadd_pd(*a, m, k);
        }
    }
    let mut sum = _mm256_setzero_pd();
    for a in acc {
        sum = _mm256_add_pd(sum, a);
    }
    let mut out = [0.0; 4];
    _mm256_storeu_pd(out.as_mut_ptr(), sum);
    out.iter().sum()
}

fn scalar_kernel(iters: u64) -> f64 {
    let m = black_box(0.999_999);
    let k = black_box(1e-9);
    let mut acc = [1.0_f64; 8];
    for _ in 0..iters {
        for a in acc.iter_mut() {
            *a = *a * m + k;
        }
    }
    acc.iter().sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_model_prices_passes_and_bodies() {
        let w = Work {
            steps: 2,
            contacts: 10,
            contact_passes: 40,
            body_substeps: 8,
            working_set: 0,
        };
        assert_eq!(
            w.flops_per_step(),
            (40 * FLOPS_PER_CONTACT_PASS + 8 * FLOPS_PER_BODY_SUBSTEP) as f64 / 2.0
        );
        assert!(w.bytes_per_step() > 20.0 * BYTES_PER_CONTACT_PASS as f64);
    }
}
