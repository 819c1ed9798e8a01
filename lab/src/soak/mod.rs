//! The soak: a real server under real abuse on loopback, measured (`ricochet-lab soak`).
//!
//! A server process (this executable's `run`, journaled) hosts a scene; client threads,
//! each with its own zenoh session, send a mix of valid, invalid and oversized commands at
//! a set rate in all, and requests (with ids, retried) that must all be answered; a viewer
//! session subscribes to frames and stops reading for a while; at a set moment the server
//! is killed (SIGKILL) and resumed from its journal on the same endpoint while the clients
//! go on. The figures: frames stepped against real time, overruns, step time percentiles
//! (from the frames' own figures), what the server applied, refused and dropped, replies
//! missed, every accepted request found in the journal, and resident memory.
//!
//! This measures; it asserts nothing. Use a release build.

pub(crate) mod process;
mod table;

pub use process::{Memory, IDLE_AFTER, SETTLE, WARM_UP};
pub use table::command_line;

use process::ServerProcess;

use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::{anyhow, Result};
use ricochet_protocol::client::Client;
use ricochet_protocol::command::{Action, Command, Direction, Health};
use ricochet_protocol::frame::peek_header;
use ricochet_protocol::net::{Mode, Network};
use zenoh::Wait;

use super::percentile;

/// What to run.
#[derive(Clone, Debug)]
pub struct SoakOptions {
    pub scene: PathBuf,
    /// Seconds the clients send for.
    pub seconds: f64,
    /// Client sessions.
    pub clients: usize,
    /// Fire-and-forget commands a second, all clients together.
    pub rate: f64,
    /// Requests a second each client makes (each waits for its answer).
    pub requests: f64,
    /// When the viewer stops reading, and for how long, in seconds.
    pub stall_at: f64,
    pub stall_for: f64,
    /// When the server is killed and resumed, in seconds (none: it is not).
    pub kill_at: Option<f64>,
    /// Extra arguments of the server's `run`.
    pub server_args: Vec<String>,
}

/// What the soak measured.
#[derive(Debug, Default)]
pub struct SoakReport {
    pub seconds: f64,
    pub dt: f64,
    /// Steps the world took over the run, across the kill (its frame number at the end
    /// less at the start).
    pub frames: u64,
    /// Frames real time would have stepped over the run, less the time the server was down.
    /// Steps a second of real time while the server was up, as the frames seen by a
    /// watching client tell (before the kill, and after the resume).
    pub rates: Vec<f64>,
    /// From the kill until the resumed server answered a watching client (an upper bound
    /// on the time the world stood still: the client's session reconnects too).
    pub downtime: f64,
    pub overruns: u64,
    pub step_ms_p50: f64,
    pub step_ms_p99: f64,
    pub step_ms_max: f64,
    pub commands_sent: u64,
    pub oversized_sent: u64,
    pub invalid_sent: u64,
    pub requests_sent: u64,
    pub requests_answered: u64,
    pub requests_missed: u64,
    pub accepted_not_journaled: u64,
    /// The journal's size at the end, MiB.
    pub journal_mib: f64,
    /// The server's counts, before the kill and after the resume added.
    pub health: Health,
    /// Resident memory of each server process.
    pub rss: Vec<Memory>,
}

pub(crate) fn free_endpoint() -> Result<String> {
    let port = std::net::TcpListener::bind("127.0.0.1:0")?
        .local_addr()?
        .port();
    Ok(format!("tcp/127.0.0.1:{port}"))
}

