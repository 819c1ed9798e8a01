//! Rigid bodies: the definition a scene or an action gives, and the flat storage the
//! solver streams through.

use glam::DVec2;

use crate::geometry::Shape;

/// Index of a group of bodies (see [`crate::world::World::group`]).
pub type GroupId = u16;

/// A stable handle to a body: it survives other bodies being removed.
#[derive(
    Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, serde::Serialize, serde::Deserialize,
)]
pub struct BodyKey(pub u32);

/// Everything needed to create a body. `BodyDef::default()` is the chapter's default
/// rigid shape: mass 1, restitution 0.8, friction 0.3, the world's gravity.
#[derive(Clone, Debug, PartialEq)]
pub struct BodyDef {
    /// The name reported in frames and dumps; unique in a world.
    pub id: String,
    /// The group the body belongs to; interactions are declared between groups.
    pub group: String,
    pub shape: Shape,
    pub pos: DVec2,
    pub vel: DVec2,
    /// Mass; 0 makes the body static (never moved by anything).
    pub mass: f64,
    pub restitution: f64,
    pub friction: f64,
    /// Overrides the world's gravity for this body (the chapter's per-shape acceleration).
    pub gravity: Option<DVec2>,
}

impl Default for BodyDef {
    fn default() -> Self {
        BodyDef {
            id: String::new(),
            group: String::from("default"),
            shape: Shape::rect(1.0, 1.0),
            pos: DVec2::ZERO,
            vel: DVec2::ZERO,
            mass: 1.0,
            restitution: 0.8,
            friction: 0.3,
            gravity: None,
        }
    }
}

/// The largest coordinate or size the engine accepts (units). Beyond it, f64 still holds
/// the numbers but a step's products overflow towards infinity.
pub const MAX_COORDINATE: f64 = 1e12;

/// The smallest mass a dynamic body may have: its inverse stays a finite number the
/// solver can multiply (a mass of 5e-324 would have an infinite one).
pub const MIN_MASS: f64 = 1e-9;
/// The largest mass: with [`MIN_MASS`], mass ratios up to 1e21, all finite.
pub const MAX_MASS: f64 = 1e12;
/// The largest friction coefficient (real materials stay below 2).
pub const MAX_FRICTION: f64 = 100.0;

/// Why a body definition was refused: the field and the reason.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{field}: {reason}")]
pub struct BodyError {
    pub field: &'static str,
    pub reason: String,
}

impl BodyDef {
    /// Checks every number; NaN, infinity, negative or vanishing masses, absurd sizes,
    /// restitution above 1 (a bounce that makes energy) and friction above
    /// [`MAX_FRICTION`] are refused, so no accepted body makes a non-finite state.
    pub fn validate(&self) -> Result<(), BodyError> {
        let err = |field, reason: String| Err(BodyError { field, reason });
        let finite_in = |v: DVec2| v.is_finite() && v.abs().max_element() <= MAX_COORDINATE;
        match self.shape {
            Shape::Rect { half } => {
                if !(finite_in(half) && half.x > 0.0 && half.y > 0.0) {
                    return err("size", format!("{} x {} must be two finite numbers above 0 and at most {MAX_COORDINATE}", half.x * 2.0, half.y * 2.0));
                }
            }
            Shape::Circle { radius } => {
                if !(radius.is_finite() && radius > 0.0 && radius <= MAX_COORDINATE) {
                    return err(
                        "radius",
                        format!(
                            "{radius} must be a finite number above 0 and at most {MAX_COORDINATE}"
                        ),
                    );
                }
            }
        }
        if !finite_in(self.pos) {
            return err(
                "pos",
                format!("{} must be finite and within ±{MAX_COORDINATE}", self.pos),
            );
        }
        if !finite_in(self.vel) {
            return err(
                "vel",
                format!("{} must be finite and within ±{MAX_COORDINATE}", self.vel),
            );
        }
        if !(self.mass == 0.0 || (MIN_MASS..=MAX_MASS).contains(&self.mass)) {
            return err(
                "mass",
                format!(
                    "{:e} must be 0 (static) or from {MIN_MASS:e} to {MAX_MASS:e}",
                    self.mass
                ),
            );
        }
        if !(0.0..=1.0).contains(&self.restitution) {
            return err(
                "restitution",
                format!(
                    "{} must be from 0 to 1 (above 1 a bounce makes energy)",
                    self.restitution
                ),
            );
        }
        if !(0.0..=MAX_FRICTION).contains(&self.friction) {
            return err(
                "friction",
                format!("{} must be from 0 to {MAX_FRICTION}", self.friction),
            );
        }
        if let Some(g) = self.gravity {
            if !finite_in(g) {
                return err("gravity", format!("{g} must be finite"));
            }
        }
        Ok(())
    }

