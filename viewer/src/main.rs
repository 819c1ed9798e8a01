//! `ricochet-viewer`: subscribes to Ricochet worlds over zenoh and logs them to Rerun.
//!
//! In: frames, snapshots and events of one world or several (zenoh). Out: Rerun entities
//! (bounds, bodies, particles, emitters, the step's figures, the commands applied), to the
//! web viewer it serves, a native viewer, a running viewer or an .rrd file. `watch` is one
//! world's loop, `sink` turns decoded state into Rerun logs, `draw` builds the shapes,
//! `blueprint` lays out the view; with several worlds, `arrange` places them in the one
//! view and `drift` plots how far they drift apart.
//!
//! Each world is watched on a thread of its own, into the one recording. One world's
//! entities are `world/...`, `stats/<plot>` and `events`; several worlds' go under a root
//! each (`world/<name>/...`, `stats/<plot>/<name>`, `events/<name>`), and the drift plots
//! under `drift/`.

mod advertise;
mod arrange;
mod between;
mod blueprint;
mod draw;
mod drift;
mod sink;
mod watch;

use std::path::PathBuf;
use std::sync::mpsc;
use std::time::{Duration, Instant};

use anyhow::{anyhow, bail, Context, Result};
use clap::{ArgGroup, Parser};
use ricochet_protocol::client::Client;
use ricochet_protocol::command::WorldInfo;
use ricochet_protocol::keys::DEFAULT_WORLD;
use ricochet_protocol::net::{init_tracing, NetworkArgs, Verbosity};

use crate::sink::{Place, WorldSink};
use crate::watch::{DriftFeed, Pace};

/// Draws a Ricochet world in Rerun: bounds, bodies, particles, the step's figures and the
/// commands applied. Given several worlds (a world and its forks under other settings),
/// draws them side by side and plots how far they drift apart.
#[derive(Parser, Debug)]
#[command(version = ricochet_protocol::VERSION, group(ArgGroup::new("sink").args(["web", "spawn", "connect_rerun", "save"])))]
struct Opts {
    /// The world to watch. Given more than once (`--world table --world table-fine`),
    /// every world is drawn in the one 2D view, side by side in the order given, each
    /// under its name (or over each other with --overlay); every plot has a line per
    /// world, and two more plot how far each world drifts from the first, frame by frame:
    /// the largest distance between two bodies of the same id, and its kinetic energy
    /// less the first's, at the frames both have decoded.
    #[arg(long = "world", value_name = "NAME", default_value = DEFAULT_WORLD)]
    worlds: Vec<String>,
    /// With several --world: draw the worlds over each other, each in a colour of its
    /// own (the collided flag's red left out), rather than side by side.
    #[arg(long)]
    overlay: bool,
    /// Where to find the world's server (default: connect to tcp/127.0.0.1:7447, where a
    /// server listens).
    #[command(flatten)]
    network: NetworkArgs,
    #[command(flatten)]
    verbosity: Verbosity,

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
    /// Stop after drawing this many frames (of each world).
    #[arg(long, value_name = "N")]
    frames: Option<u64>,
    /// Stop when no frame has arrived for this long, seconds (default: never, but 10 with
    /// --save).
    #[arg(long, value_name = "SECS")]
    idle_exit: Option<f64>,
    /// How long to wait for the world's server to answer at start, seconds.
    #[arg(long, default_value_t = 30.0, value_name = "SECS")]
    wait: f64,

    /// Address the web viewer and gRPC server bind to (--web): 0.0.0.0 serves every
    /// interface, for a browser on another machine.
    #[arg(long, default_value = "127.0.0.1", value_name = "IP")]
    bind: String,
    /// The host name or address the printed URL names, as another machine reaches this
    /// one (--web). Default: the --bind address, or for 0.0.0.0 this machine's address.
    #[arg(long, value_name = "HOST")]
    advertise: Option<String>,
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
    // The page is opened, and reads the gRPC server, at the advertised host.
    let host = advertise::host(&opts.bind, opts.advertise.as_deref())?;
    let grpc = format!("rerun+http://{host}:{}/proxy", opts.grpc_port);
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
    // The port the page is served on (the one asked for, or the one picked for 0).
    let served = server.server_url();
    let web_port = served
        .trim_end_matches('/')
        .rsplit(':')
        .next()
        .unwrap_or_default();
    let url = format!("http://{host}:{web_port}/?url={}", grpc.replace('+', "%2B"));
    println!("ricochet-viewer: open {url}");
    // Served until the process exits.
    server.detach();
    Ok((rec, Served::Web))
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
    for (k, name) in opts.worlds.iter().enumerate() {
        if opts.worlds[..k].contains(name) {
            bail!("--world {name} is given twice");
        }
    }
    let pace = Pace {
        frames: opts.frames,
        min_draw_interval: match opts
            .fps
            .unwrap_or(if opts.save.is_some() { 0.0 } else { 30.0 })
        {
            hz if hz > 0.0 && hz.is_finite() => Duration::from_secs_f64(1.0 / hz),
            0.0 => Duration::ZERO,
            hz => bail!("--fps must be 0 or more, not {hz}"),
        },
        idle_exit: opts
            .idle_exit
            .or(opts.save.as_ref().map(|_| 10.0))
            .map(Duration::from_secs_f64),
    };
    let worlds = join_worlds(&opts)?;
    let (rec, served) = open_sink(&opts, "ricochet")?;

