//! `ricochet-server`: runs Ricochet worlds.
//!
//! `simulate` runs a scene headless, with no network, and can dump every frame as JSON
//! Lines for other tools.

use std::fs::File;
use std::io::{BufRead, BufReader, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context, Result};
use clap::{Parser, Subcommand};
use ricochet::action::Action;
use ricochet::dump;
use ricochet::scene;
use ricochet::world::World;
use serde::Deserialize;

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

#[derive(Subcommand)]
enum Command {
    /// Run a scene headless for a number of steps, without any network.
    ///
    /// Line 0 of the dump is the state before the first step, line k the state after k
    /// steps: {"frame":k,"t":seconds,"bodies":[{"id","x","y","vx","vy","collided"}],
    /// "particles":[{"x","y","size","color":[r,g,b,a]}],"emitters":count}.
    ///
    /// The same scene, seed and inputs give the same frames, bit for bit.
    Simulate {
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
    },
}

/// One line of an input log.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct TimedAction {
    frame: u64,
    action: Action,
}

fn main() -> Result<()> {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "info".into()),
        )
        .with_writer(std::io::stderr)
        .init();
    match Cli::parse().command {
        Command::Simulate {
            scene,
            steps,
            seed,
            set,
            dump,
            inputs,
        } => simulate(&scene, steps, seed, set, dump.as_deref(), inputs.as_deref()),
    }
}

fn read_inputs(path: &Path) -> Result<Vec<TimedAction>> {
    let file =
        File::open(path).with_context(|| format!("cannot open inputs {}", path.display()))?;
    let mut out: Vec<TimedAction> = Vec::new();
    for (i, line) in BufReader::new(file).lines().enumerate() {
        let line = line.with_context(|| format!("{}:{}", path.display(), i + 1))?;
        if line.trim().is_empty() || line.trim_start().starts_with('#') {
            continue;
        }
        let action: TimedAction = serde_json::from_str(&line)
            .with_context(|| format!("{}:{}: not an input line", path.display(), i + 1))?;
        if let Some(last) = out.last() {
            if action.frame < last.frame {
                bail!(
                    "{}:{}: frame {} comes after frame {}; inputs must be in frame order",
                    path.display(),
                    i + 1,
                    action.frame,
                    last.frame
                );
            }
        }
        out.push(action);
    }
    Ok(out)
}

fn simulate(
    scene_path: &Path,
    steps: u64,
    seed: Option<u64>,
    mut overrides: Vec<String>,
    dump_path: Option<&Path>,
    inputs: Option<&Path>,
) -> Result<()> {
    if let Some(seed) = seed {
        overrides.push(format!("seed={seed}"));
    }
    let text = std::fs::read_to_string(scene_path)
        .with_context(|| format!("cannot read scene {}", scene_path.display()))?;
    let mut world: World = scene::parse(&text, scene_path, &overrides)?;
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
        dump::write_frame(out, &world)?;
    }

    let progress = indicatif::ProgressBar::new(steps);
    progress.set_style(
        indicatif::ProgressStyle::with_template("{bar:40} {pos}/{len} steps {per_sec} eta {eta}")
            .expect("the template is valid"),
    );
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
            dump::write_frame(out, &world)?;
        }
        progress.inc(1);
    }
    progress.finish_and_clear();
    if let Some(mut out) = out {
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
    Ok(())
}
