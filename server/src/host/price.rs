//! What a command is expected to cost the stepping thread before it runs: a model (the
//! size of what it touches times the cost per item measured on the reference machine,
//! docs/security.md, "The cost of a command"), scaled by how much longer the last command
//! of its kind really took on this machine.
//!
//! The budgets ([`super::budget`]) refuse by the price and charge the measured time. The
//! model alone can be low on a slower machine: a `reset` of 90 000 static boxes, priced
//! 90 ms, took 130 ms on one, so it passed the 100 ms any command may take at once and
//! held the world's clock up past what it catches up. Scaled by what the last one took,
//! the next is priced at what it will take here and refused before it runs.
//!
//! The scale decays back towards the model (half of what it adds every
//! [`Calibration::HALF_LIFE`]): a command refused by its scale is tried again once the
//! decay brings its price under the burst, and relearned from what it then takes. One
//! slow run (a machine stalled under it) does not lock its kind out for good, and a
//! really slow kind runs at most once a half-life or so over the burst.

use std::collections::HashMap;
use std::time::{Duration, Instant};

use ricochet_protocol::command::{Action, Command, ServerCommand};

use super::inbox::Sender;
use super::limiter::MAX_SENDERS;

// Costs per item of the commands' work, from the times `handling_costs_per_item`
// (host/hosted.rs) measured on the shipped pile on the reference machine (2 vCPU Xeon),
// two to three times over them: a reset of the 5050 boxes took 1.7 ms, a clear of them
// 0.3 ms, 10 000 particles spawned 0.6 ms, a load by name 1.5 ms.

/// Any command: parse, journal, event, reply.
pub const BASE_NS: f64 = 20_000.0;
/// A pass over the bodies (select, agitate, clear, a setting).
pub const SCAN_NS_PER_BODY: f64 = 100.0;
/// A pass over the particles (a setting, a world dropped).
pub const SCAN_NS_PER_PARTICLE: f64 = 10.0;
/// A body built, or dropped (reset).
pub const BUILD_NS_PER_BODY: f64 = 1_000.0;
/// A byte of scene text parsed (reset, load).
pub const NS_PER_SCENE_BYTE: f64 = 50.0;
/// A particle spawned.
pub const NS_PER_PARTICLE: f64 = 100.0;

/// The kinds of command whose cost grows with the world they run on: each is scaled by
/// its own last run. Others are not scaled: a load builds a world the model knows only
/// by its text (its time is the new scene's, not the machine's), and the rest cost their
/// base whatever the world.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// A pass over the bodies: select, agitate, clear.
    Scan,
    Spawn,
    Set,
    Reset,
    Load,
    /// Everything else: priced at its base, never scaled (a journal write can take a
    /// millisecond beside a 20 µs command; scaling every small command by it would price
    /// them all as the slowest).
    Base,
}

const SCALED: usize = 4;

impl Kind {
    fn index(self) -> Option<usize> {
        match self {
            Kind::Scan => Some(0),
            Kind::Spawn => Some(1),
            Kind::Set => Some(2),
            Kind::Reset => Some(3),
            Kind::Load | Kind::Base => None,
        }
    }
}

