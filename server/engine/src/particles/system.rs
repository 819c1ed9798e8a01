//! Particles ("Particles and Particle Systems"): positions without area that move by
//! symplectic Euler with drag, change colour and size each update and expire.
//!
//! Stored as flat arrays (one per field) so the update loop streams through memory and
//! a million particles cost what their bytes cost. Hot fields are updated every step;
//! colour is cold: it is derived from the particle's age when a frame is read, which is
//! also more exact than the chapter's running sum of colour deltas.

use glam::{Vec2, Vec4};

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
#[derive(Clone, Debug, Default, PartialEq)]
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
    pub fn len(&self) -> usize {
        self.x.len()
    }

    pub fn is_empty(&self) -> bool {
        self.x.is_empty()
    }

    /// Adds a particle; `gravity` is the world's particle gravity, used unless the
    /// definition overrides it.
    pub fn push(&mut self, def: &ParticleDef, gravity: Vec2) {
        let a = def.gravity.unwrap_or(gravity);
        self.id.push(self.next_id);
        self.next_id = self.next_id.wrapping_add(1);
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
        let n = self.len();
        let (x, y, vx, vy) = (
            &mut self.x[..n],
            &mut self.y[..n],
            &mut self.vx[..n],
            &mut self.vy[..n],
        );
        let (ax, ay, drag) = (&self.ax[..n], &self.ay[..n], &self.drag[..n]);
        for i in 0..n {
            let nvx = (vx[i] + ax[i] * dt) * drag[i];
            let nvy = (vy[i] + ay[i] * dt) * drag[i];
            vx[i] = nvx;
            vy[i] = nvy;
            x[i] += nvx * dt;
            y[i] += nvy * dt;
        }
        let (life, size, size_delta) = (
            &mut self.life[..n],
            &mut self.size[..n],
            &self.size_delta[..n],
        );
        let mut any_expired = false;
        for i in 0..n {
            life[i] -= 1.0;
            size[i] *= size_delta[i];
            any_expired |= life[i] < 0.0;
        }
        if any_expired {
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
        let (min, max) = (centre - half, centre + half);
        let mut moved = 0;
        for i in 0..self.len() {
            let (px, py) = (self.x[i], self.y[i]);
            if px > min.x && px < max.x && py > min.y && py < max.y {
                let (dx, dy) = (px - centre.x, py - centre.y);
                let to_x = half.x - dx.abs();
                let to_y = half.y - dy.abs();
                if to_x < to_y {
                    self.x[i] = if dx < 0.0 { min.x } else { max.x };
                } else {
                    self.y[i] = if dy < 0.0 { min.y } else { max.y };
                }
                moved += 1;
            }
        }
        moved
    }

    /// Projects every particle inside the circle out to its boundary ("resolveCirclePos").
    /// A particle exactly at the centre goes out along +y instead of dividing by zero.
    pub fn project_out_of_circle(&mut self, centre: Vec2, radius: f32) -> u64 {
        let r_sq = radius * radius;
        let mut moved = 0;
        for i in 0..self.len() {
            let (dx, dy) = (self.x[i] - centre.x, self.y[i] - centre.y);
            let d_sq = dx * dx + dy * dy;
            if d_sq < r_sq {
                let dist = d_sq.sqrt();
                let (nx, ny) = if dist > 0.0 {
                    (dx / dist, dy / dist)
                } else {
                    (0.0, 1.0)
                };
                self.x[i] = centre.x + nx * radius;
                self.y[i] = centre.y + ny * radius;
                moved += 1;
            }
        }
        moved
    }
}

/// A shape as the particle projection reads it (32-bit, as particles are).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ParticleShape {
    Rect { centre: Vec2, half: Vec2 },
    Circle { centre: Vec2, radius: f32 },
}

impl ParticleShape {
    fn bounds(&self) -> (Vec2, Vec2) {
        match *self {
            ParticleShape::Rect { centre, half } => (centre - half, centre + half),
            ParticleShape::Circle { centre, radius } => {
                (centre - Vec2::splat(radius), centre + Vec2::splat(radius))
            }
        }
    }

    /// Projects a point inside the shape to its boundary; `None` if it is not inside.
    #[inline]
    fn project(&self, p: Vec2) -> Option<Vec2> {
        match *self {
            ParticleShape::Rect { centre, half } => {
                let d = p - centre;
                if d.x.abs() >= half.x || d.y.abs() >= half.y {
                    return None;
                }
                let (to_x, to_y) = (half.x - d.x.abs(), half.y - d.y.abs());
                Some(if to_x < to_y {
                    Vec2::new(centre.x + if d.x < 0.0 { -half.x } else { half.x }, p.y)
                } else {
                    Vec2::new(p.x, centre.y + if d.y < 0.0 { -half.y } else { half.y })
                })
            }
            ParticleShape::Circle { centre, radius } => {
                let d = p - centre;
                let d_sq = d.length_squared();
                if d_sq >= radius * radius {
                    return None;
                }
                let dist = d_sq.sqrt();
                let n = if dist > 0.0 { d / dist } else { Vec2::Y };
                Some(centre + n * radius)
            }
        }
    }
}

