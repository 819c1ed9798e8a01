//! `ricochet-server`: runs Ricochet worlds.
//!
//! `run` hosts a world on zenoh in real time; `simulate` runs a scene headless, with no
//! network, and can dump every frame as JSON Lines; `router` runs a zenoh router where
//! servers and clients on several hosts meet.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use clap::{Args, Parser, Subcommand};
use ricochet_engine::scene;
use ricochet_engine::world::{Limits, World};
use ricochet_protocol::command::{parse_input_log, TimedAction};
use ricochet_protocol::frame::{peek_header, FrameEncoder, HEADER_BYTES, KIND_KEY};
use ricochet_protocol::keys::DEFAULT_WORLD;
use ricochet_protocol::net::{init_tracing, Mode, NetworkArgs};
use ricochet_protocol::world::{self as wire, write_frame};
use ricochet_server::host::inbox::InboxLimits;
use ricochet_server::host::{self, HostOptions};
use ricochet_server::report::{self, bench, soak, tradeoff};

#[derive(Parser)]
#[command(
    name = "ricochet-server",
    version,
    about = "Ricochet: a 2D physics and particle server"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Args)]
struct RunArgs {
    /// The scene file (TOML).
    #[arg(long, required_unless_present = "resume")]
    scene: Option<PathBuf>,
    /// The world's name in key expressions.
    #[arg(long, default_value = DEFAULT_WORLD)]
    world: String,
    #[command(flatten)]
    network: NetworkArgs,
    /// Start paused; `resume` or `step` commands move the world.
    #[arg(long)]
    paused: bool,
    /// Override a `[world]` field (as for simulate). Repeatable.
    #[arg(long = "set", value_name = "NAME=VALUE")]
    set: Vec<String>,
    /// A key frame (all dynamic state) every this many frames.
    #[arg(long, default_value_t = 60)]
    keyframe_interval: u64,
    /// Stop after this many frames instead of running until killed.
    #[arg(long)]
    max_frames: Option<u64>,
    /// Append every frame the server publishes to this file as JSON Lines, in the
    /// form of `simulate --dump` (full precision), flushed each frame.
    #[arg(long, value_name = "FILE")]
    dump: Option<PathBuf>,
    /// The directory `load` commands may name scenes in (nothing outside it is read);
    /// the directory of --scene by default.
    #[arg(long, value_name = "DIR")]
    scenes: Option<PathBuf>,
    /// Lower or raise a limit of the hosted worlds, e.g. --limit bodies=5000
    /// --limit step_work=1e7 (names and defaults: docs/security.md). A scene's
    /// `[limits]` may lower these, never raise them. Repeatable.
    #[arg(long = "limit", value_name = "NAME=VALUE")]
    limit: Vec<String>,
    /// Steps per second of wall time at most: a world with a shorter dt runs slower
    /// than real time instead of flooding its viewers.
    #[arg(long, default_value_t = 1000.0, value_name = "HZ")]
    max_rate: f64,
    /// Commands a second each sender may send over time (a sender is the zenoh id its
    /// session declares; Ricochet's clients declare theirs). Over it, commands are
    /// dropped and requests answered so.
    #[arg(long, default_value_t = 1000.0, value_name = "N")]
    sender_rate: f64,
    /// Commands a sender may send at once above its rate.
    #[arg(long, default_value_t = 500.0, value_name = "N")]
    sender_burst: f64,
    /// Commands (and, apart, requests) waiting for the frame boundary at most; past it
    /// they are dropped and requests answered so.
    #[arg(long, default_value_t = 4096, value_name = "N")]
    queue: usize,
    /// Write every accepted command, with the frame it took effect in, and every stepped
    /// frame to FILE (JSON Lines, each line flushed as written), so the world can be
    /// resumed after a crash with --resume FILE.
    #[arg(long, value_name = "FILE", conflicts_with = "resume")]
    journal: Option<PathBuf>,
    /// Rebuild the world a journal holds, bit for bit, to its last frame, and go on
    /// (appending to the same journal). The journal gives the scene, world name,
    /// overrides and limits; --scene, --world, --set and --limit are not needed.
    #[arg(long, value_name = "FILE")]
    resume: Option<PathBuf>,
}

