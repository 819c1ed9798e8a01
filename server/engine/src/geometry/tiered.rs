//! Boxes of every size in two tiers: a uniform grid for the boxes that cover a few of its
//! cells, a dynamic tree ([`Tree`]) for the others.
//!
//! A grid finds the neighbours of a small box in a few cells, faster than a tree's
//! descent, but a box covering many cells costs every cell, each time it moves: a large
//! body among small ones, or a small one thrown fast whose box is grown by its travel.
//! Those go to the tree, where a box costs one leaf whatever its size. A query meets the
//! grid's boxes in the cells it covers (or, when it covers more cells than the grid holds
//! boxes, by walking the grid's boxes), and the tree's by descending it.
//!
//! In: items (body indices) with their boxes. Out: the items whose boxes may overlap a
//! box, each once, in an order that depends on the insertions (the caller sorts).

use glam::DVec2;

use super::grid::{Cells, Grid};
use super::tree::Tree;

/// A box covering more cells than this goes to the tree.
pub const GRID_CELLS: i64 = 16;
/// When the boxes going to the tree at once are this share of it or more (one in this
/// many), the tree is built again whole: cheaper than inserting them one by one, and a
/// better tree.
const REBUILD_SHARE: usize = 8;

/// Where an item is.
const NOWHERE: u32 = u32::MAX;
const IN_GRID: u32 = u32::MAX - 1;
/// Waiting for [`Tiered::flush`] to put it in the tree.
const PENDING: u32 = u32::MAX - 2;

/// The two tiers and where each item is.
#[derive(Clone, Debug, Default)]
pub struct Tiered {
    grid: Grid,
    tree: Tree,
    /// Each item's leaf in the tree, or `IN_GRID`, `PENDING`, `NOWHERE`.
    at: Vec<u32>,
    /// Items in the grid.
    in_grid: Vec<u32>,
    /// Each grid item's position in `in_grid`.
    grid_slot: Vec<u32>,
    pending: Vec<(u32, DVec2, DVec2)>,
    /// The search each item was last met by (a grid item comes once per cell it covers).
    seen: Vec<u32>,
    search: u32,
    stack: Vec<u32>,
}

impl Tiered {
    /// Empties the tiers for items `0..n`, with grid cells of side `cell`.
    pub fn reset(&mut self, cell: f64, n: usize) {
        self.grid = Grid::new(cell, GRID_CELLS);
        self.tree.clear();
        self.at.clear();
        self.at.resize(n, NOWHERE);
        self.in_grid.clear();
        self.grid_slot.clear();
        self.grid_slot.resize(n, NOWHERE);
        self.pending.clear();
        self.seen.clear();
        self.seen.resize(n, 0);
        self.search = 0;
    }

    /// Items `reset` was given room for.
    pub fn capacity(&self) -> usize {
        self.at.len()
    }

    /// Items in the tree (after `flush`).
    pub fn in_tree(&self) -> usize {
        self.tree.len()
    }

    /// Puts `item` with the box `min..max` in its tier (the tree's after `flush`).
    pub fn insert(&mut self, item: u32, min: DVec2, max: DVec2) {
        match self.grid.cells_of(min, max) {
            Cells::Range(..) => {
                self.grid.insert(item, min, max);
                self.at[item as usize] = IN_GRID;
                self.grid_slot[item as usize] = self.in_grid.len() as u32;
                self.in_grid.push(item);
            }
            Cells::Oversized => {
                self.pending.push((item, min, max));
                self.at[item as usize] = PENDING;
            }
        }
    }

    /// Takes `item` out; `min..max` is the box it was inserted with.
    pub fn remove(&mut self, item: u32, min: DVec2, max: DVec2) {
        match self.at[item as usize] {
            NOWHERE => return,
            IN_GRID => {
                self.grid.remove(item, self.grid.cells_of(min, max));
                let k = self.grid_slot[item as usize] as usize;
                self.in_grid.swap_remove(k);
                if let Some(&moved) = self.in_grid.get(k) {
                    self.grid_slot[moved as usize] = k as u32;
                }
                self.grid_slot[item as usize] = NOWHERE;
            }
            PENDING => self.pending.retain(|p| p.0 != item),
            leaf => self.tree.remove(leaf),
        }
        self.at[item as usize] = NOWHERE;
    }

