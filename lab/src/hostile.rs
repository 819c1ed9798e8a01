//! The hostile run: attacks from the security audit against real servers on loopback
//! (this executable's `run`), each measured twice, with its defence as shipped and with
//! that defence switched off by the server's own flags, so the table shows what the
//! defence buys (`ricochet-lab hostile`, docs/security.md).
//!
//! - **Whole-world commands**: a world of 90 000 static boxes (a step costs next to
//!   nothing, a `reset` rebuilds every box: more than a frame) flooded with resets from
//!   one sender and, as requests, from another. Measured: the frames the world stepped
//!   over the frames due (`health.frames` before and after, over the flood's wall time).
//!   Switched off: `--command-share 1 --sender-share 1 --command-burst-ms 60000`.
//! - **A journal under a command flood**: the emitters demo, journaled, flooded by four
//!   senders with valid commands at their rate limit. Measured: the most bytes the
//!   journal and its checkpoints held on disk at once (sampled every 20 ms). Switched
//!   off: no checkpoints (`--journal-bytes` and `--checkpoint-after-ms` at their largest).
//! - **Made-up sender ids**: one session floods `snapshot` queries, each claiming one of
//!   20 sender ids of sessions connected to nothing. Measured: queries answered a second.
//!   Switched off: `--sender-ids claimed` (every claim keeps buckets of its own).
//! - **A borrowed sender id**: a spy on a client's path sees its commands and floods under
//!   its id (bare claims, the client's signed messages sent again, and those with a new
//!   counter), while the client makes a request every 50 ms at a rate of 20 a second.
//!   Measured: the client's requests answered. Switched off: `--sender-ids connected`
//!   (claims of connected sessions taken unsigned).

use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{anyhow, Result};
use ricochet_protocol::client::Client;
use ricochet_protocol::command::{Action, Command, Direction, ServerCommand};
use ricochet_protocol::net::{Mode, Network};
use zenoh::Wait;

use super::soak::process::ServerProcess;
use super::soak::{free_endpoint, wait_answered};

/// A world of 300 x 300 static boxes.
const TILES: &str = "[world]\ngravity = [0, -10]\nbounds = [[0, 0], [700, 700]]\n\n\
[[generate]]\nkind = \"grid\"\nid = \"tile\"\ngroup = \"tiles\"\nshape = \"rect\"\n\
size = [1, 1]\nstart = [5, 5]\nstep = [2, 2]\ncols = 300\nrows = 300\nmass = 0\n";

/// The bound the journal run uses: small, so a short flood passes it many times.
const JOURNAL_BYTES: u64 = 1 << 20;

/// One attack's figures.
#[derive(Clone, Debug)]
pub struct Attack {
    pub name: &'static str,
    pub defence: &'static str,
    pub measure: &'static str,
    pub defended: String,
    pub undefended: String,
}

/// Every attack's figures.
#[derive(Clone, Debug)]
pub struct HostileReport {
    pub attacks: Vec<Attack>,
    pub seconds: f64,
}

/// A server on a free loopback endpoint, and a client of it once it answers.
fn serve(world: &str, args: &[String]) -> Result<(ServerProcess, Network)> {
    let endpoint = free_endpoint()?;
    let mut all: Vec<String> = ["--world", world, "--listen", &endpoint]
        .map(str::to_string)
        .to_vec();
    all.extend(args.iter().cloned());
    let server = ServerProcess::start(&all)?;
    let network = Network::client(Mode::Peer, vec![endpoint]);
    let client = Client::open(&network, world)?;
    wait_answered(&client, Duration::from_secs(60))?;
    Ok((server, network))
}