#[derive(Subcommand)]
enum Command {
    /// Host a world on zenoh and run it in real time at the scene's fixed step.
    ///
    /// With no flags it listens on tcp/127.0.0.1:7447 and clients on the same machine
    /// connect there by default. Commands arrive on ricochet/<world>/cmd (fire and forget)
    /// and ricochet/<world>/rpc (request, reply); frames leave on ricochet/<world>/frame,
    /// the statics snapshot on ricochet/<world>/snapshot (also a queryable), the dynamic
    /// state for late joiners on the ricochet/<world>/state queryable, one event per
    /// handled command on ricochet/<world>/event; a liveliness token
    /// ricochet/<world>/alive/<zid> says the world is up and which peer serves it.
    Run(RunArgs),
    /// Measure the engine's speed on shipped scenes (figures, not pass/fail).
    ///
    /// The 100-level pyramid under each solver setting (with its worst drift over the
    /// run), particles among shapes, free particles, and a hero among few or many static
    /// platforms: the scenes of assets/scenes/ and assets/scenes/bench/. Prints a table;
    /// with --out writes DIR/bench.csv and the table of DIR/README.md. Use a release
    /// build.
    Bench {
        /// Steps of the pyramid (the brief: 500). The chapter's relaxation runs at most 20:
        /// it is quadratic in the pile.
        #[arg(long, default_value_t = 500)]
        steps: u64,
        /// Only the cases whose scene contains this.
        #[arg(long)]
        only: Option<String>,
        /// Write DIR/bench.csv and the generated table of DIR/README.md (docs/bench).
        #[arg(long, value_name = "DIR")]
        out: Option<PathBuf>,
        /// Where the scenes are.
        #[arg(long, default_value = "assets/scenes", value_name = "DIR")]
        scenes: PathBuf,
        /// Measure the pyramid under this setting instead of the listed ones: overrides of
        /// the shipped scene's `[world]` as NAME=VALUE (repeatable), e.g.
        /// `--set impulse_iterations=6 --set substeps=1`.
        #[arg(long = "set", value_name = "NAME=VALUE")]
        set: Vec<String>,
    },
    /// Measure what each solver setting costs and buys.
    ///
    /// Runs the matrix of scenes x solver settings and writes DIR/tradeoff.csv and
    /// DIR/tradeoff.png (time against error, the front in red). Use a release build.
    Tradeoff {
        /// Where to write the report.
        #[arg(long, default_value = "docs/tradeoff")]
        out: PathBuf,
    },
    /// Soak a real server on loopback and measure it (figures, not pass/fail).
    ///
    /// Starts `run` on the scene, journaled; client sessions send valid, invalid and
    /// oversized commands at --rate in all and requests (retried with ids) that must all
    /// be answered; a viewer stops reading frames for --stall-for seconds; at --kill-at
    /// the server is killed (SIGKILL) and resumed from its journal. Prints a table; with
    /// --out, writes it between the soak markers of FILE (docs/reliability.md). Use a
    /// release build.
    Soak {
        #[arg(long, default_value = "assets/scenes/particles.toml")]
        scene: PathBuf,
        #[arg(long, default_value_t = 60.0)]
        seconds: f64,
        #[arg(long, default_value_t = 4)]
        clients: usize,
        /// Fire-and-forget commands a second, all clients together.
        #[arg(long, default_value_t = 10_000.0)]
        rate: f64,
        /// Requests a second of each client (each waits for its answer).
        #[arg(long, default_value_t = 20.0)]
        requests: f64,
        #[arg(long, default_value_t = 10.0)]
        stall_at: f64,
        #[arg(long, default_value_t = 10.0)]
        stall_for: f64,
        /// When to kill and resume the server, seconds into the run; never if absent.
        #[arg(long)]
        kill_at: Option<f64>,
        /// Extra arguments of the server's `run`. Repeatable.
        #[arg(long = "server-arg", value_name = "ARG", allow_hyphen_values = true)]
        server_args: Vec<String>,
        /// Write the table between the soak markers of this file.
        #[arg(long, value_name = "FILE")]
        out: Option<PathBuf>,
    },
    /// Make the TLS certificates of a secured deployment (assets/zenoh/): a certificate
    /// authority and the router's certificate signed by it, as PEM files in DIR
    /// (ca.pem, ca-key.pem, router.pem, router-key.pem; keys readable by their owner
    /// only). Clients trust ca.pem; keep ca-key.pem offline.
    Certs {
        /// Where to write them.
        #[arg(long, default_value = "certs", value_name = "DIR")]
        out: PathBuf,
        /// A host name or IP address clients reach the router by. Repeatable.
        #[arg(long = "host", value_name = "NAME", default_values_t = ["localhost".to_string(), "127.0.0.1".to_string()])]
        hosts: Vec<String>,
        /// Days the certificates are valid.
        #[arg(long, default_value_t = 365)]
        days: u32,
    },
    /// Run a zenoh router where servers and clients on several hosts meet.
    ///
    /// They connect to it with `--mode client --connect tcp/<router>:7447`.
    Router {
        #[command(flatten)]
        network: NetworkArgs,
    },
    /// Run a scene headless for a number of steps, without any network.
    ///
    /// Line 0 of the dump is the state before the first step, line k the state after k
    /// steps: {"frame":k,"t":seconds,"bodies":[{"id","x","y","vx","vy","collided"}],
    /// "particles":[{"x","y","size","color":[r,g,b,a]}],"emitters":count}.
    ///
    /// The same scene, seed and inputs give the same frames, bit for bit.
    Simulate(SimulateArgs),
}

