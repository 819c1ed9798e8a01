//! Particles ("Particles and Particle Systems"): positions without area that move by
//! symplectic Euler with drag, change colour and size each update and expire.
//!
//! Stored as flat arrays (one per field) so the update loop streams through memory and
//! a million particles cost what their bytes cost. Hot fields are updated every step;
//! colour is cold: it is derived from the particle's age when a frame is read, which is
//! also more exact than the chapter's running sum of colour deltas.

use glam::{Vec2, Vec4};

pub use super::shapes::{ParticleShape, ShapeGrid};

/// The particle colour model, the one the engine and every receiver of frames use: the
/// start colour plus `delta` per update lived, for a particle `age` updates old.
pub fn color_after(start: Vec4, delta: Vec4, age: f32) -> Vec4 {
    start + delta * age
}

/// The particle size model: `size` scaled by `size_delta` once per update, `updates`
/// updates later.
pub fn size_after(size: f32, size_delta: f32, updates: i32) -> f32 {
    size * size_delta.powi(updates)
}

/// One particle as a scene or a preset defines it.
#[derive(Clone, Debug, PartialEq)]
pub struct ParticleDef {
    pub pos: Vec2,
    pub vel: Vec2,
    /// Updates left to live; the particle is removed once this falls below 0.
    pub life: f32,
    pub size: f32,
    pub color: Vec4,
    /// Colour reached when `life` runs out (components above 1 are oversaturated).
    pub final_color: Vec4,
    /// Size factor applied every update (the chapter's `setSizeDelta`).
    pub size_delta: f32,
    /// Velocity factor applied every update.
    pub drag: f32,
    /// Overrides the world's particle gravity.
    pub gravity: Option<Vec2>,
}

impl Default for ParticleDef {
    fn default() -> Self {
        ParticleDef {
            pos: Vec2::ZERO,
            vel: Vec2::ZERO,
            life: 60.0,
            size: 1.0,
            color: Vec4::ONE,
            final_color: Vec4::ONE,
            size_delta: 1.0,
            drag: 0.95,
            gravity: None,
        }
    }
}

/// Why a particle definition was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{field}: {reason}")]
pub struct ParticleError {
    pub field: &'static str,
    pub reason: String,
}

impl ParticleDef {
    pub fn validate(&self) -> Result<(), ParticleError> {
        let err = |field, reason: String| Err(ParticleError { field, reason });
        if !self.pos.is_finite() {
            return err("pos", format!("{} is not finite", self.pos));
        }
        if !self.vel.is_finite() {
            return err("vel", format!("{} is not finite", self.vel));
        }
        if !(self.life.is_finite() && self.life >= 0.0) {
            return err(
                "life",
                format!(
                    "{} must be a finite number of updates, 0 or more",
                    self.life
                ),
            );
        }
        if !(self.size.is_finite() && self.size >= 0.0) {
            return err(
                "size",
                format!("{} must be finite and not negative", self.size),
            );
        }
        if !self.color.is_finite() {
            return err("color", format!("{} is not finite", self.color));
        }
        if !self.final_color.is_finite() {
            return err("final_color", format!("{} is not finite", self.final_color));
        }
        if !(self.size_delta.is_finite() && self.size_delta >= 0.0) {
            return err(
                "size_delta",
                format!("{} must be finite and not negative", self.size_delta),
            );
        }
        if !(self.drag.is_finite() && self.drag >= 0.0) {
            return err(
                "drag",
                format!("{} must be finite and not negative", self.drag),
            );
        }
        if self.gravity.is_some_and(|g| !g.is_finite()) {
            return err("gravity", "is not finite".into());
        }
        Ok(())
    }
}

/// All particles of a world, one array per field.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Particles {
    /// Stable ids, increasing in creation order (what the wire protocol tracks).
    pub id: Vec<u32>,
    next_id: u32,
    // Hot: read and written by every update.
    pub x: Vec<f32>,
    pub y: Vec<f32>,
    pub vx: Vec<f32>,
    pub vy: Vec<f32>,
    pub life: Vec<f32>,
    pub size: Vec<f32>,
    // Read by every update.
    pub ax: Vec<f32>,
    pub ay: Vec<f32>,
    pub drag: Vec<f32>,
    pub size_delta: Vec<f32>,
    // Cold: read only to draw.
    pub initial_life: Vec<f32>,
    /// Start colour, RGBA.
    pub color: Vec<[f32; 4]>,
    /// Colour change per update, RGBA.
    pub color_delta: Vec<[f32; 4]>,
}

