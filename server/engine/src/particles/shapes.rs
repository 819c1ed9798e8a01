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
                // The chapter's arithmetic (`system::rect_on`), to the last bit: inside the
                // corners' open box, out through the nearer side.
                let (min, max) = (centre - half, centre + half);
                if !(p.x > min.x && p.x < max.x && p.y > min.y && p.y < max.y) {
                    return None;
                }
                let d = p - centre;
                let (to_x, to_y) = (half.x - d.x.abs(), half.y - d.y.abs());
                Some(if to_x < to_y {
                    Vec2::new(if d.x < 0.0 { min.x } else { max.x }, p.y)
                } else {
                    Vec2::new(p.x, if d.y < 0.0 { min.y } else { max.y })
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
    /// Where any shape may be: one bit per fine cell ([`FINE`] to a side of a cell), set
    /// where a shape's bounds reach. Most particles are far from every shape; this lets
    /// the pass set them aside without a branch.
    covered: Coverage,
}

/// Fine cells to a side of a grid cell in [`ShapeGrid::covered`] (fewer when the grid is
/// large: at most [`MAX_FINE_BITS`] bits).
const FINE: usize = 8;
const MAX_FINE_BITS: usize = 1 << 22;

/// A bitmap of fine cells.
#[derive(Clone, Debug, Default)]
struct Coverage {
    bits: Vec<u64>,
    /// 1 / the fine cell's side.
    inv: f32,
    cols: usize,
    rows: usize,
}

impl Coverage {
    fn new(origin: Vec2, cell: f32, cols: usize, rows: usize, shapes: &[ParticleShape]) -> Self {
        let mut fine = FINE;
        while fine > 1 && cols * fine * rows * fine > MAX_FINE_BITS {
            fine /= 2;
        }
        let (cols, rows) = (cols * fine, rows * fine);
        let mut c = Coverage {
            // One more bit, never set: where points off the grid look.
            bits: vec![0; (cols * rows + 1).div_ceil(64)],
            inv: fine as f32 / cell,
            cols,
            rows,
        };
        for s in shapes {
            let (a, b) = s.bounds();
            let (x0, y0) = c.clamped(a - origin);
            let (x1, y1) = c.clamped(b - origin);
            for y in y0..=y1 {
                for x in x0..=x1 {
                    let k = y * cols + x;
                    c.bits[k / 64] |= 1 << (k % 64);
                }
            }
        }
        c
    }

    /// The fine cell of offset `d` from the origin, clamped to the grid.
    fn clamped(&self, d: Vec2) -> (usize, usize) {
        let f = d * self.inv;
        let at = |v: f32, n: usize| (v.floor().max(0.0) as usize).min(n - 1);
        (at(f.x, self.cols), at(f.y, self.rows))
    }

    /// Sifts a batch of positions: writes to `near` the places (in the batch) of those a
    /// shape's bounds may hold, in order, and returns how many. Off the grid or NaN, a
    /// position is not held. The cell of a point is never left of or below the cell of a
    /// bound it is within (the mapping only grows), so a point inside a shape always
    /// finds its bit set.
    #[inline]
    fn sift(&self, origin: Vec2, x: &[f32], y: &[f32], near: &mut [u16; BATCH]) -> usize {
        // First every position's bit, in a loop without branches the compiler vectorises;
        // then the bits looked up, and the held positions kept.
        let mut bit = [0u32; BATCH];
        let (cols, rows) = (self.cols as f32, self.rows as f32);
        let off = (self.cols * self.rows) as u32;
        for ((b, &px), &py) in bit.iter_mut().zip(x).zip(y) {
            let fx = (px - origin.x) * self.inv;
            let fy = (py - origin.y) * self.inv;
            let on = (fx >= 0.0) & (fy >= 0.0) & (fx < cols) & (fy < rows);
            let k = (fy as u32)
                .wrapping_mul(self.cols as u32)
                .wrapping_add(fx as u32);
            *b = if on { k } else { off };
        }
        let mut n = 0;
        for (i, &k) in bit[..x.len()].iter().enumerate() {
            near[n] = i as u16;
            n += ((self.bits[k as usize / 64] >> (k % 64)) & 1) as usize;
        }
        n
    }
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
        let covered = Coverage::new(lo, cell, cols, rows, &shapes);
        Some(ShapeGrid {
            shapes,
            origin: lo,
            cell,
            cols,
            rows,
            starts,
            slots,
            covered,
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

/// Particles a pass sets aside at a time.
const BATCH: usize = 256;

/// [`Particles::project_out_of_grid`] on positions `x`, `y`: each batch of particles is
/// first sifted without branches for those some shape's bounds may hold (most are not),
/// then only those look up their shapes.
fn grid_on(x: &mut [f32], y: &mut [f32], grid: &ShapeGrid) -> u64 {
    let mut moved = 0;
    let mut near = [0u16; BATCH];
    for base in (0..x.len()).step_by(BATCH) {
        let end = (base + BATCH).min(x.len());
        let n = grid
            .covered
            .sift(grid.origin, &x[base..end], &y[base..end], &mut near);
        for &k in &near[..n] {
            moved += project_one(x, y, base + k as usize, grid);
        }
    }
    moved
}

/// Projects particle `i` out of the grid's shapes, in shape order; 1 per projection.
#[inline]
fn project_one(x: &mut [f32], y: &mut [f32], i: usize, grid: &ShapeGrid) -> u64 {
    let mut moved = 0;
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
    moved
}
