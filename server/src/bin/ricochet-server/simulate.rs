//! `simulate`: a scene run headless for a number of steps, its frames dumped, its figures
//! and its bytes on the wire reported.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use ricochet_engine::scene;
use ricochet_engine::world::{Limits, World};
use ricochet_server::wire::stats::WireStats;
use ricochet_server::wire::Replay;
use ricochet_server::wire::{self as wire, write_frame};

use crate::args::SimulateArgs;

pub fn simulate(args: SimulateArgs) -> Result<()> {
    let SimulateArgs {
        scene: scene_path,
        steps,
        seed,
        how,
        dump: dump_path,
        inputs,
        stats: stats_path,
        wire_stats,
        keyframe_interval,
        hashes: hashes_path,
        frames: frames_path,
    } = args;
    let limits = how.limits(Limits::default())?;
    let mut overrides = how.set;
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
    if let Some(pick) = ricochet_server::accuracy::apply_to(
        scene_path,
        &text,
        &mut overrides,
        how.accuracy,
        how.accuracy_cache.as_deref(),
    )? {
        eprintln!("{}", pick.reason());
    }
    let mut world: World = scene::parse_with(&text, scene_path, &overrides, &limits)
        .map_err(|e| anyhow::anyhow!("{}", e.report(&text)))?;
    if steps == 0 {
        eprintln!("{}", groups_report(&world));
    }
    let inputs = match inputs {
        Some(p) => ricochet_server::scenes::read_inputs(p)?,
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
    let mut hashes_out = match hashes_path.as_deref() {
        None => None,
        Some(p) => {
            Some(BufWriter::new(File::create(p).with_context(|| {
                format!("cannot create hashes {}", p.display())
            })?))
        }
    };
    let mut hashed = |world: &World| -> Result<()> {
        if let Some(out) = hashes_out.as_mut() {
            let line = ricochet_protocol::command::FrameHash {
                frame: world.frame(),
                hash: ricochet_server::host::travel::hex(world.state_hash()),
            };
            serde_json::to_writer(&mut *out, &line)?;
            out.write_all(b"\n")?;
        }
        Ok(())
    };
    hashed(&world)?;
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
    let mut frames_out = match frames_path.as_deref() {
        None => None,
        Some(p) => {
            let file =
                File::create(p).with_context(|| format!("cannot create frames {}", p.display()))?;
            Some(Payloads::start(
                BufWriter::new(file),
                &world,
                keyframe_interval,
            )?)
        }
    };
    let mut wire = wire_stats.map(|interval| WireStats::new(&world, interval));
    let mut replay = Replay::new(&inputs);
    let mut refused = 0usize;
    let started = Instant::now();
    let mut stepping = Duration::ZERO;
    for _ in 0..steps {
        let frame = world.frame();
        let done = replay.step(&mut world, |input, outcome| match outcome {
            Ok(outcome) if !outcome.ids.is_empty() => {
                tracing::debug!(frame, ids = ?outcome.ids, "action applied")
            }
            Ok(_) => {}
            Err(e) => {
                tracing::warn!(frame, action = ?input.action, "action refused: {e}");
            }
        });
        refused += done.refused;
        stepping += done.step_time;
        if let Some(out) = out.as_mut() {
            write_frame(out, &world)?;
        }
        hashed(&world)?;
        if let Some(out) = stats_out.as_mut() {
            serde_json::to_writer(&mut *out, &wire::stats_record(&world))?;
            out.write_all(b"\n")?;
        }
        if let Some(w) = wire.as_mut() {
            w.frame(&world);
        }
        if let Some(f) = frames_out.as_mut() {
            f.frame(&world)?;
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
    if let Some(mut out) = hashes_out {
        out.flush()?;
    }
    if let Some(f) = frames_out {
        f.out.into_inner()?.sync_all()?;
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
        stats.solver_passes,
        stats.deepest_penetration,
        stats.kinetic_energy,
    );
    if let Some(w) = wire {
        eprintln!("{}", w.summary());
    }
    Ok(())
}

/// `--frames`: the payloads `run` would publish, each as a u32 little-endian length then
/// its bytes: the statics snapshot, then the frame of the start and of every step.
struct Payloads {
    out: BufWriter<File>,
    encoder: ricochet_protocol::frame::FrameEncoder,
}

impl Payloads {
    fn start(out: BufWriter<File>, world: &World, keyframe_interval: u64) -> Result<Self> {
        let mut payloads = Payloads {
            out,
            encoder: ricochet_protocol::frame::FrameEncoder::new(keyframe_interval),
        };
        payloads.put(&wire::statics_snapshot(world))?;
        payloads.frame(world)?;
        Ok(payloads)
    }

    fn frame(&mut self, world: &World) -> Result<()> {
        let bytes = wire::encode_frame(&mut self.encoder, world, 0.0, 0);
        self.put(&bytes)
    }

    fn put(&mut self, bytes: &[u8]) -> Result<()> {
        self.out.write_all(&(bytes.len() as u32).to_le_bytes())?;
        self.out.write_all(bytes)?;
        Ok(())
    }
}

/// What `--steps 0` says of a scene's groups (the scene refuses an interaction naming a
/// group that no body, generator or `groups` entry names): each group with its bodies,
/// and the interactions between them.
fn groups_report(world: &World) -> String {
    let mut counts = vec![0usize; world.group_names().count()];
    for body in world.bodies() {
        counts[body.group as usize] += 1;
    }
    let groups: Vec<String> = world
        .group_names()
        .zip(&counts)
        .map(|(name, n)| match n {
            0 => format!("{name} (no body yet: joined at run time)"),
            1 => format!("{name} (1 body)"),
            n => format!("{name} ({n} bodies)"),
        })
        .collect();
    let side = |s: &ricochet_engine::world::Side| match s {
        ricochet_engine::world::Side::Particles => ricochet_engine::world::PARTICLES.to_string(),
        ricochet_engine::world::Side::Group(g) => world.group_name(*g).to_string(),
    };
    let interactions: Vec<String> = world
        .interactions()
        .iter()
        .map(|i| format!("{}-{}", side(&i.a), side(&i.b)))
        .collect();
    format!(
        "groups checked: every interaction names a group of the scene; {} groups: {}; {} interactions: {}",
        groups.len(),
        groups.join(", "),
        interactions.len(),
        interactions.join(", ")
    )
}