/// What `simulate` runs and writes.
#[derive(clap::Args)]
struct SimulateArgs {
    /// The scene file (TOML), e.g. assets/scenes/emitters.toml.
    #[arg(long)]
    scene: PathBuf,
    /// How many fixed steps to run.
    #[arg(long)]
    steps: u64,
    /// Seed of the world's random generator (overrides the scene's `[world] seed`).
    #[arg(long)]
    seed: Option<u64>,
    /// Override a `[world]` field, e.g. --set relaxation_iterations=30
    /// --set gravity=[0,-9.8] --set integrator=explicit. Repeatable.
    #[arg(long = "set", value_name = "NAME=VALUE")]
    set: Vec<String>,
    /// Write every frame as JSON Lines to this file ("-" for standard output).
    #[arg(long)]
    dump: Option<PathBuf>,
    /// Actions to apply, JSON Lines of {"frame": N, "action": {"do": ...}}: each is
    /// applied after N steps, before step N + 1, in file order.
    #[arg(long)]
    inputs: Option<PathBuf>,
    /// Write every step's figures as JSON Lines to this file (line k: step k): contacts,
    /// solver passes, deepest penetration, kinetic energy, particle contacts, sleeping
    /// bodies.
    #[arg(long, value_name = "FILE")]
    stats: Option<PathBuf>,
    /// Encode every frame as the server would send it and report the bytes per frame,
    /// per dynamic body and per particle.
    #[arg(long)]
    wire_stats: bool,
    /// With --wire-stats: a key frame every this many frames, as `run` would send.
    #[arg(long, default_value_t = 60)]
    keyframe_interval: u64,
    /// Lower or raise a limit of the world, as for `run` (docs/security.md). Repeatable.
    #[arg(long = "limit", value_name = "NAME=VALUE")]
    limit: Vec<String>,
}

