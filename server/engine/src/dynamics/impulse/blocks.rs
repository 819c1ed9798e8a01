//! Contacts in blocks, so a pass runs on several threads and gives the one-thread bits.
//!
//! The moving bodies are cut into [`block_count`] bands (rows, or columns in a world more
//! than twice as wide as tall) holding about as many bodies each, from where they are
//! ([`assign`]; cut again when the moving bodies change and every [`RECUT_FRAMES`]): a
//! pile makes blocks of a few neighbouring rows whatever order its bodies were created
//! in. A contact whose moving bodies lie in one band belongs to that band's block; a
//! contact across two bands goes to the boundary (on the 100-level pyramid, 8 blocks and
//! about 7% of the contacts). A pass solves each block's contacts in the order they were
//! found, block after block, then the boundary's. Two blocks never write the same body
//! (bodies that do not move, static or asleep, are read and never written), so the blocks
//! may run at once on any number of threads and each contact still sees exactly what it
//! sees on one thread: the result is the same bits for any thread count. The blocks
//! depend on the moving bodies and their places only, never on the threads.

use glam::DVec2;

use super::SolverBody;

/// Moving bodies per block below which a world is not split.
pub const BLOCK_BODIES: usize = 512;

/// The most blocks.
pub const MAX_BLOCKS: usize = 64;

/// Bodies sampled at most to place the cuts between blocks.
const CUT_SAMPLE: usize = 1024;

/// Frames after which the blocks are cut again from where the bodies are (sooner when
/// the moving bodies change). Bodies that wandered across a cut in between only make the
/// boundary larger: slower, never different.
pub const RECUT_FRAMES: u32 = 120;

/// How many blocks `moving` bodies make: a power of two (an even split for 2, 4 and 8
/// threads), each of at least [`BLOCK_BODIES`] bodies, at most [`MAX_BLOCKS`].
pub fn block_count(moving: usize) -> usize {
    let wanted = (moving / BLOCK_BODIES).clamp(1, MAX_BLOCKS);
    1 << wanted.ilog2()
}

/// Each moving body's block, in `out` (in the order of `places`): `blocks` bands across
/// y (across x when `places` spread more than twice as wide as tall), cut at the
/// coordinates that split a sample of the bodies into `blocks` equal counts; bodies at
/// one coordinate (a row) stay in one band. `scratch` is reused. Depends on the places
/// only.
pub fn assign(places: &[DVec2], blocks: usize, out: &mut Vec<u16>, scratch: &mut Vec<f64>) {
    out.clear();
    if blocks <= 1 || places.is_empty() {
        out.resize(places.len(), 0);
        return;
    }
    let (lo, hi) = places
        .iter()
        .fold((DVec2::INFINITY, DVec2::NEG_INFINITY), |(lo, hi), p| {
            (lo.min(*p), hi.max(*p))
        });
    let span = hi - lo;
    let along = |p: &DVec2| if span.x > 2.0 * span.y { p.x } else { p.y };
    let stride = places.len().div_ceil(CUT_SAMPLE);
    scratch.clear();
    scratch.extend(places.iter().step_by(stride).map(along));
    let n = scratch.len();
    let mut cuts = [0.0; MAX_BLOCKS];
    let mut rest: &mut [f64] = scratch;
    let mut taken = 0;
    for (k, cut) in cuts.iter_mut().enumerate().take(blocks).skip(1) {
        let at = n * k / blocks - taken;
        let (_, nth, after) = rest.select_nth_unstable_by(at, f64::total_cmp);
        *cut = *nth;
        taken += at + 1;
        rest = after;
        if rest.is_empty() {
            break;
        }
    }
    let cuts = &cuts[1..blocks];
    out.extend(
        places
            .iter()
            .map(|p| cuts.partition_point(|c| c.total_cmp(&along(p)).is_le()) as u16),
    );
}

/// The bucket of a contact between slots `a` and `b` (`blocks` = the boundary).
/// `moves(s)`: whether slot `s` is written by the solver (a moving body); `block(s)` its
/// block if it is.
// Called for every contact found: inlined whatever codegen unit the solver lands in.
#[inline(always)]
pub fn bucket_of(
    a: u32,
    b: u32,
    blocks: usize,
    moves: impl Fn(u32) -> bool,
    block: impl Fn(u32) -> usize,
) -> usize {
    match (moves(a), moves(b)) {
        (true, true) if block(a) == block(b) => block(a),
        (true, true) => blocks,
        (true, false) => block(a),
        (false, true) => block(b),
        // Two bodies that do not move: the pass changes nothing; keep it anywhere.
        (false, false) => blocks,
    }
}

/// The solver's bodies as the passes share them between threads.
///
/// Invariants the users of [`Bodies::get`] and the writers keep (checked where contacts are
/// built and bucketed): every slot a contact names is below `len`; a body whose
/// `inv_mass` is 0 is never written; the contacts running at once on different threads
/// belong to different blocks, whose written bodies are disjoint.
#[derive(Clone, Copy)]
pub struct Bodies {
    ptr: *mut SolverBody,
    len: usize,
}

// SAFETY: `Bodies` is a view of a `&mut [SolverBody]` that outlives every use of it (the
// pass that made it waits for its threads); the invariants above make the threads' writes
// disjoint and keep every read of a written body on the thread that writes it.
unsafe impl Send for Bodies {}
unsafe impl Sync for Bodies {}

