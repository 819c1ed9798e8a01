//! A viewer on a slow link: a network namespace made by the test, joined to this one by a
//! veth pair whose both ends a token bucket holds to `LINK` bits a second (`tc qdisc ...
//! tbf`), dropping what would wait in its queue more than 400 ms. This kernel has no
//! netem, so the delay is added by a relay in the test (`Delay`): the watchers reach the
//! server through it, and every byte waits `DELAY` in each direction on its way. The
//! server runs here; `ricochet watch` runs in the namespace, with real processes.
//!
//! The world is kept busy with fire, well over the link's rate in frames at every step. A
//! watcher that states its link's budget (`--max-bandwidth`) gets a reduced-rate stream
//! that fits and stays within `MAX_LAG` of the server once joined; a watcher of every step
//! over the same link does not keep up, which is what the reduced-rate streams are for.
//!
//! Needs root (the namespace, the link and its queue): CI runs as root. Every wait is
//! bounded; the namespace and the link are removed when the test ends.

mod common;

use std::collections::HashMap;
use std::io::{Read, Write};
use std::net::{TcpListener, TcpStream};
use std::process::{Command as Process, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{mpsc, Arc, Mutex};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use common::*;
use ricochet_protocol::client::Client;
use ricochet_protocol::command::{Action, Command};
use ricochet_protocol::net::{Mode, Network};

/// The link's rate.
const LINK: &str = "1mbit";
const LINK_BITS: f64 = 1e6;
/// The budget the careful watcher states: well under the link, as the streams' rates
/// swing with the fire.
const BUDGET: &str = "600k";
/// The careful watcher's frames arrive at most this late.
const MAX_LAG: Duration = Duration::from_millis(500);
const WATCH_SECONDS: f64 = 10.0;
/// What the relay adds to the link's own delay, each way.
const DELAY: Duration = Duration::from_millis(40);

/// A namespace joined to this one by a rate-limited veth pair; removed when dropped.
struct SlowLink {
    ns: String,
    host_if: String,
    /// This side's address, and the namespace's.
    host_ip: String,
}

impl SlowLink {
    fn make() -> Result<SlowLink, String> {
        let id = std::process::id() % 10_000;
        let net = 100 + id % 150;
        let link = SlowLink {
            ns: format!("rslow{id}"),
            host_if: format!("rsa{id}"),
            host_ip: format!("10.211.{net}.1"),
        };
        let peer_if = format!("rsb{id}");
        let ns_ip = format!("10.211.{net}.2");
        let tbf = ["tbf", "rate", LINK, "burst", "16kbit", "latency", "400ms"];
        sh(&["ip", "netns", "add", &link.ns])?;
        sh(&[
            "ip",
            "link",
            "add",
            &link.host_if,
            "type",
            "veth",
            "peer",
            "name",
            &peer_if,
        ])?;
        sh(&["ip", "link", "set", &peer_if, "netns", &link.ns])?;
        sh(&[
            "ip",
            "addr",
            "add",
            &format!("{}/24", link.host_ip),
            "dev",
            &link.host_if,
        ])?;
        sh(&["ip", "link", "set", &link.host_if, "up"])?;
        let in_ns = |args: &[&str]| {
            let mut all = vec!["ip", "netns", "exec", &link.ns];
            all.extend_from_slice(args);
            sh(&all)
        };
        in_ns(&["ip", "addr", "add", &format!("{ns_ip}/24"), "dev", &peer_if])?;
        in_ns(&["ip", "link", "set", &peer_if, "up"])?;
        in_ns(&["ip", "link", "set", "lo", "up"])?;
        let mut host_q = vec!["tc", "qdisc", "add", "dev", &link.host_if, "root"];
        host_q.extend_from_slice(&tbf);
        sh(&host_q)?;
        let mut ns_q = vec!["tc", "qdisc", "add", "dev", &peer_if, "root"];
        ns_q.extend_from_slice(&tbf);
        in_ns(&ns_q)?;
        Ok(link)
    }
}

impl Drop for SlowLink {
    fn drop(&mut self) {
        let _ = sh(&["ip", "link", "del", &self.host_if]);
        let _ = sh(&["ip", "netns", "del", &self.ns]);
    }
}

/// A TCP relay that holds every byte `DELAY` before passing it on, each way, with a
/// bounded queue (a slow reader holds up its writer, as a link does). It stops taking
/// connections when dropped; a connection's threads end when either side closes.
struct Delay {
    stop: Arc<AtomicBool>,
}

impl Delay {
    /// Listens on `at` (an `ip:port`) and relays each connection to `to`.
    fn start(at: &str, to: String) -> Delay {
        let listener = TcpListener::bind(at).unwrap();
        listener.set_nonblocking(true).unwrap();
        let stop = Arc::new(AtomicBool::new(false));
        let stopped = stop.clone();
        std::thread::spawn(move || {
            while !stopped.load(Ordering::Relaxed) {
                match listener.accept() {
                    Ok((inbound, _)) => {
                        inbound.set_nonblocking(false).unwrap();
                        let Ok(outbound) = TcpStream::connect(&to) else {
                            continue;
                        };
                        for (from, into) in [
                            (inbound.try_clone().unwrap(), outbound.try_clone().unwrap()),
                            (outbound, inbound),
                        ] {
                            Delay::pump(from, into);
                        }
                    }
                    Err(_) => std::thread::sleep(Duration::from_millis(10)),
                }
            }
        });
        Delay { stop }
    }

    /// Reads `from` and writes what it read to `into`, each chunk `DELAY` after it came.
    fn pump(mut from: TcpStream, mut into: TcpStream) {
        let (tx, rx) = mpsc::sync_channel::<(Instant, Vec<u8>)>(64);
        std::thread::spawn(move || {
            let mut buf = vec![0u8; 16 * 1024];
            while let Ok(n @ 1..) = from.read(&mut buf) {
                if tx
                    .send((Instant::now() + DELAY, buf[..n].to_vec()))
                    .is_err()
                {
                    break;
                }
            }
        });
        std::thread::spawn(move || {
            for (due, bytes) in rx {
                std::thread::sleep(due.saturating_duration_since(Instant::now()));
                if into.write_all(&bytes).is_err() {
                    break;
                }
            }
            let _ = into.shutdown(std::net::Shutdown::Both);
        });
    }
}

impl Drop for Delay {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
    }
}

