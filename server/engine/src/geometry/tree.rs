//! A dynamic tree of boxes: a binary tree whose leaves hold the boxes and whose inner
//! nodes hold the box around their two children. A query for a box descends only into
//! the nodes it overlaps, so it costs about the depth of the tree plus what it finds,
//! whatever the sizes of the boxes: one box a thousand times larger than the others
//! costs one leaf, not the area it covers.
//!
//! A box is inserted beside the node that grows the tree's total perimeter least (the
//! perimeter of a node is about the chance a query meets it), and a node along the way
//! whose children's heights differ by two or more has the higher one rotated up, so the
//! depth stays about logarithmic whatever the order of insertions (a thousand boxes in a
//! row: 15 levels at most). A whole set of boxes is built at once top-down,
//! halving at the median along the wider spread of the boxes' centres.
//!
//! The shape of the tree depends on the order of insertions and removals, which is
//! always the caller's (deterministic); what a query finds does not depend on it, only
//! the order in which it is found.

use glam::DVec2;

/// No node.
const NONE: u32 = u32::MAX;

#[derive(Clone, Copy, Debug)]
struct Node {
    min: DVec2,
    max: DVec2,
    /// The parent (the next free node while the node is free).
    parent: u32,
    /// The children; `NONE` for a leaf.
    left: u32,
    right: u32,
    /// 0 for a leaf, one more than the higher child for an inner node.
    height: u32,
    /// The leaf's item.
    item: u32,
}

/// Boxes with an item each (a body index), found by the boxes they overlap.
#[derive(Clone, Debug)]
pub struct Tree {
    nodes: Vec<Node>,
    root: u32,
    /// The first free node, chained through `parent`.
    free: u32,
    leaves: usize,
}

impl Default for Tree {
    fn default() -> Self {
        Tree {
            nodes: Vec::new(),
            root: NONE,
            free: NONE,
            leaves: 0,
        }
    }
}

/// Half the perimeter of a box: the cost of a node in the insertion's choice.
fn perimeter(min: DVec2, max: DVec2) -> f64 {
    (max.x - min.x) + (max.y - min.y)
}

fn overlaps(n: &Node, min: DVec2, max: DVec2) -> bool {
    n.min.x <= max.x && min.x <= n.max.x && n.min.y <= max.y && min.y <= n.max.y
}

impl Tree {
    /// Leaves in the tree.
    pub fn len(&self) -> usize {
        self.leaves
    }

    pub fn is_empty(&self) -> bool {
        self.leaves == 0
    }

    /// Empties the tree (its memory is kept).
    pub fn clear(&mut self) {
        self.nodes.clear();
        self.root = NONE;
        self.free = NONE;
        self.leaves = 0;
    }

    /// The height of the tree: 0 for one leaf (and for none).
    pub fn height(&self) -> u32 {
        if self.root == NONE {
            0
        } else {
            self.nodes[self.root as usize].height
        }
    }

    fn alloc(&mut self, node: Node) -> u32 {
        if self.free == NONE {
            self.nodes.push(node);
            (self.nodes.len() - 1) as u32
        } else {
            let i = self.free;
            self.free = self.nodes[i as usize].parent;
            self.nodes[i as usize] = node;
            i
        }
    }

    fn release(&mut self, i: u32) {
        let n = &mut self.nodes[i as usize];
        n.parent = self.free;
        n.left = NONE;
        n.right = NONE;
        self.free = i;
    }

    fn leaf(item: u32, min: DVec2, max: DVec2) -> Node {
        Node {
            min,
            max,
            parent: NONE,
            left: NONE,
            right: NONE,
            height: 0,
            item,
        }
    }

    /// Sets an inner node's box and height from its children.
    fn fix(&mut self, i: u32) {
        let n = self.nodes[i as usize];
        let (l, r) = (self.nodes[n.left as usize], self.nodes[n.right as usize]);
        let n = &mut self.nodes[i as usize];
        n.min = l.min.min(r.min);
        n.max = l.max.max(r.max);
        n.height = 1 + l.height.max(r.height);
    }

