//! `ricochet-viewer`: subscribes to a Ricochet world over zenoh and logs it to Rerun.
//!
//! In: frames, snapshots and events of one world (zenoh). Out: Rerun entities (bounds,
//! bodies, particles, emitters, the step's figures, the commands applied), to the web
//! viewer it serves, a native viewer, a running viewer or an .rrd file. `sink` turns
//! decoded state into Rerun logs, `draw` builds the shapes, `blueprint` lays out the view.
//!
//! Frames are delta-encoded, so every frame that arrives is decoded (cheap); drawing is
//! what costs, so each pass of the loop draws only the newest state (at most `--fps` times
//! a second) and logs the figures of every frame it decoded. When Rerun is slower than the world, frames are skipped, never
//! queued without bound, and the server is never held back: it publishes real-time frames
//! with zenoh's drop congestion control. A gap in the frames (a frame lost on the way)
//! is repaired by asking the server for a key frame of its state now.

mod between;
mod blueprint;
mod draw;
mod sink;

use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::{anyhow, bail, Context, Result};
use clap::{ArgGroup, Parser};
use ricochet_protocol::client::{parse_event, Client};
use ricochet_protocol::frame::DecodeError;
use ricochet_protocol::keys::DEFAULT_WORLD;
use ricochet_protocol::net::{init_tracing, NetworkArgs};

use crate::between::Between;
use crate::sink::WorldSink;

/// Draws a Ricochet world in Rerun: bounds, bodies, particles, the step's figures and the
/// commands applied.
#[derive(Parser, Debug)]
#[command(version, group(ArgGroup::new("sink").args(["web", "spawn", "connect_rerun", "save"])))]
struct Opts {
    /// The world to watch.
    #[arg(long, default_value = DEFAULT_WORLD)]
    world: String,
    /// Where to find the world's server (default: connect to tcp/127.0.0.1:7447, where a
    /// server listens).
    #[command(flatten)]
    network: NetworkArgs,

    /// Serve Rerun's web viewer and its gRPC server on localhost and print the address
    /// (the default).
    #[arg(long)]
    web: bool,
    /// Spawn the native viewer (`rerun` on the PATH: `pip install rerun-sdk==0.36.3`).
    #[arg(long)]
    spawn: bool,
    /// Stream to a Rerun viewer already running, e.g. rerun+http://127.0.0.1:9876/proxy.
    #[arg(long, value_name = "URL")]
    connect_rerun: Option<String>,
    /// Write an .rrd file (headless).
    #[arg(long, value_name = "FILE.rrd")]
    save: Option<PathBuf>,

    /// Draw at most this many frames a second (0: every frame that arrives). The figures
    /// of every frame are logged whatever the rate. Default 30, and 0 with --save.
    #[arg(long, value_name = "HZ")]
    fps: Option<f64>,
    /// Watch the fullest frame stream whose rate fits this link: bits a second, with an
    /// optional k, M or G (`5M`, `5Mbit`, `500kbit`). The server's reduced-rate streams
    /// carry one frame in 2, 4 or 8 steps (default: every step).
    #[arg(long, value_name = "RATE", value_parser = ricochet_protocol::net::parse_bits_per_second)]
    max_bandwidth: Option<f64>,
    /// Stop after drawing this many frames.
    #[arg(long, value_name = "N")]
    frames: Option<u64>,
    /// Stop when no frame has arrived for this long, seconds (default: never, but 10 with
    /// --save).
    #[arg(long, value_name = "SECS")]
    idle_exit: Option<f64>,
    /// How long to wait for the world's server to answer at start, seconds.
    #[arg(long, default_value_t = 30.0, value_name = "SECS")]
    wait: f64,