impl Particles {
    /// Gives the living particles the ids 0, 1, .. in their order.
    fn renumber(&mut self) {
        for (k, id) in self.id.iter_mut().enumerate() {
            *id = k as u32;
        }
        self.next_id = self.id.len() as u32;
    }

    #[cfg(test)]
    pub(crate) fn set_next_id(&mut self, id: u32) {
        self.next_id = id;
    }

    /// Checks particles read back from a checkpoint: one entry per particle in every
    /// array, every number finite. Names the first array that is wrong.
    pub fn check(&self) -> Result<(), (String, String)> {
        let n = self.x.len();
        let scalars: [(&str, &[f32]); 11] = [
            ("x", &self.x),
            ("y", &self.y),
            ("vx", &self.vx),
            ("vy", &self.vy),
            ("life", &self.life),
            ("size", &self.size),
            ("ax", &self.ax),
            ("ay", &self.ay),
            ("drag", &self.drag),
            ("size_delta", &self.size_delta),
            ("initial_life", &self.initial_life),
        ];
        let colours: [(&str, &[[f32; 4]]); 2] =
            [("color", &self.color), ("color_delta", &self.color_delta)];
        let bad = |name: &str, reason: String| Err((format!("particles.{name}"), reason));
        if self.id.len() != n {
            return bad("id", format!("{} ids for {n} particles", self.id.len()));
        }
        for (name, values) in scalars {
            if values.len() != n {
                return bad(name, format!("{} values for {n} particles", values.len()));
            }
            if let Some(k) = values.iter().position(|v| !v.is_finite()) {
                return bad(
                    &format!("{name}[{k}]"),
                    format!("{} is not finite", values[k]),
                );
            }
        }
        for (name, values) in colours {
            if values.len() != n {
                return bad(name, format!("{} values for {n} particles", values.len()));
            }
            if let Some(k) = values.iter().position(|c| !c.iter().all(|v| v.is_finite())) {
                return bad(&format!("{name}[{k}]"), "not finite".into());
            }
        }
        Ok(())
    }

    pub fn len(&self) -> usize {
        self.x.len()
    }

    pub fn is_empty(&self) -> bool {
        self.x.is_empty()
    }

    /// Adds a particle; `gravity` is the world's particle gravity, used unless the
    /// definition overrides it.
    ///
    /// Ids increase in creation order; when they would pass `u32::MAX` (four billion
    /// particles into a run), the living particles are renumbered 0, 1, .. in the same
    /// order, so ids never wrap (receivers see every particle replaced once).
    pub fn push(&mut self, def: &ParticleDef, gravity: Vec2) {
        let a = def.gravity.unwrap_or(gravity);
        if self.next_id == u32::MAX {
            self.renumber();
        }
        self.id.push(self.next_id);
        self.next_id += 1;
        self.x.push(def.pos.x);
        self.y.push(def.pos.y);
        self.vx.push(def.vel.x);
        self.vy.push(def.vel.y);
        self.life.push(def.life);
        self.size.push(def.size);
        self.ax.push(a.x);
        self.ay.push(a.y);
        self.drag.push(def.drag);
        self.size_delta.push(def.size_delta);
        self.initial_life.push(def.life);
        self.color.push(def.color.to_array());
        // The chapter's setFinalColor: the colour walks to the final one over the life.
        let delta = if def.life != 0.0 {
            (def.final_color - def.color) / def.life
        } else {
            Vec4::ZERO
        };
        self.color_delta.push(delta.to_array());
    }

    /// The colour of particle `i` now ([`color_after`] its age).
    pub fn color_of(&self, i: usize) -> Vec4 {
        color_after(
            Vec4::from(self.color[i]),
            Vec4::from(self.color_delta[i]),
            self.initial_life[i] - self.life[i],
        )
    }

    pub fn pos(&self, i: usize) -> Vec2 {
        Vec2::new(self.x[i], self.y[i])
    }

    /// One update of every particle ("Particle.update", "ParticleGameObject.update"):
    /// `v += a dt; v *= drag; p += v dt`, one update of life used, size scaled. Then the
    /// expired (life below 0) are removed, keeping the order of the rest.
    pub fn update(&mut self, dt: f32) {
        self.update_on(dt, 1);
    }