/// Frames stepped over frames due while 90 000 boxes are flooded with resets.
fn whole_world(dir: &Path, seconds: f64, defended: bool) -> Result<f64> {
    let scene = dir.join("tiles.toml");
    std::fs::write(&scene, TILES)?;
    let mut args = vec!["--scene".to_string(), scene.display().to_string()];
    if !defended {
        args.extend(
            [
                "--command-share",
                "1",
                "--sender-share",
                "1",
                "--command-burst-ms",
                "60000",
            ]
            .map(str::to_string),
        );
    }
    let world = "hostile-reset";
    let (_server, network) = serve(world, &args)?;
    let (flooder, asker, watcher) = (
        Client::open(&network, world)?,
        Client::open(&network, world)?,
        Client::open(&network, world)?,
    );
    wait_answered(&asker, Duration::from_secs(30))?;
    let info = watcher.info(Duration::from_secs(10))?;
    let before = info.health.map(|h| h.frames).unwrap_or(0);
    let reset = Command::Server(ServerCommand::Reset { paused: false });
    let began = Instant::now();
    while began.elapsed().as_secs_f64() < seconds {
        for _ in 0..20 {
            flooder.send(&reset)?;
        }
        let _ = asker.request(&reset, Duration::from_secs(2));
        std::thread::sleep(Duration::from_millis(20));
    }
    let elapsed = began.elapsed().as_secs_f64();
    let after = watcher
        .info(Duration::from_secs(30))?
        .health
        .ok_or_else(|| anyhow!("the server reported no health"))?
        .frames;
    Ok(after.saturating_sub(before) as f64 / (elapsed / info.dt))
}

/// Bytes of the files of `dir` whose names start with `stem`.
fn bytes_on_disk(dir: &Path, stem: &str) -> u64 {
    std::fs::read_dir(dir)
        .map(|entries| {
            entries
                .flatten()
                .filter(|e| e.file_name().to_string_lossy().starts_with(stem))
                .filter_map(|e| e.metadata().ok())
                .map(|m| m.len())
                .sum()
        })
        .unwrap_or(0)
}

/// The most bytes a journal and its checkpoints held at once under a flood of valid
/// commands.
fn journal_flood(dir: &Path, scenes: &Path, seconds: f64, defended: bool) -> Result<u64> {
    let sub = dir.join(if defended { "bounded" } else { "unbounded" });
    std::fs::create_dir_all(&sub)?;
    let journal = sub.join("world.journal");
    let mut args = vec![
        "--scene".to_string(),
        scenes.join("emitters.toml").display().to_string(),
        "--journal".to_string(),
        journal.display().to_string(),
    ];
    let bound = if defended {
        JOURNAL_BYTES.to_string()
    } else {
        u64::MAX.to_string()
    };
    args.extend(["--journal-bytes".to_string(), bound]);
    if !defended {
        args.extend(["--checkpoint-after-ms", "1e300"].map(str::to_string));
    }
    let world = "hostile-journal";
    let (_server, network) = serve(world, &args)?;
    let senders = (0..4)
        .map(|_| Client::open(&network, world))
        .collect::<Result<Vec<_>>>()?;
    let stop = Arc::new(AtomicBool::new(false));
    let floods: Vec<_> = senders
        .into_iter()
        .map(|client| {
            let stop = stop.clone();
            std::thread::spawn(move || {
                let (press, release) = (
                    Command::World(Action::Press {
                        dir: Direction::Left,
                    }),
                    Command::World(Action::Release {
                        dir: Direction::Left,
                    }),
                );
                // At the per-sender rate limit (1000 a second): every one applied.
                while !stop.load(Ordering::Relaxed) {
                    for _ in 0..5 {
                        let _ = client.send(&press);
                        let _ = client.send(&release);
                    }
                    std::thread::sleep(Duration::from_millis(10));
                }
            })
        })
        .collect();
    let began = Instant::now();
    let mut most = 0;
    while began.elapsed().as_secs_f64() < seconds {
        most = most.max(bytes_on_disk(&sub, "world.journal"));
        std::thread::sleep(Duration::from_millis(20));
    }
    stop.store(true, Ordering::Relaxed);
    for flood in floods {
        let _ = flood.join();
    }
    Ok(most.max(bytes_on_disk(&sub, "world.journal")))
}

