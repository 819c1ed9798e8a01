//! The uniform grid every rigid broad phase bins boxes in: square cells of one size,
//! hashed by their integer coordinates so the grid needs no bounds, and a list aside for
//! boxes too large to bin (they would fill too many cells).
//!
//! In: slots (body indices) with their boxes. Out: the slots whose cells a box touches.
//! The static grid of a large all-static group (`dynamics::broad_phase`) builds it once;
//! the persistent pair set's index (`geometry::tiered`) keeps the boxes that cover a few
//! cells in it, and the others in a dynamic tree (`geometry::tree`), where a large or
//! fast body costs one leaf, not the cells it covers.
//! (The particle pass keeps its own dense, frozen layout of the few shapes particles hit,
//! `particles::system::ShapeGrid`: a point lookup there is an array index, not a hash.)

use glam::DVec2;

/// A hash map keyed by small integers (rustc's Fx hash). Only lookups use it, never
/// iteration order where order matters, so results stay deterministic.
pub type KeyMap<K, V> = rustc_hash::FxHashMap<K, V>;

/// The cell coordinate `floor(t)`, clamped to +-1e15 (0 for NaN), without a call to the
/// C library's `floor` (a build for any x86-64 has no instruction for it).
fn floor_cell(t: f64) -> i64 {
    let t = t.clamp(-1e15, 1e15);
    let i = t as i64;
    i - i64::from(i as f64 > t)
}

/// Where a slot sits in the grid.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Cells {
    /// In the cells `x0..=x1, y0..=y1`.
    Range(i64, i64, i64, i64),
    /// Too large to bin: kept aside, a candidate of every query.
    Oversized,
}

/// Square cells of side `cell`, each listing the slots whose boxes touch it.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct Grid {
    cell: f64,
    /// A box covering more cells than this is kept aside instead.
    max_cells: i64,
    cells: KeyMap<(i64, i64), Vec<u32>>,
    oversized: Vec<u32>,
    /// Cells left empty by `remove`, kept for the next box that comes (a body moving
    /// through the grid would otherwise free and allocate a cell at every step); swept
    /// out when they are most of the cells.
    #[serde(default)]
    empty: usize,
}

impl Default for Grid {
    fn default() -> Self {
        Grid::new(1.0, 64)
    }
}

impl Grid {
    /// An empty grid of cells of side `cell` (at least 1e-9).
    pub fn new(cell: f64, max_cells: i64) -> Self {
        Grid {
            cell: cell.max(1e-9),
            max_cells,
            cells: KeyMap::default(),
            oversized: Vec::new(),
            empty: 0,
        }
    }

    /// Empties the grid and sets its cell size.
    pub fn reset(&mut self, cell: f64) {
        self.cell = cell.max(1e-9);
        self.cells.clear();
        self.oversized.clear();
        self.empty = 0;
    }

    /// The cells `x0..=x1, y0..=y1` a box covers, and how many they are (saturating).
    pub fn range_of(&self, min: DVec2, max: DVec2) -> ((i64, i64, i64, i64), i64) {
        let c = |v: f64| floor_cell(v / self.cell);
        let (x0, y0, x1, y1) = (c(min.x), c(min.y), c(max.x), c(max.y));
        let count = (x1 - x0 + 1).saturating_mul(y1 - y0 + 1);
        ((x0, y0, x1, y1), count)
    }

    /// The cells a box covers, or `Oversized` when they are more than the grid bins.
    pub fn cells_of(&self, min: DVec2, max: DVec2) -> Cells {
        let ((x0, y0, x1, y1), count) = self.range_of(min, max);
        if count > self.max_cells {
            Cells::Oversized
        } else {
            Cells::Range(x0, y0, x1, y1)
        }
    }

    /// Puts `slot` in every cell its box touches (or aside); says where it went.
    pub fn insert(&mut self, slot: u32, min: DVec2, max: DVec2) -> Cells {
        let place = self.cells_of(min, max);
        match place {
            Cells::Oversized => self.oversized.push(slot),
            Cells::Range(x0, y0, x1, y1) => {
                for cx in x0..=x1 {
                    for cy in y0..=y1 {
                        let list = self.cells.entry((cx, cy)).or_default();
                        if list.is_empty() && list.capacity() > 0 {
                            self.empty = self.empty.saturating_sub(1);
                        }
                        list.push(slot);
                    }
                }
            }
        }
        place
    }

    /// Takes `slot` out of the cells `insert` put it in.
    pub fn remove(&mut self, slot: u32, place: Cells) {
        match place {
            Cells::Oversized => self.oversized.retain(|&j| j != slot),
            Cells::Range(x0, y0, x1, y1) => {
                for cx in x0..=x1 {
                    for cy in y0..=y1 {
                        if let Some(list) = self.cells.get_mut(&(cx, cy)) {
                            if let Some(k) = list.iter().position(|&j| j == slot) {
                                list.swap_remove(k);
                                if list.is_empty() {
                                    self.empty += 1;
                                }
                            }
                        }
                    }
                }
                if self.empty > 1024 && self.empty * 2 > self.cells.len() {
                    self.cells.retain(|_, list| !list.is_empty());
                    self.empty = 0;
                }
            }
        }
    }

