//! Movement ("Implementing Symplectic Euler Integration").

use glam::DVec2;

use super::body::Body;
use super::config::{Integrator, WorldConfig};

/// The acceleration a body feels: its own or the world's gravity, scaled by the inverse
/// mass when the world keeps the chapter's convention (`mass_scaled_acceleration`).
pub fn acceleration(body: &Body, config: &WorldConfig) -> DVec2 {
    acceleration_under(body, config.gravity, config.mass_scaled_acceleration)
}

/// [`acceleration`] under the world gravity `gravity`, scaled by the inverse mass when
/// `mass_scaled`.
pub fn acceleration_under(body: &Body, gravity: DVec2, mass_scaled: bool) -> DVec2 {
    let a = body.gravity.unwrap_or(gravity);
    if mass_scaled {
        a * body.inv_mass
    } else {
        a
    }
}

/// Advances the bodies listed in `movers` (the dynamic ones) by a step of `dt` with the
/// configured integrator. Static bodies (mass 0) are never moved, whatever velocity they
/// were given.
pub fn integrate_bodies(bodies: &mut [Body], movers: &[u32], config: &WorldConfig, dt: f64) {
    for &i in movers {
        let body = &mut bodies[i as usize];
        if body.is_static() {
            continue;
        }
        let a = acceleration(body, config);
        match config.integrator {
            Integrator::Symplectic => {
                body.vel += a * dt;
                body.pos += body.vel * dt;
            }
            Integrator::Explicit => {
                body.pos += body.vel * dt;
                body.vel += a * dt;
            }
            Integrator::Exact => {
                body.pos += body.vel * dt + a * (0.5 * dt * dt);
                body.vel += a * dt;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Shape;

    /// Integrates every body of `bodies`.
    fn integrate_bodies(bodies: &mut [Body], config: &WorldConfig, dt: f64) {
        let all: Vec<u32> = (0..bodies.len() as u32).collect();
        super::integrate_bodies(bodies, &all, config, dt);
    }

    fn ball(inv_mass: f64) -> Body {
        Body::for_test(
            Shape::circle(1.0),
            DVec2::new(0.0, 100.0),
            DVec2::ZERO,
            inv_mass,
        )
    }

    /// Symplectic Euler from rest under constant `g`: v_n = n g dt and
    /// y_n = y_0 + g dt² n(n+1)/2 (the sum of the updated velocities).
    #[test]
    fn drop_from_rest_matches_the_closed_form_of_symplectic_euler() {
        let config = WorldConfig {
            mass_scaled_acceleration: false,
            ..WorldConfig::default()
        };
        let mut bodies = vec![ball(0.5)];
        let (g, dt) = (config.gravity.y, config.dt);
        for n in 1..=120u32 {
            integrate_bodies(&mut bodies, &config, config.dt);
            let n = n as f64;
            let y = 100.0 + g * dt * dt * n * (n + 1.0) / 2.0;
            assert!(
                (bodies[0].pos.y - y).abs() < 1e-9,
                "step {n}: {} vs {y}",
                bodies[0].pos.y
            );
            assert!((bodies[0].vel.y - n * g * dt).abs() < 1e-9);
        }
    }

    /// Explicit Euler lags one step behind: y_n = y_0 + g dt² n(n-1)/2.
    #[test]
    fn explicit_euler_uses_the_old_velocity() {
        let config = WorldConfig {
            integrator: Integrator::Explicit,
            mass_scaled_acceleration: false,
            ..WorldConfig::default()
        };
        let mut bodies = vec![ball(1.0)];
        let (g, dt) = (config.gravity.y, config.dt);
        for n in 1..=60u32 {
            integrate_bodies(&mut bodies, &config, config.dt);
            let n = n as f64;
            let y = 100.0 + g * dt * dt * n * (n - 1.0) / 2.0;
            assert!((bodies[0].pos.y - y).abs() < 1e-9);
        }
    }

    /// The exact integrator follows `y = y0 + v0 t + g t²/2` to rounding: a projectile
    /// thrown up and sideways, 2 s at 1/60 s.
    #[test]
    fn the_exact_integrator_follows_the_closed_form_of_a_projectile() {
        let config = WorldConfig {
            integrator: Integrator::Exact,
            mass_scaled_acceleration: false,
            ..WorldConfig::default()
        };
        let mut thrown = ball(1.0);
        thrown.vel = DVec2::new(7.0, 31.0);
        let (p0, v0, g, dt) = (thrown.pos, thrown.vel, config.gravity, 1.0 / 60.0);
        let mut bodies = vec![thrown];
        let mut worst: f64 = 0.0;
        for n in 1..=120u32 {
            integrate_bodies(&mut bodies, &config, dt);
            let t = n as f64 * dt;
            let p = p0 + v0 * t + g * (0.5 * t * t);
            worst = worst.max((bodies[0].pos - p).length());
            assert!((bodies[0].vel - (v0 + g * t)).length() < 1e-9);
        }
        assert!(worst < 1e-9, "worst position error {worst}");
        // Symplectic Euler on the same throw is off by g dt t / 2 at t = 2 s.
        let symplectic = WorldConfig {
            integrator: Integrator::Symplectic,
            ..config
        };
        let mut bodies = vec![thrown];
        for _ in 0..120 {
            integrate_bodies(&mut bodies, &symplectic, dt);
        }
        let off = (bodies[0].pos - (p0 + v0 * 2.0 + g * 2.0)).length();
        assert!(
            (off - g.length() * dt).abs() < 1e-9,
            "symplectic off by {off}"
        );
    }

    #[test]
    fn mass_scaled_acceleration_halves_the_fall_of_a_mass_two_body() {
        let config = WorldConfig::default();
        let mut bodies = vec![ball(1.0), ball(0.5)];
        integrate_bodies(&mut bodies, &config, config.dt);
        assert!((bodies[1].vel.y * 2.0 - bodies[0].vel.y).abs() < 1e-12);
        let classical = WorldConfig {
            mass_scaled_acceleration: false,
            ..config
        };
        let mut bodies = vec![ball(1.0), ball(0.5)];
        integrate_bodies(&mut bodies, &classical, classical.dt);
        assert_eq!(bodies[0].vel, bodies[1].vel);
    }

    #[test]
    fn static_bodies_never_move() {
        let config = WorldConfig::default();
        let mut platform = ball(0.0);
        platform.vel = DVec2::new(3.0, 4.0);
        let mut bodies = vec![platform];
        integrate_bodies(&mut bodies, &config, config.dt);
        assert_eq!(bodies[0].pos, DVec2::new(0.0, 100.0));
    }
}
