//! `ricochet-peers`: every scene of the suite of scene kinds (`assets/scenes/suite/`), or
//! of any directory (`--scenes`, such as the families' seeds), in Ricochet, Box2D v3 and
//! rapier2d, alternated in one run, each judged by the scene's criteria; writes the
//! generated `peers.md` and `peers.csv`.
//!
//!     cargo run --release --manifest-path lab/peers/Cargo.toml -- --out docs/bench

mod box2d;
mod engine;
mod families;
mod limit;
mod rapier;
mod run;
mod scene;
mod table;

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use clap::Parser;
use ricochet_engine::dynamics::WorldConfig;

use crate::scene::Scene;
use crate::table::{SceneResult, Setup};

/// Ricochet against Box2D v3 and rapier2d on the suite of scene kinds.
#[derive(Parser, Debug)]
#[command(name = "ricochet-peers")]
struct Args {
    /// Writes DIR/peers.md and DIR/peers.csv.
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
    /// Runs only the scenes whose file name contains TEXT.
    #[arg(long, value_name = "TEXT")]
    only: Option<String>,
    /// Rounds: each runs every engine once on every scene.
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(1..))]
    rounds: u32,
    /// The scenes' directory [default: assets/scenes/suite from the repository root, or
    /// ../../assets/scenes/suite from lab/peers/].
    #[arg(long, value_name = "DIR")]
    scenes: Option<PathBuf>,
    /// Runs Ricochet under these `[world]` overrides, NAME=VALUE (repeatable); Box2D and
    /// rapier follow `sleeping` (e.g. --set sleeping=false: every engine awake).
    #[arg(long = "set", value_name = "NAME=VALUE")]
    set: Vec<String>,
}

fn main() -> Result<()> {
    let args = Args::parse();
    let dir = match &args.scenes {
        Some(d) => d.clone(),
        None => default_scenes()?,
    };
    let rounds = args.rounds as usize;
    eprintln!("measuring this machine's memory bandwidth and peak arithmetic (one core)");
    let limits = limit::Machine::measure();
    let files = scene::scene_files(&dir, args.only.as_deref())?;
    let mut results = Vec::new();
    for path in &files {
        let scene = Scene::load(path, &args.set)?;
        let outcomes = run::rounds(&scene, rounds)?;
        results.push(SceneResult::new(&scene, outcomes));
    }
    let setup = Setup {
        command: command_line(),
        rounds,
        machine: machine(),
        scenes: scenes_named(&dir),
        box2d_version: box2d::version()?,
        boxdd_version: locked_version("boxdd")?,
        rapier_version: locked_version("rapier2d")?,
        ricochet: {
            let mut config = WorldConfig::default();
            for o in &args.set {
                config
                    .set_from_str(o)
                    .with_context(|| format!("--set {o}"))?;
            }
            config
        },
        overrides: args.set.clone(),
        limits,
    };
    table::write(&args.out, &setup, &results)?;
    eprintln!("wrote {}/peers.md and peers.csv", args.out.display());
    Ok(())
}

/// `dir` as the page names it: from the repository's root when it lies inside it.
fn scenes_named(dir: &Path) -> String {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let (Ok(dir), Ok(root)) = (dir.canonicalize(), root.canonicalize()) else {
        return dir.display().to_string();
    };
    match dir.strip_prefix(&root) {
        Ok(inside) => format!("{}/", inside.display()),
        Err(_) => format!("{}/", dir.display()),
    }
}

/// The suite's directory as seen from the working directory: the repository root or
/// `lab/peers/`.
fn default_scenes() -> Result<PathBuf> {
    let candidates = [
        PathBuf::from("assets/scenes/suite"),
        PathBuf::from("../../assets/scenes/suite"),
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/scenes/suite"),
    ];
    candidates
        .iter()
        .find(|d| d.is_dir())
        .cloned()
        .context("no assets/scenes/suite here, in .. or beside the crate: pass --scenes DIR")
}

/// The command that ran this one: the `cargo run` line when cargo started it, else the
/// binary's own.
fn command_line() -> String {
    let args: Vec<String> = std::env::args().skip(1).map(|a| quote(&a)).collect();
    if std::env::var_os("CARGO").is_some() {
        let manifest = Path::new(env!("CARGO_MANIFEST_DIR")).join("Cargo.toml");
        let manifest = std::env::current_dir()
            .ok()
            .and_then(|cwd| manifest.strip_prefix(&cwd).ok().map(Path::to_path_buf))
            .unwrap_or(manifest);
        let profile = if cfg!(debug_assertions) {
            ""
        } else {
            " --release"
        };
        let features = if box2d::DOUBLE_PRECISION {
            " --features double"
        } else {
            ""
        };
        format!(
            "cargo run{profile}{features} --manifest-path {} -- {}",
            manifest.display(),
            args.join(" ")
        )
    } else {
        let me = std::env::args()
            .next()
            .unwrap_or_else(|| "ricochet-peers".into());
        format!("{me} {}", args.join(" "))
    }
}

fn quote(arg: &str) -> String {
    if arg
        .chars()
        .all(|c| c.is_ascii_alphanumeric() || "-_./=".contains(c))
    {
        arg.to_string()
    } else {
        format!("'{}'", arg.replace('\'', r"'\''"))
    }
}

/// "N cores, MODEL": the cores this process may use, and the CPU's name.
fn machine() -> String {
    let system = sysinfo::System::new_with_specifics(
        sysinfo::RefreshKind::nothing().with_cpu(sysinfo::CpuRefreshKind::nothing()),
    );
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let model = system
        .cpus()
        .first()
        .map(|c| c.brand().trim())
        .filter(|b| !b.is_empty())
        .unwrap_or("unknown CPU");
    format!("{cores} cores, {model}")
}

/// The version of `package` in this crate's Cargo.lock.
fn locked_version(package: &str) -> Result<String> {
    const LOCK: &str = include_str!("../Cargo.lock");
    let mut lines = LOCK.lines();
    while let Some(line) = lines.next() {
        if line == format!("name = \"{package}\"") {
            if let Some(v) = lines.next().and_then(|l| l.strip_prefix("version = \"")) {
                return Ok(v.trim_end_matches('"').to_string());
            }
        }
    }
    anyhow::bail!("{package} is not in peers/Cargo.lock")
}