    /// Address the web viewer and gRPC server bind to (--web).
    #[arg(long, default_value = "127.0.0.1", value_name = "IP")]
    bind: String,
    /// Port of the web viewer's page (--web).
    #[arg(long, default_value_t = 9090)]
    web_port: u16,
    /// Port of the gRPC server the page reads from (--web).
    #[arg(long, default_value_t = 9876)]
    grpc_port: u16,
    /// History the gRPC server keeps for viewers that open the page later (--web); the
    /// oldest frames go first, static data stays. A page opened late is sent the present
    /// first and the history after, newest first, as it keeps up.
    #[arg(long, default_value = "1GiB", value_name = "SIZE")]
    memory_limit: String,
    /// How long a live viewer gathers rows before sending them, milliseconds: one chunk
    /// per entity per batch. A page takes a few large chunks far faster than many small
    /// ones (a software-rendered page under load took in 0.1 s of the world a second at
    /// 50 ms, 0.4 s at 500 ms); a longer batch updates the picture less often.
    #[arg(long, default_value_t = 100, value_name = "MS")]
    batch: u64,
}

/// Whether the page is served by this process.
#[derive(PartialEq)]
enum Served {
    Web,
    Nothing,
}

fn open_sink(opts: &Opts, app_id: &'static str) -> Result<(re_sdk::RecordingStream, Served)> {
    let builder = re_sdk::RecordingStreamBuilder::new(app_id);
    if let Some(path) = &opts.save {
        // A file takes whole chunks at its own pace.
        let rec = builder
            .save(path)
            .with_context(|| format!("cannot write {}", path.display()))?;
        return Ok((rec, Served::Nothing));
    }
    // A live viewer ingests a few larger chunks far faster than many small ones: flush
    // every --batch ms (6 frames at 60 Hz by default) rather than every 8.
    if opts.batch == 0 || opts.batch > 10_000 {
        bail!("--batch must be 1 to 10000 ms, not {}", opts.batch);
    }
    let builder = builder.batcher_config(re_sdk::log::ChunkBatcherConfig {
        flush_tick: Duration::from_millis(opts.batch),
        // A sink that cannot keep up holds the viewer's loop back soon (4 MiB queued here,
        // not the default 100 MiB): the loop then skips frames and draws the newest state
        // rather than queueing minutes of the world for a page that is behind. (The gRPC
        // server queues up to 1024 chunks more for each page; that bound is Rerun's.)
        max_bytes_in_flight: 4 * 1024 * 1024,
        ..re_sdk::log::ChunkBatcherConfig::DEFAULT
    });
    if opts.spawn {
        let rec = builder.spawn().map_err(|e| {
            anyhow!("cannot spawn the native viewer ({e}); is `rerun` on the PATH? `pip install rerun-sdk==0.36.3` provides it")
        })?;
        return Ok((rec, Served::Nothing));
    }
    if let Some(url) = &opts.connect_rerun {
        let rec = builder
            .connect_grpc_opts(url.clone())
            .with_context(|| format!("cannot connect to the Rerun viewer at {url}"))?;
        return Ok((rec, Served::Nothing));
    }
    let memory_limit = re_sdk::MemoryLimit::parse(&opts.memory_limit)
        .map_err(|e| anyhow!("--memory-limit {}: {e}", opts.memory_limit))?;
    let rec = builder
        .serve_grpc_opts(
            &opts.bind,
            opts.grpc_port,
            re_sdk::ServerOptions {
                memory_limit,
                // The present before the past: a page that opens late is sent what
                // arrives now ahead of the history.
                playback_behavior: re_sdk::PlaybackBehavior::NewestFirst,
                ..Default::default()
            },
        )
        .with_context(|| {
            format!(
                "cannot serve gRPC on {}:{} (--grpc-port)",
                opts.bind, opts.grpc_port
            )
        })?;
    let grpc = format!("rerun+http://{}:{}/proxy", opts.bind, opts.grpc_port);
    let server = re_sdk::serve_web_viewer(re_sdk::web_viewer::WebViewerConfig {
        bind_ip: opts.bind.clone(),
        web_port: opts.web_port.into(),
        connect_to: vec![grpc.clone()],
        open_browser: false,
        ..Default::default()
    })
    .with_context(|| {
        format!(
            "cannot serve the web viewer on {}:{} (--web-port)",
            opts.bind, opts.web_port
        )
    })?;
    let url = format!(
        "{}/?url={}",
        server.server_url().trim_end_matches('/'),
        grpc.replace('+', "%2B")
    );
    println!("ricochet-viewer: open {url}");
    // Served until the process exits.
    server.detach();
    Ok((rec, Served::Web))
}