/// Snapshot queries answered a second while one session floods them under 20 made-up
/// sender ids.
fn claimed_ids(scenes: &Path, seconds: f64, defended: bool) -> Result<f64> {
    let mut args = vec![
        "--scene".to_string(),
        scenes.join("emitters.toml").display().to_string(),
    ];
    if !defended {
        args.extend(["--sender-ids", "claimed"].map(str::to_string));
    }
    let world = "hostile-claims";
    let (_server, network) = serve(world, &args)?;
    let flooder = Client::open(&network, world)?;
    // Ids of sessions that exist but are connected to nothing: made-up claims.
    let mut isolated = Vec::new();
    let mut ids = Vec::new();
    for _ in 0..20 {
        let mut config = zenoh::Config::default();
        for (key, value) in [
            ("scouting/multicast/enabled", "false"),
            ("listen/endpoints", "[]"),
        ] {
            config
                .insert_json5(key, value)
                .map_err(|e| anyhow!("zenoh configuration {key}: {e}"))?;
        }
        let session = zenoh::open(config).wait().map_err(|e| anyhow!("{e}"))?;
        let publisher = session
            .declare_publisher("elsewhere")
            .wait()
            .map_err(|e| anyhow!("{e}"))?;
        ids.push(publisher.id());
        isolated.push((session, publisher));
    }
    let key = flooder.keys().snapshot.clone();
    let began = Instant::now();
    let (mut answered, mut sent) = (0u64, 0u32);
    while began.elapsed().as_secs_f64() < seconds {
        let mut pending = Vec::new();
        for _ in 0..60 {
            sent += 1;
            let source = zenoh::sample::SourceInfo::new(ids[sent as usize % ids.len()], sent);
            let get = flooder
                .session()
                .get(key.as_str())
                .source_info(source)
                .timeout(Duration::from_secs(5))
                .wait()
                .map_err(|e| anyhow!("{e}"))?;
            pending.push(get);
        }
        for replies in pending {
            while let Ok(reply) = replies.recv() {
                answered += u64::from(reply.result().is_ok());
            }
        }
    }
    Ok(answered as f64 / began.elapsed().as_secs_f64())
}

