//! The shapes particles collide with, in the form the particle pass reads: 32-bit shapes
//! and a dense uniform grid of them ([`ShapeGrid`]).
//!
//! In: the static and moving shapes of a particle interaction. Out: particles projected
//! out of them, in the chapter's order. The grid is dense and frozen for the step (a
//! point lookup is an array index), unlike the hashed, incremental grid rigid bodies use
//! (`geometry::grid`), because a particle step is one lookup per particle, 10^5 to 10^6
//! times.

use glam::Vec2;

use super::system::{circle_on, rect_on, Particles};

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
        self.project_out_of_grid_on(grid, 1)
    }

    /// [`Particles::project_out_of_grid`] split among `threads` (the same bits).
    pub fn project_out_of_grid_on(&mut self, grid: &ShapeGrid, threads: u32) -> u64 {
        let chunks = self.position_chunks(threads);
        crate::parallel::run(threads, chunks, |(x, y)| grid_on(x, y, grid))
            .into_iter()
            .sum()
    }

    /// Projects every particle out of each of `shapes` in turn (the chapter's order: shape
    /// after shape over every particle), split among `threads` (the same bits: each
    /// particle meets the shapes in the same order). Returns how many projections were
    /// made.
    pub fn project_out_of_shapes_on(&mut self, shapes: &[ParticleShape], threads: u32) -> u64 {
        let chunks = self.position_chunks(threads);
        crate::parallel::run(threads, chunks, |(x, y)| {
            shapes
                .iter()
                .map(|s| match *s {
                    ParticleShape::Rect { centre, half } => rect_on(x, y, centre, half),
                    ParticleShape::Circle { centre, radius } => circle_on(x, y, centre, radius),
                })
                .sum::<u64>()
        })
        .into_iter()
        .sum()
    }
}

/// [`Particles::project_out_of_grid`] on positions `x`, `y`.
fn grid_on(x: &mut [f32], y: &mut [f32], grid: &ShapeGrid) -> u64 {
    let mut moved = 0;
    for i in 0..x.len() {
        let mut p = Vec2::new(x[i], y[i]);
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
        x[i] = p.x;
        y[i] = p.y;
    }
    moved
}