    /// Moves `item` from the box `old_min..old_max` it was inserted with to `min..max`:
    /// nothing to do when both cover the same cells of the grid (a slow body placed
    /// again), else taken out and put in again.
    pub fn relocate(&mut self, item: u32, old: (DVec2, DVec2), min: DVec2, max: DVec2) {
        if self.at[item as usize] == IN_GRID {
            let now = self.grid.cells_of(min, max);
            if matches!(now, Cells::Range(..)) && now == self.grid.cells_of(old.0, old.1) {
                return;
            }
        }
        self.remove(item, old.0, old.1);
        self.insert(item, min, max);
    }

    /// Puts the items waiting for the tree in it: one by one, or, when they are many, by
    /// building the tree again with them.
    pub fn flush(&mut self) {
        if self.pending.is_empty() {
            return;
        }
        let mut boxes = std::mem::take(&mut self.pending);
        if boxes.len() * REBUILD_SHARE >= self.tree.len() + boxes.len() {
            self.tree.leaves(&mut boxes);
            self.tree.build(&boxes, &mut self.at);
        } else {
            for &(item, min, max) in &boxes {
                self.at[item as usize] = self.tree.insert(item, min, max);
            }
        }
        boxes.clear();
        self.pending = boxes;
    }

    /// Calls `f` with every item whose box may overlap `min..max`, each once: every item
    /// of the tree whose box overlaps it, and every item of the grid in the cells it
    /// covers. Call after `flush`.
    pub fn query(&mut self, min: DVec2, max: DVec2, mut f: impl FnMut(u32)) {
        self.tree.query(min, max, &mut self.stack, &mut f);
        let (range, cells) = self.grid.range_of(min, max);
        if cells > 4 * self.in_grid.len() as i64 + 64 {
            self.in_grid.iter().copied().for_each(f);
            return;
        }
        self.search = self.search.wrapping_add(1);
        if self.search == 0 {
            self.seen.fill(0);
            self.search = 1;
        }
        let (seen, search) = (&mut self.seen, self.search);
        self.grid.visit(range, |j| {
            let s = &mut seen[j as usize];
            if *s != search {
                *s = search;
                f(j);
            }
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn touches(a: (DVec2, DVec2), b: (DVec2, DVec2)) -> bool {
        a.0.x <= b.1.x && b.0.x <= a.1.x && a.0.y <= b.1.y && b.0.y <= a.1.y
    }

    proptest! {
        /// Boxes of 1e-2 to 1e2 across inserted, moved and removed: a query meets every
        /// box that overlaps it, once, and nothing that was removed.
        #[test]
        fn a_query_meets_every_overlapping_box_once_in_either_tier(
            ops in proptest::collection::vec(
                (0u8..3, 0usize..50, -100.0f64..100.0, -100.0f64..100.0, -2.0f64..2.0, -2.0f64..2.0),
                1..200),
        ) {
            let mut boxes: Vec<Option<(DVec2, DVec2)>> = vec![None; 50];
            let mut t = Tiered::default();
            t.reset(0.5, 50);
            for (op, k, x, y, w, h) in ops {
                let half = DVec2::new(10f64.powf(w), 10f64.powf(h)) / 2.0;
                let b = (DVec2::new(x, y) - half, DVec2::new(x, y) + half);
                if let Some(old) = boxes[k] {
                    t.remove(k as u32, old.0, old.1);
                    boxes[k] = None;
                }
                if op != 1 {
                    t.insert(k as u32, b.0, b.1);
                    boxes[k] = Some(b);
                }
                t.flush();
                let mut met = Vec::new();
                t.query(b.0, b.1, |i| met.push(i));
                met.sort_unstable();
                prop_assert!(met.windows(2).all(|w| w[0] < w[1]), "met once");
                prop_assert!(met.iter().all(|&i| boxes[i as usize].is_some()));
                for (i, o) in boxes.iter().enumerate() {
                    if o.is_some_and(|o| touches(o, b)) {
                        prop_assert!(met.binary_search(&(i as u32)).is_ok(), "missing {}", i);
                    }
                }
            }
        }
    }
}
