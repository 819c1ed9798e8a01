//! The steps between two frames of a reduced-rate stream (one frame in `k` steps, for a
//! slow link): drawn one step at a time as they come due, interpolated from the frames on
//! either side, so motion stays smooth at the world's step rate. The price is one stream
//! frame of lag: a frame is drawn fully when the next one is about to arrive.

use std::time::{Duration, Instant};

use ricochet_protocol::frame::{FrameDecoder, MAX_STEPS_A_FRAME};

/// Two frames of a stream and the steps between them drawn so far.
pub struct Between {
    from: FrameDecoder,
    to: FrameDecoder,
    /// When `to` arrived: step `from.frame + 1` is due then, each next one `dt` later.
    arrived: Instant,
    /// The last step drawn.
    drawn: u64,
}

impl Between {
    /// Whether the steps from `from` to `to` are to be interpolated: two to
    /// [`MAX_STEPS_A_FRAME`] steps apart in one run of the world (not a gap, not a restart).
    pub fn spans(from: &FrameDecoder, to: &FrameDecoder) -> bool {
        to.frame
            .checked_sub(from.frame)
            .is_some_and(|steps| (2..=MAX_STEPS_A_FRAME).contains(&steps))
            && to.dt > 0.0
    }

    /// The steps from the frame last drawn, `from`, to `to`, which just arrived (two
    /// frames that [`Between::spans`]).
    pub fn new(from: FrameDecoder, to: FrameDecoder, now: Instant) -> Between {
        Between {
            drawn: from.frame,
            from,
            to,
            arrived: now,
        }
    }

    /// The frame the next stream frame is interpolated from: the newest of the two.
    pub fn into_newest(self) -> FrameDecoder {
        self.to
    }

    /// The step to draw at `now`, if one is due and not drawn yet: the latest due, or
    /// with `in_order` the one after the last drawn (a recording keeps every step however
    /// late its process runs; a live view keeps up with the present).
    pub fn due(&self, now: Instant, in_order: bool) -> Option<u64> {
        let elapsed = now.saturating_duration_since(self.arrived).as_secs_f64();
        let step = self.from.frame + 1 + (elapsed / self.to.dt) as u64;
        let step = step.min(self.to.frame);
        match (step > self.drawn, in_order) {
            (true, true) => Some(self.drawn + 1),
            (true, false) => Some(step),
            (false, _) => None,
        }
    }

    /// The steps not drawn yet, each marked drawn as it is taken.
    pub fn rest(&mut self) -> impl Iterator<Item = FrameDecoder> + '_ {
        (self.drawn + 1..=self.to.frame).map(|step| self.draw(step))
    }

    /// How long until the next step is due (zero when one is, `None` when all are drawn).
    pub fn wait(&self, now: Instant) -> Option<Duration> {
        if self.drawn >= self.to.frame {
            return None;
        }
        let next = (self.drawn - self.from.frame) as f64 * self.to.dt;
        let at = self.arrived + Duration::from_secs_f64(next);
        Some(at.saturating_duration_since(now))
    }

    /// The state at `step`, marked drawn.
    pub fn draw(&mut self, step: u64) -> FrameDecoder {
        self.drawn = step;
        interpolate(&self.from, &self.to, step)
    }
}

/// The state at `step`, between `from` and `to` (`from.frame < step <= to.frame`): bodies
/// and particles in both moved on a straight line between their two places; those only in
/// `to` as they are there (a particle born after `step` left out, one born before placed
/// back along its velocity); those only in `from` gone.
pub fn interpolate(from: &FrameDecoder, to: &FrameDecoder, step: u64) -> FrameDecoder {
    let span = (to.frame - from.frame) as f64;
    let t = (step - from.frame) as f64 / span;
    let mut d = to.clone();
    d.frame = step;
    d.time = from.time + (to.time - from.time) * t;
    for body in &mut d.bodies {
        if let Ok(i) = from.bodies.binary_search_by_key(&body.key, |b| b.key) {
            for (p, p0) in body.p.iter_mut().zip(from.bodies[i].p) {
                let moved = p.wrapping_sub(p0) as f64 * t;
                *p = p0.wrapping_add(moved.round() as i64);
            }
        }
    }
    let back = ((to.frame - step) as f64 * to.dt) as f32;
    d.particles.retain(|p| p.record_frame <= step);
    for p in &mut d.particles {
        match from.particles.binary_search_by_key(&p.id, |q| q.id) {
            Ok(i) => {
                for (x, x0) in p.pos.iter_mut().zip(from.particles[i].pos) {
                    *x = x0 + (*x - x0) * t as f32;
                }
            }
            Err(_) => {
                for (x, v) in p.pos.iter_mut().zip(p.vel) {
                    *x -= v * back;
                }
            }
        }
    }
    d
}