/// The share of a client's requests answered while a spy floods under its id.
fn borrowed_id(scenes: &Path, seconds: f64, defended: bool) -> Result<f64> {
    let mut args: Vec<String> = vec![
        "--scene".into(),
        scenes.join("impulse.toml").display().to_string(),
    ];
    args.extend(["--sender-rate", "20", "--sender-burst", "20"].map(str::to_string));
    if !defended {
        args.extend(["--sender-ids", "connected"].map(str::to_string));
    }
    let world = "hostile-borrowed";
    let (_server, network) = serve(world, &args)?;
    // The spy listens, and the client connects to it as well as to the server.
    let spy_endpoint = free_endpoint()?;
    let mut spy_network = network.clone();
    spy_network.listen = vec![spy_endpoint.clone()];
    let spy = Client::open(&spy_network, world)?;
    let mut both = network.clone();
    both.connect.push(spy_endpoint);
    let client = Client::open(&both, world)?;
    type Seen = (zenoh::session::EntityGlobalId, Vec<u8>, Vec<u8>);
    let seen: Arc<std::sync::Mutex<Vec<Seen>>> = Arc::default();
    let _watch = {
        let seen = seen.clone();
        spy.session()
            .declare_subscriber(spy.keys().cmd.clone())
            .callback(move |sample| {
                if let (Some(source), Some(attachment)) =
                    (sample.source_info(), sample.attachment())
                {
                    seen.lock().unwrap_or_else(|e| e.into_inner()).push((
                        *source.source_id(),
                        sample.payload().to_bytes().into_owned(),
                        attachment.to_bytes().into_owned(),
                    ));
                }
            })
            .wait()
            .map_err(|e| anyhow!("{e}"))?
    };
    let began = Instant::now();
    while seen.lock().unwrap_or_else(|e| e.into_inner()).len() < 3 {
        client.send_raw(b"{}".to_vec())?;
        if began.elapsed() > Duration::from_secs(10) {
            return Err(anyhow!("the spy never saw the client's commands"));
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    let captured = seen.lock().unwrap_or_else(|e| e.into_inner()).clone();
    let victim = captured[0].0;
    let stop = Arc::new(AtomicBool::new(false));
    let flood = {
        let stop = stop.clone();
        let key = spy.keys().cmd.clone();
        std::thread::spawn(move || -> Result<()> {
            let publisher = spy
                .session()
                .declare_publisher(key)
                .wait()
                .map_err(|e| anyhow!("{e}"))?;
            let mut k = 0u32;
            while !stop.load(Ordering::Relaxed) {
                for (_, payload, attachment) in &captured {
                    k = k.wrapping_add(1);
                    let source = || zenoh::sample::SourceInfo::new(victim, k);
                    let mut moved = attachment.clone();
                    moved[33] = moved[33].wrapping_add(100);
                    for (body, proof) in [
                        (b"{}".to_vec(), None),
                        (payload.clone(), Some(attachment.clone())),
                        (payload.clone(), Some(moved)),
                    ] {
                        let mut put = publisher.put(body).source_info(source());
                        if let Some(proof) = proof {
                            put = put.attachment(proof);
                        }
                        put.wait().map_err(|e| anyhow!("{e}"))?;
                    }
                }
                std::thread::sleep(Duration::from_micros(200));
            }
            Ok(())
        })
    };
    std::thread::sleep(Duration::from_millis(300));
    let began = Instant::now();
    let (mut sent, mut answered) = (0u32, 0u32);
    while began.elapsed().as_secs_f64() < seconds {
        sent += 1;
        let reply = client.request(
            &Command::Server(ServerCommand::Resume),
            Duration::from_secs(5),
        )?;
        answered += u32::from(reply.ok);
        std::thread::sleep(Duration::from_millis(50));
    }
    stop.store(true, Ordering::Relaxed);
    flood
        .join()
        .map_err(|_| anyhow!("the spy's flood panicked"))??;
    Ok(f64::from(answered) / f64::from(sent.max(1)))
}

/// Runs every attack for `seconds` each, with its defence and without.
pub fn run(scenes: &Path, seconds: f64) -> Result<HostileReport> {
    let dir = tempfile::tempdir()?;
    let percent = |f: f64| format!("{:.0}%", f * 100.0);
    let mib = |b: u64| format!("{:.1} MiB", b as f64 / (1024.0 * 1024.0));
    let attacks = vec![
        Attack {
            name: "a flood of `reset` on 90 000 boxes (each more than a frame's work)",
            defence: "commands priced and held to a share of the server's time (`--command-share 0.2`, `--sender-share 0.1`)",
            measure: "frames stepped over frames due",
            defended: percent(whole_world(dir.path(), seconds, true)?),
            undefended: percent(whole_world(dir.path(), seconds, false)?),
        },
        Attack {
            name: "four senders at their rate limit of valid commands, journaled",
            defence: "checkpoints bound the journal (`--journal-bytes 1048576` here)",
            measure: "the most bytes the journal and its checkpoints held on disk at once",
            defended: mib(journal_flood(dir.path(), scenes, seconds, true)?),
            undefended: mib(journal_flood(dir.path(), scenes, seconds, false)?),
        },
        Attack {
            name: "one session floods `snapshot` queries, each claiming one of 20 made-up sender ids",
            defence: "a claim naming no session connected to the server shares the anonymous sender's buckets (`--sender-ids connected`)",
            measure: "queries answered a second (one sender may make 50 a second, 100 at once)",
            defended: format!("{:.0}", claimed_ids(scenes, seconds, true)?),
            undefended: format!("{:.0}", claimed_ids(scenes, seconds, false)?),
        },
        Attack {
            name: "a spy that sees a client's commands floods under the client's id (bare claims, its signed messages again, and with new counters)",
            defence: "a claim keeps its own buckets only when signed by the key its id derives from, each counter once (`--sender-ids signed`)",
            measure: "the client's requests answered (20 a second allowed; it makes one every 50 ms)",
            defended: percent(borrowed_id(scenes, seconds, true)?),
            undefended: percent(borrowed_id(scenes, seconds, false)?),
        },
    ];
    Ok(HostileReport { attacks, seconds })
}

impl HostileReport {
    /// The table, with the command and machine it was measured by.
    pub fn to_markdown(&self) -> String {
        let mut out = format!(
            "Measured by `{}` on {}; {} s of each attack, against a fresh server each time.\n\n\
             | attack | defence | measured | with the defence | switched off |\n|---|---|---|---:|---:|\n",
            super::command_line(),
            super::machine().replace(", one thread used", ""),
            self.seconds
        );
        for a in &self.attacks {
            out += &format!(
                "| {} | {} | {} | {} | {} |\n",
                a.name, a.defence, a.measure, a.defended, a.undefended
            );
        }
        out
    }
}