pub(crate) fn wait_answered(client: &Client, limit: Duration) -> Result<Duration> {
    let began = Instant::now();
    while began.elapsed() < limit {
        if client
            .request(
                &Command::World(Action::Deselect),
                Duration::from_millis(500),
            )
            .is_ok()
        {
            return Ok(began.elapsed());
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    Err(anyhow!("the server did not answer within {limit:?}"))
}

fn health(client: &Client) -> Result<Health> {
    client
        .info(Duration::from_secs(5))?
        .health
        .ok_or_else(|| anyhow!("the server reports no health"))
}

fn add(a: &Health, b: &Health) -> Health {
    Health {
        frames: a.frames + b.frames,
        overruns: a.overruns + b.overruns,
        applied: a.applied + b.applied,
        refused: a.refused + b.refused,
        retries: a.retries + b.retries,
        rate_limited: a.rate_limited + b.rate_limited,
        queue_full: a.queue_full + b.queue_full,
        unsent: a.unsent + b.unsent,
        queries: a.queries + b.queries,
        over_budget: a.over_budget + b.over_budget,
    }
}

/// Runs the soak.
pub fn run(opts: &SoakOptions) -> Result<SoakReport> {
    let dir = tempfile::tempdir()?;
    let journal = dir.path().join("soak.journal");
    let endpoint = free_endpoint()?;
    let world = "soak";
    let mut args: Vec<String> = ["--world", world, "--listen", &endpoint]
        .iter()
        .map(|s| s.to_string())
        .collect();
    args.extend(opts.server_args.iter().cloned());
    let mut first_args = args.clone();
    first_args.extend([
        "--scene".to_string(),
        opts.scene.display().to_string(),
        "--journal".to_string(),
        journal.display().to_string(),
        // No checkpoints: the soak finds every accepted request in the journal by its id,
        // which a checkpoint would fold into the world's state.
        "--journal-bytes".to_string(),
        u64::MAX.to_string(),
        "--checkpoint-after-ms".to_string(),
        "1e300".to_string(),
    ]);
    let network = Network::client(Mode::Peer, vec![endpoint.clone()]);
    let mut server = ServerProcess::start(&first_args)?;
    let watcher = Client::open(&network, world)?;
    wait_answered(&watcher, Duration::from_secs(30))?;
    let dt = watcher.info(Duration::from_secs(5))?.dt;

    // The frames' own figures: step time and overruns, per frame.
    let steps: Arc<Mutex<Vec<f64>>> = Arc::default();
    let last_frame = Arc::new(AtomicU64::new(0));
    let overruns = Arc::new(Mutex::new((0u64, 0u64))); // (before the kill, now)
    let _frames = {
        let (steps, last_frame, overruns) = (steps.clone(), last_frame.clone(), overruns.clone());
        watcher
            .session()
            .declare_subscriber(watcher.keys().frame.clone())
            .callback(move |sample| {
                if let Ok(h) = peek_header(&sample.payload().to_bytes()) {
                    if h.kind != 2 {
                        steps.lock().unwrap().push(f64::from(h.stats.step_ms));
                        last_frame.fetch_max(h.frame, Ordering::Relaxed);
                        overruns.lock().unwrap().1 = u64::from(h.stats.overruns);
                    }
                }
            })
            .wait()
            .map_err(|e| anyhow!("subscribe: {e}"))?
    };

    // Every session connected before the load, and the server's memory taken then: its
    // start is a server with its clients, before they act, past one heap trim (as its end
    // is), so what connecting left freed but untrimmed does not count.
    let sessions = (0..opts.clients)
        .map(|_| Client::open(&network, world).map(Arc::new))
        .collect::<Result<Vec<_>>>()?;
    let stalled = Client::open(&network, world)?;
    for client in sessions.iter().map(|c| &**c).chain([&stalled]) {
        wait_answered(client, Duration::from_secs(30))?;
    }
    std::thread::sleep(SETTLE);
    server.mark_start();

    // The run starts with the first frame seen.
    let waiting = Instant::now();
    while last_frame.load(Ordering::Relaxed) == 0 {
        anyhow::ensure!(
            waiting.elapsed() < Duration::from_secs(10),
            "no frames from the server"
        );
        std::thread::sleep(Duration::from_millis(5));
    }
    let began = Instant::now();
    let first_frame = last_frame.load(Ordering::Relaxed);
    let end = began + Duration::from_secs_f64(opts.seconds);
    let sent = Arc::new(AtomicU64::new(0));
    let oversized = Arc::new(AtomicU64::new(0));
    let invalid = Arc::new(AtomicU64::new(0));
    let asked = Arc::new(AtomicU64::new(0));
    let answered = Arc::new(AtomicU64::new(0));
    let missed = Arc::new(AtomicU64::new(0));
    let accepted_ids: Arc<Mutex<Vec<(String, String)>>> = Arc::default();
    let mut threads = Vec::new();

    // The viewer that stops reading: its callback blocks, so its session stops taking
    // frames off the socket.
    let stall_from = began + Duration::from_secs_f64(opts.stall_at);
    let stall_until = stall_from + Duration::from_secs_f64(opts.stall_for);
    let stalled_frames = stalled
        .session()
        .declare_subscriber(stalled.keys().frame.clone())
        .callback(move |_| {
            let now = Instant::now();
            if now >= stall_from && now < stall_until {
                std::thread::sleep(stall_until - now);
            }
        })
        .wait()
        .map_err(|e| anyhow!("subscribe: {e}"))?;

    for (c, client) in sessions.into_iter().enumerate() {
        // Commands at the client's share of the rate, in 1 ms batches.
        let per_ms = opts.rate / opts.clients as f64 / 1000.0;
        let (sender, sent, oversized, invalid) = (
            client.clone(),
            sent.clone(),
            oversized.clone(),
            invalid.clone(),
        );
        threads.push(std::thread::spawn(move || {
            let big = format!(r#"{{"do":"load","text":"{}"}}"#, "#".repeat(70_000)).into_bytes();
            let mut owed = 0.0;
            let mut n = 0u64;
            while Instant::now() < end {
                owed += per_ms;
                while owed >= 1.0 {
                    owed -= 1.0;
                    n += 1;
                    let bytes = match n % 20 {
                        0 => {
                            oversized.fetch_add(1, Ordering::Relaxed);
                            big.clone()
                        }
                        1 | 2 => {
                            invalid.fetch_add(1, Ordering::Relaxed);
                            br#"{"do":"teleport","to":[1,2]}"#.to_vec()
                        }
                        k if k % 2 == 0 => Command::World(Action::Press {
                            dir: Direction::Right,
                        })
                        .to_json()
                        .into_bytes(),
                        _ => Command::World(Action::Release {
                            dir: Direction::Right,
                        })
                        .to_json()
                        .into_bytes(),
                    };
                    if sender.send_raw(bytes).is_ok() {
                        sent.fetch_add(1, Ordering::Relaxed);
                    }
                }
                std::thread::sleep(Duration::from_millis(1));
            }
        }));
        // Requests, each waited for (retried with its id), at the set rate.
        let me = client.session().zid().to_string();
        let (asker, asked, answered, missed, ids) = (
            client,
            asked.clone(),
            answered.clone(),
            missed.clone(),
            accepted_ids.clone(),
        );
        let interval = Duration::from_secs_f64(1.0 / opts.requests.max(0.01));
        threads.push(std::thread::spawn(move || {
            let mut next = Instant::now() + interval.mul_f64(c as f64 / 4.0);
            while Instant::now() < end {
                if let Some(wait) = next.checked_duration_since(Instant::now()) {
                    std::thread::sleep(wait);
                }
                next += interval;
                asked.fetch_add(1, Ordering::Relaxed);
                let command = Command::World(Action::SpawnParticles {
                    preset: "fire".into(),
                    at: [100.0, 60.0],
                    count: 5,
                });
                match asker.request_retrying(&command, Duration::from_secs(2), 10) {
                    Ok(reply) => {
                        answered.fetch_add(1, Ordering::Relaxed);
                        if let (true, Some(id)) = (reply.ok, reply.id) {
                            ids.lock().unwrap().push((me.clone(), id));
                        }
                    }
                    Err(_) => {
                        missed.fetch_add(1, Ordering::Relaxed);
                    }
                }
            }
        }));
    }

    // The kill and the resume.
    let mut rss = Vec::new();
    let mut before_kill = Health::default();
    let mut downtime = 0.0;
    // (first frame, when) of the stretch the server is up.
    let mut up_from = (first_frame, began);
    let mut rates = Vec::new();
    if let Some(at) = opts.kill_at {
        std::thread::sleep(
            (began + Duration::from_secs_f64(at)).saturating_duration_since(Instant::now()),
        );
        before_kill = health(&watcher)?;
        let killed_at = Instant::now();
        let frame = last_frame.load(Ordering::Relaxed);
        rates.push((frame - up_from.0) as f64 / killed_at.duration_since(up_from.1).as_secs_f64());
        {
            let mut o = overruns.lock().unwrap();
            o.0 = o.1;
        }
        rss.push(server.stop());
        let mut resume_args = args.clone();
        resume_args.extend(["--resume".to_string(), journal.display().to_string()]);
        resume_args.extend(
            [
                "--journal-bytes",
                &u64::MAX.to_string(),
                "--checkpoint-after-ms",
                "1e300",
            ]
            .map(str::to_string),
        );
        server = ServerProcess::start(&resume_args)?;
        wait_answered(&watcher, Duration::from_secs(60))?;
        downtime = killed_at.elapsed().as_secs_f64();
        server.mark_start();
        // The first frame of the resumed server this client sees.
        let seen = last_frame.load(Ordering::Relaxed);
        let waiting = Instant::now();
        while last_frame.load(Ordering::Relaxed) == seen
            && waiting.elapsed() < Duration::from_secs(5)
        {
            std::thread::sleep(Duration::from_millis(1));
        }
        up_from = (last_frame.load(Ordering::Relaxed), Instant::now());
    }
    for t in threads {
        let _ = t.join();
    }
    let elapsed = began.elapsed().as_secs_f64();
    let frame = last_frame.load(Ordering::Relaxed);
    rates.push((frame - up_from.0) as f64 / up_from.1.elapsed().as_secs_f64());
    let frames = frame - first_frame;
    let after = health(&watcher)?;
    // The load gone (the clients' sessions closed with their threads), the server idles.
    drop(stalled_frames);
    drop(stalled);
    std::thread::sleep(IDLE_AFTER);
    server.mark_idle();
    let journal_text = std::fs::read_to_string(&journal)?;
    let journal_mib = journal_text.len() as f64 / (1024.0 * 1024.0);
    let journaled: std::collections::HashSet<(String, String)> = journal_text
        .lines()
        .filter_map(ricochet_server::host::journal::text_of)
        .filter_map(|l| serde_json::from_str::<serde_json::Value>(l).ok())
        .filter_map(|v| {
            Some((
                v["sender"].as_str()?.to_string(),
                v["id"].as_str()?.to_string(),
            ))
        })
        .collect();
    let accepted_not_journaled = accepted_ids
        .lock()
        .unwrap()
        .iter()
        .filter(|key| !journaled.contains(*key))
        .count() as u64;
    rss.push(server.stop());

    let mut step_ms = std::mem::take(&mut *steps.lock().unwrap());
    step_ms.sort_by(f64::total_cmp);
    let (before, now) = *overruns.lock().unwrap();
    Ok(SoakReport {
        seconds: elapsed,
        dt,
        frames,
        rates,
        downtime,
        overruns: before + now,
        step_ms_p50: percentile(&step_ms, 0.5),
        step_ms_p99: percentile(&step_ms, 0.99),
        step_ms_max: step_ms.last().copied().unwrap_or(f64::NAN),
        commands_sent: sent.load(Ordering::Relaxed),
        oversized_sent: oversized.load(Ordering::Relaxed),
        invalid_sent: invalid.load(Ordering::Relaxed),
        requests_sent: asked.load(Ordering::Relaxed),
        requests_answered: answered.load(Ordering::Relaxed),
        requests_missed: missed.load(Ordering::Relaxed),
        accepted_not_journaled,
        journal_mib,
        health: add(&before_kill, &after),
        rss,
    })
}