fn main() -> Result<()> {
    init_tracing("info");
    match Cli::parse().command {
        Command::Run(RunArgs {
            scene,
            world,
            network,
            paused,
            set,
            keyframe_interval,
            max_frames,
            dump,
            scenes,
            limit,
            max_rate,
            sender_rate,
            sender_burst,
            queue,
            journal,
            resume,
        }) => {
            for (flag, value) in [
                ("--sender-rate", sender_rate),
                ("--sender-burst", sender_burst),
            ] {
                if !(value.is_finite() && value >= 1.0) {
                    anyhow::bail!("{flag} {value}: must be a number of commands of 1 or more");
                }
            }
            if queue == 0 {
                anyhow::bail!("--queue 0: at least one command must be able to wait");
            }
            if !(max_rate.is_finite() && max_rate > 0.0) {
                anyhow::bail!(
                    "--max-rate {max_rate}: must be a number of steps per second above 0"
                );
            }
            let scenes_dir = match (scenes, &scene) {
                (Some(dir), _) => dir,
                (None, None) => PathBuf::from("."),
                (None, Some(scene)) => scene
                    .parent()
                    .filter(|p| !p.as_os_str().is_empty())
                    .unwrap_or(Path::new("."))
                    .to_path_buf(),
            };
            host::run(HostOptions {
                scene,
                world,
                network: network.server(),
                paused,
                overrides: set,
                keyframe_interval,
                max_frames,
                dump,
                scenes_dir,
                limits: Limits::default().with(&limit)?,
                max_rate,
                inbox: InboxLimits {
                    rate: sender_rate,
                    burst: sender_burst,
                    queue,
                    ..InboxLimits::default()
                },
                journal,
                resume,
            })
        }
        Command::Bench {
            steps,
            only,
            out,
            scenes,
            set,
        } => run_bench(steps, only.as_deref(), out.as_deref(), &scenes, set),
        Command::Tradeoff { out } => {
            std::fs::create_dir_all(&out)
                .with_context(|| format!("cannot create {}", out.display()))?;
            let cells = tradeoff::run_matrix();
            std::fs::write(out.join("tradeoff.csv"), tradeoff::to_csv(&cells))?;
            tradeoff::chart(&cells, &out.join("tradeoff.png"))?;
            for c in &cells {
                println!(
                    "{:<11} {:<38} {:>9.4} ms  error {:>10.3e}  deepest {:>9.2e}  energy {:>+9.2e}{}{}",
                    c.scene, c.setting, c.ms_per_step, c.error, c.deepest_penetration, c.energy_drift,
                    if c.nan { "  NaN" } else { "" },
                    if tradeoff::on_front(c, &cells) { "  front" } else { "" }
                );
            }
            let readme = out.join("README.md");
            if readme.exists() {
                report::splice(
                    &readme,
                    "tradeoff",
                    &format!(
                        "Measured by `ricochet-server tradeoff --out {}` on {}.\n\n{}",
                        out.display(),
                        report::machine(),
                        tradeoff::to_markdown(&cells)
                    ),
                )?;
            }
            eprintln!(
                "wrote {}, {} and the table of {}",
                out.join("tradeoff.csv").display(),
                out.join("tradeoff.png").display(),
                readme.display()
            );
            Ok(())
        }
        Command::Soak {
            scene,
            seconds,
            clients,
            rate,
            requests,
            stall_at,
            stall_for,
            kill_at,
            server_args,
            out,
        } => {
            let opts = soak::SoakOptions {
                scene,
                seconds,
                clients: clients.max(1),
                rate,
                requests,
                stall_at,
                stall_for,
                kill_at,
                server_args,
            };
            let report = soak::run(&opts)?;
            let table = report.to_markdown(&opts);
            println!("{table}");
            if let Some(out) = out {
                report::splice(
                    &out,
                    "soak",
                    &format!(
                        "Measured by `{}` on {}.\n\n{table}",
                        soak::command_line(&opts, Some(&out)),
                        report::machine()
                    ),
                )?;
                eprintln!("wrote the table of {}", out.display());
            }
            Ok(())
        }
        Command::Certs { out, hosts, days } => {
            for file in ricochet_server::certs::make(&out, &hosts, days)? {
                eprintln!("wrote {}", file.display());
            }
            Ok(())
        }
        Command::Router { network } => {
            let mut net = network.server();
            net.mode = Some(Mode::Router);
            host::run_router(&net)
        }
        Command::Simulate(args) => simulate(args),
    }
}

