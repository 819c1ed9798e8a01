//! Fan-out: one server, `N` viewers, the chapter's 100 000-particle effect at 60 Hz,
//! measured twice: viewers connected to the server directly (peer mode), and viewers and
//! server meeting through a router (`ricochet-lab fanout`, docs/network.md).
//!
//! Real processes: this executable's `run` (and `router`); the viewers are `N` zenoh
//! sessions in this process, each joining the world and decoding every frame of the full
//! stream, as `ricochet-viewer` does before it draws. Measured over the run:
//! - the server's CPU (`/proc/<pid>/stat`, user and system time over wall time, in cores)
//!   and the bytes it sent on its TCP connections (the kernel's count, `ss -tinp`): with a
//!   router it sends each frame once, directly once per viewer;
//! - its late steps (`overruns` of its health, from its info);
//! - each viewer's frames decoded over the frames published, and its lag: when a frame
//!   reached it after it reached the first viewer to get it (no common clock is needed).
//!
//! The emitter of particles-100k releases its 100 000 particles at the start and they
//! burn out within four seconds: a feeder starts it again every four seconds.
//!
//! Viewers stand for viewers on other machines: on a machine of two cores or more the
//! server is pinned to core 0 and this process (its viewers) and the router to the others
//! (`taskset`), so they do not take the server's core.

