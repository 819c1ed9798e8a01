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
use clap::Parser;
use ricochet_engine::scene;
use ricochet_engine::world::{Limits, World};
use ricochet_protocol::command::{parse_input_log, TimedAction};
use ricochet_protocol::frame::{peek_header, FrameEncoder, HEADER_BYTES, KIND_KEY};
use ricochet_protocol::net::{init_tracing, Mode};
use ricochet_protocol::world::{self as wire, write_frame};
use ricochet_server::host::inbox::InboxLimits;
use ricochet_server::host::{self, HostOptions};
use ricochet_server::report::{self, bench, soak, tradeoff};

mod args;

use args::{Cli, Command, RunArgs, SceneTradeoffArgs, SimulateArgs};

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
            accuracy,
            accuracy_cache,
        }) => {
            host::without_thread_caches();
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
            // Without --scenes, the directory of --scene, unless that is the working
            // directory: a scene named bare (or a resumed journal) must not open the
            // server's working directory to `load`.
            let scenes_dir = match (scenes, &scene) {
                (Some(dir), _) => Some(dir),
                (None, None) => None,
                (None, Some(scene)) => {
                    let dir = scene.parent().unwrap_or(Path::new(""));
                    let cwd = std::env::current_dir()
                        .ok()
                        .and_then(|d| d.canonicalize().ok());
                    let here = dir.as_os_str().is_empty()
                        || dir.canonicalize().ok().is_some_and(|d| Some(d) == cwd);
                    (!here).then(|| dir.to_path_buf())
                }
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
                accuracy,
                accuracy_cache,
            })
        }
        Command::Bench {
            steps,
            only,
            out,
            scenes,
            set,
        } => run_bench(steps, only.as_deref(), out.as_deref(), &scenes, set),
        Command::Suite { scenes, only, out } => {
            let progress = indicatif::ProgressBar::new(0).with_style(
                indicatif::ProgressStyle::with_template("{bar:30} {pos}/{len} {msg}")
                    .expect("a valid template"),
            );
            let rows = report::suite::run_all(&scenes, only.as_deref(), &progress)?;
            let targeted = report::suite::run_targeted(
                &scenes,
                only.as_deref(),
                report::suite::TARGET,
                &progress,
            )?;
            progress.finish_and_clear();
            println!("{}", report::suite::to_markdown(&rows));
            println!("{}", report::suite::targeted_markdown(&targeted));
            if let Some(dir) = out {
                let command = std::iter::once("ricochet-server".to_string())
                    .chain(std::env::args().skip(1))
                    .collect::<Vec<_>>()
                    .join(" ");
                report::suite::write(&dir, &rows, &targeted, &command)?;
                eprintln!(
                    "wrote {} and the tables of its README.md",
                    dir.join("suite.csv").display()
                );
            }
            Ok(())
        }
        Command::Tradeoff { out, scene } if !scene.scene.is_empty() => scene_tradeoff(out, scene),
        Command::Tradeoff { out, .. } => {
            std::fs::create_dir_all(&out)
                .with_context(|| format!("cannot create {}", out.display()))?;
            let progress = indicatif::ProgressBar::new(0);
            progress.set_style(
                indicatif::ProgressStyle::with_template(
                    "{prefix}: {bar:40} {pos}/{len} steps, eta {eta}: {msg}",
                )
                .expect("the template is valid"),
            );
            let (cells, references) = tradeoff::run_all(&progress)?;
            progress.finish_and_clear();
            std::fs::write(out.join("tradeoff.csv"), tradeoff::to_csv(&cells))?;
            tradeoff::chart(&cells, &out.join("tradeoff.png"))?;
            for c in &cells {
                println!(
                    "{:<11} {:<34} {:>9.5} ms  error {:>10.3e}  reference {:>9.2e}  energy {:>9.2e}{}{}",
                    c.scene, c.setting, c.ms_per_step, c.error, c.reference_error, c.energy_drift,
                    if c.nan { "  NaN" } else { "" },
                    if tradeoff::on_front(c, &cells) { "  front" } else { "" }
                );
            }
            let readme = out.join("README.md");
            if readme.exists() {
                let references: String = references
                    .iter()
                    .map(|(scene, line)| format!("- {scene}: {line}\n"))
                    .collect();
                report::splice(
                    &readme,
                    "tradeoff",
                    &format!(
                        "Measured by `ricochet-server tradeoff --out {}` on {}.\n\n{}\n{}",
                        out.display(),
                        report::machine(),
                        references,
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
    let mut table = bench::to_markdown(&rows);
    let speedups = bench::speedups(&rows);
    if !speedups.is_empty() {
        table += &format!("\nSpeed-up on 2 threads (same run, same bits):\n\n{speedups}");
    }
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

/// `tradeoff --scene FILE...`: the trade measured on each scene.
fn scene_tradeoff(out: PathBuf, args: SceneTradeoffArgs) -> Result<()> {
    use ricochet_server::report::scene_tradeoff::{index, measure, Candidate, Options, Subject};
    if args.inputs.is_some() && args.scene.len() > 1 {
        anyhow::bail!("--inputs goes with one --scene (the actions are that scene's)");
    }
    let inputs = match &args.inputs {
        Some(p) => read_inputs(p)?,
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
        let path = &subject.path;
        let progress = indicatif::ProgressBar::new(args.steps);
        progress.set_style(
            indicatif::ProgressStyle::with_template(&format!(
                "scene {}/{}: {{bar:40}} {{pos}}/{{len}} steps, eta {{eta}}: {{msg}}",
                k + 1,
                subjects.len()
            ))
            .expect("the template is valid"),
        );
        let report = measure(subject, candidates.clone(), &opts, &progress)?;
        progress.finish_and_clear();
        println!("{}", report.to_text());
        let stem = path
            .file_stem()
            .map_or("scene".into(), |s| s.to_string_lossy().into_owned());
        let (csv, png, md) = (
            out.join(format!("{stem}.csv")),
            out.join(format!("{stem}.png")),
            out.join(format!("{stem}.md")),
        );
        std::fs::write(&csv, report.to_csv())?;
        report.chart(&png)?;
        let mut command = format!(
            "ricochet-server tradeoff --scene {} --steps {}",
            path.display(),
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
        std::fs::write(
            &md,
            format!(
                "# Speed against accuracy: `{}`\n\nGenerated by `{command}` on {}; not edited by hand.\n\n{}\n\n{}\n![time against error]({stem}.png)\n",
                path.display(),
                report::machine(),
                report.reference_line(),
                report.to_markdown(),
            ),
        )?;
        eprintln!(
            "wrote {}, {} and {}",
            csv.display(),
            png.display(),
            md.display()
        );
        pages.push((format!("{stem}.md"), report));
    }
    if pages.len() > 1 {
        let scenes: Vec<String> = args.scene.iter().map(|p| p.display().to_string()).collect();
        let file = out.join("index.md");
        std::fs::write(
            &file,
            format!(
                "# Speed against accuracy, scene by scene\n\nGenerated by `ricochet-server tradeoff --steps {} --out {} --scene {}` on {}; not edited by hand. Each scene's page has its full table and chart.\n\n{}",
                args.steps,
                out.display(),
                scenes.join(" "),
                report::machine(),
                index(&pages),
            ),
        )?;
        eprintln!("wrote {}", file.display());
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
        accuracy,
        accuracy_cache,
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
    if let Some(pick) = ricochet_server::accuracy::for_scene(
        scene_path,
        &text,
        &overrides,
        accuracy,
        accuracy_cache.as_deref(),
    )? {
        eprintln!("{}", pick.reason());
        overrides = pick
            .candidate
            .overrides
            .iter()
            .chain(&overrides)
            .cloned()
            .collect();
    }
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
