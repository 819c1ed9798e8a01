//! The server process's memory: one heap, no per-thread caches, free pages given back.

/// glibc's settings that keep no per-thread caches of freed blocks, and no cache of the
/// stacks of threads that ended.
pub const NO_THREAD_CACHES: &str = "glibc.malloc.tcache_count=0:glibc.pthread.stack_cache_size=0";

/// Starts this process again, same arguments, with glibc's per-thread caches of freed
/// blocks and its cache of ended threads' stacks turned off ([`NO_THREAD_CACHES`]), unless
/// `GLIBC_TUNABLES` already says how many blocks to keep (an operator's choice stands).
/// Those caches keep up to seven freed blocks of each small size per thread; after a burst
/// of traffic they pinned about half a MiB of heap pages that no trim could give back; the
/// stacks of the threads zenoh starts under load and ends later stayed resident (the
/// soak's figures, docs/reliability.md). glibc reads the setting
/// only at start, hence the new image; the process id stays. Returns only if the setting is
/// already in place or the new image could not start (then the server runs as it is).
pub fn without_thread_caches() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    {
        use std::os::unix::process::CommandExt;
        let current = std::env::var("GLIBC_TUNABLES").unwrap_or_default();
        if current.contains("tcache_count") {
            return;
        }
        let tunables = if current.is_empty() {
            NO_THREAD_CACHES.to_string()
        } else {
            format!("{current}:{NO_THREAD_CACHES}")
        };
        let Ok(exe) = std::env::current_exe() else {
            return;
        };
        let e = std::process::Command::new(exe)
            .args(std::env::args_os().skip(1))
            .env("GLIBC_TUNABLES", tunables)
            .exec();
        tracing::warn!(
            "running with glibc's thread caches: could not start again without them: {e}"
        );
    }
}

/// Makes every thread allocate from one heap (glibc gives each thread that allocates its
/// own arena otherwise; zenoh's runtime threads each kept a few hundred KiB of pages after
/// a load). Called before the session opens; the step allocates little, so the shared
/// heap's lock costs nothing measurable (docs/reliability.md).
pub(super) fn one_heap() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt sets an allocator parameter; M_ARENA_MAX takes any positive count.
    unsafe {
        libc::mallopt(libc::M_ARENA_MAX, 1);
    }
}

/// Returns the heap's free pages to the operating system (glibc keeps them resident
/// otherwise: a burst of traffic would hold its memory for good). Called every
/// [`super::TRIM_EVERY`]; cheap on a heap of a few MiB.
pub(super) fn give_back_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: malloc_trim only releases free memory of the allocator's own heaps;
    // mallinfo2 only reads its counters.
    unsafe {
        libc::malloc_trim(0);
        let heap = libc::mallinfo2();
        tracing::debug!(
            in_use_kib = heap.uordblks / 1024,
            free_kib = heap.fordblks / 1024,
            mapped_kib = heap.hblkhd / 1024,
            "heap after a trim"
        );
    }
}
