//! What the viewer draws, as plain data: outlines, colours, points. No Rerun types here, so
//! every rule is tested on its own.
//!
//! The world's y axis points up (gravity is `-y`); Rerun's 2D views point y down, so every
//! position is logged as `(x, -y)` ([`to_view`]).

use ricochet_protocol::frame::{Body, Particle};

/// Segments of a circle outline, as the chapter draws them.
pub const CIRCLE_SEGMENTS: usize = 16;

/// RGBA of a shape flagged collided.
pub const COLLIDED: [u8; 4] = [255, 0, 0, 255];

/// RGBA of the scene's bounds.
pub const BOUNDS: [u8; 4] = [110, 110, 110, 255];

/// RGBA of the 2D view's background (the views's own, whatever the viewer's theme).
pub const BACKGROUND: [u8; 4] = [18, 18, 24, 255];

/// RGBA of an emitter's marker.
pub const EMITTER: [u8; 4] = [255, 255, 255, 255];

/// Group colours, none of them red or orange (those are the collided flag and the fire).
const PALETTE: [[u8; 4]; 8] = [
    [80, 170, 255, 255],  // blue
    [90, 220, 120, 255],  // green
    [200, 130, 255, 255], // violet
    [240, 240, 240, 255], // white
    [60, 220, 220, 255],  // cyan
    [255, 120, 220, 255], // pink
    [170, 200, 90, 255],  // olive
    [150, 150, 255, 255], // lavender
];

/// Colours of several worlds watched at once (their plot lines and names, and every
/// shape when overlaid), none of them red or orange, nor the one world's plot green.
const WORLD_COLORS: [[u8; 4]; 4] = [
    [70, 180, 255, 255],  // blue
    [255, 90, 220, 255],  // magenta
    [250, 230, 70, 255],  // yellow
    [240, 240, 240, 255], // white
];

/// The colour of the `index`th world watched.
pub fn world_color(index: usize) -> [u8; 4] {
    WORLD_COLORS[index % WORLD_COLORS.len()]
}

/// A world point in the view's frame.
pub fn to_view(p: [f64; 2]) -> [f32; 2] {
    [p[0] as f32, -(p[1] as f32)]
}

/// The colour of a group, by its index in the scene's list of groups.
pub fn group_color(group_index: usize) -> [u8; 4] {
    PALETTE[group_index % PALETTE.len()]
}

/// The line strips of one body: a rectangle's outline and its X mark (three strips), or a
/// circle's outline of [`CIRCLE_SEGMENTS`] segments (one strip). Positions are the view's.
pub fn outline(circle: bool, pos: [f64; 2], size: [f32; 2]) -> Vec<Vec<[f32; 2]>> {
    let c = to_view(pos);
    if circle {
        let r = size[0];
        let ring = (0..=CIRCLE_SEGMENTS)
            .map(|k| {
                let a = std::f32::consts::TAU * k as f32 / CIRCLE_SEGMENTS as f32;
                [c[0] + r * a.cos(), c[1] + r * a.sin()]
            })
            .collect();
        return vec![ring];
    }
    let (hx, hy) = (size[0] / 2.0, size[1] / 2.0);
    let (l, r, t, b) = (c[0] - hx, c[0] + hx, c[1] - hy, c[1] + hy);
    vec![
        vec![[l, t], [r, t], [r, b], [l, b], [l, t]],
        vec![[l, t], [r, b]],
        vec![[r, t], [l, b]],
    ]
}

/// Strips and one colour per strip for a set of bodies of one group.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Outlines {
    pub strips: Vec<Vec<[f32; 2]>>,
    pub colors: Vec<[u8; 4]>,
    /// Body ids, one per body (not per strip).
    pub bodies: usize,
    pub collided: usize,
}

impl Outlines {
    pub fn push(&mut self, body: &Body, color: [u8; 4]) {
        let strips = outline(body.circle, body.pos(), body.size);
        let color = if body.collided { COLLIDED } else { color };
        self.colors.extend(std::iter::repeat_n(color, strips.len()));
        self.strips.extend(strips);
        self.bodies += 1;
        self.collided += usize::from(body.collided);
    }
}

