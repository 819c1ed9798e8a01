//! The demo objects of the chapter's projects: the hero steered by held directions,
//! patrolling minions, homing dye packs and the stability demo's dumb minions.
//!
//! Rates the chapter gives per update (at 60 updates a second) are kept here per second,
//! so a scene that changes `dt` keeps the same motion in time.

use glam::DVec2;
use serde::{Deserialize, Serialize};

/// A direction of the hero's controls (the chapter's WASD keys).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Direction {
    Up,
    Down,
    Left,
    Right,
}

/// Which directions are held: a held key is a state, not a packet per frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Held {
    pub up: bool,
    pub down: bool,
    pub left: bool,
    pub right: bool,
}

impl Held {
    pub fn set(&mut self, dir: Direction, pressed: bool) {
        match dir {
            Direction::Up => self.up = pressed,
            Direction::Down => self.down = pressed,
            Direction::Left => self.left = pressed,
            Direction::Right => self.right = pressed,
        }
    }

    /// The velocity change per second the held directions ask for: the chapter adds
    /// up +2, down -2, left -1, right +1 to the velocity per update at 60 updates/s.
    pub fn push(&self) -> DVec2 {
        let axis = |pos: bool, neg: bool| (pos as i32 - neg as i32) as f64;
        DVec2::new(
            axis(self.right, self.left) * HERO_PUSH.x,
            axis(self.up, self.down) * HERO_PUSH.y,
        )
    }
}

/// What drives a body besides physics.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum Behavior {
    #[default]
    None,
    /// Steered by held directions.
    Hero { held: Held },
    /// Keeps a horizontal patrol speed; a collision that reverses its motion turns it back.
    Patrol { speed: f64, dir: f64 },
    /// Flies along its heading, turning toward the hero; removed when its life runs out or
    /// when it touches the hero, where it starts an explosion.
    DyePack { heading: DVec2, life: u32 },
    /// The stability demo's test body: pure physics, selectable and agitated by actions.
    DumbMinion,
}

impl Behavior {
    pub fn name(&self) -> &'static str {
        match self {
            Behavior::None => "none",
            Behavior::Hero { .. } => "hero",
            Behavior::Patrol { .. } => "minion",
            Behavior::DyePack { .. } => "dye_pack",
            Behavior::DumbMinion => "dumb_minion",
        }
    }
}

/// Hero's velocity change per second per held axis: (1, 2) per update at 60 updates/s.
pub const HERO_PUSH: DVec2 = DVec2::new(60.0, 120.0);
/// Hero: rectangle 16 x 22, mass 0.7, restitution 0.3.
pub const HERO_SIZE: DVec2 = DVec2::new(16.0, 22.0);
pub const HERO_MASS: f64 = 0.7;
pub const HERO_RESTITUTION: f64 = 0.3;

/// Minion: circle of radius 6.5 (rectangle 17 x 14 in the bounds demo), mass 2, friction
/// 0, no gravity, patrolling at 5 units/s.
pub const MINION_RADIUS: f64 = 6.5;
pub const MINION_RECT: DVec2 = DVec2::new(17.0, 14.0);
pub const MINION_MASS: f64 = 2.0;
pub const MINION_SPEED: f64 = 5.0;

/// Dye pack: circle of radius 1.5, mass 0.1, no gravity, 0.5 units per update along its
/// heading (30 units/s), turning 0.8 of the way toward the hero per update, living 300
/// updates, exploding into 200 particles of the "fire" preset.
pub const DYE_PACK_RADIUS: f64 = 1.5;
pub const DYE_PACK_MASS: f64 = 0.1;
pub const DYE_PACK_SPEED: f64 = 30.0;
pub const DYE_PACK_TURN_RATE: f64 = 0.8;
pub const DYE_PACK_LIFE: u32 = 300;
pub const DYE_PACK_EXPLOSION: u32 = 200;
pub const DYE_PACK_EXPLOSION_PRESET: &str = "fire";

/// Agitation: each dumb minion gets a random velocity change in [-s, s] on each axis.
pub const DEFAULT_AGITATION: f64 = 25.0;

/// Turns `heading` toward `to_target` by `rate` of the angle between them ("rotateObjPointTo").
pub fn turn_toward(heading: DVec2, to_target: DVec2, rate: f64) -> DVec2 {
    let len = to_target.length();
    if len.is_nan() || len <= 0.0 {
        return heading;
    }
    let target = to_target / len;
    let angle = heading.perp_dot(target).atan2(heading.dot(target));
    DVec2::from_angle(angle * rate).rotate(heading)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn held_directions_push_as_the_chapter_at_60_hz() {
        let mut held = Held::default();
        held.set(Direction::Up, true);
        held.set(Direction::Left, true);
        assert_eq!(held.push() / 60.0, DVec2::new(-1.0, 2.0));
        held.set(Direction::Right, true);
        held.set(Direction::Up, false);
        assert_eq!(held.push(), DVec2::ZERO);
    }

    #[test]
    fn turning_covers_the_rate_of_the_angle() {
        let h = turn_toward(DVec2::X, DVec2::new(0.0, 5.0), 0.5);
        let expected = DVec2::from_angle(std::f64::consts::FRAC_PI_4);
        assert!((h - expected).length() < 1e-12, "{h}");
        // Full turn rate points straight at the target, from behind too.
        let h = turn_toward(DVec2::X, DVec2::new(-3.0, -0.001), 1.0);
        assert!((h - DVec2::new(-3.0, -0.001).normalize()).length() < 1e-9);
        // A target at the same point leaves the heading alone.
        assert_eq!(turn_toward(DVec2::Y, DVec2::ZERO, 0.8), DVec2::Y);
    }
}
