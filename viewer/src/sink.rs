//! Turns a world's decoded state into Rerun log calls: one batched archetype per group,
//! one for all particles, one for the emitters, a scalar per figure.

use std::collections::BTreeSet;

use anyhow::Result;
use re_sdk::RecordingStream;
use re_sdk_types::archetypes::{Clear, LineStrips2D, Points2D, Scalars, SeriesLines, TextLog};
use re_sdk_types::components::{Color, Radius, TextLogLevel};
use ricochet_protocol::command::{Event, WorldInfo};
use ricochet_protocol::frame::{Body, FrameDecoder, FrameStats};

use crate::blueprint::{self, PLOTS};
use crate::draw;

/// Outline width, in UI points (constant on screen whatever the zoom).
const LINE_RADIUS: f32 = 0.75;

/// Each plot's line colour: distinct from the world's colours, so a test can find the plots.
pub const PLOT_COLOR: [u8; 4] = [0, 255, 0, 255];

/// What the viewer has logged, to log only what changed.
pub struct WorldSink {
    rec: RecordingStream,
    app_id: &'static str,
    info: Option<WorldInfo>,
    static_groups: BTreeSet<String>,
    dynamic_groups: BTreeSet<String>,
    had_particles: bool,
    had_emitters: bool,
    timeline: draw::Timeline,
    pub frames_drawn: u64,
}

impl WorldSink {
    pub fn new(rec: RecordingStream, app_id: &'static str) -> Result<Self> {
        for (path, title) in PLOTS {
            rec.log_static(
                format!("stats/{path}"),
                &SeriesLines::new()
                    .with_colors([Color::from_unmultiplied_rgba(
                        PLOT_COLOR[0],
                        PLOT_COLOR[1],
                        PLOT_COLOR[2],
                        PLOT_COLOR[3],
                    )])
                    .with_names([title])
                    .with_widths([2.0]),
            )?;
        }
        Ok(WorldSink {
            rec,
            app_id,
            info: None,
            static_groups: BTreeSet::new(),
            dynamic_groups: BTreeSet::new(),
            had_particles: false,
            had_emitters: false,
            timeline: draw::Timeline::default(),
            frames_drawn: 0,
        })
    }

    pub fn recording(&self) -> &RecordingStream {
        &self.rec
    }

    /// A new scene (or the first): the layout and the bounds, as static data.
    pub fn set_info(&mut self, info: WorldInfo) -> Result<()> {
        if self.info.as_ref() == Some(&info) {
            return Ok(());
        }
        let relayout = self
            .info
            .as_ref()
            .is_none_or(|old| old.bounds != info.bounds || old.scene != info.scene);
        if relayout {
            blueprint::send(&self.rec, self.app_id, info.bounds, &info.scene)?;
        }
        self.rec.log_static(
            "world/bounds",
            &LineStrips2D::new([draw::bounds_outline(info.bounds)])
                .with_colors([color(draw::BOUNDS)])
                .with_radii([Radius::new_ui_points(LINE_RADIUS)]),
        )?;
        let new_pick = self
            .info
            .as_ref()
            .is_none_or(|old| old.accuracy != info.accuracy);
        if let (true, Some(why)) = (new_pick, &info.accuracy) {
            // What the server picked for the scene's accuracy target, and why.
            self.rec.log(
                "events",
                &TextLog::new(format!("server setting: {why}")).with_level(TextLogLevel::INFO),
            )?;
        }
        self.info = Some(info);
        Ok(())
    }

    /// Static bodies: logged as static data, once per snapshot (the server re-publishes
    /// the snapshot only when they change).
    pub fn log_statics(&mut self, statics: &[Body]) -> Result<()> {
        let groups = self.info.as_ref().map_or(&[][..], |i| &i.groups[..]);
        log_outlines(
            &self.rec,
            "world/statics",
            true,
            statics,
            groups,
            &mut self.static_groups,
        )
    }

    /// The figures of one frame's step (every frame, drawn or not).
    pub fn log_stats(
        &mut self,
        frame: u64,
        time: f64,
        stats: &FrameStats,
        bytes: usize,
    ) -> Result<()> {
        self.set_time(frame, time)?;
        let values = [
            stats.step_ms as f64,
            stats.contacts as f64,
            stats.solver_passes as f64,
            stats.deepest_penetration as f64,
            stats.energy_change as f64,
            stats.residual as f64,
            stats.kinetic_energy as f64,
            stats.particles as f64,
            bytes as f64,
        ];
        for ((path, _), v) in PLOTS.iter().zip(values) {
            self.rec.log(format!("stats/{path}"), &Scalars::single(v))?;
        }
        Ok(())
    }