    /// Puts `child` where `old` was under `parent` (or at the root).
    fn replace_child(&mut self, parent: u32, old: u32, child: u32) {
        self.nodes[child as usize].parent = parent;
        if parent == NONE {
            self.root = child;
        } else if self.nodes[parent as usize].left == old {
            self.nodes[parent as usize].left = child;
        } else {
            self.nodes[parent as usize].right = child;
        }
    }

    /// Adds a leaf with `item` and the box `min..max`; returns the leaf (for `remove`).
    pub fn insert(&mut self, item: u32, min: DVec2, max: DVec2) -> u32 {
        let leaf = self.alloc(Tree::leaf(item, min, max));
        self.leaves += 1;
        if self.root == NONE {
            self.root = leaf;
            return leaf;
        }
        // Down from the root to the node whose new parent grows the perimeters least: a
        // new parent beside a node costs the perimeter of the two, and every ancestor
        // above grows by what the box adds to it.
        let mut at = self.root;
        loop {
            let n = self.nodes[at as usize];
            if n.left == NONE {
                break;
            }
            let joined = perimeter(n.min.min(min), n.max.max(max));
            let here = 2.0 * joined;
            let inherited = 2.0 * (joined - perimeter(n.min, n.max));
            let down = |c: u32| {
                let c = &self.nodes[c as usize];
                let grown = perimeter(c.min.min(min), c.max.max(max));
                if c.left == NONE {
                    grown + inherited
                } else {
                    grown - perimeter(c.min, c.max) + inherited
                }
            };
            let (l, r) = (down(n.left), down(n.right));
            if here < l && here < r {
                break;
            }
            at = if l < r { n.left } else { n.right };
        }
        let sibling = at;
        let above = self.nodes[sibling as usize].parent;
        let parent = self.alloc(Node {
            min,
            max,
            parent: NONE,
            left: sibling,
            right: leaf,
            height: 0,
            item: NONE,
        });
        self.replace_child(above, sibling, parent);
        self.nodes[sibling as usize].parent = parent;
        self.nodes[leaf as usize].parent = parent;
        self.refit(parent);
        leaf
    }

    /// Removes a leaf `insert` or `build` gave.
    pub fn remove(&mut self, leaf: u32) {
        self.leaves -= 1;
        if leaf == self.root {
            self.root = NONE;
            self.release(leaf);
            return;
        }
        let parent = self.nodes[leaf as usize].parent;
        let p = self.nodes[parent as usize];
        let sibling = if p.left == leaf { p.right } else { p.left };
        self.replace_child(p.parent, parent, sibling);
        self.release(parent);
        self.release(leaf);
        if p.parent != NONE {
            self.refit(p.parent);
        }
    }

    /// Rebalances and refits from inner node `i` up to the root.
    fn refit(&mut self, mut i: u32) {
        while i != NONE {
            i = self.balance(i);
            self.fix(i);
            i = self.nodes[i as usize].parent;
        }
    }

    /// Lifts the higher child of inner node `a` into its place when it is two or more
    /// higher than the other; returns the node now at `a`'s place.
    fn balance(&mut self, a: u32) -> u32 {
        let n = self.nodes[a as usize];
        let (hl, hr) = (
            self.nodes[n.left as usize].height,
            self.nodes[n.right as usize].height,
        );
        if hr > hl + 1 {
            self.lift(a, n.right)
        } else if hl > hr + 1 {
            self.lift(a, n.left)
        } else {
            a
        }
    }

    /// Rotates child `x` of `a` up: `x` takes `a`'s place, `a` becomes a child of `x`
    /// and takes the lower of `x`'s children in `x`'s stead.
    fn lift(&mut self, a: u32, x: u32) -> u32 {
        let nx = self.nodes[x as usize];
        let (hp, hq) = (
            self.nodes[nx.left as usize].height,
            self.nodes[nx.right as usize].height,
        );
        let (keep, give) = if hp > hq {
            (nx.left, nx.right)
        } else {
            (nx.right, nx.left)
        };
        let above = self.nodes[a as usize].parent;
        self.replace_child(above, a, x);
        if self.nodes[a as usize].left == x {
            self.nodes[a as usize].left = give;
        } else {
            self.nodes[a as usize].right = give;
        }
        self.nodes[give as usize].parent = a;
        let nx = &mut self.nodes[x as usize];
        nx.left = a;
        nx.right = keep;
        self.nodes[a as usize].parent = x;
        self.fix(a);
        self.fix(x);
        x
    }