    /// [`Particles::update`] split among `threads` (the same bits for any count: each
    /// particle is its own work).
    pub fn update_on(&mut self, dt: f32, threads: u32) {
        let n = self.len();
        let (_, size) = crate::parallel::chunking(threads, n);
        let chunks: Vec<_> = self.x[..n]
            .chunks_mut(size)
            .zip(self.y[..n].chunks_mut(size))
            .zip(self.vx[..n].chunks_mut(size))
            .zip(self.vy[..n].chunks_mut(size))
            .zip(self.life[..n].chunks_mut(size))
            .zip(self.size[..n].chunks_mut(size))
            .zip(self.ax[..n].chunks(size))
            .zip(self.ay[..n].chunks(size))
            .zip(self.drag[..n].chunks(size))
            .zip(self.size_delta[..n].chunks(size))
            .map(
                |(((((((((x, y), vx), vy), life), sz), ax), ay), drag), sd)| {
                    (x, y, vx, vy, life, sz, ax, ay, drag, sd)
                },
            )
            .collect();
        let expired = crate::parallel::run(threads, chunks, |chunk| {
            let (x, y, vx, vy, life, size, ax, ay, drag, size_delta) = chunk;
            for i in 0..x.len() {
                let nvx = (vx[i] + ax[i] * dt) * drag[i];
                let nvy = (vy[i] + ay[i] * dt) * drag[i];
                vx[i] = nvx;
                vy[i] = nvy;
                x[i] += nvx * dt;
                y[i] += nvy * dt;
            }
            let mut any_expired = false;
            for i in 0..life.len() {
                life[i] -= 1.0;
                size[i] *= size_delta[i];
                any_expired |= life[i] < 0.0;
            }
            any_expired
        });
        if expired.into_iter().any(|e| e) {
            self.remove_expired();
        }
    }

    /// Removes particles whose life is below 0, in place, keeping the order.
    fn remove_expired(&mut self) {
        let keep: Vec<bool> = self.life.iter().map(|&l| l >= 0.0).collect();
        fn compact<T: Copy>(v: &mut Vec<T>, keep: &[bool]) {
            let mut w = 0;
            for r in 0..v.len() {
                if keep[r] {
                    v[w] = v[r];
                    w += 1;
                }
            }
            v.truncate(w);
        }
        compact(&mut self.id, &keep);
        compact(&mut self.x, &keep);
        compact(&mut self.y, &keep);
        compact(&mut self.vx, &keep);
        compact(&mut self.vy, &keep);
        compact(&mut self.life, &keep);
        compact(&mut self.size, &keep);
        compact(&mut self.ax, &keep);
        compact(&mut self.ay, &keep);
        compact(&mut self.drag, &keep);
        compact(&mut self.size_delta, &keep);
        compact(&mut self.initial_life, &keep);
        compact(&mut self.color, &keep);
        compact(&mut self.color_delta, &keep);
    }

    /// Projects every particle inside the rectangle (centre, half extents) out through
    /// its nearest side ("resolveRectPos"). Returns how many were moved.
    ///
    /// The chapter measured the distance to the right and top sides only; here all four
    /// sides are considered, as for circles against rectangles.
    pub fn project_out_of_rect(&mut self, centre: Vec2, half: Vec2) -> u64 {
        let n = self.len();
        rect_on(&mut self.x[..n], &mut self.y[..n], centre, half)
    }

    /// Projects every particle inside the circle out to its boundary ("resolveCirclePos").
    /// A particle exactly at the centre goes out along +y instead of dividing by zero.
    pub fn project_out_of_circle(&mut self, centre: Vec2, radius: f32) -> u64 {
        let n = self.len();
        circle_on(&mut self.x[..n], &mut self.y[..n], centre, radius)
    }

    /// The particles' positions split for `threads`, in order (see [`crate::parallel`]).
    pub(crate) fn position_chunks(&mut self, threads: u32) -> Vec<(&mut [f32], &mut [f32])> {
        let n = self.len();
        let (_, size) = crate::parallel::chunking(threads, n);
        self.x[..n]
            .chunks_mut(size)
            .zip(self.y[..n].chunks_mut(size))
            .collect()
    }
}

/// [`Particles::project_out_of_rect`] on positions `x`, `y`.
pub(crate) fn rect_on(x: &mut [f32], y: &mut [f32], centre: Vec2, half: Vec2) -> u64 {
    let (min, max) = (centre - half, centre + half);
    let mut moved = 0;
    for i in 0..x.len() {
        let (px, py) = (x[i], y[i]);
        if px > min.x && px < max.x && py > min.y && py < max.y {
            let (dx, dy) = (px - centre.x, py - centre.y);
            let to_x = half.x - dx.abs();
            let to_y = half.y - dy.abs();
            if to_x < to_y {
                x[i] = if dx < 0.0 { min.x } else { max.x };
            } else {
                y[i] = if dy < 0.0 { min.y } else { max.y };
            }
            moved += 1;
        }
    }
    moved
}