    /// Sets the timelines for a server frame; a new run (a load or a reset) clears what
    /// the old one drew.
    fn set_time(&mut self, frame: u64, time: f64) -> Result<()> {
        let dt = self.info.as_ref().map_or(1.0 / 60.0, |i| i.dt);
        let (frame, time, restarted) = self.timeline.map(frame, time, dt);
        if restarted {
            // Chunks of one run only: the batcher would otherwise mix the two. The flush is
            // started, not waited for: a blocking flush waits without bound on a sink whose
            // reader is slow (a software-rendered web page), and the viewer's loop with it.
            self.rec.flush_async()?;
        }
        self.rec.set_time_sequence("frame", frame as i64);
        self.rec.set_duration_secs("sim_time", time);
        if restarted {
            for path in ["world/bodies", "world/particles", "world/emitters"] {
                self.rec.log(path, &Clear::recursive())?;
            }
            self.dynamic_groups.clear();
            self.had_particles = false;
            self.had_emitters = false;
            self.log_note(
                "a new run of the world began (scene loaded or reset)",
                "INFO",
            )?;
        }
        Ok(())
    }

    /// Draws the state the decoder holds now: bodies per group, particles, emitters.
    pub fn draw(&mut self, d: &FrameDecoder) -> Result<()> {
        self.set_time(d.frame, d.time)?;
        self.draw_state(d)
    }

    /// Draws a step between two frames of a reduced-rate stream (`between`), which comes
    /// after the newer frame's figures were logged: of the current run whatever its number.
    pub fn draw_between(&mut self, d: &FrameDecoder) -> Result<()> {
        let (frame, time) = self.timeline.within(d.frame, d.time);
        self.rec.set_time_sequence("frame", frame as i64);
        self.rec.set_duration_secs("sim_time", time);
        self.draw_state(d)
    }

    fn draw_state(&mut self, d: &FrameDecoder) -> Result<()> {
        let groups = self.info.as_ref().map_or(&[][..], |i| &i.groups[..]);
        log_outlines(
            &self.rec,
            "world/bodies",
            false,
            &d.bodies,
            groups,
            &mut self.dynamic_groups,
        )?;

        if !d.particles.is_empty() || self.had_particles {
            let p = draw::particle_points(&d.particles, d.frame);
            self.rec.log(
                "world/particles",
                &Points2D::new(p.positions)
                    .with_colors(p.colors.into_iter().map(color))
                    .with_radii(p.radii),
            )?;
            self.had_particles = !d.particles.is_empty();
        }
        if !d.emitters.is_empty() || self.had_emitters {
            let positions: Vec<[f32; 2]> = d.emitters.iter().map(|e| [e.x, -e.y]).collect();
            let labels: Vec<String> = d
                .emitters
                .iter()
                .map(|e| format!("emitter ({} left)", e.remaining))
                .collect();
            self.rec.log(
                "world/emitters",
                &Points2D::new(positions)
                    .with_colors([color(draw::EMITTER)])
                    .with_radii([Radius::new_ui_points(5.0)])
                    .with_labels(labels),
            )?;
            self.had_emitters = !d.emitters.is_empty();
        }
        self.frames_drawn += 1;
        Ok(())
    }

    /// One handled command, as a line of the text log.
    pub fn log_event(&self, event: &Event) -> Result<()> {
        self.rec
            .set_time_sequence("frame", self.timeline.frame_of(event.frame) as i64);
        let command = event
            .command
            .as_ref()
            .and_then(|c| serde_json::to_string(c).ok())
            .unwrap_or_else(|| "(unparsable command)".into());
        let (text, level) = if event.ok {
            let ids = if event.ids.is_empty() {
                String::new()
            } else {
                format!(" -> {}", event.ids.join(", "))
            };
            (format!("{command}{ids}"), TextLogLevel::INFO)
        } else {
            (
                format!(
                    "refused {command}: {}",
                    event.error.as_deref().unwrap_or("no reason given")
                ),
                TextLogLevel::ERROR,
            )
        };
        self.rec
            .log("events", &TextLog::new(text).with_level(level))?;
        Ok(())
    }

    /// A line of the viewer's own (a resync, dropped frames, a new scene).
    pub fn log_note(&self, text: &str, level: &str) -> Result<()> {
        self.rec
            .log("events", &TextLog::new(text).with_level(level))?;
        Ok(())
    }
}

/// One `LineStrips2D` per group of `bodies` under `root/<group>` (static data or at the
/// current time), and a clear for each group in `logged` that has no body left; `logged`
/// becomes the groups logged now.
fn log_outlines(
    rec: &RecordingStream,
    root: &str,
    as_static: bool,
    bodies: &[Body],
    groups: &[String],
    logged: &mut BTreeSet<String>,
) -> Result<()> {
    let by_group = draw::outlines_by_group(bodies, groups);
    let now: BTreeSet<String> = by_group.iter().map(|(g, _)| g.clone()).collect();
    for gone in logged.difference(&now) {
        rec.log_with_static(format!("{root}/{gone}"), as_static, &Clear::flat())?;
    }
    for (group, o) in by_group {
        rec.log_with_static(
            format!("{root}/{group}"),
            as_static,
            &LineStrips2D::new(o.strips)
                .with_colors(o.colors.into_iter().map(color))
                .with_radii([Radius::new_ui_points(LINE_RADIUS)]),
        )?;
    }
    *logged = now;
    Ok(())
}

fn color(c: [u8; 4]) -> Color {
    Color::from_unmultiplied_rgba(c[0], c[1], c[2], c[3])
}