    /// The inverse mass the solver uses: 0 for a static body.
    pub fn inv_mass(&self) -> f64 {
        if self.mass > 0.0 {
            1.0 / self.mass
        } else {
            0.0
        }
    }
}

/// One body as the solver sees it: the hot data every pass streams through, nothing else.
/// What only users and the demo read (the body's id and behaviour) lives apart, in
/// [`crate::world::BodyInfo`], at the same index.
#[derive(Clone, Copy, Debug, serde::Serialize, serde::Deserialize)]
pub struct Body {
    pub pos: DVec2,
    pub vel: DVec2,
    pub shape: Shape,
    pub inv_mass: f64,
    pub restitution: f64,
    pub friction: f64,
    /// Touched by a rigid collision during the current step (drawn red by the chapter).
    pub collided: bool,
    pub gravity: Option<DVec2>,
    pub group: GroupId,
    pub key: BodyKey,
    /// Seconds the body has moved slower than the world's `sleep_speed`.
    pub rest_time: f64,
    /// The body's place averaged over the world's `sleep_delay` since its rest began: a
    /// body at rest stays within `sleep_speed * sleep_delay` of it (push-out that only
    /// shuffles a body in place, as in a container fuller than it can hold, does not
    /// keep it awake).
    #[serde(default)]
    pub rest_anchor: DVec2,
    /// The deepest penetration of its contacts, averaged over the world's `sleep_delay`
    /// since its rest began (see [`crate::dynamics::sleep::rest`]): a body pushed out of
    /// overlaps it cannot leave (jammed) rests however the push-out shuffles it.
    #[serde(default)]
    pub rest_depth: f64,
    /// Set while the body sleeps (see [`crate::dynamics::sleep`]).
    pub asleep: Option<Sleeper>,
}

/// What a sleeping body keeps: during a step the solvers see it as static.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Sleeper {
    /// Its inverse mass, restored after each step.
    pub inv_mass: f64,
}

impl Body {
    pub fn is_static(&self) -> bool {
        self.inv_mass == 0.0
    }

    pub fn mass(&self) -> f64 {
        if self.inv_mass > 0.0 {
            1.0 / self.inv_mass
        } else {
            0.0
        }
    }

    /// A body with the chapter's defaults (restitution 0.8, friction 0.3), for tests.
    #[cfg(test)]
    pub(crate) fn for_test(shape: Shape, pos: DVec2, vel: DVec2, inv_mass: f64) -> Body {
        Body {
            pos,
            vel,
            shape,
            inv_mass,
            restitution: 0.8,
            friction: 0.3,
            collided: false,
            gravity: None,
            group: 0,
            key: BodyKey(0),
            rest_time: 0.0,
            rest_anchor: pos,
            rest_depth: 0.0,
            asleep: None,
        }
    }

    /// Kinetic energy `m v² / 2` (0 for a static body).
    pub fn kinetic_energy(&self) -> f64 {
        0.5 * self.mass() * self.vel.length_squared()
    }
}