    /// Empties the tree and builds it from `boxes` (item, min, max) at once, top-down;
    /// `leaf[item]` is set to each item's leaf.
    pub fn build(&mut self, boxes: &[(u32, DVec2, DVec2)], leaf: &mut [u32]) {
        self.clear();
        let mut ids: Vec<u32> = Vec::with_capacity(boxes.len());
        for &(item, min, max) in boxes {
            let l = self.alloc(Tree::leaf(item, min, max));
            leaf[item as usize] = l;
            ids.push(l);
        }
        self.leaves = boxes.len();
        if !ids.is_empty() {
            self.root = self.split(&mut ids);
        }
    }

    /// The subtree over the leaves `ids` (at least one); returns its root.
    fn split(&mut self, ids: &mut [u32]) -> u32 {
        if ids.len() == 1 {
            return ids[0];
        }
        let centre = |n: &Node| n.min + n.max;
        let (mut lo, mut hi) = (DVec2::INFINITY, DVec2::NEG_INFINITY);
        for &i in ids.iter() {
            let c = centre(&self.nodes[i as usize]);
            lo = lo.min(c);
            hi = hi.max(c);
        }
        let along_x = hi.x - lo.x >= hi.y - lo.y;
        let key = |n: &Node| {
            let c = centre(n);
            if along_x {
                c.x
            } else {
                c.y
            }
        };
        let mid = ids.len() / 2;
        let nodes = &self.nodes;
        ids.select_nth_unstable_by(mid, |&p, &q| {
            let (p, q) = (&nodes[p as usize], &nodes[q as usize]);
            key(p).total_cmp(&key(q)).then(p.item.cmp(&q.item))
        });
        let (left, right) = ids.split_at_mut(mid);
        let (l, r) = (self.split(left), self.split(right));
        let parent = self.alloc(Node {
            min: DVec2::ZERO,
            max: DVec2::ZERO,
            parent: NONE,
            left: l,
            right: r,
            height: 0,
            item: NONE,
        });
        self.nodes[l as usize].parent = parent;
        self.nodes[r as usize].parent = parent;
        self.fix(parent);
        parent
    }

    /// Calls `f` with the item of every leaf whose box overlaps or touches `min..max`,
    /// each once. `stack` is scratch space.
    pub fn query(&self, min: DVec2, max: DVec2, stack: &mut Vec<u32>, mut f: impl FnMut(u32)) {
        if self.root == NONE {
            return;
        }
        stack.clear();
        stack.push(self.root);
        while let Some(i) = stack.pop() {
            let n = &self.nodes[i as usize];
            if !overlaps(n, min, max) {
                continue;
            }
            if n.left == NONE {
                f(n.item);
            } else {
                stack.push(n.left);
                stack.push(n.right);
            }
        }
    }

    /// Appends every leaf's item and box to `out`, in no particular order.
    pub fn leaves(&self, out: &mut Vec<(u32, DVec2, DVec2)>) {
        if self.root == NONE {
            return;
        }
        let mut stack = vec![self.root];
        while let Some(i) = stack.pop() {
            let n = &self.nodes[i as usize];
            if n.left == NONE {
                out.push((n.item, n.min, n.max));
            } else {
                stack.push(n.left);
                stack.push(n.right);
            }
        }
    }