impl Bodies {
    pub fn new(bodies: &mut [SolverBody]) -> Bodies {
        Bodies {
            ptr: bodies.as_mut_ptr(),
            len: bodies.len(),
        }
    }

    #[inline(always)]
    pub fn get(&self, i: usize) -> SolverBody {
        assert!(i < self.len);
        // SAFETY: in bounds (above); no other thread writes body `i` while this one runs
        // (the block invariants of the type).
        unsafe { *self.ptr.add(i) }
    }

    /// Body `i` to change, if it moves (a body whose `inv_mass` is 0 is left alone: it is
    /// the body's own, read here, so no caller can make a static body written).
    #[inline(always)]
    pub fn update(&self, i: usize, change: impl FnOnce(&mut SolverBody)) {
        if self.get(i).inv_mass != 0.0 {
            // SAFETY: in bounds (`get` checked it); a moving body is written by the
            // contacts of one block only, which run on one thread, one after the other
            // (the type's invariants), so this is the only reference to it.
            change(unsafe { &mut *self.ptr.add(i) });
        }
    }
}

/// Splits `blocks` into `groups` runs of consecutive blocks, as even as can be.
pub fn groups<T>(blocks: &mut [T], groups: usize) -> Vec<&mut [T]> {
    let n = blocks.len();
    let mut out = Vec::with_capacity(groups);
    let mut rest = blocks;
    let mut taken = 0;
    for g in 0..groups {
        let end = (g + 1) * n / groups;
        let (head, tail) = std::mem::take(&mut rest).split_at_mut(end - taken);
        taken = end;
        out.push(head);
        rest = tail;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::super::Contact;
    use super::*;

    #[test]
    fn block_counts_are_powers_of_two_within_bounds() {
        assert_eq!(block_count(0), 1);
        assert_eq!(block_count(BLOCK_BODIES - 1), 1);
        assert_eq!(block_count(5050), 8);
        assert_eq!(block_count(3 * BLOCK_BODIES), 2);
        assert_eq!(block_count(usize::MAX / 2), MAX_BLOCKS);
    }

    #[test]
    fn contacts_go_to_the_block_of_their_moving_bodies() {
        let moves = |s: u32| s < 100;
        // 100 moving slots in 4 blocks of 25.
        let block = |s: u32| s as usize / 25;
        assert_eq!(bucket_of(0, 24, 4, moves, block), 0);
        assert_eq!(bucket_of(24, 25, 4, moves, block), 4);
        assert_eq!(bucket_of(60, 150, 4, moves, block), 2);
        assert_eq!(bucket_of(150, 99, 4, moves, block), 3);
        assert_eq!(bucket_of(150, 151, 4, moves, block), 4);
    }

    #[test]
    fn blocks_are_bands_of_equal_counts_keeping_rows_whole_in_any_creation_order() {
        let (mut out, mut scratch) = (Vec::new(), Vec::new());
        // 8 rows of 10 bodies, listed in no order: 4 bands of 2 rows each; a row is
        // never split.
        let mut places: Vec<DVec2> = (0..80)
            .map(|k| DVec2::new((k % 10) as f64, (k / 10) as f64))
            .collect();
        places.reverse();
        places.swap(3, 70);
        assign(&places, 4, &mut out, &mut scratch);
        for (p, &b) in places.iter().zip(&out) {
            assert_eq!(b as f64, (p.y / 2.0).floor(), "{p}");
        }
        // More than twice as wide as tall: bands across x.
        let wide: Vec<DVec2> = places.iter().map(|p| DVec2::new(p.y * 10.0, p.x)).collect();
        assign(&wide, 2, &mut out, &mut scratch);
        for (p, &b) in wide.iter().zip(&out) {
            assert_eq!(b, u16::from(p.x >= 40.0), "{p}");
        }
        // One block: everything in block 0.
        assign(&places, 1, &mut out, &mut scratch);
        assert!(out.iter().all(|&b| b == 0) && out.len() == 80);
        // A NaN place goes somewhere, the same every time.
        let mut odd = places.clone();
        odd[5] = DVec2::NAN;
        assign(&odd, 4, &mut out, &mut scratch);
        let first = out.clone();
        assign(&odd, 4, &mut out, &mut scratch);
        assert_eq!(first, out);
        assert!(out.iter().all(|&b| b < 4));
    }

    #[test]
    fn a_body_that_does_not_move_is_never_written() {
        let body = |inv_mass| SolverBody {
            vel: glam::DVec2::ZERO,
            pseudo: glam::DVec2::ZERO,
            delta: glam::DVec2::ZERO,
            inv_mass,
        };
        let mut sb = vec![body(1.0), body(0.0)];
        let view = Bodies::new(&mut sb);
        for i in 0..2 {
            view.update(i, |s| s.vel.x = 5.0);
        }
        assert_eq!((sb[0].vel.x, sb[1].vel.x), (5.0, 0.0));
    }

    #[test]
    #[should_panic]
    fn a_slot_past_the_bodies_is_refused() {
        let mut sb = Vec::new();
        Bodies::new(&mut sb).get(0);
    }

    #[test]
    fn groups_cover_every_block_once_in_order() {
        for n in 1..10 {
            for g in 1..=n {
                let mut blocks: Vec<Vec<Contact>> = (0..n).map(|_| Vec::new()).collect();
                let split = groups(&mut blocks, g);
                assert_eq!(split.len(), g);
                assert_eq!(split.iter().map(|s| s.len()).sum::<usize>(), n);
                assert!(split.iter().all(|s| !s.is_empty()));
            }
        }
    }
}