/// What a world of `bodies` bodies and `particles` particles, made from a scene text of
/// `scene_bytes` bytes, expects `command` to cost by the model: its kind and nanoseconds.
/// `particles_per_action` caps a spawn (the world refuses more at no cost); `command_bytes`
/// is the largest text a `load` may carry (a file by name is priced as that).
pub fn model(
    command: &Command,
    bodies: f64,
    particles: f64,
    scene_bytes: usize,
    particles_per_action: u32,
    command_bytes: u64,
) -> (Kind, f64) {
    match command {
        Command::World(action) => match action {
            // A pass over the bodies (and, for a selection, a pick among them).
            Action::Select { .. }
            | Action::Agitate { .. }
            | Action::Clear { .. }
            | Action::Remove { .. } => (Kind::Scan, BASE_NS + bodies * SCAN_NS_PER_BODY),
            // A spawn over the per-action limit is refused by the world at no cost.
            Action::SpawnParticles { count, .. } => {
                let count = (*count).min(particles_per_action);
                (Kind::Spawn, BASE_NS + f64::from(count) * NS_PER_PARTICLE)
            }
            // A setting may rebuild what depends on it: the broad phase's cells, the
            // particles' grid.
            Action::Set { .. } => (
                Kind::Set,
                BASE_NS + bodies * SCAN_NS_PER_BODY + particles * SCAN_NS_PER_PARTICLE,
            ),
            _ => (Kind::Base, BASE_NS),
        },
        // The scene is parsed again and every body and particle of the old world
        // dropped; the new one is built.
        Command::Server(ServerCommand::Reset { .. }) => (
            Kind::Reset,
            BASE_NS
                + scene_bytes as f64 * NS_PER_SCENE_BYTE
                + bodies * BUILD_NS_PER_BODY
                + particles * SCAN_NS_PER_PARTICLE,
        ),
        // The new world's size is known once it is built: a load is priced by its text
        // (a file by name as the largest text a command may carry) and the old world
        // dropped, and charged what the build took.
        Command::Server(ServerCommand::Load { text, .. }) => {
            let bytes = text.as_ref().map_or(command_bytes as usize, String::len);
            (
                Kind::Load,
                BASE_NS
                    + bytes as f64 * NS_PER_SCENE_BYTE
                    + bodies * SCAN_NS_PER_BODY
                    + particles * SCAN_NS_PER_PARTICLE,
            )
        }
        // A world copied whole (save, fork) or rebuilt from its bytes (restore, rewind;
        // a rewind's replayed steps are added by the host, which knows a step's time).
        Command::Server(
            ServerCommand::Save { .. }
            | ServerCommand::Restore { .. }
            | ServerCommand::Rewind { .. }
            | ServerCommand::Fork { .. },
        ) => (
            Kind::Reset,
            BASE_NS + bodies * BUILD_NS_PER_BODY + particles * SCAN_NS_PER_PARTICLE,
        ),
        // A pass over the bodies, and a line of the reply for each picked.
        Command::Server(ServerCommand::Bodies { .. }) => {
            (Kind::Scan, BASE_NS + bodies * SCAN_NS_PER_BODY)
        }
        Command::Server(_) => (Kind::Base, BASE_NS),
    }
}

/// A command's price: the model's figure and the scale of its kind when it was priced.
#[derive(Clone, Copy, Debug)]
pub struct Price {
    kind: Kind,
    model_ns: f64,
    scale: f64,
}

impl Price {
    /// The time the command is expected to take here.
    pub fn time(&self) -> Duration {
        Duration::try_from_secs_f64(self.model_ns * self.scale * 1e-9).unwrap_or(Duration::MAX)
    }
}

/// How much longer than the model the last command of each scaled kind took here, and
/// when (at least 1: the model is never priced down, so a fast machine keeps the
/// reference's prices).
#[derive(Clone, Debug, Default)]
pub struct Calibration([Option<(f64, Instant)>; SCALED]);

/// The largest scale a kind may get: a command that took a thousand times its model
/// (a machine stalled under it) still gets a finite price.
const MAX_SCALE: f64 = 1_000.0;

impl Calibration {
    /// The time in which a scale loses half of what it adds to the model.
    pub const HALF_LIFE: Duration = Duration::from_secs(30);

    /// The price at `now` of a command the model puts at `model_ns` of kind `kind`.
    pub fn price(&self, (kind, model_ns): (Kind, f64), now: Instant) -> Price {
        let scale = kind
            .index()
            .and_then(|k| self.0[k])
            .map_or(1.0, |(scale, at)| {
                let halves =
                    now.saturating_duration_since(at).as_secs_f64() / Self::HALF_LIFE.as_secs_f64();
                1.0 + (scale - 1.0) * 0.5f64.powf(halves)
            });
        Price {
            kind,
            model_ns,
            scale,
        }
    }

    /// Whether every scale has decayed to within a thousandth of the model by `now`.
    fn rested(&self, now: Instant) -> bool {
        self.0.iter().flatten().all(|&(scale, at)| {
            let halves =
                now.saturating_duration_since(at).as_secs_f64() / Self::HALF_LIFE.as_secs_f64();
            (scale - 1.0) * 0.5f64.powf(halves) < 1e-3
        })
    }

    /// Learns from a command priced `price` that took `took`, done at `now`: its kind is
    /// scaled by `took` over the model from then on.
    pub fn learn(&mut self, price: &Price, took: Duration, now: Instant) {
        if let Some(k) = price.kind.index() {
            if price.model_ns > 0.0 {
                let ratio = took.as_secs_f64() * 1e9 / price.model_ns;
                self.0[k] = Some((ratio.clamp(1.0, MAX_SCALE), now));
            }
        }
    }
}

/// Each sender's [`Calibration`]: what one sender's commands took scales its own prices,
/// never another's (an attacker whose commands run slow cannot price an honest client's
/// out). At most [`MAX_SENDERS`] senders; past it, the senders whose scales have decayed
/// back to the model are forgotten, and newcomers then share the anonymous sender's.
#[derive(Clone, Debug, Default)]
pub struct Calibrations(HashMap<Sender, Calibration>);