    /// Checks the links, boxes and heights of every node under the root (for tests):
    /// every child points back at its parent, every inner box is its children's, every
    /// height one more than the higher child's. Returns the leaves' items found.
    #[cfg(test)]
    pub(crate) fn validate(&self) -> Vec<u32> {
        let mut items = Vec::new();
        if self.root == NONE {
            return items;
        }
        assert_eq!(self.nodes[self.root as usize].parent, NONE);
        let mut stack = vec![self.root];
        while let Some(i) = stack.pop() {
            let n = self.nodes[i as usize];
            if n.left == NONE {
                assert_eq!(n.height, 0);
                items.push(n.item);
                continue;
            }
            let (l, r) = (self.nodes[n.left as usize], self.nodes[n.right as usize]);
            assert_eq!((l.parent, r.parent), (i, i));
            assert_eq!(n.min, l.min.min(r.min));
            assert_eq!(n.max, l.max.max(r.max));
            assert_eq!(n.height, 1 + l.height.max(r.height));
            stack.push(n.left);
            stack.push(n.right);
        }
        assert_eq!(items.len(), self.leaves);
        items
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn touches(a: (DVec2, DVec2), b: (DVec2, DVec2)) -> bool {
        a.0.x <= b.1.x && b.0.x <= a.1.x && a.0.y <= b.1.y && b.0.y <= a.1.y
    }

    /// A box of size 1e-2 to 1e2 (even in the logarithm) at `(x, y)`.
    fn sized(x: f64, y: f64, w: f64, h: f64) -> (DVec2, DVec2) {
        let half = DVec2::new(10f64.powf(w), 10f64.powf(h)) / 2.0;
        (DVec2::new(x, y) - half, DVec2::new(x, y) + half)
    }

    proptest! {
        /// After any inserts, removals and moves of boxes from 1e-2 to 1e2, every query
        /// finds exactly the boxes that overlap it, each once, and the tree stays linked
        /// and fitted.
        #[test]
        fn queries_find_exactly_the_overlapping_boxes(
            ops in proptest::collection::vec(
                (0u8..3, 0usize..40, -100.0f64..100.0, -100.0f64..100.0, -2.0f64..2.0, -2.0f64..2.0),
                1..150),
            built in 0usize..40,
        ) {
            let mut boxes: Vec<Option<(DVec2, DVec2)>> = vec![None; 40];
            let mut leaf = vec![NONE; 40];
            let mut tree = Tree::default();
            // Some boxes built at once first.
            let start: Vec<(u32, DVec2, DVec2)> = (0..built)
                .map(|k| {
                    let b = sized(k as f64 * 5.0 - 100.0, (k * k) as f64 % 37.0, -2.0 + (k % 5) as f64, 0.0);
                    boxes[k] = Some(b);
                    (k as u32, b.0, b.1)
                })
                .collect();
            tree.build(&start, &mut leaf);
            tree.validate();
            let mut stack = Vec::new();
            for (op, k, x, y, w, h) in ops {
                let b = sized(x, y, w, h);
                match (op, boxes[k]) {
                    (0, None) | (2, None) => {
                        leaf[k] = tree.insert(k as u32, b.0, b.1);
                        boxes[k] = Some(b);
                    }
                    (1, Some(_)) => {
                        tree.remove(leaf[k]);
                        boxes[k] = None;
                    }
                    (_, Some(_)) => {
                        tree.remove(leaf[k]);
                        leaf[k] = tree.insert(k as u32, b.0, b.1);
                        boxes[k] = Some(b);
                    }
                    _ => {}
                }
                let mut items = tree.validate();
                items.sort_unstable();
                let held: Vec<u32> = (0..40).filter(|&k| boxes[k].is_some()).map(|k| k as u32).collect();
                prop_assert_eq!(items, held);
                let mut found = Vec::new();
                tree.query(b.0, b.1, &mut stack, |i| found.push(i));
                found.sort_unstable();
                let want: Vec<u32> = (0..40)
                    .filter(|&k| boxes[k].is_some_and(|o| touches(o, b)))
                    .map(|k| k as u32)
                    .collect();
                prop_assert_eq!(found, want);
            }
        }
    }

    #[test]
    fn a_thousand_boxes_in_a_row_stay_logarithmically_deep() {
        let mut tree = Tree::default();
        for k in 0..1000u32 {
            let p = DVec2::new(k as f64, 0.0);
            tree.insert(k, p, p + 0.5);
        }
        tree.validate();
        assert!(tree.height() <= 15, "height {}", tree.height());
        let mut leaf = vec![0; 1000];
        let boxes: Vec<(u32, DVec2, DVec2)> = (0..1000u32)
            .map(|k| (k, DVec2::splat(k as f64), DVec2::splat(k as f64 + 0.5)))
            .collect();
        tree.build(&boxes, &mut leaf);
        tree.validate();
        assert_eq!(tree.height(), 10);
    }
}
