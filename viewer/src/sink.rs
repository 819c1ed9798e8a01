//! Turns a world's decoded state into Rerun log calls: one batched archetype per group,
//! one for all particles, one for the emitters, a scalar per figure.
//!
//! Where a world's entities go is its [`Place`]: the only world's under `world/`,
//! `stats/<plot>` and `events`; each of several worlds' under a root of its own
//! (`world/<name>/...`, `stats/<plot>/<name>`, `events/<name>`), moved aside by a
//! transform on its root or drawn in one colour over the others.

use std::collections::BTreeSet;

use anyhow::Result;
use re_sdk::RecordingStream;
use re_sdk_types::archetypes::{
    Clear, LineStrips2D, Points2D, Scalars, SeriesLines, TextLog, Transform3D,
};
use re_sdk_types::components::{Color, Radius, TextLogLevel};
use ricochet_protocol::command::{Event, WorldInfo};
use ricochet_protocol::frame::{Body, FrameDecoder, FrameStats};

use crate::blueprint::{self, Views, PLOTS};
use crate::draw;

/// Outline width, in UI points (constant on screen whatever the zoom).
const LINE_RADIUS: f32 = 0.75;

/// Each plot's line colour: distinct from the world's colours, so a test can find the plots.
pub const PLOT_COLOR: [u8; 4] = [0, 255, 0, 255];

/// Where one world's entities go in the recording, and how its shapes are coloured.
#[derive(Clone, Debug, PartialEq)]
pub struct Place {
    /// The world's name when several are drawn; `None` for the only one, whose entity
    /// paths are those of a viewer of one world (`world/...`, `stats/<plot>`, `events`).
    pub name: Option<String>,
    /// How far the world's root is moved in the 2D view, world units (side by side).
    pub offset: [f64; 2],
    /// One colour for every shape of the world instead of its groups' (overlaid worlds).
    pub tint: Option<[u8; 4]>,
    /// The colour of the world's lines in the plots, and of its name.
    pub color: [u8; 4],
    /// Where the world's name is written, in its own coordinates (several worlds).
    pub label_at: [f64; 2],
}

impl Place {
    /// The only world watched: today's paths, the groups' colours, the plots' green.
    pub fn only() -> Place {
        Place {
            name: None,
            offset: [0.0, 0.0],
            tint: None,
            color: PLOT_COLOR,
            label_at: [0.0, 0.0],
        }
    }

    /// The root of the world's shapes: `world` or `world/<name>`.
    pub fn root(&self) -> String {
        match &self.name {
            None => "world".into(),
            Some(name) => format!("world/{name}"),
        }
    }

    /// The series of one of the step's figures: `stats/<plot>` or `stats/<plot>/<name>`.
    pub fn stat(&self, plot: &str) -> String {
        match &self.name {
            None => format!("stats/{plot}"),
            Some(name) => format!("stats/{plot}/{name}"),
        }
    }

    /// The world's text log: `events` or `events/<name>`.
    pub fn events(&self) -> String {
        match &self.name {
            None => "events".into(),
            Some(name) => format!("events/{name}"),
        }
    }
}

/// What the viewer has logged, to log only what changed.
pub struct WorldSink {
    rec: RecordingStream,
    app_id: &'static str,
    place: Place,
    info: Option<WorldInfo>,
    static_groups: BTreeSet<String>,
    dynamic_groups: BTreeSet<String>,
    had_particles: bool,
    had_emitters: bool,
    timeline: draw::Timeline,
    pub frames_drawn: u64,
}

impl WorldSink {
    /// A sink for the world at `place`: its plots' lines are logged now; the layout is
    /// sent with the world's info when it is the only world (several worlds share one,
    /// sent by the caller).
    pub fn new(rec: RecordingStream, app_id: &'static str, place: Place) -> Result<Self> {
        for (path, title) in PLOTS {
            let name = match &place.name {
                None => title.to_string(),
                Some(world) => world.clone(),
            };
            rec.log_static(
                place.stat(path),
                &SeriesLines::new()
                    .with_colors([color(place.color)])
                    .with_names([name])
                    .with_widths([2.0]),
            )?;
        }
        if let Some(name) = &place.name {
            let [dx, dy] = place.offset;
            rec.log_static(
                place.root(),
                &Transform3D::from_translation([dx as f32, -dy as f32, 0.0]),
            )?;
            rec.log_static(
                format!("{}/name", place.root()),
                &Points2D::new([draw::to_view(place.label_at)])
                    .with_colors([color(place.color)])
                    .with_radii([Radius::new_ui_points(3.0)])
                    .with_labels([name.as_str()]),
            )?;
        }
        Ok(WorldSink {
            rec,
            app_id,
            place,
            info: None,
            static_groups: BTreeSet::new(),
            dynamic_groups: BTreeSet::new(),
            had_particles: false,
            had_emitters: false,
            timeline: draw::Timeline::default(),
            frames_drawn: 0,
        })
    }

    /// The timeline frame and time the last frame's figures were logged at.
    pub fn logged_at(&self) -> Option<(u64, f64)> {
        self.timeline.last()
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
        if relayout && self.place.name.is_none() {
            blueprint::send(
                &self.rec,
                self.app_id,
                &Views::one_world(info.bounds, &info.scene),
            )?;
        }
        self.rec.log_static(
            format!("{}/bounds", self.place.root()),
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
                self.place.events(),
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
            &format!("{}/statics", self.place.root()),
            true,
            statics,
            groups,
            self.place.tint,
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
            self.rec.log(self.place.stat(path), &Scalars::single(v))?;
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
            let root = self.place.root();
            for leaf in ["bodies", "particles", "emitters"] {
                self.rec
                    .log(format!("{root}/{leaf}"), &Clear::recursive())?;
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
        let root = self.place.root();
        log_outlines(
            &self.rec,
            &format!("{root}/bodies"),
            false,
            &d.bodies,
            groups,
            self.place.tint,
            &mut self.dynamic_groups,
        )?;

        if !d.particles.is_empty() || self.had_particles {
            let p = draw::particle_points(&d.particles, d.frame);
            self.rec.log(
                format!("{root}/particles"),
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
                format!("{root}/emitters"),
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
            .log(self.place.events(), &TextLog::new(text).with_level(level))?;
        Ok(())
    }

    /// A line of the viewer's own (a resync, dropped frames, a new scene).
    pub fn log_note(&self, text: &str, level: &str) -> Result<()> {
        self.rec
            .log(self.place.events(), &TextLog::new(text).with_level(level))?;
        Ok(())
    }
}

/// One `LineStrips2D` per group of `bodies` under `root/<group>` (static data or at the
/// current time), all in `tint` if given, and a clear for each group in `logged` that has
/// no body left; `logged` becomes the groups logged now.
fn log_outlines(
    rec: &RecordingStream,
    root: &str,
    as_static: bool,
    bodies: &[Body],
    groups: &[String],
    tint: Option<[u8; 4]>,
    logged: &mut BTreeSet<String>,
) -> Result<()> {
    let by_group = draw::outlines_by_group(bodies, groups);
    let now: BTreeSet<String> = by_group.iter().map(|(g, _)| g.clone()).collect();
    for gone in logged.difference(&now) {
        rec.log_with_static(format!("{root}/{gone}"), as_static, &Clear::flat())?;
    }
    for (group, mut o) in by_group {
        if let Some(tint) = tint {
            // Overlaid worlds are told apart by colour alone: the collided flag's red
            // would hide whose body it is.
            o.colors.fill(tint);
        }
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
