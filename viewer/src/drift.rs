//! How far worlds watched together drift apart, frame by frame: a fork under other
//! settings against the world it was forked from is the speed/accuracy trade on the
//! user's own scene, while it runs.
//!
//! Every world's loop sends each frame it decodes ([`FrameSample`]: the bodies' positions
//! by id, the frame's kinetic energy) to one thread, which keeps a short ring of recent
//! frames per world ([`Drifts`]) and compares the first world with each other one at the
//! frames both have decoded, never at different frames: the largest distance between two
//! bodies of the same id, and the difference in kinetic energy. The worlds' streams
//! arrive independently, so a frame is compared when the second of the two arrives, as
//! long as the first is still in its ring ([`RING`] frames, 2 s at 60 Hz).

use std::collections::VecDeque;
use std::sync::mpsc::Receiver;

use anyhow::Result;
use re_sdk::RecordingStream;
use re_sdk_types::archetypes::{Scalars, SeriesLines};
use re_sdk_types::components::Color;
use ricochet_protocol::frame::FrameDecoder;

/// The drift plots: entity path (one series under it per world compared with the first),
/// title.
pub const DRIFT_PLOTS: [(&str, &str); 2] = [
    ("drift/body_distance", "largest distance, same body"),
    ("drift/kinetic_energy", "kinetic energy difference"),
];

/// Frames kept per world for comparison.
pub const RING: usize = 120;

/// One decoded frame of a world, as far as the drift plots read it.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameSample {
    /// The server's frame number (a fork numbers on from the frame it was forked at).
    pub frame: u64,
    /// Where the world's figures of this frame went on the viewer's timelines: `frame`
    /// and `sim_time` seconds (they differ from the server's after a load or a reset).
    pub logged_at: (u64, f64),
    pub kinetic_energy: f64,
    /// The dynamic bodies' ids and positions, sorted by id.
    pub bodies: Vec<(String, [f64; 2])>,
}

impl FrameSample {
    /// The frame `d` holds now, logged at `logged_at`.
    pub fn of(d: &FrameDecoder, logged_at: (u64, f64)) -> FrameSample {
        let mut bodies: Vec<(String, [f64; 2])> =
            d.bodies.iter().map(|b| (b.id.clone(), b.pos())).collect();
        bodies.sort_by(|a, b| a.0.cmp(&b.0));
        FrameSample {
            frame: d.frame,
            logged_at,
            kinetic_energy: f64::from(d.stats.kinetic_energy),
            bodies,
        }
    }
}

/// How far one world is from the first at one frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Drift {
    /// The largest distance between a body of one world and the body of the same id in
    /// the other, world units (0 when they share none).
    pub max_distance: f64,
    /// The world's kinetic energy less the first world's.
    pub energy_difference: f64,
    /// Bodies of either world with no body of their id in the other (spawned or removed
    /// in one only): left out of the distance.
    pub unmatched: usize,
}

/// Compares `other` with `first` at the same frame (both sorted by id: one merge pass).
pub fn compare(first: &FrameSample, other: &FrameSample) -> Drift {
    let (a, b) = (&first.bodies, &other.bodies);
    let (mut i, mut j) = (0, 0);
    let mut max_distance: f64 = 0.0;
    let mut unmatched = 0;
    while i < a.len() && j < b.len() {
        match a[i].0.cmp(&b[j].0) {
            std::cmp::Ordering::Less => (i, unmatched) = (i + 1, unmatched + 1),
            std::cmp::Ordering::Greater => (j, unmatched) = (j + 1, unmatched + 1),
            std::cmp::Ordering::Equal => {
                let (p, q) = (a[i].1, b[j].1);
                let d = (p[0] - q[0]).hypot(p[1] - q[1]);
                if d.is_finite() {
                    max_distance = max_distance.max(d);
                }
                (i, j) = (i + 1, j + 1);
            }
        }
    }
    unmatched += (a.len() - i) + (b.len() - j);
    Drift {
        max_distance,
        energy_difference: other.kinetic_energy - first.kinetic_energy,
        unmatched,
    }
}

/// A comparison made: world `world` against the first at server frame `frame`, logged at
/// the first world's place on the timelines.
#[derive(Clone, Debug, PartialEq)]
pub struct Comparison {
    pub world: usize,
    pub frame: u64,
    pub logged_at: (u64, f64),
    pub drift: Drift,
}

/// Recent frames of every world, world 0 the one the others are compared with.
pub struct Drifts {
    rings: Vec<VecDeque<FrameSample>>,
}

impl Drifts {
    pub fn new(worlds: usize) -> Drifts {
        Drifts {
            rings: (0..worlds).map(|_| VecDeque::with_capacity(RING)).collect(),
        }
    }

    /// Keeps `sample` of world `world` and returns the comparisons it completes: with
    /// every other world's same frame if `world` is the first, else with the first's.
    /// A frame lower than the world's newest begins a new run (a load, a reset, a
    /// restore): the world's ring starts again.
    pub fn record(&mut self, world: usize, sample: FrameSample) -> Vec<Comparison> {
        let ring = &mut self.rings[world];
        match ring.back().map(|s| s.frame) {
            Some(newest) if sample.frame < newest => ring.clear(),
            Some(newest) if sample.frame == newest => {
                ring.pop_back();
            }
            _ => {}
        }
        let find = |ring: &VecDeque<FrameSample>, frame: u64| {
            ring.iter().rev().find(|s| s.frame == frame).cloned()
        };
        let mut made = Vec::new();
        if world == 0 {
            for (k, other) in self.rings.iter().enumerate().skip(1) {
                if let Some(o) = find(other, sample.frame) {
                    made.push(Comparison {
                        world: k,
                        frame: sample.frame,
                        logged_at: sample.logged_at,
                        drift: compare(&sample, &o),
                    });
                }
            }
        } else if let Some(first) = find(&self.rings[0], sample.frame) {
            made.push(Comparison {
                world,
                frame: sample.frame,
                logged_at: first.logged_at,
                drift: compare(&first, &sample),
            });
        }
        let ring = &mut self.rings[world];
        ring.push_back(sample);
        if ring.len() > RING {
            ring.pop_front();
        }
        made
    }
}