/// Bodies grouped by group name, in the scene's group order (groups the scene does not
/// list come after, by name). Returns `(group, outlines)`.
pub fn outlines_by_group<'a>(
    bodies: impl IntoIterator<Item = &'a Body>,
    groups: &[String],
) -> Vec<(String, Outlines)> {
    let mut out: Vec<(String, Outlines)> = Vec::new();
    let mut unlisted: Vec<String> = Vec::new();
    for body in bodies {
        let slot = match out.iter().position(|(g, _)| *g == body.group) {
            Some(i) => i,
            None => {
                out.push((body.group.clone(), Outlines::default()));
                out.len() - 1
            }
        };
        let index = match groups.iter().position(|g| *g == body.group) {
            Some(i) => i,
            None => {
                let k = unlisted
                    .iter()
                    .position(|g| *g == body.group)
                    .unwrap_or_else(|| {
                        unlisted.push(body.group.clone());
                        unlisted.len() - 1
                    });
                groups.len() + k
            }
        };
        out[slot].1.push(body, group_color(index));
    }
    out.sort_by_key(|(g, _)| {
        (
            groups.iter().position(|x| x == g).unwrap_or(usize::MAX),
            g.clone(),
        )
    });
    out
}

/// Share of a channel's excess above 1 that spills into the other two channels, in order
/// of their distance on the colour wheel (red spills into green, then blue).
const SPILL: [f32; 2] = [0.5, 0.25];

/// A particle's colour for display. The chapter blends particles additively, so a channel
/// above 1 (its fire ends at red 3.5 to 4.5) reads as hotter than its hue: the excess
/// spills into the neighbouring channels, so an oversaturated red walks through orange and
/// yellow toward white, as overlapping additive sprites do. Alpha is kept.
pub fn display_color(c: [f32; 4]) -> [u8; 4] {
    let finite = |v: f32| if v.is_finite() { v } else { 0.0 };
    let rgb = [finite(c[0]), finite(c[1]), finite(c[2])];
    let mut out = rgb;
    for (i, v) in rgb.iter().enumerate() {
        let excess = (v - 1.0).max(0.0);
        out[(i + 1) % 3] += SPILL[0] * excess;
        out[(i + 2) % 3] += SPILL[1] * excess;
    }
    let q = |v: f32| (v.clamp(0.0, 1.0) * 255.0).round() as u8;
    [q(out[0]), q(out[1]), q(out[2]), q(finite(c[3]))]
}

/// Particles as points: view positions, colours and radii (half the particle's size, in
/// world units), at `frame`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Points {
    pub positions: Vec<[f32; 2]>,
    pub colors: Vec<[u8; 4]>,
    pub radii: Vec<f32>,
}

pub fn particle_points(particles: &[Particle], frame: u64) -> Points {
    let mut p = Points {
        positions: Vec::with_capacity(particles.len()),
        colors: Vec::with_capacity(particles.len()),
        radii: Vec::with_capacity(particles.len()),
    };
    for particle in particles {
        let [x, y] = particle.pos();
        p.positions.push([x, -y]);
        p.colors.push(display_color(particle.color_at(frame)));
        p.radii
            .push((particle.size_at(frame) * 0.5).abs().max(0.05));
    }
    p
}

/// The bounds' outline in the view's frame.
pub fn bounds_outline(bounds: [[f64; 2]; 2]) -> Vec<[f32; 2]> {
    let [lo, hi] = bounds;
    let (a, b) = (to_view(lo), to_view(hi));
    vec![
        [a[0], a[1]],
        [b[0], a[1]],
        [b[0], b[1]],
        [a[0], b[1]],
        [a[0], a[1]],
    ]
}