fn run_bench(
    steps: u64,
    only: Option<&str>,
    out: Option<&Path>,
    scenes: &Path,
    set: Vec<String>,
) -> Result<()> {
    let pyramid = (!set.is_empty()).then_some(set);
    let cases: Vec<bench::Case> = bench::cases(pyramid, steps)
        .into_iter()
        .filter(|c| only.is_none_or(|o| c.scene.contains(o)))
        .collect();
    let total: u64 = cases.iter().map(|c| c.settings.len() as u64).sum();
    let progress = indicatif::ProgressBar::new(total).with_style(
        indicatif::ProgressStyle::with_template("{bar:30} {pos}/{len} {msg}")
            .expect("a valid template"),
    );
    let mut rows = Vec::new();
    for case in &cases {
        for (label, overrides) in &case.settings {
            progress.set_message(format!("{} / {label}", case.scene));
            // The chapter's relaxation is quadratic in the pile: a few steps show its cost.
            let relaxation = overrides.iter().any(|o| o == "solver=relaxation");
            let n = if relaxation {
                case.steps.min(20)
            } else {
                case.steps
            };
            rows.push(bench::measure(scenes, case, label, overrides, n)?);
            progress.inc(1);
        }
    }
    progress.finish_and_clear();
    let table = bench::to_markdown(&rows);
    println!("{table}");
    if let Some(dir) = out {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
        std::fs::write(dir.join("bench.csv"), bench::to_csv(&rows)?)?;
        let readme = dir.join("README.md");
        let command = std::iter::once("ricochet-server".to_string())
            .chain(std::env::args().skip(1))
            .collect::<Vec<_>>()
            .join(" ");
        report::splice(
            &readme,
            "bench",
            &format!(
                "Measured by `{command}` on {}.\n\n{table}",
                report::machine()
            ),
        )?;
        eprintln!(
            "wrote {} and the table of {}",
            dir.join("bench.csv").display(),
            readme.display()
        );
    }
    Ok(())
}

fn read_inputs(path: &Path) -> Result<Vec<TimedAction>> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("cannot read inputs {}", path.display()))?;
    parse_input_log(&text).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))
}

fn simulate(args: SimulateArgs) -> Result<()> {
    let SimulateArgs {
        scene: scene_path,
        steps,
        seed,
        set: mut overrides,
        dump: dump_path,
        inputs,
        stats: stats_path,
        wire_stats,
        keyframe_interval,
        limit,
    } = args;
    let limits = Limits::default().with(&limit)?;
    let (scene_path, dump_path, stats_path, inputs) = (
        scene_path.as_path(),
        dump_path.as_deref(),
        stats_path.as_deref(),
        inputs.as_deref(),
    );
    let wire_stats = wire_stats.then_some(keyframe_interval);
    if let Some(seed) = seed {
        overrides.push(format!("seed={seed}"));
    }
    let text = std::fs::read_to_string(scene_path)
        .with_context(|| format!("cannot read scene {}", scene_path.display()))?;
    let mut world: World = scene::parse_with(&text, scene_path, &overrides, &limits)?;
    let inputs = match inputs {
        Some(p) => read_inputs(p)?,
        None => Vec::new(),
    };

    let mut out: Option<Box<dyn Write>> = match dump_path {
        None => None,
        Some(p) if p == Path::new("-") => Some(Box::new(BufWriter::new(std::io::stdout().lock()))),
        Some(p) => Some(Box::new(BufWriter::new(
            File::create(p).with_context(|| format!("cannot create dump {}", p.display()))?,
        ))),
    };
    if let Some(out) = out.as_mut() {
        write_frame(out, &world)?;
    }
    let mut stats_out = match stats_path {
        None => None,
        Some(p) => {
            Some(BufWriter::new(File::create(p).with_context(|| {
                format!("cannot create stats {}", p.display())
            })?))
        }
    };

    let progress = indicatif::ProgressBar::new(steps);
    progress.set_style(
        indicatif::ProgressStyle::with_template("{bar:40} {pos}/{len} steps {per_sec} eta {eta}")
            .expect("the template is valid"),
    );
    let mut wire = wire_stats.map(|interval| WireStats::new(&world, interval));
    let mut next_input = inputs.iter().peekable();
    let mut refused = 0u64;
    let started = Instant::now();
    let mut stepping = std::time::Duration::ZERO;
    for _ in 0..steps {
        while let Some(input) = next_input.next_if(|a| a.frame <= world.frame()) {
            match world.apply(&input.action) {
                Ok(outcome) if !outcome.ids.is_empty() => {
                    tracing::debug!(frame = world.frame(), ids = ?outcome.ids, "action applied")
                }
                Ok(_) => {}
                Err(e) => {
                    refused += 1;
                    tracing::warn!(frame = world.frame(), action = ?input.action, "action refused: {e}");
                }
            }
        }
        let t = Instant::now();
        world.step();
        stepping += t.elapsed();
        if let Some(out) = out.as_mut() {
            write_frame(out, &world)?;
        }
        if let Some(out) = stats_out.as_mut() {
            serde_json::to_writer(&mut *out, &wire::stats_record(&world))?;
            out.write_all(b"\n")?;
        }
        if let Some(w) = wire.as_mut() {
            w.frame(&world);
        }
        progress.inc(1);
    }
    progress.finish_and_clear();
    if let Some(mut out) = out {
        out.flush()?;
    }
    if let Some(mut out) = stats_out {
        out.flush()?;
    }
    let stats = world.stats();
    let per_step = if steps > 0 {
        stepping.as_secs_f64() * 1e3 / steps as f64
    } else {
        0.0
    };
    eprintln!(
        "{}: {steps} steps in {:.3} s ({per_step:.4} ms/step stepping), t = {:.3} s; {} bodies, {} particles, {} emitters; \
         last step: {} contacts, {} relaxation passes, deepest penetration {:.4}, kinetic energy {:.4}; {refused} actions refused",
        scene_path.display(),
        started.elapsed().as_secs_f64(),
        world.time(),
        world.bodies().len(),
        world.particles().len(),
        world.emitters().len(),
        stats.contacts,
        stats.relaxation_iterations,
        stats.deepest_penetration,
        stats.kinetic_energy,
    );
    if let Some(w) = wire {
        w.report();
    }
    Ok(())
}