/// Shapes binned in a uniform grid, so each particle tests only the shapes of its cell.
///
/// The projection gives exactly the chapter's result (every shape in turn over every
/// particle): a particle meets the shapes in the same order, and after each projection
/// looks again from where it landed, so a shape it was pushed into is not missed.
#[derive(Clone, Debug, Default)]
pub struct ShapeGrid {
    shapes: Vec<ParticleShape>,
    origin: Vec2,
    cell: f32,
    cols: usize,
    rows: usize,
    /// Cell c holds `slots[starts[c]..starts[c + 1]]`, shape indices in increasing order.
    starts: Vec<u32>,
    slots: Vec<u32>,
}

/// Cells a shape may cover before the grid gives up on binning.
const MAX_CELLS: usize = 1 << 20;

impl ShapeGrid {
    /// Bins `shapes`; `None` when they are too uneven in size to bin usefully.
    pub fn build(shapes: Vec<ParticleShape>) -> Option<Self> {
        if shapes.is_empty() {
            return None;
        }
        let (mut lo, mut hi) = (Vec2::splat(f32::MAX), Vec2::splat(f32::MIN));
        let mut mean_extent = 0.0;
        for s in &shapes {
            let (a, b) = s.bounds();
            lo = lo.min(a);
            hi = hi.max(b);
            mean_extent += (b - a).max_element();
        }
        mean_extent /= shapes.len() as f32;
        if !(lo.is_finite() && hi.is_finite() && mean_extent > 0.0) {
            return None;
        }
        let mut cell = mean_extent;
        let span = hi - lo;
        while ((span.x / cell).ceil() as usize + 1) * ((span.y / cell).ceil() as usize + 1)
            > MAX_CELLS
        {
            cell *= 2.0;
        }
        let cols = (span.x / cell).floor() as usize + 1;
        let rows = (span.y / cell).floor() as usize + 1;
        let cell_of =
            |v: f32, o: f32, n: usize| (((v - o) / cell).floor().max(0.0) as usize).min(n - 1);
        let mut counts = vec![0u32; cols * rows + 1];
        let mut ranges = Vec::with_capacity(shapes.len());
        let mut covered = 0usize;
        for s in &shapes {
            let (a, b) = s.bounds();
            let r = (
                cell_of(a.x, lo.x, cols),
                cell_of(a.y, lo.y, rows),
                cell_of(b.x, lo.x, cols),
                cell_of(b.y, lo.y, rows),
            );
            covered += (r.2 - r.0 + 1) * (r.3 - r.1 + 1);
            ranges.push(r);
        }
        if covered > 16 * shapes.len() + MAX_CELLS {
            return None;
        }
        for &(x0, y0, x1, y1) in &ranges {
            for y in y0..=y1 {
                for x in x0..=x1 {
                    counts[y * cols + x + 1] += 1;
                }
            }
        }
        for c in 1..counts.len() {
            counts[c] += counts[c - 1];
        }
        let starts = counts.clone();
        let mut fill = counts;
        let mut slots = vec![0u32; covered];
        for (k, &(x0, y0, x1, y1)) in ranges.iter().enumerate() {
            for y in y0..=y1 {
                for x in x0..=x1 {
                    let c = y * cols + x;
                    slots[fill[c] as usize] = k as u32;
                    fill[c] += 1;
                }
            }
        }
        Some(ShapeGrid {
            shapes,
            origin: lo,
            cell,
            cols,
            rows,
            starts,
            slots,
        })
    }

    /// The shapes of the cell holding `p` (in increasing order), empty outside the grid.
    #[inline]
    fn near(&self, p: Vec2) -> &[u32] {
        let f = (p - self.origin) / self.cell;
        if !(f.x >= 0.0 && f.y >= 0.0) || f.x >= self.cols as f32 || f.y >= self.rows as f32 {
            return &[];
        }
        let c = f.y as usize * self.cols + f.x as usize;
        &self.slots[self.starts[c] as usize..self.starts[c + 1] as usize]
    }
}

impl Particles {
    /// Projects every particle out of the grid's shapes, in shape order. Returns how many
    /// projections were made.
    pub fn project_out_of_grid(&mut self, grid: &ShapeGrid) -> u64 {
        let mut moved = 0;
        for i in 0..self.len() {
            let mut p = Vec2::new(self.x[i], self.y[i]);
            let mut next = 0u32;
            'again: loop {
                for &k in grid.near(p) {
                    if k < next {
                        continue;
                    }
                    if let Some(q) = grid.shapes[k as usize].project(p) {
                        p = q;
                        moved += 1;
                        next = k + 1;
                        continue 'again;
                    }
                }
                break;
            }
            self.x[i] = p.x;
            self.y[i] = p.y;
        }
        moved
    }
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
            for _ in 0..2000 {
                let pos = Vec2::new(
                    rng.random_range(-10.0..110.0),
                    rng.random_range(-10.0..70.0),
                );
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
            assert_eq!(a.x, b.x, "round {round}");
            assert_eq!(a.y, b.y, "round {round}");
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