/// The view's visible range for the bounds, with a margin of 4% on every side:
/// `([x_min, x_max], [y_min, y_max])` in the view's frame.
pub fn camera(bounds: [[f64; 2]; 2]) -> ([f64; 2], [f64; 2]) {
    let [lo, hi] = bounds;
    let mx = (hi[0] - lo[0]).abs() * 0.04;
    let my = (hi[1] - lo[1]).abs() * 0.04;
    ([lo[0] - mx, hi[0] + mx], [-hi[1] - my, -lo[1] + my])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn body(group: &str, circle: bool, pos: [f64; 2], size: [f32; 2], collided: bool) -> Body {
        let q = |v: f64| (v / ricochet_protocol::frame::FINE).round() as i64;
        Body {
            key: 0,
            id: "b".into(),
            group: group.into(),
            circle,
            size,
            p: [q(pos[0]), q(pos[1])],
            d: [0, 0],
            dt: 0.0,
            collided,
        }
    }

    #[test]
    fn a_rectangle_is_an_outline_and_an_x_through_its_centre() {
        let strips = outline(false, [10.0, 20.0], [4.0, 2.0]);
        assert_eq!(strips.len(), 3);
        assert_eq!(
            strips[0],
            vec![
                [8.0, -21.0],
                [12.0, -21.0],
                [12.0, -19.0],
                [8.0, -19.0],
                [8.0, -21.0]
            ]
        );
        // The two diagonals cross at the centre (10, -20).
        for d in &strips[1..] {
            let mid = [(d[0][0] + d[1][0]) / 2.0, (d[0][1] + d[1][1]) / 2.0];
            assert_eq!(mid, [10.0, -20.0]);
        }
    }

    #[test]
    fn a_circle_is_sixteen_segments_on_its_radius() {
        let strips = outline(true, [1.0, -2.0], [3.0, 3.0]);
        assert_eq!(strips.len(), 1);
        let ring = &strips[0];
        assert_eq!(ring.len(), CIRCLE_SEGMENTS + 1);
        for p in ring {
            let d = ((p[0] - 1.0).powi(2) + (p[1] - 2.0).powi(2)).sqrt();
            assert!((d - 3.0).abs() < 1e-5, "{d}");
        }
        assert!((ring[0][0] - ring[16][0]).abs() < 1e-5 && (ring[0][1] - ring[16][1]).abs() < 1e-5);
    }

    #[test]
    fn collided_bodies_are_red_and_others_take_their_groups_colour() {
        let groups = vec!["platforms".to_string(), "hero".to_string()];
        let bodies = [
            body("hero", false, [0.0, 0.0], [1.0, 1.0], true),
            body("platforms", false, [5.0, 0.0], [1.0, 1.0], false),
            body("minions", true, [9.0, 0.0], [1.0, 1.0], false),
        ];
        let by = outlines_by_group(&bodies, &groups);
        let names: Vec<&str> = by.iter().map(|(g, _)| g.as_str()).collect();
        assert_eq!(names, ["platforms", "hero", "minions"]);
        assert!(by[1].1.colors.iter().all(|c| *c == COLLIDED));
        assert_eq!(by[1].1.collided, 1);
        assert!(by[0].1.colors.iter().all(|c| *c == group_color(0)));
        assert_eq!(by[0].1.colors.len(), 3);
        assert_eq!(by[2].1.colors, vec![group_color(2)]);
        // No group colour can be mistaken for the collided flag.
        for i in 0..PALETTE.len() {
            let c = group_color(i);
            assert!(!(c[0] > 200 && c[1] < 100 && c[2] < 100), "{c:?}");
        }
    }

    #[test]
    fn oversaturated_colours_turn_bright_and_keep_their_alpha() {
        assert_eq!(display_color([0.5, 0.25, 0.0, 1.0]), [128, 64, 0, 255]);
        // Red at 1.5: the half above 1 spills a half into green, a quarter into blue.
        assert_eq!(display_color([1.5, 0.25, 0.0, 0.5]), [255, 128, 32, 128]);
        // The fire's final colour is white hot.
        assert_eq!(display_color([4.0, 0.45, 0.35, 0.6])[..3], [255, 255, 255]);
        // Not a number shows as nothing; green above 1 spills into blue, then red.
        assert_eq!(display_color([f32::NAN, 2.0, -1.0, 7.0]), [64, 255, 0, 255]);
    }

    #[test]
    fn the_camera_holds_the_bounds_with_y_flipped() {
        let (x, y) = camera([[0.0, 0.0], [200.0, 112.5]]);
        assert!(x[0] < 0.0 && x[1] > 200.0);
        assert!(y[0] < -112.5 && y[1] > 0.0);
        let b = bounds_outline([[0.0, 0.0], [200.0, 112.5]]);
        assert_eq!(b[2], [200.0, -112.5]);
    }
}

