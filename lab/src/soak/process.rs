//! The soak's server process, and its memory as the kernel tells it.

use std::process::{Child, Command as Process, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::{Context, Result};

/// Process `pid`'s resident memory, MiB (Linux): (anonymous, all), and its threads.
/// Anonymous memory is what the process allocated (heap, stacks, buffers); the rest is
/// mostly its executable's code, paged in from the file as code paths first run, shared
/// and reclaimable. `sysinfo` reads the whole resident set and the threads; the anonymous
/// part, which is what a leak grows, only `/proc/PID/status` gives.
fn rss_mib(pid: u32) -> Option<(f64, f64, u32)> {
    let id = sysinfo::Pid::from_u32(pid);
    let mut system = sysinfo::System::new();
    system.refresh_processes_specifics(
        sysinfo::ProcessesToUpdate::Some(&[id]),
        false,
        sysinfo::ProcessRefreshKind::nothing()
            .with_memory()
            .with_tasks(),
    );
    let process = system.process(id)?;
    let threads = process.tasks().map_or(1, |t| t.len().max(1)) as u32;
    let all = process.memory() as f64 / (1024.0 * 1024.0);
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    let anon_kib: f64 = status
        .lines()
        .find(|l| l.starts_with("RssAnon:"))?
        .split_whitespace()
        .nth(1)?
        .parse()
        .ok()?;
    Some((anon_kib / 1024.0, all, threads))
}

/// Resident anonymous memory of a server process (what it allocated), MiB, sampled every
/// 100 ms from when it first answered; and its whole resident set at start and end.
#[derive(Clone, Copy, Debug, Default)]
pub struct Memory {
    pub start: f64,
    /// [`WARM_UP`] after the start, if it lived that long: what its buffers settle at.
    pub warm: Option<f64>,
    pub peak: f64,
    pub end: f64,
    pub total_start: f64,
    pub total_end: f64,
    /// The process's threads at start and at the end.
    pub threads_start: u32,
    pub threads_end: u32,
    /// Anonymous memory [`IDLE_AFTER`] after the load ended (the server that lived to the
    /// end only).
    pub idle: Option<f64>,
}

/// How long the server idles after the load before its memory is taken again: past the
/// time it remembers request ids, and a memory trim (every 10 s).
pub const IDLE_AFTER: Duration =
    Duration::from_secs(ricochet_server::host::answered::REMEMBER_FOR.as_secs() + 12);

/// How long the connected clients wait before the load starts and the server's memory is
/// taken as its start: past one of the server's heap trims.
pub const SETTLE: Duration = Duration::from_secs(ricochet_server::host::TRIM_EVERY.as_secs() + 1);

/// When a server's memory counts as warmed up.
pub const WARM_UP: Duration = Duration::from_secs(10);

pub(crate) struct ServerProcess {
    child: Child,
    rss: Arc<Mutex<(Memory, Option<Instant>)>>,
    sampling: Arc<AtomicBool>,
}

impl Drop for ServerProcess {
    fn drop(&mut self) {
        self.sampling.store(false, Ordering::Relaxed);
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl ServerProcess {
    pub(crate) fn start(args: &[String]) -> Result<ServerProcess> {
        let child = Process::new(crate::server_binary()?)
            .arg("run")
            .args(args)
            .env(
                "RUST_LOG",
                std::env::var("RUST_LOG").unwrap_or_else(|_| "warn".into()),
            )
            .stdout(Stdio::null())
            .spawn()
            .context("start the server")?;
        let pid = child.id();
        let rss = Arc::new(Mutex::new((Memory::default(), None::<Instant>)));
        let sampling = Arc::new(AtomicBool::new(true));
        let (samples, on) = (rss.clone(), sampling.clone());
        std::thread::spawn(move || {
            while on.load(Ordering::Relaxed) {
                if let Some((mib, total, threads)) = rss_mib(pid) {
                    let mut s = samples.lock().unwrap();
                    if let Some(since) = s.1 {
                        s.0.peak = s.0.peak.max(mib);
                        s.0.end = mib;
                        s.0.total_end = total;
                        s.0.threads_end = threads;
                        if s.0.warm.is_none() && since.elapsed() >= WARM_UP {
                            s.0.warm = Some(mib);
                        }
                    }
                }
                std::thread::sleep(Duration::from_millis(100));
            }
        });
        Ok(ServerProcess {
            child,
            rss,
            sampling,
        })
    }

    /// The server's process id.
    pub(crate) fn pid(&self) -> u32 {
        self.child.id()
    }

    /// Takes the memory now as the start: the server is up, its world loaded.
    pub(super) fn mark_start(&self) {
        if let Some((mib, total, threads)) = rss_mib(self.child.id()) {
            let mut s = self.rss.lock().unwrap();
            *s = (
                Memory {
                    start: mib,
                    warm: None,
                    peak: mib,
                    end: mib,
                    total_start: total,
                    total_end: total,
                    threads_start: threads,
                    threads_end: threads,
                    idle: None,
                },
                Some(Instant::now()),
            );
        }
    }

    /// Takes the memory now as the idle figure.
    pub(super) fn mark_idle(&self) {
        if let Some((mib, _, _)) = rss_mib(self.child.id()) {
            self.rss.lock().unwrap().0.idle = Some(mib);
        }
    }

    /// Kills the server (SIGKILL) and gives its memory figures.
    pub(super) fn stop(self) -> Memory {
        let rss = self.rss.lock().unwrap().0;
        drop(self);
        rss
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn this_process_has_memory_and_threads() {
        let held = std::hint::black_box(vec![1u8; 64 << 20]);
        let worker =
            std::thread::spawn(|| std::thread::sleep(std::time::Duration::from_millis(500)));
        let (anon, all, threads) =
            super::rss_mib(std::process::id()).expect("this process is read");
        assert!(anon >= 60.0 && all >= anon, "{anon} MiB anonymous of {all}");
        assert!(threads >= 2, "{threads} threads");
        drop(held);
        worker.join().unwrap();
    }
}