/// [`Particles::project_out_of_circle`] on positions `x`, `y`.
pub(crate) fn circle_on(x: &mut [f32], y: &mut [f32], centre: Vec2, radius: f32) -> u64 {
    let r_sq = radius * radius;
    let mut moved = 0;
    for i in 0..x.len() {
        let (dx, dy) = (x[i] - centre.x, y[i] - centre.y);
        let d_sq = dx * dx + dy * dy;
        if d_sq < r_sq {
            let dist = d_sq.sqrt();
            let (nx, ny) = if dist > 0.0 {
                (dx / dist, dy / dist)
            } else {
                (0.0, 1.0)
            };
            x[i] = centre.x + nx * radius;
            y[i] = centre.y + ny * radius;
            moved += 1;
        }
    }
    moved
}

#[cfg(test)]
mod tests {
    use super::*;

    fn one(def: ParticleDef) -> Particles {
        let mut p = Particles::default();
        p.push(&def, Vec2::new(0.0, -50.0));
        p
    }

    #[test]
    fn ids_never_wrap_they_are_renumbered_in_order() {
        let mut p = Particles::default();
        let def = ParticleDef {
            life: 100.0,
            ..Default::default()
        };
        p.set_next_id(u32::MAX - 2);
        for _ in 0..5 {
            p.push(&def, Vec2::ZERO);
        }
        assert_eq!(p.id, [0, 1, 2, 3, 4]);
        assert!(p.id.windows(2).all(|w| w[0] < w[1]));
    }

    #[test]
    fn a_particle_of_life_l_lives_l_plus_one_updates_and_reaches_its_final_colour() {
        let mut p = one(ParticleDef {
            life: 10.0,
            color: Vec4::new(1.0, 0.0, 0.0, 1.0),
            final_color: Vec4::new(3.0, 0.5, 0.5, 0.5),
            ..Default::default()
        });
        for k in 1..=10 {
            p.update(1.0 / 60.0);
            assert_eq!(p.len(), 1, "still alive after update {k}");
        }
        let c = p.color_of(0);
        assert!(
            (c - Vec4::new(3.0, 0.5, 0.5, 0.5)).abs().max_element() < 1e-6,
            "{c}"
        );
        p.update(1.0 / 60.0);
        assert_eq!(p.len(), 0);
    }

    #[test]
    fn motion_with_drag_and_size_factor() {
        let mut p = one(ParticleDef {
            vel: Vec2::new(10.0, 0.0),
            size: 2.0,
            size_delta: 0.5,
            drag: 0.5,
            gravity: Some(Vec2::ZERO),
            ..Default::default()
        });
        p.update(0.1);
        // v = (10 + 0) * 0.5 = 5; x = 5 * 0.1.
        assert_eq!(p.vx[0], 5.0);
        assert_eq!(p.x[0], 0.5);
        assert_eq!(p.size[0], 1.0);
    }

    #[test]
    fn expiry_keeps_the_order_of_the_survivors() {
        let mut p = Particles::default();
        for (i, life) in [5.0, 0.0, 3.0, 0.5, 9.0].into_iter().enumerate() {
            p.push(
                &ParticleDef {
                    pos: Vec2::new(i as f32, 0.0),
                    life,
                    ..Default::default()
                },
                Vec2::ZERO,
            );
        }
        p.update(0.0);
        assert_eq!(p.x, vec![0.0, 2.0, 4.0]);
        assert_eq!(p.life, vec![4.0, 2.0, 8.0]);
        assert_eq!(p.color.len(), 3);
    }

    #[test]
    fn particles_leave_a_rectangle_by_the_nearest_of_all_four_sides() {
        let mut p = Particles::default();
        for pos in [(4.0, 0.5), (-4.0, 0.5), (0.5, 4.5), (0.5, -4.5), (9.0, 9.0)] {
            p.push(
                &ParticleDef {
                    pos: Vec2::from(pos),
                    ..Default::default()
                },
                Vec2::ZERO,
            );
        }
        let moved = p.project_out_of_rect(Vec2::ZERO, Vec2::new(5.0, 5.0));
        assert_eq!(moved, 4);
        assert_eq!(p.pos(0), Vec2::new(5.0, 0.5));
        assert_eq!(p.pos(1), Vec2::new(-5.0, 0.5));
        assert_eq!(p.pos(2), Vec2::new(0.5, 5.0));
        assert_eq!(p.pos(3), Vec2::new(0.5, -5.0));
        assert_eq!(p.pos(4), Vec2::new(9.0, 9.0));
    }

