//! Bytes on the wire: shipped scenes run headless, every frame encoded exactly as `run`
//! sends it (`ricochet-lab wire`, docs/network.md; `ricochet-server simulate --wire-stats`
//! for one scene).
//!
//! In: scenes, a number of steps, the key-frame interval. Out: per scene, the bytes of
//! the frames over the whole run (key frames included) against the bodies and particles
//! they carry, and the bandwidth a viewer needs at 60 frames a second.

use std::path::Path;

use anyhow::{Context, Result};
use ricochet_engine::scene;
use ricochet_server::wire::stats::WireStats;

/// A scene of the report: its file under the scenes directory, what moves in it, and the
/// goal its figure is held to (issue's wording), if any.
struct Case {
    file: &'static str,
    what: &'static str,
    /// `[world]` settings over the file's (`--set`), named in the table.
    set: &'static [&'static str],
    goal: Option<(f64, &'static str)>,
}

const CASES: &[Case] = &[
    Case {
        file: "bounds.toml",
        what: "5 bodies, nothing moves",
        set: &[],
        goal: None,
    },
    Case {
        file: "impulse.toml",
        what: "hero at rest, 4 patrolling minions",
        set: &[],
        goal: None,
    },
    Case {
        file: "emitters.toml",
        what: "minions, an explosion burning",
        set: &[],
        goal: None,
    },
    Case {
        file: "pyramid-10.toml",
        what: "55 boxes settling",
        set: &[],
        goal: None,
    },
    Case {
        file: "pyramid-100.toml",
        what: "5050 boxes at rest",
        set: &[],
        goal: Some((0.2, "at rest")),
    },
    Case {
        file: "suite/rain.toml",
        what: "1200 bodies falling and piling up",
        set: &[],
        goal: Some((1.0, "falling and piling up")),
    },
    // The same rain with twice the passes: its pile comes to rest (at the default, two
    // passes a sub-step, it keeps breathing: the whole pile bobs up and down together,
    // slower and slower, for the whole run).
    Case {
        file: "suite/rain.toml",
        what: "1200 bodies falling and piling up",
        set: &["impulse_iterations=4"],
        goal: Some((1.0, "falling and piling up")),
    },
    // The rain's rows fall in step (each body as the others of its row, bit for bit), which the
    // coder's contexts make cheap; here every body has a size and place of its own.
    Case {
        file: "wire/rain-irregular.toml",
        what: "1200 bodies of every size, scattered, falling and piling up",
        set: &[],
        goal: Some((1.0, "falling and piling up")),
    },
    Case {
        file: "particles-idle-10k.toml",
        what: "10 000 embers, still after emission",
        set: &[],
        goal: None,
    },
    Case {
        file: "particles-10k.toml",
        what: "10 000 fire particles",
        set: &[],
        goal: None,
    },
    Case {
        file: "particles-100k.toml",
        what: "100 000 fire particles onto a floor",
        set: &[],
        goal: Some((0.5, "particles")),
    },
];

/// One scene's figures.
#[derive(Clone, Debug)]
pub struct Row {
    pub file: &'static str,
    /// `[world]` settings over the file's.
    pub set: &'static [&'static str],
    pub what: &'static str,
    pub goal: Option<(f64, &'static str)>,
    pub stats: WireStats,
}

/// The figures of every scene.
#[derive(Clone, Debug)]
pub struct WireReport {
    pub steps: u64,
    pub keyframe_interval: u64,
    pub rows: Vec<Row>,
}

/// Runs each scene of the report for `steps` steps.
pub fn run(scenes: &Path, steps: u64, keyframe_interval: u64) -> Result<WireReport> {
    let mut rows = Vec::new();
    for case in CASES {
        let path = scenes.join(case.file);
        let set: Vec<String> = case.set.iter().map(|s| s.to_string()).collect();
        let mut world = std::fs::read_to_string(&path)
            .map_err(anyhow::Error::from)
            .and_then(|text| Ok(scene::parse(&text, &path, &set)?))
            .with_context(|| format!("loading {}", path.display()))?;
        let mut stats = WireStats::new(&world, keyframe_interval);
        for _ in 0..steps {
            world.step();
            stats.frame(&world);
        }
        rows.push(Row {
            file: case.file,
            set: case.set,
            what: case.what,
            goal: case.goal,
            stats,
        });
    }
    Ok(WireReport {
        steps,
        keyframe_interval,
        rows,
    })
}

impl WireReport {
    /// The table, with the command that made it.
    pub fn to_markdown(&self) -> String {
        let mut out = format!(
            "Measured by `{}` ({} steps of each scene from its start, a key frame every {} \
             frames, every byte of every frame counted, headers and key frames included; the \
             time to encode a frame from the world and to decode it, mean over every frame and \
             median, on {}):\n\n",
            super::command_line(),
            self.steps,
            self.keyframe_interval,
            super::machine(),
        );
        out.push_str(
            "| scene | what moves | bodies and particles a frame | bytes a frame | key frame | \
             delta frame | bytes per body or particle a frame | at 60 frames/s | encode, us \
             (mean / median) | decode, us | goal |\n\
             |---|---|---:|---:|---:|---:|---:|---:|---:|---:|---|\n",
        );
        for r in &self.rows {
            let s = &r.stats;
            let per = s.bytes_per_thing();
            let goal = match r.goal {
                Some((at_most, what)) => format!(
                    "{what}: at most {at_most} B, {}",
                    if per <= at_most { "met" } else { "**not met**" }
                ),
                None => String::new(),
            };
            let (encode, decode) = (s.encode_us(), s.decode_us());
            out.push_str(&format!(
                "| {}{} | {} | {:.0} | {:.0} | {:.0} | {:.0} | {:.3} | {} | {:.0} / {:.0} | \
                 {:.0} / {:.0} | {goal} |\n",
                r.file,
                r.set
                    .iter()
                    .map(|s| format!(" `--set {s}`"))
                    .collect::<String>(),
                r.what,
                s.things_per_frame(),
                s.bytes_per_frame(),
                s.key_frame_bytes(),
                s.delta_frame_bytes(),
                per,
                rate(s.bytes_per_frame() * 60.0 * 8.0),
                encode.0,
                encode.1,
                decode.0,
                decode.1,
            ));
        }
        out
    }
}

/// Bits per second, in the unit that reads best.
fn rate(bits: f64) -> String {
    if bits >= 1e6 {
        format!("{:.1} Mbit/s", bits / 1e6)
    } else {
        format!("{:.0} kbit/s", bits / 1e3)
    }
}