/// The series of the drift plots for world `name` against `first`, in `color`.
pub fn log_series(rec: &RecordingStream, first: &str, name: &str, color: [u8; 4]) -> Result<()> {
    for (path, _) in DRIFT_PLOTS {
        rec.log_static(
            format!("{path}/{name}"),
            &SeriesLines::new()
                .with_colors([Color::from_unmultiplied_rgba(
                    color[0], color[1], color[2], color[3],
                )])
                .with_names([format!("{name} vs {first}")])
                .with_widths([2.0]),
        )?;
    }
    Ok(())
}

/// Takes every world's frames from `samples` until all worlds stop, and logs each
/// comparison to the drift plots (this thread's own times on the timelines: Rerun keeps
/// the time per thread). `names` are the worlds', the first compared with the others.
pub fn run(
    rec: RecordingStream,
    names: Vec<String>,
    samples: Receiver<(usize, FrameSample)>,
) -> Result<u64> {
    let mut drifts = Drifts::new(names.len());
    let mut compared = 0u64;
    for (world, sample) in samples {
        for c in drifts.record(world, sample) {
            rec.set_time_sequence("frame", c.logged_at.0.min(i64::MAX as u64) as i64);
            rec.set_duration_secs("sim_time", c.logged_at.1);
            let name = &names[c.world];
            let [distance, energy] = DRIFT_PLOTS.map(|(path, _)| format!("{path}/{name}"));
            rec.log(distance, &Scalars::single(c.drift.max_distance))?;
            rec.log(energy, &Scalars::single(c.drift.energy_difference))?;
            compared += 1;
        }
    }
    Ok(compared)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(frame: u64, kinetic_energy: f64, bodies: &[(&str, [f64; 2])]) -> FrameSample {
        let mut bodies: Vec<(String, [f64; 2])> =
            bodies.iter().map(|(id, p)| (id.to_string(), *p)).collect();
        bodies.sort_by(|a, b| a.0.cmp(&b.0));
        FrameSample {
            frame,
            logged_at: (frame, frame as f64 / 60.0),
            kinetic_energy,
            bodies,
        }
    }

    #[test]
    fn the_largest_distance_is_between_bodies_of_the_same_id() {
        let a = sample(
            5,
            10.0,
            &[("a", [0.0, 0.0]), ("b", [1.0, 1.0]), ("x", [0.0, 0.0])],
        );
        let b = sample(
            5,
            12.5,
            &[("a", [3.0, 4.0]), ("b", [1.0, 2.0]), ("y", [90.0, 0.0])],
        );
        let d = compare(&a, &b);
        assert_eq!(d.max_distance, 5.0);
        assert_eq!(d.energy_difference, 2.5);
        assert_eq!(d.unmatched, 2, "x and y have no twin");
        let same = compare(&a, &a);
        assert_eq!((same.max_distance, same.energy_difference), (0.0, 0.0));
    }

    #[test]
    fn frames_are_compared_once_both_worlds_have_them_and_never_across_frames() {
        let mut drifts = Drifts::new(2);
        let at = |f: u64, x: f64| sample(f, 1.0, &[("a", [x, 0.0])]);
        assert!(drifts.record(0, at(10, 0.0)).is_empty());
        assert!(drifts.record(0, at(11, 0.0)).is_empty());
        // The other world is behind: its frame 9 has no twin kept, its 10 has.
        assert!(drifts.record(1, at(9, 7.0)).is_empty());
        let made = drifts.record(1, at(10, 2.0));
        assert_eq!(made.len(), 1);
        assert_eq!((made[0].world, made[0].frame), (1, 10));
        assert_eq!(made[0].drift.max_distance, 2.0);
        // Then ahead: frame 12 waits for the first world's.
        assert!(drifts.record(1, at(12, 3.0)).is_empty());
        let made = drifts.record(0, at(12, 0.0));
        assert_eq!(made.len(), 1);
        assert_eq!((made[0].frame, made[0].drift.max_distance), (12, 3.0));
        assert_eq!(made[0].logged_at, (12, 0.2));
    }

    #[test]
    fn a_new_run_forgets_the_old_frames_and_the_ring_is_bounded() {
        let mut drifts = Drifts::new(3);
        let at = |f: u64| sample(f, 0.0, &[]);
        for f in 0..(RING as u64 + 50) {
            drifts.record(1, at(f));
        }
        assert_eq!(drifts.rings[1].len(), RING);
        assert_eq!(drifts.rings[1].front().unwrap().frame, 50);
        // Frame 60 is kept for world 1: compared with world 0's.
        assert_eq!(drifts.record(0, at(60)).len(), 1);
        // World 1 reset: its frames start again at 0, so its old frame 60 is gone.
        drifts.record(1, at(0));
        assert_eq!(drifts.rings[1].len(), 1);
        assert!(drifts.record(0, at(61)).is_empty());
        // World 2 is compared with the first too, not with world 1.
        assert!(drifts.record(2, at(5)).is_empty());
        assert_eq!(drifts.record(2, at(61))[0].world, 2);
    }
}
