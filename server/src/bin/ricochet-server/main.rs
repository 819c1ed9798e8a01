//! `ricochet-server`: runs Ricochet worlds.
//!
//! `run` hosts a world on zenoh in real time; `simulate` runs a scene headless, with no
//! network, and can dump every frame as JSON Lines; `router` runs a zenoh router where
//! servers and clients on several hosts meet; `bench`, `suite`, `tradeoff` and `soak`
//! measure (their work and their pages are the report modules'). Each command here reads
//! its flags, calls the library and says what it wrote.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Parser;
use indicatif::{ProgressBar, ProgressStyle};
use ricochet_protocol::net::{init_tracing, Mode};
use ricochet_server::host;
use ricochet_server::report::{self, bench, scene_tradeoff, soak, suite, tradeoff};

mod args;
mod simulate;

use args::{Cli, Command, SceneTradeoffArgs};

fn main() -> Result<()> {
    init_tracing("info");
    match Cli::parse().command {
        Command::Run(args) => {
            host::without_thread_caches();
            host::run(args.host_options()?)
        }
        Command::Simulate(args) => simulate::simulate(args),
        Command::Router { network } => {
            let mut net = network.server();
            net.mode = Some(Mode::Router);
            host::run_router(&net)
        }
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
                bench::write(&dir, &rows, &report::command_line())?;
                eprintln!(
                    "wrote {} and the tables of {}",
                    dir.join("bench.csv").display(),
                    dir.join("README.md").display()
                );
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
                suite::write(&dir, &rows, &targeted, &report::command_line())?;
                eprintln!(
                    "wrote {} and the tables of its README.md",
                    dir.join("suite.csv").display()
                );
            }
            Ok(())
        }
        Command::Tradeoff { out, scene } if !scene.scene.is_empty() => scene_tradeoff(out, scene),
        Command::Tradeoff { out, .. } => {
            let progress = bar("{prefix}: {bar:40} {pos}/{len} steps, eta {eta}: {msg}");
            let (cells, references) = tradeoff::run_all(&progress)?;
            progress.finish_and_clear();
            print!("{}", tradeoff::to_text(&cells));
            let command = format!("ricochet-server tradeoff --out {}", out.display());
            let written = tradeoff::write(&out, &cells, &references, &command)?;
            eprintln!("wrote {}", list(&written));
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
            let report = ricochet_server::report::hostile::run(&scenes, seconds)?;
            print_table(&report.to_markdown(), out.as_deref(), "hostile")
        }
        Command::Wire {
            steps,
            keyframe_interval,
            scenes,
            out,
        } => {
            let report = ricochet_server::report::wire::run(&scenes, steps, keyframe_interval)?;
            print_table(&report.to_markdown(), out.as_deref(), "wire")
        }
        Command::Fanout {
            viewers,
            seconds,
            scenes,
            out,
        } => {
            let report = ricochet_server::report::fanout::run(&scenes, viewers, seconds)?;
            print_table(&report.to_markdown(), out.as_deref(), "fanout")
        }
        Command::Certs { out, hosts, days } => {
            for file in ricochet_server::certs::make(&out, &hosts, days)? {
                eprintln!("wrote {}", file.display());
            }
            Ok(())
        }
    }
}

/// Prints a report's table and, with `out`, writes it between the `name` markers of
/// that page.
fn print_table(table: &str, out: Option<&std::path::Path>, name: &str) -> Result<()> {
    println!("{table}");
    if let Some(out) = out {
        ricochet_server::report::splice(out, name, table)?;
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

/// `tradeoff --scene FILE...`: the trade measured on each scene, a page each, and an
/// index of the pages when there are several.
fn scene_tradeoff(out: PathBuf, args: SceneTradeoffArgs) -> Result<()> {
    use scene_tradeoff::{measure, write_index, Candidate, Options, Subject};
    if args.inputs.is_some() && args.scene.len() > 1 {
        anyhow::bail!("--inputs goes with one --scene (the actions are that scene's)");
    }
    let inputs = match &args.inputs {
        Some(p) => simulate::read_inputs(p)?,
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
            "ricochet-server tradeoff --scene {} --steps {}",
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
            "ricochet-server tradeoff --steps {} --out {} --scene {}",
            args.steps,
            out.display(),
            scenes.join(" ")
        );
        eprintln!("wrote {}", write_index(&out, &pages, &command)?.display());
    }
    Ok(())
}