impl Calibrations {
    /// The price at `now` of `sender`'s command the model puts at `model_ns` of `kind`.
    pub fn price(&self, sender: &Sender, priced: (Kind, f64), now: Instant) -> Price {
        match self.0.get(sender) {
            Some(calibration) => calibration.price(priced, now),
            None => Calibration::default().price(priced, now),
        }
    }

    /// Learns from `sender`'s command priced `price` that took `took`, done at `now`.
    pub fn learn(&mut self, sender: &Sender, price: &Price, took: Duration, now: Instant) {
        if !self.0.contains_key(sender) && self.0.len() >= MAX_SENDERS {
            self.0.retain(|_, c| !c.rested(now));
        }
        let key = if self.0.contains_key(sender) || self.0.len() < MAX_SENDERS {
            sender.clone()
        } else {
            None
        };
        self.0.entry(key).or_default().learn(price, took, now);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A reset the model puts at 90 ms.
    const RESET: (Kind, f64) = (Kind::Reset, 90e6);

    fn ms(p: Price) -> f64 {
        p.time().as_secs_f64() * 1e3
    }

    #[test]
    fn a_kind_is_priced_at_what_its_last_run_took_never_below_the_model() {
        let t0 = Instant::now();
        let mut c = Calibration::default();
        let reset = RESET;
        assert!((ms(c.price(reset, t0)) - 90.0).abs() < 1e-9);
        // It took 130 ms: the next is priced 130 ms.
        c.learn(&c.price(reset, t0), Duration::from_millis(130), t0);
        assert!((ms(c.price(reset, t0)) - 130.0).abs() < 1e-6);
        // Another kind is not touched.
        assert!((ms(c.price((Kind::Scan, 1e6), t0)) - 1.0).abs() < 1e-9);
        // Faster than the model: back to the model, not below it.
        c.learn(&c.price(reset, t0), Duration::from_millis(10), t0);
        assert!((ms(c.price(reset, t0)) - 90.0).abs() < 1e-9);
        // A small command that waited on the disk scales nothing, nor does a load.
        c.learn(
            &c.price((Kind::Base, BASE_NS), t0),
            Duration::from_millis(5),
            t0,
        );
        assert!((ms(c.price((Kind::Base, BASE_NS), t0)) - 0.02).abs() < 1e-9);
        c.learn(
            &c.price((Kind::Load, 1e6), t0),
            Duration::from_millis(50),
            t0,
        );
        assert!((ms(c.price((Kind::Load, 1e6), t0)) - 1.0).abs() < 1e-9);
        // A stalled run gives a large but finite price.
        c.learn(&c.price(reset, t0), Duration::from_secs(1_000_000), t0);
        assert!(c.price(reset, t0).time() < Duration::from_secs(100));
    }

    #[test]
    fn a_scale_decays_back_to_the_model_so_no_kind_is_locked_out() {
        let t0 = Instant::now();
        let mut c = Calibration::default();
        let reset = RESET;
        // One stalled run at three times the model: priced 270 ms, over any burst.
        c.learn(&c.price(reset, t0), Duration::from_millis(270), t0);
        assert!((ms(c.price(reset, t0)) - 270.0).abs() < 1e-6);
        // A half-life on, half of what it added is gone; ten on, next to all of it.
        let later = t0 + Calibration::HALF_LIFE;
        assert!((ms(c.price(reset, later)) - 180.0).abs() < 1e-6);
        let much_later = t0 + Calibration::HALF_LIFE * 10;
        assert!(ms(c.price(reset, much_later)) < 90.2);
    }

    #[test]
    fn past_the_sender_cap_newcomers_share_until_others_rest() {
        let mut c = Calibrations::default();
        let now = Instant::now();
        let price = Calibration::default().price(RESET, now);
        for k in 0..MAX_SENDERS {
            c.learn(&Some(k.to_string()), &price, Duration::from_secs(9), now);
        }
        // Every scale is fresh: a newcomer's run is learnt for the anonymous sender.
        let newcomer = Some("new".to_string());
        c.learn(&newcomer, &price, Duration::from_secs(9), now);
        assert!(ms(c.price(&None, RESET, now)) > 90.0 * 99.0);
        assert_eq!(ms(c.price(&newcomer, RESET, now)), 90.0);
        assert!(c.0.len() <= MAX_SENDERS + 1);
        // Long after, every scale has decayed to the model: forgotten, room again.
        let later = now + Calibration::HALF_LIFE * 40;
        c.learn(&newcomer, &price, Duration::from_secs(9), later);
        assert!(c.0.len() <= 2, "{} senders kept", c.0.len());
        assert!(ms(c.price(&newcomer, RESET, later)) > 90.0 * 99.0);
    }
}