    /// Checks a grid read back from a checkpoint: a finite cell size, at most `max_cells`
    /// cells a box (a crafted bound would make one visit run for ever), every slot below
    /// `slots`. Names what is wrong.
    pub fn check(&self, slots: usize, max_cells: i64) -> Result<(), String> {
        if !(self.cell.is_finite() && self.cell >= 1e-9) {
            return Err(format!(
                "cell size {} is not a finite number of at least 1e-9",
                self.cell
            ));
        }
        if !(1..=max_cells).contains(&self.max_cells) {
            return Err(format!(
                "{} cells a box is not 1 to {max_cells}",
                self.max_cells
            ));
        }
        let slot = self
            .cells
            .values()
            .flatten()
            .chain(&self.oversized)
            .find(|&&s| s as usize >= slots);
        if let Some(s) = slot {
            return Err(format!("slot {s} is out of range ({slots} bodies)"));
        }
        Ok(())
    }

    /// Whether `place` is a range of cells this grid could have given (at most its
    /// `max_cells`, corners in order).
    pub fn holds(&self, place: Cells) -> bool {
        match place {
            Cells::Oversized => true,
            Cells::Range(x0, y0, x1, y1) => {
                let side = |lo: i64, hi: i64| {
                    hi.checked_sub(lo)
                        .and_then(|d| d.checked_add(1))
                        .filter(|&n| n >= 1)
                };
                side(x0, x1)
                    .zip(side(y0, y1))
                    .and_then(|(w, h)| w.checked_mul(h))
                    .is_some_and(|n| n <= self.max_cells)
            }
        }
    }

    /// Calls `f` with every slot binned in the cells of `range`, then every slot kept
    /// aside; a slot in several of the cells comes once per cell.
    pub fn visit(&self, range: (i64, i64, i64, i64), mut f: impl FnMut(u32)) {
        let (x0, y0, x1, y1) = range;
        for cx in x0..=x1 {
            for cy in y0..=y1 {
                if let Some(list) = self.cells.get(&(cx, cy)) {
                    list.iter().copied().for_each(&mut f);
                }
            }
        }
        self.oversized.iter().copied().for_each(f);
    }

    /// Appends to `out` the slots whose cells the box touches, and those kept aside, in
    /// increasing order without repeats. A box reaching over more than `4096` cells
    /// takes every slot.
    pub fn query(&self, min: DVec2, max: DVec2, out: &mut Vec<u32>) {
        let start = out.len();
        let c = |v: f64| floor_cell(v / self.cell);
        let (x0, y0, x1, y1) = (c(min.x), c(min.y), c(max.x), c(max.y));
        if (x1 - x0 + 1).saturating_mul(y1 - y0 + 1) > 4096 {
            out.extend(self.cells.values().flatten().copied());
            out.extend_from_slice(&self.oversized);
        } else {
            self.visit((x0, y0, x1, y1), |s| out.push(s));
        }
        out[start..].sort_unstable();
        let mut w = start;
        for r in start..out.len() {
            if r == start || out[r] != out[w - 1] {
                out[w] = out[r];
                w += 1;
            }
        }
        out.truncate(w);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_query_finds_what_touches_its_cells_once_and_in_order() {
        let mut g = Grid::new(1.0, 64);
        g.insert(3, DVec2::new(0.1, 0.1), DVec2::new(1.9, 0.9)); // cells (0,0), (1,0)
        g.insert(1, DVec2::new(5.0, 5.0), DVec2::new(5.5, 5.5));
        let huge = g.insert(7, DVec2::new(-100.0, -100.0), DVec2::new(100.0, 100.0));
        assert_eq!(huge, Cells::Oversized);
        let mut out = Vec::new();
        g.query(DVec2::new(0.5, 0.2), DVec2::new(1.5, 0.4), &mut out);
        assert_eq!(out, [3, 7]);
        out.clear();
        g.query(DVec2::new(-1e6, -1e6), DVec2::new(1e6, 1e6), &mut out);
        assert_eq!(out, [1, 3, 7]);
    }

    #[test]
    fn cells_are_the_floor_of_a_coordinate_over_the_side() {
        for t in [
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            2.999,
            -2.999,
            1e14 + 0.5,
            -1e14 - 0.5,
        ] {
            assert_eq!(floor_cell(t), t.floor() as i64, "{t}");
        }
        assert_eq!(floor_cell(1e300), 1_000_000_000_000_000);
        assert_eq!(floor_cell(f64::NEG_INFINITY), -1_000_000_000_000_000);
        assert_eq!(floor_cell(f64::NAN), 0);
    }

    #[test]
    fn removed_slots_are_gone_from_every_cell() {
        let mut g = Grid::new(1.0, 64);
        let place = g.insert(4, DVec2::new(0.1, 0.1), DVec2::new(2.9, 2.9));
        g.insert(9, DVec2::new(0.1, 0.1), DVec2::new(0.2, 0.2));
        g.remove(4, place);
        let mut seen = Vec::new();
        g.visit((0, 0, 2, 2), |s| seen.push(s));
        assert_eq!(seen, [9]);
    }
}
