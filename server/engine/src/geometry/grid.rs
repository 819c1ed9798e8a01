//! The uniform grid every rigid broad phase bins boxes in: square cells of one size, kept
//! in a dense block where the boxes are and hashed by their integer coordinates beyond it,
//! so the grid needs no bounds, and a list aside for boxes too large to bin (they would
//! fill too many cells).
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

/// The most cells the grid keeps in its dense block ([`Block`]): 64 Ki cells, 1.5 MiB of
/// empty lists at most, and [`BLOCK_CELLS_A_BOX`] a box it holds.
const BLOCK_CELLS: i64 = 1 << 16;
const BLOCK_CELLS_A_BOX: i64 = 16;

/// A dense rectangle of cells `x0..x0 + w, y0..y0 + h`, column by column: a cell there is
/// an array index, not a hash lookup. It grows to hold where the boxes go, up to
/// [`BLOCK_CELLS`]; the cells outside it are hashed.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
struct Block {
    x0: i64,
    y0: i64,
    w: i64,
    h: i64,
    lists: Vec<Vec<u32>>,
}

impl Block {
    /// The index of cell `(cx, cy)`, if the block has it.
    #[inline]
    fn index(&self, cx: i64, cy: i64) -> Option<usize> {
        let (dx, dy) = (cx.wrapping_sub(self.x0), cy.wrapping_sub(self.y0));
        ((dx as u64) < self.w as u64 && (dy as u64) < self.h as u64)
            .then(|| (dx * self.h + dy) as usize)
    }

    /// Whether the block has every cell of `x0..=x1, y0..=y1`.
    #[inline]
    fn covers(&self, (x0, y0, x1, y1): (i64, i64, i64, i64)) -> bool {
        x0 >= self.x0 && y0 >= self.y0 && x1 < self.x0 + self.w && y1 < self.y0 + self.h
    }
}

