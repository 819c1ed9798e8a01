//! Where several worlds go in the one 2D view: side by side, left to right in the order
//! given, with a gap between them (each world's root moved by a transform, so every
//! position logged stays the world's own); or overlaid, each in one colour. And the layout
//! that shows them: one 2D view whose camera holds them all, the drift plots first, then
//! the step's figures with a line per world.

use ricochet_protocol::command::WorldInfo;

use crate::blueprint::{Views, PLOTS};
use crate::draw;
use crate::drift::DRIFT_PLOTS;
use crate::sink::Place;

/// The gap between worlds side by side, as a share of the widest world.
const GAP: f64 = 0.08;

/// How far above its bounds a world's name is written, as a share of its height (clear of
/// a wall along the top), and the room the camera keeps for it.
const LABEL_RISE: f64 = 0.08;

/// The places of `worlds` (name and first info, at least two) and the layout of the view.
pub fn arrange(worlds: &[(String, WorldInfo)], overlay: bool) -> (Vec<Place>, Views) {
    let width = |b: [[f64; 2]; 2]| (b[1][0] - b[0][0]).abs();
    let widest = worlds
        .iter()
        .map(|(_, i)| width(i.bounds))
        .fold(0.0, f64::max);
    let gap = widest * GAP;
    let n = worlds.len();
    let mut places = Vec::with_capacity(n);
    // The left edge of the next world, in the view.
    let mut left = worlds[0].1.bounds[0][0];
    let mut all = worlds[0].1.bounds;
    for (k, (name, info)) in worlds.iter().enumerate() {
        let [lo, hi] = info.bounds;
        let (w, h) = (width(info.bounds), (hi[1] - lo[1]).abs());
        let offset = if overlay { 0.0 } else { left - lo[0] };
        left += w + gap;
        // Names above the bounds: each at its world's left edge, or spread along the top
        // when the worlds lie over each other.
        let label_x = if overlay {
            lo[0] + w * k as f64 / n as f64
        } else {
            lo[0]
        };
        places.push(Place {
            name: Some(name.clone()),
            offset: [offset, 0.0],
            tint: overlay.then(|| draw::world_color(k)),
            color: draw::world_color(k),
            label_at: [label_x, hi[1] + LABEL_RISE * h],
        });
        all = [
            [all[0][0].min(lo[0] + offset), all[0][1].min(lo[1])],
            [
                all[1][0].max(hi[0] + offset),
                all[1][1].max(hi[1] + LABEL_RISE * h),
            ],
        ];
    }
    let names: Vec<&str> = worlds.iter().map(|(n, _)| n.as_str()).collect();
    let joined = names.join(if overlay { " over " } else { " beside " });
    let plots = DRIFT_PLOTS
        .iter()
        .map(|(path, title)| ((*path).to_string(), format!("{title} (vs {})", worlds[0].0)))
        .chain(
            PLOTS
                .iter()
                .map(|(path, title)| (format!("stats/{path}"), (*title).to_string())),
        )
        .collect();
    let views = Views {
        title: format!("{joined} ({})", worlds[0].1.scene),
        bounds: all,
        plots,
    };
    (places, views)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn info(bounds: [[f64; 2]; 2]) -> WorldInfo {
        serde_json::from_value(serde_json::json!({
            "scene": "table.toml",
            "bounds": bounds,
            "groups": [],
            "dt": 1.0 / 60.0,
            "generation": 0,
        }))
        .expect("a world's info")
    }

    #[test]
    fn worlds_side_by_side_do_not_overlap_and_the_camera_holds_them_all() {
        let b = [[10.0, 0.0], [50.0, 20.0]];
        let worlds = [
            ("table".to_string(), info(b)),
            ("fine".to_string(), info(b)),
            ("finer".to_string(), info(b)),
        ];
        let (places, views) = arrange(&worlds, false);
        let offsets: Vec<f64> = places.iter().map(|p| p.offset[0]).collect();
        // 40 wide, a gap of 3.2.
        assert_eq!(offsets, [0.0, 43.2, 86.4]);
        for pair in places.windows(2) {
            assert!(pair[1].offset[0] - pair[0].offset[0] > 40.0);
        }
        assert_eq!(views.bounds, [[10.0, 0.0], [136.4, 21.6]]);
        assert!(places.iter().all(|p| p.tint.is_none()));
        assert_eq!(places[1].root(), "world/fine");
        assert_eq!(
            places[1].stat("kinetic_energy"),
            "stats/kinetic_energy/fine"
        );
        assert_eq!(views.plots[0].0, "drift/body_distance");
        assert_eq!(views.plots.len(), DRIFT_PLOTS.len() + PLOTS.len());
        assert_eq!(views.title, "table beside fine beside finer (table.toml)");
    }

    #[test]
    fn overlaid_worlds_stay_in_place_each_in_its_own_colour() {
        let b = [[0.0, 0.0], [40.0, 20.0]];
        let worlds = [("a".to_string(), info(b)), ("b".to_string(), info(b))];
        let (places, views) = arrange(&worlds, true);
        assert!(places.iter().all(|p| p.offset == [0.0, 0.0]));
        assert_eq!(views.bounds, [[0.0, 0.0], [40.0, 21.6]]);
        let tints: Vec<_> = places.iter().map(|p| p.tint.unwrap()).collect();
        assert_ne!(tints[0], tints[1]);
        // Their names do not sit on each other.
        assert_ne!(places[0].label_at, places[1].label_at);
    }
}