    // One world: today's paths and layout (sent with its info). Several: a place each,
    // one layout for all, and a thread that compares their frames.
    let several = worlds.len() > 1;
    let names: Vec<String> = worlds.iter().map(|(c, _)| c.keys().world.clone()).collect();
    let places = if several {
        let infos: Vec<(String, WorldInfo)> = names
            .iter()
            .cloned()
            .zip(worlds.iter().map(|(_, info)| info.clone()))
            .collect();
        let (places, views) = arrange::arrange(&infos, opts.overlay);
        blueprint::send(&rec, "ricochet", &views)?;
        for (name, place) in names.iter().zip(&places).skip(1) {
            drift::log_series(&rec, &names[0], name, place.color)?;
        }
        places
    } else {
        vec![Place::only()]
    };
    // A few seconds of frames of every world: the comparison is quick, so a full channel
    // only ever holds a world's loop back for a moment.
    let (samples, compared) = mpsc::sync_channel(1024);
    let drift = several.then(|| {
        let (rec, names) = (rec.clone(), names.clone());
        std::thread::spawn(move || drift::run(rec, names, compared))
    });

    let began = Instant::now();
    let (done, finished) = mpsc::channel();
    for (index, ((client, info), place)) in worlds.into_iter().zip(places).enumerate() {
        let sink = WorldSink::new(rec.clone(), "ricochet", place)?;
        let feed = several.then(|| DriftFeed {
            world: index,
            samples: samples.clone(),
        });
        let done = done.clone();
        std::thread::Builder::new()
            .name(format!("world {}", names[index]))
            .spawn(move || {
                let _ = done.send((index, watch::watch(client, info, sink, pace, feed)));
            })
            .context("cannot start a world's thread")?;
    }
    // The comparing thread stops once every world's loop has.
    drop((samples, done));
    for _ in 0..names.len() {
        let (index, result) = finished
            .recv()
            .map_err(|_| anyhow!("a world's loop stopped without a word (it panicked)"))?;
        let name = &names[index];
        let tally = if several {
            result.with_context(|| format!("world `{name}`"))?
        } else {
            result?
        };
        tracing::info!(
            world = %name,
            drawn = tally.drawn,
            skipped = tally.skipped,
            resyncs = tally.resyncs,
            seconds = format!("{:.2}", began.elapsed().as_secs_f64()),
            draw_ms = format!(
                "{:.3}",
                tally.draw_time.as_secs_f64() * 1e3 / tally.drawn.max(1) as f64
            ),
            "done"
        );
    }
    if let Some(drift) = drift {
        let compared = drift
            .join()
            .map_err(|_| anyhow!("the drift plots' thread panicked"))??;
        tracing::info!(compared, "frames compared between the worlds");
    }
    rec.flush_blocking()?;
    if served == Served::Web {
        // The page reads from this process: keep it up so the recording can be browsed.
        println!("ricochet-viewer: stopped drawing; still serving the recording (Ctrl-C to quit)");
        loop {
            std::thread::park();
        }
    }
    Ok(())
}

/// Opens a client for every world (one zenoh session for all) and waits for each to
/// answer; on a link of `--max-bandwidth`, each watches the stream that fits it.
fn join_worlds(opts: &Opts) -> Result<Vec<(Client, WorldInfo)>> {
    let network = opts.network.clone().client();
    let wait = Duration::from_secs_f64(opts.wait);
    let mut worlds: Vec<(Client, WorldInfo)> = Vec::with_capacity(opts.worlds.len());
    for name in &opts.worlds {
        let mut client = match worlds.first() {
            None => Client::open(&network, name)?,
            Some((first, _)) => first.alongside(name)?,
        };
        let info = wait_for_world(&client, wait)?;
        tracing::info!(world = %name, scene = %info.scene, "joined");
        if let Some(bits) = opts.max_bandwidth {
            client.watch_every(info.stream_for(bits));
            tracing::info!(
                world = %name,
                every = client.every(),
                "watching the stream of one frame in {} steps, to fit {bits} bits a second",
                client.every()
            );
        }
        worlds.push((client, info));
    }
    Ok(worlds)
}

fn main() {
    let opts = Opts::parse();
    init_tracing("info,zenoh=warn,re_chunk=error", opts.verbosity);
    if let Err(e) = run(opts) {
        eprintln!("ricochet-viewer: {e:#}");
        std::process::exit(1);
    }
}