fn now_ms() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .unwrap()
        .as_millis() as u64
}

/// What a watcher across the link, reaching the server at `endpoint`, printed: (frame,
/// received at, unix ms) per frame, and the stream it watched.
fn watch_across(
    link: &SlowLink,
    server: &Server,
    endpoint: &str,
    budget: Option<&str>,
) -> (Vec<(u64, u64)>, u64) {
    let mut args = vec![
        "netns".to_string(),
        "exec".into(),
        link.ns.clone(),
        bin("ricochet").display().to_string(),
        "--world".into(),
        server.world.clone(),
        "--connect".into(),
        endpoint.to_string(),
        "watch".into(),
        "--json".into(),
        "--seconds".into(),
        WATCH_SECONDS.to_string(),
    ];
    if let Some(b) = budget {
        args.extend(["--max-bandwidth".into(), b.to_string()]);
    }
    let out = Process::new("ip")
        .args(&args)
        .env("RUST_LOG", "warn")
        .stderr(Stdio::inherit())
        .output()
        .expect("ip netns exec runs");
    let text = ok(&out);
    let mut every = 1;
    let frames = text
        .lines()
        .map(|l| {
            let v: serde_json::Value = serde_json::from_str(l).unwrap();
            every = v["every"].as_u64().unwrap();
            (
                v["frame"].as_u64().unwrap(),
                v["received_ms"].as_u64().unwrap(),
            )
        })
        .collect();
    (frames, every)
}

/// The worst lag over the last quarter of a watch (before, it may still be catching up
/// from its first key frame), against when the frames reached this side.
fn worst_lag(frames: &[(u64, u64)], here: &HashMap<u64, u64>) -> Option<Duration> {
    let last = &frames[frames.len() * 3 / 4..];
    last.iter()
        .filter_map(|(f, at)| here.get(f).map(|h| at.saturating_sub(*h)))
        .max()
        .map(Duration::from_millis)
}

