//! The work around the passes that splits as they do, with the same bits: what each
//! contact does, block by block on the team's threads and then the boundary on the
//! caller ([`each_block`]); what each body does, in ranges of bodies ([`each_range`]).
//!
//! A contact of a block touches the moving bodies of its block only (and bodies that do
//! not move, which the work here only reads or marks), so a body meets its block's
//! contacts in their order, then the boundary's: the order of one thread taking the
//! buckets one after the other. Work whose result depends only on that order (a sum per
//! body, a list per body) gives the one-thread bits on any number of threads.

use std::ops::Range;

use super::blocks;
use super::team::Team;

/// Runs `work` on every item of every bucket but the last (the blocks: a group of
/// neighbouring blocks on each of the team's members at once), then on the last (the
/// boundary, on the caller). One member alone takes every bucket in order.
pub(super) fn each_block<C: Send>(
    team: &Team,
    buckets: &mut [Vec<C>],
    work: impl Fn(&mut C) + Sync,
) {
    let Some((boundary, blocks)) = buckets.split_last_mut() else {
        return;
    };
    on_groups(team, blocks, |group| {
        group.iter_mut().flatten().for_each(&work);
        0.0
    });
    boundary.iter_mut().for_each(&work);
}

/// Runs `run` on runs of neighbouring `blocks`, one run on each of the team's members at
/// once (every block in one run on the caller when it is alone or there is one block);
/// returns the largest result.
pub(super) fn on_groups<C: Send>(
    team: &Team,
    blocks: &mut [Vec<C>],
    run: impl Fn(&mut [Vec<C>]) -> f64 + Sync,
) -> f64 {
    let n = team.size().min(blocks.len());
    if n <= 1 {
        return run(blocks);
    }
    let groups: Vec<Group<C>> = blocks::groups(blocks, n)
        .into_iter()
        .map(|g| Group(g.as_mut_ptr(), g.len()))
        .collect();
    team.run(&|k| match groups.get(k) {
        // SAFETY: the groups are disjoint runs of `blocks`, borrowed for this call, and
        // member `k` alone takes group `k`.
        Some(g) => run(unsafe { std::slice::from_raw_parts_mut(g.0, g.1) }),
        None => 0.0,
    })
}

/// Runs `work(k, range)` on `0..len` cut into one range per member `k` of the team, in
/// order, at once (the whole range on the caller, as member 0, when the team is the caller
/// alone or `len` is small). Returns how many ranges it cut.
pub(super) fn each_range(
    team: &Team,
    len: usize,
    work: impl Fn(usize, Range<usize>) + Sync,
) -> usize {
    let n = ranges(team, len);
    if n <= 1 {
        work(0, 0..len);
        return 1;
    }
    team.run(&|k| {
        work(k, len * k / n..len * (k + 1) / n);
        0.0
    });
    n
}

/// How many ranges [`each_range`] cuts `0..len` into for `team`.
pub(super) fn ranges(team: &Team, len: usize) -> usize {
    if len < RANGE_SPLIT {
        1
    } else {
        team.size()
    }
}

/// Items below which [`each_range`] keeps a range whole (the hand-over would cost more).
const RANGE_SPLIT: usize = 1024;

/// One member's run of buckets.
struct Group<C>(*mut Vec<C>, usize);

// SAFETY: a group is a run of buckets no other member touches during the call that made it
// (`on_groups`), and it does not outlive that call.
unsafe impl<C: Send> Send for Group<C> {}
unsafe impl<C: Send> Sync for Group<C> {}

/// A slice that the members of a team write at once, each at items no other member
/// touches during the call (the blocks' bodies, a range's items, the pair of a contact).
pub(super) struct Shared<'a, T> {
    ptr: *mut T,
    len: usize,
    _items: std::marker::PhantomData<&'a mut [T]>,
}

// SAFETY: a view of a `&mut [T]` borrowed for `'a`; the users of `at` keep every item
// to one member at a time (its contract).
unsafe impl<T: Send> Send for Shared<'_, T> {}
unsafe impl<T: Send> Sync for Shared<'_, T> {}

impl<'a, T> Shared<'a, T> {
    pub(super) fn new(items: &'a mut [T]) -> Self {
        Shared {
            ptr: items.as_mut_ptr(),
            len: items.len(),
            _items: std::marker::PhantomData,
        }
    }

    /// Item `i` (panics past the end).
    ///
    /// # Safety
    /// No other member reads or writes item `i` while the reference lives.
    #[inline(always)]
    #[allow(clippy::mut_from_ref)]
    pub(super) unsafe fn at(&self, i: usize) -> &mut T {
        assert!(i < self.len);
        // SAFETY: in bounds (above); exclusive by the caller's contract.
        unsafe { &mut *self.ptr.add(i) }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dynamics::impulse::team::Crew;

    #[test]
    fn each_block_visits_every_item_once_blocks_before_the_boundary() {
        let mut crew = Crew::default();
        for size in [1, 2, 3] {
            let team = crew.team(size);
            for blocks in [1, 2, 5, 8] {
                // Item (bucket, k); the boundary is the last bucket.
                let mut buckets: Vec<Vec<(usize, usize, u32)>> = (0..=blocks)
                    .map(|b| (0..b * 3 + 1).map(|k| (b, k, 0)).collect())
                    .collect();
                let boundary_seen = std::sync::atomic::AtomicUsize::new(0);
                let blocks_seen = std::sync::atomic::AtomicUsize::new(0);
                each_block(&team, &mut buckets, |item| {
                    use std::sync::atomic::Ordering::SeqCst;
                    item.2 += 1;
                    if item.0 == blocks {
                        boundary_seen.fetch_add(1, SeqCst);
                    } else {
                        // No block's item after the boundary started.
                        assert_eq!(boundary_seen.load(SeqCst), 0);
                        blocks_seen.fetch_add(1, SeqCst);
                    }
                });
                assert!(buckets.iter().flatten().all(|i| i.2 == 1));
                assert_eq!(
                    blocks_seen.into_inner(),
                    (0..blocks).map(|b| b * 3 + 1).sum::<usize>()
                );
            }
        }
    }

    #[test]
    fn each_range_covers_every_index_once() {
        let mut crew = Crew::default();
        for size in [1, 2, 3] {
            let team = crew.team(size);
            for len in [0, 1, RANGE_SPLIT - 1, RANGE_SPLIT, 5000] {
                let mut hits = vec![0u8; len];
                let view = Shared::new(&mut hits);
                each_range(&team, len, |_, r| {
                    for i in r {
                        // SAFETY: the ranges are disjoint.
                        unsafe { *view.at(i) += 1 };
                    }
                });
                assert!(hits.iter().all(|&h| h == 1), "{size} {len}");
            }
        }
    }
}