/// Square cells of side `cell`, each listing the slots whose boxes touch it.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct Grid {
    cell: f64,
    /// A box covering more cells than this is kept aside instead.
    max_cells: i64,
    /// The cells where the boxes are, dense; the others hashed in `cells`. Which holds a
    /// cell changes nothing a caller sees: a cell's list is the same either way.
    #[serde(default)]
    block: Block,
    cells: KeyMap<(i64, i64), Vec<u32>>,
    oversized: Vec<u32>,
    /// Boxes binned in cells (not those kept aside).
    #[serde(default)]
    boxes: usize,
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
            block: Block::default(),
            cells: KeyMap::default(),
            oversized: Vec::new(),
            boxes: 0,
            empty: 0,
        }
    }

    /// Empties the grid and sets its cell size.
    pub fn reset(&mut self, cell: f64) {
        self.cell = cell.max(1e-9);
        self.block = Block::default();
        self.boxes = 0;
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
                self.boxes += 1;
                if !self.block.covers((x0, y0, x1, y1)) {
                    self.grow((x0, y0, x1, y1));
                }
                for cx in x0..=x1 {
                    for cy in y0..=y1 {
                        if let Some(k) = self.block.index(cx, cy) {
                            self.block.lists[k].push(slot);
                            continue;
                        }
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

    /// Grows the dense block to hold the cells `range` as well, when the two fit in
    /// [`BLOCK_CELLS`]: to twice the extent they need (a body flying on finds room
    /// already), or to just that, if that at least doubles the block. The hashed cells the
    /// block comes to cover move into it.
    fn grow(&mut self, range: (i64, i64, i64, i64)) {
        let (x0, y0, x1, y1) = range;
        let b = &self.block;
        let (ux0, uy0, ux1, uy1) = if b.w == 0 {
            (x0, y0, x1, y1)
        } else {
            (
                x0.min(b.x0),
                y0.min(b.y0),
                x1.max(b.x0 + b.w - 1),
                y1.max(b.y0 + b.h - 1),
            )
        };
        // Room for the boxes the grid holds, not for wherever one flew off to: a block
        // of many empty cells costs its making and its misses in the cache.
        let most = BLOCK_CELLS.min(BLOCK_CELLS_A_BOX * (self.boxes as i64 + 16));
        let fits = |w: i64, h: i64| w.checked_mul(h).is_some_and(|n| n <= most) && w > 0 && h > 0;
        let (Some(uw), Some(uh)) = (
            ux1.checked_sub(ux0).and_then(|d| d.checked_add(1)),
            uy1.checked_sub(uy0).and_then(|d| d.checked_add(1)),
        ) else {
            return;
        };
        let (nx0, ny0, nw, nh) = if fits(2 * uw, 2 * uh) {
            (ux0 - uw / 2, uy0 - uh / 2, 2 * uw, 2 * uh)
        } else if fits(uw, uh) {
            (ux0, uy0, uw, uh)
        } else {
            return;
        };
        // Each growth at least doubles the block, so it is built again a few times at most
        // (a body flying on past a full block goes to the hashed cells).
        if nw * nh < 2 * b.w * b.h {
            return;
        }
        let mut next = Block {
            x0: nx0,
            y0: ny0,
            w: nw,
            h: nh,
            lists: Vec::new(),
        };
        next.lists.resize_with((nw * nh) as usize, Vec::new);
        let old = std::mem::take(&mut self.block);
        for (k, list) in old.lists.into_iter().enumerate() {
            let (dx, dy) = (k as i64 / old.h, k as i64 % old.h);
            if let Some(j) = next.index(old.x0 + dx, old.y0 + dy) {
                next.lists[j] = list;
            }
        }
        self.cells
            .retain(|&(cx, cy), list| match next.index(cx, cy) {
                Some(j) => {
                    next.lists[j] = std::mem::take(list);
                    false
                }
                None => true,
            });
        self.empty = self.cells.values().filter(|l| l.is_empty()).count();
        self.block = next;
    }

    /// The list of cell `(cx, cy)`, if it has one.
    #[inline]
    fn list(&self, cx: i64, cy: i64) -> Option<&Vec<u32>> {
        match self.block.index(cx, cy) {
            Some(k) => Some(&self.block.lists[k]),
            None => self.cells.get(&(cx, cy)),
        }
    }

    /// Takes `slot` out of the cells `insert` put it in.
    pub fn remove(&mut self, slot: u32, place: Cells) {
        match place {
            Cells::Oversized => self.oversized.retain(|&j| j != slot),
            Cells::Range(x0, y0, x1, y1) => {
                self.boxes = self.boxes.saturating_sub(1);
                for cx in x0..=x1 {
                    for cy in y0..=y1 {
                        if let Some(k) = self.block.index(cx, cy) {
                            let list = &mut self.block.lists[k];
                            if let Some(k) = list.iter().position(|&j| j == slot) {
                                list.swap_remove(k);
                            }
                        } else if let Some(list) = self.cells.get_mut(&(cx, cy)) {
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
        let b = &self.block;
        if b.w < 0 || b.h < 0 || b.w.checked_mul(b.h) != Some(b.lists.len() as i64) {
            return Err(format!(
                "a block of {} x {} cells holds {} lists",
                b.w,
                b.h,
                b.lists.len()
            ));
        }
        let slot = self
            .cells
            .values()
            .chain(&b.lists)
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
        if self.block.covers(range) {
            // Every cell in the block: a column of the range is a run of its lists.
            let b = &self.block;
            for cx in x0..=x1 {
                let top = ((cx - b.x0) * b.h + (y0 - b.y0)) as usize;
                for list in &b.lists[top..=top + (y1 - y0) as usize] {
                    list.iter().copied().for_each(&mut f);
                }
            }
        } else {
            for cx in x0..=x1 {
                for cy in y0..=y1 {
                    if let Some(list) = self.list(cx, cy) {
                        list.iter().copied().for_each(&mut f);
                    }
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
            out.extend(
                self.cells
                    .values()
                    .chain(&self.block.lists)
                    .flatten()
                    .copied(),
            );
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

    proptest::proptest! {
        /// Boxes inserted and removed near each other and far off (past what the dense
        /// block may cover): every visit meets the slots of each cell in the order a plain
        /// map of cells keeps them, wherever the grid keeps the cell.
        #[test]
        fn a_visit_meets_each_cells_slots_as_a_map_of_cells_keeps_them(
            ops in proptest::collection::vec(
                (0u32..40, proptest::bool::ANY, -30.0f64..30.0, -30.0f64..30.0, 0.0f64..3.0, 0u8..4),
                1..300),
        ) {
            let mut g = Grid::new(0.5, 64);
            let mut model: std::collections::BTreeMap<(i64, i64), Vec<u32>> = Default::default();
            let mut placed: Vec<Option<(Cells, (DVec2, DVec2))>> = vec![None; 40];
            for (slot, remove, x, y, side, far) in ops {
                // One box in four a million cells off.
                let at = DVec2::new(x, y) + DVec2::splat(if far == 0 { 5e5 } else { 0.0 });
                let b = (at, at + DVec2::splat(side));
                if let Some((place, _)) = placed[slot as usize].take() {
                    g.remove(slot, place);
                    if let Cells::Range(x0, y0, x1, y1) = place {
                        for c in (x0..=x1).flat_map(|cx| (y0..=y1).map(move |cy| (cx, cy))) {
                            let list = model.get_mut(&c).expect("inserted");
                            let k = list.iter().position(|&j| j == slot).expect("inserted");
                            list.swap_remove(k);
                        }
                    }
                }
                if !remove {
                    let place = g.insert(slot, b.0, b.1);
                    if let Cells::Range(x0, y0, x1, y1) = place {
                        for cx in x0..=x1 {
                            for cy in y0..=y1 {
                                model.entry((cx, cy)).or_default().push(slot);
                            }
                        }
                    }
                    placed[slot as usize] = Some((place, b));
                }
                for (_, b) in placed.iter().flatten() {
                    let ((x0, y0, x1, y1), _) = g.range_of(b.0, b.1);
                    let mut seen: Vec<u32> = Vec::new();
                    g.visit((x0, y0, x1, y1), |s| seen.push(s));
                    let mut want: Vec<u32> = Vec::new();
                    for cx in x0..=x1 {
                        for cy in y0..=y1 {
                            want.extend(model.get(&(cx, cy)).into_iter().flatten());
                        }
                    }
                    want.extend(&g.oversized);
                    proptest::prop_assert_eq!(seen, want);
                }
            }
        }
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