#[test]
fn a_viewer_on_a_slow_link_keeps_up_on_the_stream_its_budget_fits() {
    let link = match SlowLink::make() {
        Ok(link) => link,
        Err(e) => panic!("cannot make the slow link (the test needs root): {e}"),
    };
    let free_port = || {
        TcpListener::bind(format!("{}:0", link.host_ip))
            .unwrap()
            .local_addr()
            .unwrap()
            .port()
    };
    let port = free_port();
    let endpoint = format!("tcp/{}:{port}", link.host_ip);
    // The watchers' way to the server: through the relay, which adds the delay.
    let relay_at = format!("{}:{}", link.host_ip, free_port());
    let _delay = Delay::start(&relay_at, format!("{}:{port}", link.host_ip));
    let delayed = format!("tcp/{relay_at}");
    let scene = scene("emitters.toml");
    let server = Server::launch_at(&endpoint, "slow-link", &["--scene", &scene]);
    let client = server.client();
    resume(&client);

    // Fire, started again and again: thousands of particles alive at any time.
    let stop = Arc::new(AtomicBool::new(false));
    let feeder = {
        let stop = stop.clone();
        let client = server.client();
        std::thread::spawn(move || {
            let mut k = 0.0;
            while !stop.load(Ordering::Relaxed) {
                let fire = Command::World(Action::StartEmitter {
                    preset: "fire".into(),
                    count: 1500,
                    at: [50.0 + 100.0 * (k % 2.0), 60.0],
                });
                let _ = client.send(&fire);
                k += 1.0;
                std::thread::sleep(Duration::from_millis(500));
            }
        })
    };
    // When each frame reached this side of the link (no queue on the way).
    let here: Arc<Mutex<HashMap<u64, u64>>> = Arc::default();
    let recorder = {
        let (stop, here) = (stop.clone(), here.clone());
        let network = Network::client(Mode::Peer, vec![endpoint.clone()]);
        std::thread::spawn(move || {
            let client = Client::open(&network, "slow-link").unwrap();
            let frames = client.frames().unwrap();
            while !stop.load(Ordering::Relaxed) {
                if let Ok(Some(sample)) = frames.recv_timeout(Duration::from_millis(100)) {
                    let bytes = sample.payload().to_bytes();
                    if let Ok(h) = ricochet_protocol::frame::peek_header(&bytes) {
                        here.lock().unwrap().insert(h.frame, now_ms());
                    }
                }
            }
        })
    };
    // Let the fire build and the server measure its streams' rates (the peak of five
    // whole seconds).
    std::thread::sleep(Duration::from_secs(6));
    let info = client.info(Duration::from_secs(5)).unwrap();
    let full = info.streams.iter().find(|s| s.every == 1).unwrap();
    assert!(
        full.bytes_per_second * 8.0 > 1.3 * LINK_BITS,
        "the fire should need more than the link: {:?}",
        info.streams
    );

    let (careful, every) = watch_across(&link, &server, &delayed, Some(BUDGET));
    let (greedy, _) = watch_across(&link, &server, &delayed, None);
    stop.store(true, Ordering::Relaxed);
    feeder.join().unwrap();
    recorder.join().unwrap();
    let here = here.lock().unwrap();

    assert!(
        every > 1,
        "a budget under the full rate picks a tier ({} frames watched; the server's streams: {:?})",
        careful.len(),
        info.streams
    );
    assert!(careful.iter().all(|(f, _)| f.is_multiple_of(every)));
    // Once joined (the first key frame takes a while over the link), its frames came
    // steadily: most of its stream's frames over the second half of the watch.
    let half = &careful[careful.len() / 2..];
    assert!(half.len() >= 10, "{} frames in all", careful.len());
    let span = (half.last().unwrap().0 - half[0].0) / every + 1;
    assert!(
        half.len() as u64 * 10 >= span * 7,
        "{} of {span} frames of the stream of one in {every}",
        half.len()
    );
    let lag = worst_lag(&careful, &here).expect("frames seen on both sides");
    let lags: Vec<(u64, i64)> = careful[careful.len() * 3 / 4..]
        .iter()
        .filter_map(|(f, at)| here.get(f).map(|h| (*f, *at as i64 - *h as i64)))
        .collect();
    assert!(
        lag <= MAX_LAG,
        "the careful watcher of one frame in {every} fell {lag:?} behind (frame, ms): {:?}; the server's streams: {:?}",
        &lags[..lags.len().min(20)],
        info.streams
    );

    // Every step over the same link: it loses frames, or falls behind, or both.
    let greedy_lag = worst_lag(&greedy, &here).unwrap_or(Duration::MAX);
    let greedy_share = greedy.len() as f64 / (WATCH_SECONDS * 60.0);
    assert!(
        greedy_lag > MAX_LAG * 2 || greedy_share < 0.8,
        "the full stream kept up over the slow link ({greedy_share:.2} of frames, {greedy_lag:?} behind): the test's link is not slow"
    );
    eprintln!(
        "slow link {LINK}, {DELAY:?} each way: the stream of one in {every} kept {:.0}% of its frames once joined, {lag:?} behind at worst; every step kept {:.0}%, {greedy_lag:?} behind",
        half.len() as f64 * 100.0 / span as f64,
        greedy_share * 100.0
    );
}
