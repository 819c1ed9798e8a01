//! Threads for the parts of a step that split without changing a bit: work whose items
//! are independent (each particle is its own) runs on contiguous chunks, in order, on a
//! shared pool, and the chunks' results are combined in chunk order, so any thread count
//! gives the one-thread result exactly.
//!
//! A world asks for `threads` ([`crate::dynamics::config::WorldConfig::threads`]); it gets
//! at most the machine's cores, and pools are shared by every world asking for the same
//! count (at most one pool per count up to the core count: a peer setting `threads` cannot
//! make the process start threads without bound).

use std::sync::{Arc, Mutex, OnceLock};

use rayon::prelude::*;

/// Items below which work is not split (the split would cost more than it saves).
pub const MIN_SPLIT: usize = 8192;

/// The threads a request for `threads` gets: at least 1, at most the machine's cores.
pub fn effective(threads: u32) -> usize {
    if threads <= 1 {
        return 1;
    }
    // Asked once: the answer reads the process's affinity and cgroup limits.
    static CORES: OnceLock<usize> = OnceLock::new();
    let cores = *CORES.get_or_init(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    (threads as usize).clamp(1, cores)
}

/// The shared pool of `n` threads (`n` >= 2).
fn pool(n: usize) -> Arc<rayon::ThreadPool> {
    static POOLS: OnceLock<Mutex<Vec<Option<Arc<rayon::ThreadPool>>>>> = OnceLock::new();
    let mut pools = POOLS.get_or_init(Default::default).lock().expect("pools");
    if pools.len() <= n {
        pools.resize(n + 1, None);
    }
    pools[n]
        .get_or_insert_with(|| {
            Arc::new(
                rayon::ThreadPoolBuilder::new()
                    .num_threads(n)
                    .thread_name(|k| format!("ricochet-step-{k}"))
                    .build()
                    .expect("a thread pool"),
            )
        })
        .clone()
}

/// How many chunks `len` items split into for `threads`, and the chunk length.
pub fn chunking(threads: u32, len: usize) -> (usize, usize) {
    let n = effective(threads);
    if n == 1 || len < MIN_SPLIT {
        return (1, len.max(1));
    }
    let size = len.div_ceil(n);
    (len.div_ceil(size), size)
}

/// Runs `work` on each of `chunks` (already split, in order) on `threads`, returning the
/// results in chunk order.
pub fn run<T: Send, R: Send>(
    threads: u32,
    chunks: Vec<T>,
    work: impl Fn(T) -> R + Sync + Send,
) -> Vec<R> {
    if chunks.len() <= 1 {
        return chunks.into_iter().map(work).collect();
    }
    pool(effective(threads)).install(|| chunks.into_par_iter().map(&work).collect())
}