/// Bytes on the wire, frame by frame (`simulate --wire-stats`).
struct WireStats {
    encoder: FrameEncoder,
    statics_bytes: usize,
    frames: u64,
    bytes: u64,
    key_frames: (u64, u64),
    body_frames: u64,
    particle_frames: u64,
}

impl WireStats {
    fn new(world: &World, keyframe_interval: u64) -> Self {
        let mut w = WireStats {
            encoder: FrameEncoder::new(keyframe_interval),
            statics_bytes: wire::statics_snapshot(world).len(),
            frames: 0,
            bytes: 0,
            key_frames: (0, 0),
            body_frames: 0,
            particle_frames: 0,
        };
        w.frame(world);
        w
    }

    fn frame(&mut self, world: &World) {
        let bytes = wire::encode_frame(&mut self.encoder, world, 0.0, 0);
        let header = peek_header(&bytes).expect("own frames read back");
        self.frames += 1;
        self.bytes += bytes.len() as u64;
        if header.kind == KIND_KEY {
            self.key_frames.0 += 1;
            self.key_frames.1 += bytes.len() as u64;
        }
        self.body_frames += header.stats.dynamic_bodies as u64;
        self.particle_frames += header.stats.particles as u64;
    }

    fn report(&self) {
        let per = |num: u64, den: u64| {
            if den > 0 {
                num as f64 / den as f64
            } else {
                0.0
            }
        };
        let deltas = self.frames - self.key_frames.0;
        let payload = self.bytes - self.frames * HEADER_BYTES as u64;
        eprintln!(
            "wire: {} frames, {:.1} bytes/frame on average ({:.1} in key frames, {:.1} in delta frames; {} of header each);              statics snapshot {} bytes once; {:.1} dynamic bodies and {:.1} particles a frame on average;              {:.3} bytes per body-or-particle a frame beyond the header",
            self.frames,
            per(self.bytes, self.frames),
            per(self.key_frames.1, self.key_frames.0),
            per(self.bytes - self.key_frames.1, deltas),
            HEADER_BYTES,
            self.statics_bytes,
            per(self.body_frames, self.frames),
            per(self.particle_frames, self.frames),
            per(payload, self.body_frames + self.particle_frames),
        );
    }
}