#[cfg(test)]
mod tests {
    use super::*;
    use ricochet_protocol::frame::{BodyIn, FrameEncoder, FrameStats, ParticlesIn};

    const DT: f64 = 1.0 / 60.0;

    fn frame(enc: &mut FrameEncoder, k: u64, x: f64) -> Vec<u8> {
        let body = BodyIn {
            key: 0,
            id: "a",
            group: "g",
            circle: false,
            size: [1.0, 1.0],
            pos: [x, 2.0],
            vel: [0.0, 0.0],
            collided: false,
        };
        enc.encode(
            k,
            k as f64 * DT,
            DT,
            &FrameStats::default(),
            &[],
            &[body],
            &ParticlesIn::default(),
        )
    }

    /// The steps between a frame where a body is at x = 0 and one 8 steps later where it
    /// is at x = 8 (that frame's decoder), arrived at the instant returned.
    fn eight_steps() -> (FrameDecoder, Between, Instant) {
        let mut enc = FrameEncoder::new(100);
        let mut dec = FrameDecoder::new();
        dec.apply(&frame(&mut enc, 0, 0.0)).unwrap();
        let from = dec.clone();
        dec.apply(&frame(&mut enc, 8, 8.0)).unwrap();
        let t0 = Instant::now();
        assert!(Between::spans(&from, &dec), "eight steps apart");
        let between = Between::new(from, dec.clone(), t0);
        (dec, between, t0)
    }

    /// A body that moved from 0 to 8 over a stream frame of 8 steps is drawn at 1, 2, ...
    /// at the steps in between, each step due `dt` after the one before.
    #[test]
    fn the_steps_between_two_frames_are_drawn_on_a_straight_line_as_they_come_due() {
        let (dec, mut between, t0) = eight_steps();
        assert_eq!(between.due(t0, false), Some(1));
        let mut drawn = Vec::new();
        for k in 0..10u32 {
            let now = t0 + Duration::from_secs_f64(DT * f64::from(k) + 1e-6);
            if let Some(step) = between.due(now, false) {
                let d = between.draw(step);
                assert_eq!(d.frame, step);
                drawn.push((step, d.bodies[0].pos()[0]));
            }
        }
        let expected: Vec<(u64, f64)> = (1..=8).map(|s| (s, s as f64)).collect();
        for ((s, x), (es, ex)) in drawn.iter().zip(&expected) {
            assert_eq!(s, es);
            assert!((x - ex).abs() < 1e-6, "step {s}: {x} against {ex}");
        }
        assert_eq!(drawn.len(), 8);
        assert_eq!(between.wait(t0 + Duration::from_secs(1)), None);
        // Frames too far apart (a gap), or back, are not interpolated.
        let mut far = dec.clone();
        far.frame = 100;
        assert!(!Between::spans(&dec, &far));
        assert!(!Between::spans(&far, &dec));
    }

    /// Looked at late, a live view draws the latest step due and a recording the next one
    /// after the last it drew; a recording's rest is every step it did not draw.
    #[test]
    fn a_late_look_skips_to_the_present_live_and_keeps_every_step_recorded() {
        let (_, mut between, t0) = eight_steps();
        let late = t0 + Duration::from_secs_f64(DT * 3.5);
        assert_eq!(between.due(late, false), Some(4));
        assert_eq!(between.due(late, true), Some(1));
        between.draw(1);
        assert_eq!(between.due(late, true), Some(2));
        let rest: Vec<u64> = between.rest().map(|d| d.frame).collect();
        assert_eq!(rest, (2..=8).collect::<Vec<u64>>());
        assert_eq!(between.due(late, true), None);
    }
}
