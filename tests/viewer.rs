//! The viewer end to end: a real server, a real `ricochet-viewer`, Rerun's real sinks.
//!
//! - `--save`: the .rrd file is read back with the `rerun` Python package
//!   (`tests/read_rrd.py`) and checked entity by entity, frame by frame.
//! - `--web`: Debian's chromium (headless, driven by Playwright: `tests/browser/`) loads the
//!   served web viewer while the demo script runs; the screenshots are checked pixel by
//!   pixel and kept under `RICOCHET_ARTIFACTS` (default `<target>/artifacts`).
//!
//! Every wait is bounded.

mod common;

use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{Command as Process, Stdio};
use std::sync::mpsc;
use std::time::Duration;

use common::*;
use ricochet_protocol::command::{Action, Command, ServerCommand};
use serde_json::Value;

/// Spawns a thread that forwards `reader`'s lines to a channel (so waits can be bounded).
fn lines_of(reader: impl std::io::Read + Send + 'static) -> mpsc::Receiver<String> {
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(reader).lines().map_while(Result::ok) {
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    rx
}

/// The first line with `marker`, within `limit`.
fn wait_line(rx: &mpsc::Receiver<String>, marker: &str, limit: Duration, what: &str) -> String {
    let deadline = std::time::Instant::now() + limit;
    loop {
        let left = deadline.saturating_duration_since(std::time::Instant::now());
        match rx.recv_timeout(left) {
            Ok(line) if line.contains(marker) => return line,
            Ok(_) => {}
            Err(_) => panic!("{what}: no line with `{marker}` within {limit:?}"),
        }
    }
}

fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

fn artifacts() -> PathBuf {
    let dir = std::env::var_os("RICOCHET_ARTIFACTS")
        .map(PathBuf::from)
        .unwrap_or_else(|| target_dir().join("artifacts"));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn read_rrd(path: &Path) -> Value {
    let out = Process::new(python())
        .arg(root().join("tests/read_rrd.py"))
        .arg(path)
        .output()
        .expect("python3 runs");
    let stdout = ok(&out);
    serde_json::from_str(&stdout).unwrap_or_else(|e| panic!("read_rrd.py printed {stdout}: {e}"))
}

#[test]
fn a_saved_recording_holds_every_drawn_frame_with_its_particles_and_figures() {
    let dir = temp_dir();
    let server = Server::start("emitters.toml", "saved", &[]);
    let client = server.client();
    resume(&client);
    let file = dir.path().join("saved.rrd");
    let _ = std::fs::remove_file(&file);
    let frames = 120u64;
    let viewer = Process::new(bin("ricochet-viewer"))
        .args(["--world", "saved", "--connect", &server.endpoint, "--save"])
        .arg(&file)
        .args(["--frames", &frames.to_string(), "--wait", "20"])
        .env("RUST_LOG", "warn")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("ricochet-viewer starts");
    let mut viewer = Running(viewer);
    // Commands while it records: one applied, one refused; both belong in the text log.
    std::thread::sleep(Duration::from_millis(1500));
    let spawned = request(
        &client,
        Command::World(Action::SpawnDumbMinion { at: [100.0, 90.0] }),
    );
    assert!(spawned.ok, "{spawned:?}");
    let emitter = request(
        &client,
        Command::World(Action::StartEmitter {
            preset: "fire".into(),
            count: 300,
            at: [150.0, 30.0],
        }),
    );
    assert!(emitter.ok, "{emitter:?}");
    client.send_raw(b"{\"do\":\"teleport\"}".to_vec()).unwrap();

    let began = std::time::Instant::now();
    let status = loop {
        if let Some(status) = viewer.0.try_wait().unwrap() {
            break status;
        }
        assert!(
            began.elapsed() < Duration::from_secs(60),
            "the viewer did not stop after {frames} frames"
        );
        std::thread::sleep(Duration::from_millis(100));
    };
    let mut err = String::new();
    std::io::Read::read_to_string(viewer.0.stderr.as_mut().unwrap(), &mut err).unwrap();
    assert!(status.success(), "viewer failed: {err}");

    let rrd = read_rrd(&file);
    let entities = rrd["entities"].as_object().expect("entities");
    for path in [
        "/world/bounds",
        "/world/statics/platforms",
        "/world/bodies/hero",
        "/world/particles",
        "/world/emitters",
        "/stats/step_ms",
        "/stats/contacts",
        "/stats/solver_passes",
        "/stats/deepest_penetration",
        "/stats/energy_change",
        "/stats/residual",
        "/stats/kinetic_energy",
        "/stats/particles",
        "/stats/bytes_per_frame",
        "/events",
    ] {
        assert!(
            entities.contains_key(path),
            "{path} missing: {:?}",
            entities.keys().collect::<Vec<_>>()
        );
    }
    // Statics are static data, logged once; the platforms are rectangles: 3 strips each.
    let platforms = &entities["/world/statics/platforms"];
    assert_eq!(platforms["static"], true);
    let strips = platforms["strips"].as_array().unwrap();
    assert_eq!(strips.len(), 1, "statics logged once: {strips:?}");
    assert_eq!(strips[0].as_u64().unwrap() % 3, 0);
    assert!(strips[0].as_u64().unwrap() >= 3 * 30);

    // One drawing per frame drawn, each at its own frame.
    let hero = &entities["/world/bodies/hero"];
    assert_eq!(hero["static"], false);
    let drawn: Vec<u64> = hero["frames"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_u64().unwrap())
        .collect();
    assert_eq!(drawn.len() as u64, frames, "{drawn:?}");
    assert!(drawn.windows(2).all(|w| w[0] < w[1]));

    // Every drawing of the particles holds exactly as many points as the server counted in
    // that frame; the scene starts with an explosion burning, so there are some.
    let counts = rrd["particle_counts"].as_object().unwrap();
    let figures = rrd["particle_figures"].as_object().unwrap();
    assert!(!counts.is_empty());
    let mut nonzero = 0;
    for (frame, n) in counts {
        let figure = figures
            .get(frame)
            .unwrap_or_else(|| panic!("no particle figure at frame {frame}"));
        assert_eq!(n.as_f64(), figure.as_f64(), "frame {frame}");
        nonzero += usize::from(n.as_u64().unwrap() > 0);
    }
    assert!(nonzero > 10, "{counts:?}");
    // Figures for every frame decoded, drawn or not.
    assert!(rrd["stats_frames"].as_u64().unwrap() >= frames);

    let log = rrd["events"].as_array().unwrap();
    let text: Vec<&str> = log.iter().filter_map(Value::as_str).collect();
    assert!(
        text.iter()
            .any(|t| t.contains("spawn_dumb_minion") && t.contains("->")),
        "{text:?}"
    );
    assert!(
        text.iter()
            .any(|t| t.starts_with("refused") && t.contains("teleport")),
        "{text:?}"
    );
}

/// A viewer whose link fits only the server's sparsest stream (one frame in 8 steps, one
/// particle in 8) draws every step in between, interpolated from the frames on either
/// side, so its drawing keeps the world's step rate; the figures are those of the frames
/// it received.
#[test]
fn a_viewer_on_a_reduced_rate_stream_draws_every_step_in_between() {
    let dir = temp_dir();
    let server = Server::start("emitters.toml", "sparse", &[]);
    resume(&server.client());
    let file = dir.path().join("sparse.rrd");
    let drawn_frames = 100u64;
    let out = Process::new(bin("ricochet-viewer"))
        .args(["--world", "sparse", "--connect", &server.endpoint, "--save"])
        .arg(&file)
        .args([
            "--max-bandwidth",
            "1",
            "--frames",
            &drawn_frames.to_string(),
        ])
        .args(["--wait", "20", "--idle-exit", "20"])
        .env("RUST_LOG", "warn")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .output()
        .expect("ricochet-viewer runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let rrd = read_rrd(&file);
    let frames_of = |path: &str| -> Vec<u64> {
        rrd["entities"][path]["frames"]
            .as_array()
            .unwrap_or_else(|| panic!("{path} missing"))
            .iter()
            .map(|v| v.as_u64().unwrap())
            .collect()
    };
    let drawn = frames_of("/world/bodies/hero");
    let received = frames_of("/stats/step_ms");
    assert_eq!(drawn.len() as u64, drawn_frames, "{drawn:?}");
    // Received: one frame in 8 steps.
    assert!(
        received.windows(2).all(|w| w[1] - w[0] == 8),
        "received frames: {received:?}"
    );
    // Drawn: every step from the first drawing on.
    assert!(
        drawn.windows(2).all(|w| w[1] == w[0] + 1),
        "drawn frames: {drawn:?}"
    );
    assert!(
        received.len() as u64 <= drawn_frames / 8 + 3,
        "{received:?}"
    );
    let particles = frames_of("/world/particles");
    assert!(
        particles.iter().filter(|f| !received.contains(f)).count() > 50,
        "particles drawn between the frames received: {particles:?}"
    );
}

/// A decoded screenshot: RGBA8 pixels, width, height.
type Image = (Vec<u8>, u32, u32);

/// Pixels of `img` (RGBA8) inside the box `[x0, x1) x [y0, y1)` (fractions of the size)
/// for which `pred` holds.
fn count(img: &Image, frac: [f32; 4], pred: impl Fn(u8, u8, u8) -> bool) -> usize {
    let (data, w, h) = img;
    let (x0, x1) = ((frac[0] * *w as f32) as u32, (frac[1] * *w as f32) as u32);
    let (y0, y1) = ((frac[2] * *h as f32) as u32, (frac[3] * *h as f32) as u32);
    let mut n = 0;
    for y in y0..y1 {
        for x in x0..x1 {
            let i = ((y * w + x) * 4) as usize;
            n += usize::from(pred(data[i], data[i + 1], data[i + 2]));
        }
    }
    n
}

fn decode_png(path: &Path) -> Image {
    let decoder = png::Decoder::new(BufReader::new(std::fs::File::open(path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    let rgba: Vec<u8> = match info.color_type {
        png::ColorType::Rgba => buf[..info.buffer_size()].to_vec(),
        png::ColorType::Rgb => buf[..info.buffer_size()]
            .chunks(3)
            .flat_map(|c| [c[0], c[1], c[2], 255])
            .collect(),
        other => panic!("unexpected PNG colour type {other:?}"),
    };
    (rgba, info.width, info.height)
}

/// A scene of two overlapping boxes, detection only: both stay flagged collided.
const OVERLAP_SCENE: &str = r#"
[world]
gravity = [0, 0]
bounds = [[0, 0], [200, 112.5]]

[[body]]
id = "left"
group = "a"
shape = "rect"
size = [60, 40]
pos = [80, 56]

[[body]]
id = "right"
group = "b"
shape = "rect"
size = [60, 40]
pos = [120, 56]

[[interact]]
a = "a"
b = "b"
resolve = false
"#;

#[test]
fn the_web_viewer_draws_collided_outlines_particles_and_plots_in_a_browser() {
    let server = Server::start("emitters.toml", "web", &[]);
    let client = server.client();
    resume(&client);
    let (web_port, grpc_port) = (free_port(), free_port());
    let mut viewer = Process::new(bin("ricochet-viewer"))
        .args(["--world", "web", "--connect", &server.endpoint, "--web"])
        // Fewer drawings, in fewer and larger chunks, for the software-rendered page to
        // take in: under load it takes in 0.1 s of the world a second at 50 ms batches,
        // 0.4 s at 500 ms. What is drawn is what this test checks, not how often.
        .args(["--fps", "10", "--batch", "500"])
        .args(["--web-port", &web_port.to_string()])
        .args(["--grpc-port", &grpc_port.to_string()])
        .env("RUST_LOG", "warn")
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .expect("ricochet-viewer starts");
    let out = lines_of(viewer.stdout.take().unwrap());
    let _viewer = Running(viewer);
    let line = wait_line(&out, "open http", Duration::from_secs(60), "viewer");
    let url = line.split_whitespace().last().unwrap().to_string();
    assert!(url.contains(&web_port.to_string()), "{url}");

    // The demo script plays while the page loads, and fires keep burning meanwhile.
    let mut script = Process::new(bin("ricochet"))
        .args(["--world", "web", "--connect", &server.endpoint, "script"])
        .arg(root().join("assets/scripts/demo.ricochet"))
        .env("RUST_LOG", "warn")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("ricochet script starts");
    let burning = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(true));
    let stoker = {
        let burning = burning.clone();
        let client = server.client();
        std::thread::spawn(move || {
            let mut k = 0.0;
            while burning.load(std::sync::atomic::Ordering::Relaxed) {
                let fire = Command::World(Action::StartEmitter {
                    preset: "fire".into(),
                    count: 300,
                    at: [60.0 + 80.0 * (k % 2.0), 60.0],
                });
                let _ = client.send(&fire);
                k += 1.0;
                std::thread::sleep(Duration::from_millis(700));
            }
        })
    };

    let browser = root().join("tests/browser");
    assert!(
        browser.join("node_modules/playwright-core").exists(),
        "playwright-core is not installed: run `npm ci --prefix tests/browser` (.ci/install does)"
    );
    assert!(
        Path::new("/usr/bin/chromium").exists() || std::env::var_os("CHROMIUM").is_some(),
        "chromium is missing: `apt-get install chromium` (.ci/install does)"
    );
    let mut node = Process::new("node")
        .arg(browser.join("screenshot.mjs"))
        .arg(&url)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .expect("node runs");
    let replies = lines_of(node.stdout.take().unwrap());
    let mut node_in = node.stdin.take().unwrap();
    let mut node = Running(node);
    wait_line(&replies, "ready", Duration::from_secs(120), "the page");

    let dir = artifacts();
    // The 2D view fills the left three fifths of the page, the plots the right.
    let (world, plots) = ([0.0, 0.58, 0.06, 0.95], [0.62, 1.0, 0.06, 0.72]);
    let red = |r: u8, g: u8, b: u8| r >= 200 && g <= 60 && b <= 60;
    // The fire as displayed: red walking to orange, yellow and white as it oversaturates.
    let fire = |r: u8, g: u8, b: u8| {
        r >= 200 && (70..=235).contains(&g) && u16::from(b) + 20 < u16::from(g)
    };
    let plot = |r: u8, g: u8, b: u8| r <= 60 && g >= 200 && b <= 60;
    // Screenshots every few seconds until `done` holds (the software-rendered page lags
    // the world by 30 s or more on a loaded machine: the gRPC server queues up to 1024
    // chunks for it); the last one is kept.
    let mut shoot = |name: &str, done: &dyn Fn(&Image) -> bool| {
        let path = dir.join(name);
        let began = std::time::Instant::now();
        loop {
            writeln!(node_in, "shot {}", path.display()).unwrap();
            wait_line(&replies, "shot", Duration::from_secs(60), name);
            let img = decode_png(&path);
            if done(&img) || began.elapsed() > Duration::from_secs(240) {
                eprintln!("screenshot: {}", path.display());
                return img;
            }
            std::thread::sleep(Duration::from_secs(3));
        }
    };

    let demo = shoot("viewer-demo.png", &|img| {
        count(img, world, fire) >= 100 && count(img, plots, plot) >= 100
    });
    burning.store(false, std::sync::atomic::Ordering::Relaxed);
    stoker.join().unwrap();
    let _ = script.kill();
    let _ = script.wait();
    let fire_px = count(&demo, world, fire);
    let plot_px = count(&demo, plots, plot);
    assert!(fire_px >= 100, "particle colours: {fire_px} pixels");
    assert!(plot_px >= 100, "plot lines: {plot_px} pixels");

    // The world paused with its fires alive: no more frames, so the page drains what it
    // queued (a software-rendered page lags the world by tens of seconds under load) and
    // then shows the last frame, still, its particles drawn. Only then is the scene
    // replaced, so what is judged after the load is the viewer's clearing, not the page's
    // backlog.
    let reply = request(&client, Command::Server(ServerCommand::Pause));
    assert!(reply.ok, "{reply:?}");
    // The old scene's platforms, minions and hero: the palette's blue, green and violet.
    let old_scene = |r: u8, g: u8, b: u8| {
        (b >= 200 && r <= 120 && (130..=210).contains(&g))
            || (g >= 200 && r <= 130 && b <= 150)
            || (r >= 170 && g <= 160 && b >= 220)
    };
    // Still: the same figures in three shots in a row, 3 s apart.
    let last = std::cell::Cell::new(((0, 0), 0));
    let still = shoot("viewer-paused.png", &|img| {
        let figures = (count(img, world, fire), count(img, world, red));
        let (before, times) = last.get();
        let times = if before == figures { times + 1 } else { 0 };
        last.set((figures, times));
        times >= 2 && figures.0 >= 20
    });
    let paused_fire = count(&still, world, fire);
    assert!(
        paused_fire >= 20,
        "the paused world's particles drawn: {paused_fire} pixels"
    );

    // Now a scene of two boxes overlapping, detection only, no particles: only the
    // collided outlines are red.
    let reply = request(
        &client,
        Command::Server(ServerCommand::Load {
            path: None,
            text: Some(OVERLAP_SCENE.to_string()),
        }),
    );
    assert!(reply.ok, "{reply:?}");
    let reply = request(&client, Command::Server(ServerCommand::Resume));
    assert!(reply.ok, "{reply:?}");
    let collided = shoot("viewer-collided.png", &|img| {
        count(img, world, old_scene) < 50
            && count(img, world, red) >= 200
            && count(img, world, fire) < 20
    });
    let _ = writeln!(node_in, "quit");
    drop(node_in);
    let began = std::time::Instant::now();
    while node.0.try_wait().unwrap().is_none() && began.elapsed() < Duration::from_secs(20) {
        std::thread::sleep(Duration::from_millis(100));
    }
    let (old_px, red_px, fire_px) = (
        count(&collided, world, old_scene),
        count(&collided, world, red),
        count(&collided, world, fire),
    );
    assert!(
        old_px < 50,
        "the page still shows the old scene 240 s after the load ({old_px} pixels of its colours)"
    );
    assert!(red_px >= 200, "red collided outlines: {red_px} pixels");
    assert!(
        fire_px < 20,
        "the particles went with the old scene: {fire_px} fire-coloured pixels left"
    );
    assert!(count(&collided, plots, plot) >= 100, "plots still drawn");
}

/// A viewer outlives its server: the server is killed mid-recording and another takes its
/// place (another scene, on the same endpoint); the viewer says so, fetches the new
/// server's statics and state, and goes on drawing until its frame count.
#[test]
fn a_viewer_survives_its_server_being_killed_and_replaced() {
    let dir = temp_dir();
    let first = Server::start("emitters.toml", "phoenix", &[]);
    let endpoint = first.endpoint.clone();
    let file = dir.path().join("restart.rrd");
    let frames = 240u64;
    let viewer = Process::new(bin("ricochet-viewer"))
        .args(["--world", "phoenix", "--connect", &endpoint, "--save"])
        .arg(&file)
        .args(["--frames", &frames.to_string(), "--wait", "20"])
        .env("RUST_LOG", "warn")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("ricochet-viewer starts");
    let mut viewer = Running(viewer);
    std::thread::sleep(Duration::from_millis(1500));
    first.kill();
    std::thread::sleep(Duration::from_millis(500));
    let _second = Server::launch_at(&endpoint, "phoenix", &["--scene", &scene("stack-20.toml")]);

    let began = std::time::Instant::now();
    let status = loop {
        if let Some(status) = viewer.0.try_wait().unwrap() {
            break status;
        }
        assert!(
            began.elapsed() < Duration::from_secs(60),
            "the viewer did not reach {frames} frames"
        );
        std::thread::sleep(Duration::from_millis(100));
    };
    let mut err = String::new();
    std::io::Read::read_to_string(viewer.0.stderr.as_mut().unwrap(), &mut err).unwrap();
    assert!(status.success(), "viewer failed: {err}");

    let rrd = read_rrd(&file);
    let entities = rrd["entities"].as_object().expect("entities");
    assert!(
        entities.contains_key("/world/statics/platforms"),
        "the first scene's statics"
    );
    assert!(
        entities.contains_key("/world/statics/ground"),
        "the second scene's statics: {:?}",
        entities.keys().collect::<Vec<_>>()
    );
    let log = rrd["events"].as_array().unwrap();
    let text: Vec<&str> = log.iter().filter_map(Value::as_str).collect();
    assert!(
        text.iter().any(|t| t.contains("server changed")),
        "{text:?}"
    );
}

/// A user's table for two worlds side by side: no gravity, four walls, six balls already
/// moving, the first of them to hit a wall or another ball about half a second in.
fn drift_table() -> String {
    let mut scene = String::from(
        r#"
[world]
gravity = [0, 0]
bounds = [[0, 0], [40, 20]]

[[generate]]
kind = "row"
id = "wall"
group = "walls"
shape = "rect"
size = [40, 1]
start = [20, 0]
step = [0, 20]
count = 2
mass = 0

[[generate]]
kind = "row"
id = "side"
group = "walls"
shape = "rect"
size = [1, 20]
start = [0, 10]
step = [40, 0]
count = 2
mass = 0

[[interact]]
a = "balls"
b = "balls"

[[interact]]
a = "balls"
b = "walls"
"#,
    );
    let balls = [
        ([8.0, 10.0], [18.0, 1.0]),
        ([30.0, 10.5], [-12.0, 0.0]),
        ([20.0, 5.0], [3.0, -14.0]),
        ([12.0, 15.0], [-9.0, 8.0]),
        ([33.0, 4.0], [10.0, 6.0]),
        ([25.0, 16.0], [-7.0, -11.0]),
    ];
    for (k, (pos, vel)) in balls.iter().enumerate() {
        scene.push_str(&format!(
            "\n[[body]]\nid = \"ball-{k}\"\ngroup = \"balls\"\nshape = \"circle\"\nradius = 1\n\
             pos = {pos:?}\nvel = {vel:?}\nrestitution = 0.9\nfriction = 0.1\n"
        ));
    }
    scene
}

/// `--world A --world B`: a world and its fork under another setting (the chapter's
/// relaxation solver; a gravity-free table's flight and bounces are exact under any
/// number of sub-steps, so those would not drift), both
/// paused at the fork, watched by one viewer into one recording, then both resumed. Each
/// world's bodies are drawn under its own root, the fork's moved aside so the two do not
/// overlap, each with its name; the drift plots have a value at the frames both worlds
/// decoded: zero at the fork, where the two are the same state, and more once the fork's
/// collisions differ. With `--overlay`, neither world is moved.
#[test]
fn two_worlds_are_drawn_side_by_side_with_plots_of_how_far_they_drift_apart() {
    let dir = temp_dir();
    let scene_file = dir.path().join("drift-table.toml");
    std::fs::write(&scene_file, drift_table()).unwrap();
    let server = Server::launch(
        "drift",
        &[
            "--scene",
            scene_file.to_str().unwrap(),
            "--paused",
            "--max-worlds",
            "2",
        ],
    );
    let client = server.client();
    let fork = request(
        &client,
        Command::Server(ServerCommand::Fork {
            world: "drift-chapter".into(),
            settings: std::collections::BTreeMap::from([(
                "solver".to_string(),
                serde_json::json!("relaxation"),
            )]),
        }),
    );
    assert!(fork.ok, "{fork:?}");
    let forked =
        ricochet_protocol::client::Client::open(&server.network(), "drift-chapter").unwrap();
    wait_answered(&forked, "the fork");

    let file = dir.path().join("drift.rrd");
    let frames = 240u64;
    let mut viewer = Process::new(bin("ricochet-viewer"))
        .args(["--world", "drift", "--world", "drift-chapter"])
        .args(["--connect", &server.endpoint, "--save"])
        .arg(&file)
        .args(["--frames", &frames.to_string(), "--wait", "20"])
        .env("RUST_LOG", "info,zenoh=warn")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("ricochet-viewer starts");
    let log = lines_of(viewer.stderr.take().unwrap());
    let mut viewer = Running(viewer);
    // Both worlds joined (their paused state decoded, the fork's frame compared) before
    // either moves.
    // (The first line naming the fork is the viewer's `joined` of it.)
    wait_line(&log, "drift-chapter", Duration::from_secs(60), "the viewer");
    std::thread::sleep(Duration::from_millis(1500));
    resume(&client);
    resume(&forked);

    let began = std::time::Instant::now();
    let status = loop {
        if let Some(status) = viewer.0.try_wait().unwrap() {
            break status;
        }
        assert!(
            began.elapsed() < Duration::from_secs(60),
            "the viewer did not stop after {frames} frames of each world"
        );
        std::thread::sleep(Duration::from_millis(100));
    };
    let rest: Vec<String> = log.try_iter().collect();
    assert!(status.success(), "viewer failed: {rest:?}");

    let rrd = read_rrd(&file);
    let entities = rrd["entities"].as_object().expect("entities");
    for world in ["drift", "drift-chapter"] {
        for path in [
            format!("/world/{world}/bounds"),
            format!("/world/{world}/statics/walls"),
            format!("/world/{world}/bodies/balls"),
            format!("/world/{world}/name"),
            format!("/stats/kinetic_energy/{world}"),
            format!("/stats/step_ms/{world}"),
        ] {
            assert!(
                entities.contains_key(&path),
                "{path} missing: {:?}",
                entities.keys().collect::<Vec<_>>()
            );
        }
        let drawn = entities[&format!("/world/{world}/bodies/balls")]["frames"]
            .as_array()
            .unwrap()
            .len() as u64;
        assert_eq!(drawn, frames, "{world}: frames drawn");
        assert_eq!(rrd["labels"][&format!("/world/{world}/name")][0], world);
    }
    // One world's paths are not used with two.
    assert!(!entities.contains_key("/world/bodies/balls"));
    assert!(!entities.contains_key("/stats/step_ms"));
    // The fork is moved aside by more than the table's width; the first stays in place.
    let x = |path: &str| rrd["translations"][path][0].as_f64().unwrap_or(f64::NAN);
    assert_eq!(x("/world/drift"), 0.0);
    assert!(x("/world/drift-chapter") > 40.0, "{}", rrd["translations"]);

    let series = |path: &str| -> Vec<(u64, f64)> {
        let mut v: Vec<(u64, f64)> = rrd["scalars"][path]
            .as_object()
            .unwrap_or_else(|| panic!("{path} has no values: {}", rrd["scalars"]))
            .iter()
            .map(|(f, v)| (f.parse().unwrap(), v.as_f64().unwrap()))
            .collect();
        v.sort_by_key(|(f, _)| *f);
        v
    };
    let distance = series("/drift/body_distance/drift-chapter");
    let energy = series("/drift/kinetic_energy/drift-chapter");
    // Compared at the frames both decoded: nearly every one, both running in real time.
    assert!(distance.len() as u64 >= frames / 2, "{distance:?}");
    assert_eq!(
        distance.iter().map(|(f, _)| f).collect::<Vec<_>>(),
        energy.iter().map(|(f, _)| f).collect::<Vec<_>>()
    );
    // At the fork both worlds are the same state.
    assert_eq!(distance[0].1, 0.0, "{distance:?}");
    assert_eq!(energy[0].1, 0.0, "{energy:?}");
    assert!(distance.iter().all(|(_, d)| d.is_finite() && *d >= 0.0));
    let furthest = distance.iter().map(|(_, d)| *d).fold(0.0, f64::max);
    assert!(furthest > 0.05, "the fork never drifted: {distance:?}");
    assert!(
        energy.iter().any(|(_, e)| *e != 0.0),
        "the same kinetic energy throughout: {energy:?}"
    );

    // Overlaid: both worlds in place, one over the other, still compared. Each world has
    // stepped on in real time on its own since, so their frame numbers may be apart by
    // more than a few frames on a loaded machine (30 frames of each shared none, once,
    // while other builds ran): 150 frames of each overlap unless they are more than 150
    // apart.
    let file = dir.path().join("overlay.rrd");
    let out = Process::new(bin("ricochet-viewer"))
        .args(["--world", "drift", "--world", "drift-chapter", "--overlay"])
        .args(["--connect", &server.endpoint, "--save"])
        .arg(&file)
        .args(["--frames", "150", "--wait", "20"])
        .env("RUST_LOG", "warn")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .output()
        .expect("ricochet-viewer runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let rrd = read_rrd(&file);
    let x = |path: &str| rrd["translations"][path][0].as_f64().unwrap_or(f64::NAN);
    assert_eq!((x("/world/drift"), x("/world/drift-chapter")), (0.0, 0.0));
    assert!(rrd["entities"]
        .get("/world/drift-chapter/bodies/balls")
        .is_some());
    assert!(rrd["scalars"]["/drift/body_distance/drift-chapter"]
        .as_object()
        .is_some_and(|v| !v.is_empty()));
}