use std::collections::HashMap;
use std::path::Path;
use std::process::{Child, Command as Process, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::{anyhow, Context, Result};
use ricochet_protocol::client::Client;
use ricochet_protocol::command::{Action, Command, ServerCommand};
use ricochet_protocol::net::{Mode, Network};

use super::percentile;
use super::soak::process::ServerProcess;
use super::soak::{free_endpoint, wait_answered};

/// A router process, killed when dropped.
struct RouterProcess(Child);

impl Drop for RouterProcess {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Pins every thread of process `pid`, and the threads they start, to `cpus` (`taskset -a
/// -p -c`, util-linux). Returns whether it took.
fn pin(pid: u32, cpus: &str) -> bool {
    Process::new("taskset")
        .args(["-a", "-p", "-c", cpus, &pid.to_string()])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

/// CPU seconds (user and system) a process has used.
fn cpu_seconds(pid: u32) -> Option<f64> {
    let pid = sysinfo::Pid::from_u32(pid);
    let mut system = sysinfo::System::new();
    system.refresh_processes_specifics(
        sysinfo::ProcessesToUpdate::Some(&[pid]),
        false,
        sysinfo::ProcessRefreshKind::nothing().with_cpu(),
    );
    Some(system.process(pid)?.accumulated_cpu_time() as f64 / 1000.0)
}

/// Bytes a process has sent on its TCP connections now open: the kernel's `bytes_sent`
/// of each (`ss -tinp`, iproute2).
fn bytes_written(pid: u32) -> Option<u64> {
    let out = Process::new("ss").args(["-tinpH"]).output().ok()?;
    let text = String::from_utf8_lossy(&out.stdout);
    let owner = format!("pid={pid},");
    let mut lines = text.lines();
    let mut sent = 0;
    while let Some(line) = lines.next() {
        if !line.contains(&owner) {
            continue;
        }
        let Some(info) = lines.next() else { break };
        sent += info
            .split_whitespace()
            .find_map(|f| f.strip_prefix("bytes_sent:"))
            .and_then(|v| v.parse::<u64>().ok())
            .unwrap_or(0);
    }
    Some(sent)
}

/// One viewer's figures.
#[derive(Clone, Debug, Default)]
pub struct ViewerFigures {
    pub frames: u64,
    pub bytes: u64,
    /// Milliseconds after the first viewer: median, 99th percentile, worst.
    pub lag_ms: [f64; 3],
}

/// One mode's figures.
#[derive(Clone, Debug)]
pub struct Run {
    pub mode: &'static str,
    pub server_cores: f64,
    pub server_wrote_mb_s: f64,
    pub frames_published: u64,
    pub overruns: u64,
    pub viewers: Vec<ViewerFigures>,
}

/// Both modes' figures.
#[derive(Clone, Debug)]
pub struct FanoutReport {
    pub viewers: usize,
    pub seconds: f64,
    pub runs: Vec<Run>,
    /// The machine's processor and cores.
    pub cpu: String,
    /// Which cores the server, the viewers and the router ran on.
    pub placement: String,
}

/// Runs particles-100k with `viewers` viewers for `seconds`, directly and through a router.
pub fn run(scenes: &Path, viewers: usize, seconds: f64) -> Result<FanoutReport> {
    let scene = scenes.join("particles-100k.toml");
    anyhow::ensure!(scene.exists(), "no scene {}", scene.display());
    // The machine as it is before this process is pinned to some of its cores.
    let cpu = super::cpu();
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let others = match cores {
        0..=2 => "1".to_string(),
        n => format!("1-{}", n - 1),
    };
    let pinned = (cores >= 2 && pin(std::process::id(), &others)).then_some(others);
    let runs = vec![
        one(&scene, viewers, seconds, false, pinned.as_deref())?,
        one(&scene, viewers, seconds, true, pinned.as_deref())?,
    ];
    Ok(FanoutReport {
        viewers,
        seconds,
        runs,
        cpu,
        placement: match &pinned {
            Some(others) => {
                format!("the server pinned to core 0, the viewers and the router to core {others}")
            }
            None => "server, viewers and router sharing the cores".into(),
        },
    })
}

/// One mode's run; `pinned`: the cores the viewers and the router are pinned to, the
/// server then to core 0.
fn one(
    scene: &Path,
    viewers: usize,
    seconds: f64,
    routed: bool,
    pinned: Option<&str>,
) -> Result<Run> {
    let world = if routed { "fanout-routed" } else { "fanout" };
    let endpoint = free_endpoint()?;
    let scene_arg = scene.display().to_string();
    let (router, server, network) = if routed {
        let router = RouterProcess(
            Process::new(crate::server_binary()?)
                .args(["router", "--listen", &endpoint])
                .env("RUST_LOG", "warn")
                .stdout(Stdio::null())
                .spawn()
                .context("start the router")?,
        );
        let server = ServerProcess::start(
            &[
                "--world",
                world,
                "--mode",
                "client",
                "--connect",
                &endpoint,
                "--scene",
                &scene_arg,
                "--paused",
            ]
            .map(str::to_string),
        )?;
        (
            Some(router),
            server,
            Network::client(Mode::Client, vec![endpoint]),
        )
    } else {
        let server = ServerProcess::start(
            &[
                "--world", world, "--listen", &endpoint, "--scene", &scene_arg, "--paused",
            ]
            .map(str::to_string),
        )?;
        (None, server, Network::client(Mode::Peer, vec![endpoint]))
    };
    if let Some(others) = pinned {
        pin(server.pid(), "0");
        if let Some(router) = &router {
            pin(router.0.id(), others);
        }
    }
    let control = Client::open(&network, world)?;
    wait_answered(&control, Duration::from_secs(60))?;

    // The viewers join while the world is paused, then it runs.
    let arrivals: Arc<Mutex<Vec<HashMap<u64, Instant>>>> =
        Arc::new(Mutex::new(vec![HashMap::new(); viewers]));
    let bytes = Arc::new(Mutex::new(vec![0u64; viewers]));
    let stop = Arc::new(AtomicBool::new(false));
    let mut threads = Vec::new();
    let (ready_tx, ready_rx) = std::sync::mpsc::channel();
    for v in 0..viewers {
        let (network, arrivals, bytes, stop, ready) = (
            network.clone(),
            arrivals.clone(),
            bytes.clone(),
            stop.clone(),
            ready_tx.clone(),
        );
        threads.push(std::thread::spawn(move || -> Result<()> {
            let client = Client::open(&network, world)?;
            let (frames, mut decoder) = client.join(Duration::from_secs(10))?;
            let _ = ready.send(());
            while !stop.load(Ordering::Relaxed) {
                let Ok(Some(sample)) = frames.recv_timeout(Duration::from_millis(100)) else {
                    continue;
                };
                let at = Instant::now();
                let payload = sample.payload().to_bytes();
                bytes.lock().unwrap()[v] += payload.len() as u64;
                if let Ok(h) = decoder.apply(&payload) {
                    arrivals.lock().unwrap()[v].insert(h.frame, at);
                }
            }
            Ok(())
        }));
    }
    drop(ready_tx);
    for _ in 0..viewers {
        ready_rx
            .recv_timeout(Duration::from_secs(60))
            .map_err(|_| anyhow!("a viewer did not join within 60 s"))?;
    }

    let before = control.info(Duration::from_secs(10))?;
    let (cpu0, wrote0) = (
        cpu_seconds(server.pid()).unwrap_or(0.0),
        bytes_written(server.pid()).unwrap_or(0),
    );
    let began = Instant::now();
    control.request(
        &Command::Server(ServerCommand::Resume),
        Duration::from_secs(10),
    )?;
    let mut next_fire = began + Duration::from_secs(4);
    while began.elapsed().as_secs_f64() < seconds {
        if Instant::now() >= next_fire {
            let fire = Command::World(Action::StartEmitter {
                preset: "fire".into(),
                count: 100_000,
                at: [100.0, 60.0],
            });
            let _ = control.send(&fire);
            next_fire += Duration::from_secs(4);
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    let wall = began.elapsed().as_secs_f64();
    let (cpu1, wrote1) = (
        cpu_seconds(server.pid()).unwrap_or(0.0),
        bytes_written(server.pid()).unwrap_or(0),
    );
    let after = control.info(Duration::from_secs(10))?;
    stop.store(true, Ordering::Relaxed);
    for t in threads {
        t.join().map_err(|_| anyhow!("a viewer panicked"))??;
    }
    drop(server);

    let health = |i: &ricochet_protocol::command::WorldInfo| i.health.clone().unwrap_or_default();
    let frames_published = health(&after).frames - health(&before).frames;
    let arrivals = arrivals.lock().unwrap();
    // When each frame first reached a viewer.
    let mut first: HashMap<u64, Instant> = HashMap::new();
    for a in arrivals.iter() {
        for (&f, &t) in a {
            first.entry(f).and_modify(|e| *e = (*e).min(t)).or_insert(t);
        }
    }
    let bytes = bytes.lock().unwrap();
    let figures = arrivals
        .iter()
        .zip(bytes.iter())
        .map(|(a, &b)| {
            let mut lags: Vec<f64> = a
                .iter()
                .map(|(f, t)| t.duration_since(first[f]).as_secs_f64() * 1e3)
                .collect();
            lags.sort_by(f64::total_cmp);
            ViewerFigures {
                frames: a.len() as u64,
                bytes: b,
                lag_ms: [
                    percentile(&lags, 0.5),
                    percentile(&lags, 0.99),
                    lags.last().copied().unwrap_or(0.0),
                ],
            }
        })
        .collect();
    Ok(Run {
        mode: if routed {
            "through a router"
        } else {
            "directly (peer mode)"
        },
        server_cores: (cpu1 - cpu0) / wall,
        server_wrote_mb_s: (wrote1 - wrote0) as f64 / wall / 1e6,
        frames_published,
        overruns: health(&after).overruns - health(&before).overruns,
        viewers: figures,
    })
}

impl FanoutReport {
    /// The table, with the command that made it.
    pub fn to_markdown(&self) -> String {
        let mut out = format!(
            "Measured by `{}` ({} viewers decoding every frame of particles-100k, its \
             emitter started again every 4 s, {} s of each mode; {}; {}; lag: when a \
             frame reached a viewer after it reached the first viewer to get it):\n\n",
            super::command_line(),
            self.viewers,
            self.seconds,
            self.cpu,
            self.placement,
        );
        out.push_str(
            "| viewers meet the server | server CPU (cores) | server sent | frames \
             published | late steps | frames decoded, fewest of the viewers | viewer \
             received (mean) | lag median / p99 / worst, worst of the viewers |\n\
             |---|---:|---:|---:|---:|---:|---:|---:|\n",
        );
        for r in &self.runs {
            let fewest = r.viewers.iter().map(|v| v.frames).min().unwrap_or(0);
            let mean_bytes = r.viewers.iter().map(|v| v.bytes).sum::<u64>() as f64
                / r.viewers.len().max(1) as f64;
            let worst = |k: usize| r.viewers.iter().map(|v| v.lag_ms[k]).fold(0.0f64, f64::max);
            out.push_str(&format!(
                "| {} | {:.2} | {:.1} MB/s | {} | {} | {} ({:.0}%) | {:.1} MB/s | {:.1} / {:.1} / {:.1} ms |\n",
                r.mode,
                r.server_cores,
                r.server_wrote_mb_s,
                r.frames_published,
                r.overruns,
                fewest,
                fewest as f64 * 100.0 / r.frames_published.max(1) as f64,
                mean_bytes / self.seconds / 1e6,
                worst(0),
                worst(1),
                worst(2),
            ));
        }
        out
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_process_cpu_time_grows_as_it_works() {
        let pid = std::process::id();
        let before = super::cpu_seconds(pid).expect("this process is read");
        let began = std::time::Instant::now();
        let mut x = 0u64;
        while began.elapsed() < std::time::Duration::from_millis(300) {
            x = std::hint::black_box(x.wrapping_mul(31).wrapping_add(7));
        }
        let after = super::cpu_seconds(pid).expect("this process is read");
        assert!(after - before >= 0.1, "{before} s, then {after} s");
    }
}