/// The viewer's timelines across scene loads and resets. The server's frame numbers and
/// world time restart at 0 with every new scene; logged as they are, a new run would land
/// under the old one's later frames and both would show at once. So each restart shifts
/// the new run to just after the last frame logged: the timelines keep increasing for the
/// whole session, and within one run they step exactly as the server's do.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Timeline {
    frame_offset: u64,
    time_offset: f64,
    last: Option<(u64, f64)>,
    /// The server's (frame, time) last mapped.
    last_raw: Option<(u64, f64)>,
}

impl Timeline {
    /// Maps a server frame and time to the timelines; `restarted` says a new run began.
    pub fn map(&mut self, frame: u64, time: f64, dt: f64) -> (u64, f64, bool) {
        // Frame numbers and times come off the wire: the arithmetic saturates and a time
        // that is not a finite number counts as 0, so no payload can overflow it.
        let time = if time.is_finite() { time } else { 0.0 };
        let restarted = self.last_raw.is_some_and(|(f, _)| frame < f);
        if restarted {
            let (last_frame, last_time) = self.last.expect("a frame was mapped");
            self.frame_offset = last_frame.saturating_add(1).saturating_sub(frame);
            self.time_offset = last_time + dt - time;
            if !self.time_offset.is_finite() {
                self.time_offset = 0.0;
            }
        }
        self.last_raw = Some((frame, time));
        let mapped = (
            self.frame_of(frame),
            Some(time + self.time_offset)
                .filter(|t| t.is_finite())
                .unwrap_or(0.0),
        );
        self.last = Some(mapped);
        (mapped.0, mapped.1, restarted)
    }

    /// Maps a frame of the current run that may come before the last mapped (a step
    /// between two frames of a reduced-rate stream, drawn after the newer one arrived):
    /// never a new run.
    pub fn within(&self, frame: u64, time: f64) -> (u64, f64) {
        let time = time + self.time_offset;
        (
            self.frame_of(frame),
            if time.is_finite() { time } else { 0.0 },
        )
    }

    /// The timeline frame and time last mapped.
    pub fn last(&self) -> Option<(u64, f64)> {
        self.last
    }

    /// The timeline frame of a server frame of the current run (for events), at most
    /// `i64::MAX` (what Rerun's sequence timelines hold).
    pub fn frame_of(&self, frame: u64) -> u64 {
        frame.saturating_add(self.frame_offset).min(i64::MAX as u64)
    }
}

#[cfg(test)]
mod timeline_tests {
    use super::Timeline;

    #[test]
    fn a_restarted_run_continues_after_the_last_frame_logged() {
        let mut t = Timeline::default();
        assert_eq!(t.map(0, 0.0, 0.5), (0, 0.0, false));
        assert_eq!(t.map(7, 3.5, 0.5), (7, 3.5, false));
        // A load: the server starts again at frame 0.
        assert_eq!(t.map(0, 0.0, 0.5), (8, 4.0, true));
        assert_eq!(t.map(1, 0.5, 0.5), (9, 4.5, false));
        assert_eq!(t.frame_of(3), 11);
        // A reset right away, then a late join's key frame further on.
        assert_eq!(t.map(0, 0.0, 0.5), (10, 5.0, true));
        assert_eq!(t.map(5, 2.5, 0.5), (15, 7.5, false));
    }

    #[test]
    fn hostile_frame_numbers_and_times_saturate() {
        let mut t = Timeline::default();
        assert_eq!(
            t.map(u64::MAX, f64::NAN, 0.5),
            (i64::MAX as u64, 0.0, false)
        );
        assert!(t.map(3, f64::INFINITY, 0.5).2, "a lower frame is a restart");
        let (frame, time, _) = t.map(u64::MAX - 1, 1e308, f64::MAX);
        assert!(frame <= i64::MAX as u64 && time.is_finite());
        assert_eq!(t.frame_of(u64::MAX), i64::MAX as u64);
    }
}
