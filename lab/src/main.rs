//! `ricochet-lab`: what measures Ricochet, apart from what serves it.
//!
//! `bench`, `suite` and `tradeoff` step scenes in this process; `soak`, `hostile` and
//! `fanout` start real `ricochet-server` processes (the one beside this program, or
//! `--server PATH`) and measure them from outside; `wire` encodes frames as the server
//! does. Each command reads its flags, calls the library and says what it wrote. Build it
//! with `cargo build --release -p ricochet-lab`.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::{Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use ricochet_lab::scene_tradeoff::ReportPages;
use ricochet_lab::{bench, scene_tradeoff, soak, suite, tradeoff};
use ricochet_protocol::net::{init_tracing, Verbosity};

#[derive(Parser)]
#[command(
    name = "ricochet-lab",
    version = ricochet_protocol::VERSION,
    about = "Ricochet's lab: measures the engine and real servers, and writes the figures of docs/"
)]
struct Cli {
    /// The `ricochet-server` binary that soak, hostile and fanout start (default: the one
    /// beside this program).
    #[arg(long, global = true, value_name = "PATH")]
    server: Option<PathBuf>,
    #[command(flatten)]
    verbosity: Verbosity,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run scene families: for each family, scenes drawn from its ranges by seed, each
    /// judged by the physical invariants its `[criteria]` state (figures, not pass/fail).
    ///
    /// Every scene is written to --scenes-out as `<family>-<seed>.toml` (a failing seed is
    /// a file anyone can run). Prints a table per family and setting: seeds held of seeds
    /// run, the worst figure of each invariant, the mean ms/step, the failed seeds; with
    /// --out, writes it into DIR/families.md.
    Families {
        /// Only these families (default: every one).
        #[arg(long, value_enum)]
        family: Vec<ricochet_lab::families::Family>,
        /// Seeds per family, from --first.
        #[arg(long, default_value_t = 10)]
        seeds: u64,
        /// The first seed.
        #[arg(long, default_value_t = 0)]
        first: u64,
        /// Also run every scene under these `[world]` overrides, NAME=VALUE (repeatable),
        /// beside the default.
        #[arg(long = "set", value_name = "NAME=VALUE")]
        set: Vec<String>,
        /// Also run every scene under this accuracy target (scene units): the setting a
        /// fresh measure picks for it, as a server does at start-up, judged with the
        /// invariants stated at 2% (drift, energy kept, stopping distance) at 1%.
        #[arg(long, value_name = "TOL")]
        accuracy: Option<f64>,
        /// Under --accuracy, only the first N seeds of each family (each scene is
        /// measured afresh: seconds a scene).
        #[arg(long, value_name = "N")]
        accuracy_seeds: Option<u64>,
        /// Where the scenes are written.
        #[arg(long, default_value = "target/families", value_name = "DIR")]
        scenes_out: PathBuf,
        /// Write DIR/families.md.
        #[arg(long, value_name = "DIR")]
        out: Option<PathBuf>,
        /// Scenes run at once, each on a thread of its own. The figures and the table's
        /// order are the same whatever N is; the times are measured with N runs sharing
        /// the machine (the page says so).
        #[arg(long, default_value_t = 1, value_name = "N")]
        jobs: usize,
    },
    /// How a step's cost grows with the work: writes the scenes of three series (bodies,
    /// the largest body's size over the smallest's, pile depth) for the peer benchmark,
    /// and draws the chart from the peer benchmark's peers.csv.
    ///
    /// scaling --scenes-out target/scaling; then, from lab/peers, ricochet-peers --scenes
    /// target/scaling --out docs/bench/scaling; then scaling --chart
    /// docs/bench/scaling/peers.csv (writes scaling.png beside it).
    Scaling {
        /// Write the series' scenes into DIR as `<series>-<value>.toml`.
        #[arg(long, value_name = "DIR")]
        scenes_out: Option<PathBuf>,
        /// Draw the chart from the peer benchmark's CSV, beside it as scaling.png.
        #[arg(long, value_name = "CSV")]
        chart: Option<PathBuf>,
    },
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
    /// Hold the suite of scene kinds to their criteria under named settings.
    ///
    /// Runs every scene of the suite (each states its criteria in `[criteria]`) under the
    /// default and the settings it replaced or is without one of its parts, timing every
    /// step of the run. Prints the tables; with --out writes DIR/suite.csv and the tables
    /// of DIR/README.md (docs/bench). Use a release build.
    Suite {
        /// Where the suite's scenes are.
        #[arg(long, default_value = "assets/scenes/suite", value_name = "DIR")]
        scenes: PathBuf,
        /// Only the scenes whose file name contains this.
        #[arg(long)]
        only: Option<String>,
        /// Write DIR/suite.csv and the generated tables of DIR/README.md (docs/bench).
        #[arg(long, value_name = "DIR")]
        out: Option<PathBuf>,
    },
    /// Measure what each solver setting costs and buys.
    ///
    /// Runs the matrix of scenes x solver settings and writes DIR/tradeoff.csv and
    /// DIR/tradeoff.png (time against error, the front in red). Use a release build.
    ///
    /// With --scene FILE: measures that scene (any scene, yours included) under each
    /// candidate setting and under a converged reference, prints a table and writes
    /// DIR/<scene>.csv, DIR/<scene>.png and DIR/<scene>.md.
    Tradeoff {
        /// Where to write the report. Default: with one --scene FILE, a directory named
        /// after it in the current directory (`mine-tradeoff/` for mine.toml); otherwise
        /// `tradeoff/` there. (docs/tradeoff is written with `--out docs/tradeoff`.)
        #[arg(long, value_name = "DIR")]
        out: Option<PathBuf>,
        #[command(flatten)]
        scene: SceneTradeoffArgs,
    },
    /// Where a step's time goes, stage by stage (figures, not pass/fail).
    ///
    /// Runs scenes headless with the world's stage profile on and reports each stage's mean
    /// microseconds a step over the whole run and its share of the step. Prints a table;
    /// with --out, writes it between the profile markers of FILE (docs/bench/README.md).
    /// Use a release build.
    Profile {
        /// Steps of each scene.
        #[arg(long, default_value_t = 600)]
        steps: u64,
        /// Where the scenes are.
        #[arg(long, default_value = "assets/scenes", value_name = "DIR")]
        scenes: PathBuf,
        /// A scene to profile, under --scenes (repeatable; default: pyramid-100.toml,
        /// suite/rain.toml, emitters.toml).
        #[arg(long = "scene", value_name = "FILE")]
        scene: Vec<String>,
        /// Runs every scene under these `[world]` overrides, NAME=VALUE (repeatable), e.g.
        /// `--set threads=2 --set sleeping=false`: a stage's time under two settings is two
        /// runs, one table each.
        #[arg(long = "set", value_name = "NAME=VALUE")]
        set: Vec<String>,
        /// Write the table between the profile markers of this file.
        #[arg(long, value_name = "FILE")]
        out: Option<PathBuf>,
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
    /// Attack real servers on loopback, each defence on and off (figures, not pass/fail).
    ///
    /// Each attack of the security audit runs with its defence and with that defence
    /// switched off by the server's flags, and the table says what the defence buys. Prints a table; with --out, writes it
    /// between the hostile markers of FILE (docs/security.md). Use a release build.
    Hostile {
        /// Seconds of each attack.
        #[arg(long, default_value_t = 5.0)]
        seconds: f64,
        /// Where the shipped scenes are.
        #[arg(long, default_value = "assets/scenes", value_name = "DIR")]
        scenes: PathBuf,
        /// Write the table between the hostile markers of this file.
        #[arg(long, value_name = "FILE")]
        out: Option<PathBuf>,
    },
    /// Bytes on the wire per scene, frames encoded as `run` sends them.
    ///
    /// Runs shipped scenes headless and encodes every frame exactly as `run` sends it; report each scene's bytes a frame (key frames and headers included)
    /// per body or particle, and the bandwidth a viewer needs at 60 frames a second.
    /// Prints a table; with --out, writes it between the wire markers of FILE
    /// (docs/network.md).
    Wire {
        /// Steps of each scene.
        #[arg(long, default_value_t = 600)]
        steps: u64,
        /// A key frame every this many frames, as `run` sends them.
        #[arg(long, default_value_t = 60)]
        keyframe_interval: u64,
        /// Where the shipped scenes are.
        #[arg(long, default_value = "assets/scenes", value_name = "DIR")]
        scenes: PathBuf,
        /// Write the table between the wire markers of this file.
        #[arg(long, value_name = "FILE")]
        out: Option<PathBuf>,
    },
    /// One server and N viewers, directly and through a router (figures, not pass/fail).
    ///
    /// The viewers decode every frame of particles-100k (its emitter started again every
    /// 4 s), directly and through a router; reports the
    /// server's CPU, the bytes it wrote, its late steps, and each viewer's frames and lag.
    /// Prints a table; with --out, writes it between the fanout markers of FILE
    /// (docs/network.md). Use a release build.
    Fanout {
        /// Viewers.
        #[arg(long, default_value_t = 8)]
        viewers: usize,
        /// Seconds of each mode.
        #[arg(long, default_value_t = 12.0)]
        seconds: f64,
        /// Where the shipped scenes are.
        #[arg(long, default_value = "assets/scenes", value_name = "DIR")]
        scenes: PathBuf,
        /// Write the table between the fanout markers of this file.
        #[arg(long, value_name = "FILE")]
        out: Option<PathBuf>,
    },
}

/// `tradeoff --scene`: the trade measured on one scene.
#[derive(clap::Args)]
pub struct SceneTradeoffArgs {
    /// The scenes to measure (TOML), each on its own (`--scene a.toml b.toml`). Without
    /// any, the built-in report of shipped scenes.
    #[arg(long, num_args = 1..)]
    pub scene: Vec<PathBuf>,
    /// Steps of each run.
    #[arg(long, default_value_t = 300, requires = "scene")]
    pub steps: u64,
    /// Actions to apply, as `simulate --inputs` takes them (one scene only).
    #[arg(long, requires = "scene")]
    pub inputs: Option<PathBuf>,
    /// A setting to measure instead of the default matrix: `[world]` overrides separated
    /// by `;`, e.g. --candidate "solver=impulses;impulse_iterations=8". Repeatable.
    #[arg(long = "candidate", value_name = "SETS", requires = "scene")]
    pub candidates: Vec<String>,
    /// The reference is converged when two refinements agree within this many of the
    /// scene's length units (its median dynamic body size), worst body position
    /// difference over the run.
    #[arg(long, default_value_t = 1e-6, requires = "scene")]
    pub tolerance: f64,
    /// Refinements of the reference at most (each doubles sub-steps and passes).
    #[arg(long, default_value_t = 4, requires = "scene")]
    pub max_refinements: u32,
    /// Seconds the reference may take in all.
    #[arg(long, default_value_t = 300.0, requires = "scene")]
    pub reference_budget: f64,
}

fn main() -> Result<()> {
    let cli = Cli::parse();
    init_tracing("info", cli.verbosity);
    if let Some(server) = cli.server {
        ricochet_lab::use_server_binary(server);
    }
    match cli.command {
        Command::Bench {
            steps,
            only,
            out,
            scenes,
            set,
        } => {
            let progress = bar("{bar:30} {pos}/{len} {msg}");
            let rows = bench::run_all(&scenes, steps, only.as_deref(), set, &progress)?;
            progress.finish_and_clear();
            println!("{}", bench::tables(&rows));
            if let Some(dir) = out {
                bench::write(&dir, &rows, &ricochet_lab::command_line())?;
                eprintln!(
                    "wrote {} and the tables of {}",
                    dir.join("bench.csv").display(),
                    dir.join("README.md").display()
                );
            }
            Ok(())
        }
        Command::Families {
            family,
            seeds,
            first,
            set,
            accuracy,
            accuracy_seeds,
            scenes_out,
            out,
            jobs,
        } => {
            use ricochet_lab::families::{self, Family};
            anyhow::ensure!(jobs >= 1, "--jobs {jobs}: at least one scene must run");
            anyhow::ensure!(
                !set.iter().any(|s| s.trim_start().starts_with("accuracy")),
                "the engine does not read `accuracy`: give --accuracy TOL to run each scene under the setting a target picks"
            );
            if let Some(t) = accuracy {
                anyhow::ensure!(
                    t.is_finite() && t > 0.0,
                    "--accuracy {t}: must be a length above 0, in scene units"
                );
            }
            let families = if family.is_empty() {
                Family::ALL.to_vec()
            } else {
                family
            };
            let mut settings = vec![("the default".to_string(), Vec::new())];
            if !set.is_empty() {
                settings.push((set.join(" "), set));
            }
            let progress = bar("{bar:30} {pos}/{len} {msg}");
            let runs = families::run(
                &families,
                first..first + seeds,
                &settings,
                accuracy.map(|t| (t, accuracy_seeds.unwrap_or(seeds))),
                &scenes_out,
                &progress,
                jobs,
            )?;
            progress.finish_and_clear();
            let table = families::markdown(&runs);
            println!("{table}");
            if let Some(dir) = out {
                std::fs::create_dir_all(&dir)?;
                let targeted = accuracy.map_or(String::new(), |t| format!(" Rows `accuracy = {t}, judged at 1%` run each scene (of the first seeds, as many as the row says) under the setting a fresh measure picks for that target (as a server without a cache does at start-up; the last column says which, and how long the measure took), judged with the invariants stated at 2% (drift, energy kept, stopping distance) at 1%; their time is the run's, the measure's apart."));
                let shared = if jobs > 1 {
                    format!(" {jobs} scenes ran at once (`--jobs {jobs}`), so the times were measured with {jobs} runs sharing the machine.")
                } else {
                    String::new()
                };
                let page = format!(
                    "# Scene families\n\nGenerated by `{}` on {}. Each family draws scenes from its ranges by seed (`lab/src/families/mod.rs` documents them) and judges each by the invariants its `[criteria]` state; a figure is the worst over every seed's whole run, a time the mean over every step of every seed.{shared}{targeted}\n\n{table}",
                    ricochet_lab::command_line(),
                    ricochet_lab::machine()
                );
                std::fs::write(dir.join("families.md"), page)?;
                eprintln!("wrote {}", dir.join("families.md").display());
            }
            Ok(())
        }
        Command::Scaling { scenes_out, chart } => {
            anyhow::ensure!(
                scenes_out.is_some() || chart.is_some(),
                "give --scenes-out DIR, --chart CSV, or both"
            );
            if let Some(dir) = scenes_out {
                let written = ricochet_lab::scaling::write(&dir)?;
                eprintln!("wrote {} scenes into {}", written.len(), dir.display());
            }
            if let Some(csv) = chart {
                let png = csv.with_file_name("scaling.png");
                ricochet_lab::scaling::chart(&csv, &png)?;
                eprintln!("wrote {}", png.display());
            }
            Ok(())
        }
        Command::Suite { scenes, only, out } => {
            let progress = bar("{bar:30} {pos}/{len} {msg}");
            let rows = suite::run_all(&scenes, only.as_deref(), &progress)?;
            let targeted = suite::run_targeted(&scenes, only.as_deref(), suite::TARGET, &progress)?;
            progress.finish_and_clear();
            println!("{}", suite::tables(&rows, &targeted));
            if let Some(dir) = out {
                suite::write(&dir, &rows, &targeted, &ricochet_lab::command_line())?;
                eprintln!(
                    "wrote {} and the tables of its README.md",
                    dir.join("suite.csv").display()
                );
            }
            Ok(())
        }
        Command::Tradeoff { out, scene } if !scene.scene.is_empty() => {
            let out = out.unwrap_or_else(|| tradeoff_dir(&scene.scene));
            scene_tradeoff(out, scene)
        }
        Command::Tradeoff { out, .. } => {
            let out = out.unwrap_or_else(|| PathBuf::from("tradeoff"));
            let progress = bar("{prefix}: {bar:40} {pos}/{len} steps, eta {eta}: {msg}");
            let (cells, references) = tradeoff::run_all(&progress)?;
            progress.finish_and_clear();
            print!("{}", tradeoff::to_text(&cells));
            let command = format!("ricochet-lab tradeoff --out {}", out.display());
            let written = tradeoff::write(&out, &cells, &references, &command)?;
            eprintln!("wrote {}", list(&written));
            Ok(())
        }
        Command::Profile {
            steps,
            scenes,
            scene,
            set,
            out,
        } => {
            let names = if scene.is_empty() {
                ricochet_lab::profile::SCENES
                    .iter()
                    .map(|s| s.to_string())
                    .collect()
            } else {
                scene
            };
            let report = ricochet_lab::profile::run(&scenes, &names, steps, &set)?;
            print_table(&report.to_markdown(), out.as_deref(), "profile")
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
            println!("{}", report.to_markdown(&opts));
            if let Some(out) = out {
                report.write(&opts, &out)?;
                eprintln!("wrote the table of {}", out.display());
            }
            Ok(())
        }
        Command::Hostile {
            seconds,
            scenes,
            out,
        } => {
            let report = ricochet_lab::hostile::run(&scenes, seconds)?;
            print_table(&report.to_markdown(), out.as_deref(), "hostile")
        }
        Command::Wire {
            steps,
            keyframe_interval,
            scenes,
            out,
        } => {
            let report = ricochet_lab::wire::run(&scenes, steps, keyframe_interval)?;
            print_table(&report.to_markdown(), out.as_deref(), "wire")
        }
        Command::Fanout {
            viewers,
            seconds,
            scenes,
            out,
        } => {
            let report = ricochet_lab::fanout::run(&scenes, viewers, seconds)?;
            print_table(&report.to_markdown(), out.as_deref(), "fanout")
        }
    }
}

/// Prints a report's table and, with `out`, writes it between the `name` markers of
/// that page.
fn print_table(table: &str, out: Option<&std::path::Path>, name: &str) -> Result<()> {
    println!("{table}");
    if let Some(out) = out {
        ricochet_lab::splice(out, name, table)?;
        eprintln!("wrote the table of {}", out.display());
    }
    Ok(())
}

/// A progress bar of this template, its length set by the run.
fn bar(template: &str) -> ProgressBar {
    ProgressBar::new(0)
        .with_style(ProgressStyle::with_template(template).expect("a valid template"))
}

/// Files, for a line saying they were written.
fn list(files: &[PathBuf]) -> String {
    files
        .iter()
        .map(|f| f.display().to_string())
        .collect::<Vec<_>>()
        .join(", ")
}

/// Where `tradeoff --scene` writes without `--out`: `<scene>-tradeoff` in the current
/// directory for one scene, `tradeoff` for several.
fn tradeoff_dir(scenes: &[PathBuf]) -> PathBuf {
    match scenes {
        [one] => {
            let stem = one.file_stem().unwrap_or(one.as_os_str());
            PathBuf::from(format!("{}-tradeoff", stem.to_string_lossy()))
        }
        _ => PathBuf::from("tradeoff"),
    }
}

/// `tradeoff --scene FILE...`: the trade measured on each scene, a page each, and an
/// index of the pages when there are several.
fn scene_tradeoff(out: PathBuf, args: SceneTradeoffArgs) -> Result<()> {
    use scene_tradeoff::{measure, write_index, Candidate, Options, Subject};
    if args.inputs.is_some() && args.scene.len() > 1 {
        anyhow::bail!("--inputs goes with one --scene (the actions are that scene's)");
    }
    let inputs = match &args.inputs {
        Some(p) => ricochet_server::scenes::read_inputs(p)?,
        None => Vec::new(),
    };
    // NaN fails this too.
    if args.tolerance.is_nan() || args.tolerance <= 0.0 {
        anyhow::bail!("--tolerance must be above 0 (got {})", args.tolerance);
    }
    let candidates = if args.candidates.is_empty() {
        None
    } else {
        Some(
            args.candidates
                .iter()
                .map(|c| Candidate::parse(c))
                .collect::<Result<Vec<_>>>()?,
        )
    };
    // Every scene and candidate is read and checked before anything runs: a bad one fails
    // here, named.
    let mut subjects = Vec::new();
    for path in &args.scene {
        let subject = Subject::read(path, args.steps, inputs.clone())?;
        for c in candidates.iter().flatten() {
            subject
                .world(&c.overrides)
                .with_context(|| format!("{}: candidate `{}`", path.display(), c.name))?;
        }
        subjects.push(subject);
    }
    let opts = Options {
        tolerance: args.tolerance,
        max_refinements: args.max_refinements,
        reference_budget: args.reference_budget,
        budget: None,
    };
    std::fs::create_dir_all(&out).with_context(|| format!("cannot create {}", out.display()))?;
    let mut pages = Vec::new();
    for (k, subject) in subjects.iter().enumerate() {
        let progress = bar(&format!(
            "scene {}/{}: {{bar:40}} {{pos}}/{{len}} steps, eta {{eta}}: {{msg}}",
            k + 1,
            subjects.len()
        ));
        progress.set_length(args.steps);
        let report = measure(subject, candidates.clone(), &opts, &progress)?;
        progress.finish_and_clear();
        println!("{}", report.to_text());
        let mut command = format!(
            "ricochet-lab tradeoff --scene {} --steps {}",
            subject.path.display(),
            args.steps
        );
        if let Some(p) = &args.inputs {
            command += &format!(" --inputs {}", p.display());
        }
        for c in &args.candidates {
            command += &format!(" --candidate '{c}'");
        }
        if args.reference_budget != Options::default().reference_budget {
            command += &format!(" --reference-budget {}", args.reference_budget);
        }
        command += &format!(" --out {}", out.display());
        let (page, written) = report.write(&out, &command)?;
        eprintln!("wrote {}", list(&written));
        pages.push((page, report));
    }
    if pages.len() > 1 {
        let scenes: Vec<String> = args.scene.iter().map(|p| p.display().to_string()).collect();
        let command = format!(
            "ricochet-lab tradeoff --steps {} --out {} --scene {}",
            args.steps,
            out.display(),
            scenes.join(" ")
        );
        eprintln!("wrote {}", write_index(&out, &pages, &command)?.display());
    }
    Ok(())
}