/// How often the viewer checks that its statics are from the world's current server and
/// scene.
const SOURCE_CHECK: Duration = Duration::from_secs(2);

/// The world's scene generation, if its server answers.
fn info_generation(client: &Client) -> Option<u64> {
    client
        .info(Duration::from_secs(1))
        .ok()
        .map(|i| i.generation)
}

/// Asks for the world's info until its server answers or `wait` runs out.
fn wait_for_world(
    client: &Client,
    wait: Duration,
) -> Result<ricochet_protocol::command::WorldInfo> {
    let start = Instant::now();
    loop {
        match client.info(Duration::from_millis(1000)) {
            Ok(info) => return Ok(info),
            Err(e) if start.elapsed() >= wait => {
                return Err(e.context(format!(
                    "world `{}` did not answer within {wait:?}",
                    client.keys().world
                )))
            }
            Err(_) => std::thread::sleep(Duration::from_millis(200)),
        }
    }
}

fn run(opts: Opts) -> Result<()> {
    if opts.frames == Some(0) {
        bail!("--frames must be at least 1");
    }
    let min_draw_interval = match opts
        .fps
        .unwrap_or(if opts.save.is_some() { 0.0 } else { 30.0 })
    {
        hz if hz > 0.0 && hz.is_finite() => Duration::from_secs_f64(1.0 / hz),
        0.0 => Duration::ZERO,
        hz => bail!("--fps must be 0 or more, not {hz}"),
    };
    let idle_exit = opts
        .idle_exit
        .or(opts.save.as_ref().map(|_| 10.0))
        .map(Duration::from_secs_f64);
    let network = opts.network.clone().client();
    let mut client = Client::open(&network, &opts.world)?;
    let info = wait_for_world(&client, Duration::from_secs_f64(opts.wait))?;
    tracing::info!(world = %opts.world, scene = %info.scene, "joined");
    if let Some(bits) = opts.max_bandwidth {
        client.watch_every(info.stream_for(bits));
        tracing::info!(
            every = client.every(),
            "watching the stream of one frame in {} steps, to fit {bits} bits a second",
            client.every()
        );
    }

    let (rec, served) = open_sink(&opts, "ricochet")?;
    let mut sink = WorldSink::new(rec, "ricochet")?;
    sink.set_info(info)?;

    let events = client.events()?;
    let snapshots = client.snapshots()?;
    let (frames, mut decoder) = client.join(Duration::from_secs(5))?;
    // Which server, and which of its scenes, the statics came from: checked every few
    // seconds, so a restarted server or a missed snapshot is caught up with.
    let mut source = (
        client.servers(Duration::from_secs(2))?,
        info_generation(&client),
    );
    let mut last_check = Instant::now();
    // A resync that failed (the server gone, say): retried at most once a second until a
    // key frame or a resync brings the decoder back.
    let mut lost_since: Option<Instant> = None;
    sink.log_statics(&decoder.statics)?;
    // On a reduced-rate stream the state comes with the stream's next key frame.
    if decoder.synced {
        sink.log_stats(decoder.frame, decoder.time, &decoder.stats, 0)?;
        sink.draw(&decoder)?;
    }

    let mut last_frame_at = Instant::now();
    let mut skipped: u64 = 0;
    let mut resyncs: u64 = 0;
    let mut dropped_key_frames: u64 = 0;
    let mut reported_skips = Instant::now();
    let mut draw_time = Duration::ZERO;
    // Frames decoded since the last drawing.
    let mut pending = 0u64;
    let mut last_draw = Instant::now();
    // On a reduced-rate stream: the steps between its last two frames, drawn as they come
    // due; and the newest frame, which the next one is interpolated from.
    let mut between: Option<Between> = None;
    let mut newest: Option<ricochet_protocol::frame::FrameDecoder> = None;
    let began = Instant::now();
    while opts.frames.is_none_or(|n| sink.frames_drawn < n) {
        while let Ok(Some(sample)) = events.try_recv() {
            match parse_event(&sample) {
                Ok(event) => sink.log_event(&event)?,
                Err(e) => sink.log_note(&format!("unreadable event: {e:#}"), "WARN")?,
            }
        }
        // A snapshot comes when the statics change or a scene is (re)loaded.
        let mut new_statics = false;
        while let Ok(Some(sample)) = snapshots.try_recv() {
            match decoder.apply(&sample.payload().to_bytes()) {
                Ok(_) => new_statics = true,
                Err(e) => sink.log_note(&format!("unreadable snapshot: {e}"), "WARN")?,
            }
        }
        if last_check.elapsed() >= SOURCE_CHECK {
            last_check = Instant::now();
            let now = (
                client.servers(Duration::from_secs(1)).unwrap_or_default(),
                info_generation(&client),
            );
            if !now.0.is_empty() && now.1.is_some() && now != source {
                // A new server, or a new scene: the statics and state again, from scratch.
                match client.catch_up(Duration::from_secs(2)) {
                    Ok(fresh) => {
                        decoder = fresh;
                        (between, newest) = (None, None);
                        new_statics = true;
                        lost_since = None;
                        let what = if now.0 != source.0 {
                            "the world's server changed (restarted?)"
                        } else {
                            "the world's scene was reloaded"
                        };
                        sink.log_note(
                            &format!(
                                "{what}: statics and state fetched again at frame {}",
                                decoder.frame
                            ),
                            "WARN",
                        )?;
                        source = now;
                    }
                    Err(e) => sink.log_note(
                        &format!("catching up with the server failed, will retry: {e:#}"),
                        "WARN",
                    )?,
                }
            }
        }
        if new_statics {
            if let Ok(info) = client.info(Duration::from_secs(2)) {
                sink.set_info(info)?;
            }
            sink.log_statics(&decoder.statics)?;
        }

        // Between a reduced-rate stream's frames: draw each step as it comes due.
        if let Some(b) = between.as_mut() {
            let now = Instant::now();
            if let Some(step) = b
                .due(now, min_draw_interval.is_zero())
                .filter(|_| last_draw.elapsed() >= min_draw_interval)
            {
                last_draw = now;
                sink.draw_between(&b.draw(step))?;
                draw_time += last_draw.elapsed();
            }
        }
        let wait = between
            .as_ref()
            .and_then(|b| b.wait(Instant::now()))
            .map_or(Duration::from_millis(200), |w| {
                w.max(min_draw_interval.saturating_sub(last_draw.elapsed()))
                    .clamp(Duration::from_millis(1), Duration::from_millis(200))
            });
        let Ok(Some(first)) = frames.recv_timeout(wait) else {
            if idle_exit.is_some_and(|limit| last_frame_at.elapsed() >= limit) {
                sink.log_note("the world stopped sending frames", "WARN")?;
                break;
            }
            continue;
        };
        last_frame_at = Instant::now();
        let mut batch = vec![first];
        while let Ok(Some(sample)) = frames.try_recv() {
            batch.push(sample);
        }
        let mut applied = 0u64;
        for sample in &batch {
            let bytes = sample.payload().to_bytes();
            match decoder.apply(&bytes) {
                Ok(h) => {
                    applied += 1;
                    sink.log_stats(h.frame, h.time, &h.stats, bytes.len())?;
                    if decoder.dropped_key_frames > dropped_key_frames {
                        dropped_key_frames = decoder.dropped_key_frames;
                        sink.log_note(
                            &format!("a key frame the stream did not follow was dropped ({dropped_key_frames} so far)"),
                            "WARN",
                        )?;
                    }
                }
                Err(DecodeError::Stale { .. }) => {}
                Err(DecodeError::OutOfSync { held, follows }) => {
                    if lost_since.is_some_and(|t| t.elapsed() < Duration::from_secs(1)) {
                        continue;
                    }
                    // A reduced-rate stream is for a slow link: its next key frame
                    // resyncs, not the whole state at once.
                    if client.every() > 1 {
                        continue;
                    }
                    resyncs += 1;
                    let resynced = client.state(Duration::from_secs(2)).and_then(|state| {
                        decoder
                            .apply(&state)
                            .map_err(|e| anyhow!("the server's state is unreadable: {e}"))
                    });
                    match resynced {
                        Ok(_) => {
                            lost_since = None;
                            sink.log_note(
                                &format!("frames after {held} up to {follows} lost on the way; resynced at frame {} (resync {resyncs})", decoder.frame),
                                "WARN",
                            )?;
                        }
                        Err(e) => {
                            lost_since = Some(Instant::now());
                            sink.log_note(
                                &format!("frames after {held} up to {follows} lost and the resync failed ({e:#}); waiting for the next key frame"),
                                "WARN",
                            )?;
                        }
                    }
                }
                Err(e) => sink.log_note(&format!("unreadable frame: {e}"), "WARN")?,
            }
        }
        pending += applied;
        if client.every() > 1 && applied > 0 && decoder.synced {
            // A reduced-rate stream's frame: the steps since the last one are drawn as
            // they come due, this frame last (the frame before drawn whole first).
            // A recording (no drawing rate to keep) draws every step: those of the last
            // frame its process was too late for come first.
            if let Some(b) = between.as_mut().filter(|_| min_draw_interval.is_zero()) {
                for d in b.rest() {
                    sink.draw_between(&d)?;
                }
            }
            let before = between.take().map(Between::into_newest).or(newest.take());
            // One copy of the decoder a stream frame: the interpolation's end, or else
            // the next one's start.
            match before {
                Some(from) if Between::spans(&from, &decoder) => {
                    between = Some(Between::new(from, decoder.clone(), Instant::now()));
                    pending = 0;
                    continue;
                }
                _ => newest = Some(decoder.clone()),
            }
        }
        if pending == 0 || last_draw.elapsed() < min_draw_interval {
            continue;
        }
        skipped += pending - 1;
        pending = 0;
        last_draw = Instant::now();
        sink.draw(&decoder)?;
        draw_time += last_draw.elapsed();
        if skipped > 0 && reported_skips.elapsed() >= Duration::from_secs(5) {
            tracing::debug!(
                skipped,
                "frames decoded but not drawn (the --fps cap, or a slow sink)"
            );
            reported_skips = Instant::now();
        }
    }
    sink.recording().flush_blocking()?;
    let drawn = sink.frames_drawn;
    tracing::info!(
        drawn,
        skipped,
        resyncs,
        seconds = format!("{:.2}", began.elapsed().as_secs_f64()),
        draw_ms = format!("{:.3}", draw_time.as_secs_f64() * 1e3 / drawn.max(1) as f64),
        "done"
    );
    if served == Served::Web {
        // The page reads from this process: keep it up so the recording can be browsed.
        println!("ricochet-viewer: stopped drawing; still serving the recording (Ctrl-C to quit)");
        loop {
            std::thread::park();
        }
    }
    Ok(())
}

fn main() {
    init_tracing("info,zenoh=warn,re_chunk=error");
    if let Err(e) = run(Opts::parse()) {
        eprintln!("ricochet-viewer: {e:#}");
        std::process::exit(1);
    }
}