    #[test]
    fn the_shape_grid_projects_exactly_as_shape_after_shape() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        for round in 0..20 {
            let shapes: Vec<ParticleShape> = (0..rng.random_range(1..60))
                .map(|_| {
                    let centre =
                        Vec2::new(rng.random_range(0.0..100.0), rng.random_range(0.0..60.0));
                    if rng.random::<bool>() {
                        ParticleShape::Rect {
                            centre,
                            half: Vec2::new(
                                rng.random_range(0.5..15.0),
                                rng.random_range(0.5..6.0),
                            ),
                        }
                    } else {
                        ParticleShape::Circle {
                            centre,
                            radius: rng.random_range(0.5..8.0),
                        }
                    }
                })
                .collect();
            let mut a = Particles::default();
            // Random places, and the places a sift could get wrong: a hair inside each
            // shape's edges and corners, on them, and nowhere (NaN).
            let mut places: Vec<Vec2> = (0..2000)
                .map(|_| {
                    Vec2::new(
                        rng.random_range(-10.0..110.0),
                        rng.random_range(-10.0..70.0),
                    )
                })
                .collect();
            for s in &shapes {
                let (centre, half) = match *s {
                    ParticleShape::Rect { centre, half } => (centre, half),
                    ParticleShape::Circle { centre, radius } => (centre, Vec2::splat(radius)),
                };
                for (sx, sy) in [(-1.0, -1.0), (1.0, 1.0), (-1.0, 0.0), (0.0, 1.0)] {
                    let edge = centre + half * Vec2::new(sx, sy);
                    let inward = |v: f32, c: f32| if v > c { v.next_down() } else { v.next_up() };
                    places.push(edge);
                    places.push(Vec2::new(
                        inward(edge.x, centre.x),
                        inward(edge.y, centre.y),
                    ));
                }
            }
            places.push(Vec2::NAN);
            for pos in places {
                a.push(
                    &ParticleDef {
                        pos,
                        ..Default::default()
                    },
                    Vec2::ZERO,
                );
            }
            let mut b = a.clone();
            let mut by_shape = 0;
            for s in &shapes {
                by_shape += match *s {
                    ParticleShape::Rect { centre, half } => a.project_out_of_rect(centre, half),
                    ParticleShape::Circle { centre, radius } => {
                        a.project_out_of_circle(centre, radius)
                    }
                };
            }
            let grid = ShapeGrid::build(shapes).expect("binnable");
            let by_grid = b.project_out_of_grid(&grid);
            // By bits (a NaN stays the same NaN), naming the first particle that differs.
            let bits = |p: &Particles| -> Vec<(u32, u32)> {
                p.x.iter()
                    .zip(&p.y)
                    .map(|(x, y)| (x.to_bits(), y.to_bits()))
                    .collect()
            };
            let (want, got) = (bits(&a), bits(&b));
            let first = want.iter().zip(&got).position(|(w, g)| w != g);
            assert_eq!(first, None, "round {round}: particle {first:?} differs");
            assert_eq!(by_shape, by_grid);
        }
    }

    #[test]
    fn particles_leave_a_circle_radially_even_from_its_centre() {
        let mut p = Particles::default();
        for pos in [(0.6, 0.8), (2.0, 2.0), (0.0, 0.0)] {
            p.push(
                &ParticleDef {
                    pos: Vec2::from(pos) + Vec2::new(10.0, 10.0),
                    ..Default::default()
                },
                Vec2::ZERO,
            );
        }
        let moved = p.project_out_of_circle(Vec2::new(10.0, 10.0), 2.0);
        assert_eq!(moved, 2);
        assert!((p.pos(0) - Vec2::new(11.2, 11.6)).length() < 1e-5);
        assert_eq!(p.pos(1), Vec2::new(12.0, 12.0));
        assert_eq!(p.pos(2), Vec2::new(10.0, 12.0));
        assert!(p.x.iter().chain(&p.y).all(|v| v.is_finite()));
    }
}
