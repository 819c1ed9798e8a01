//! The families' generators: each draws one scene from its ranges and writes it, with the
//! `[criteria]` its invariants state, as a scene file's text. Here the scene writer and
//! the families of bodies at rest, falling or struck; bodies in flight or sliding are in
//! [`super::motion`].

use std::fmt::Write as _;

use rand::Rng;
use rand_chacha::ChaCha8Rng;

/// A scene being written.
#[derive(Default)]
pub(super) struct Scene {
    pub(super) note: String,
    pub(super) text: String,
}

impl Scene {
    pub(super) fn line(&mut self, line: impl AsRef<str>) {
        self.text.push_str(line.as_ref());
        self.text.push('\n');
    }

    #[allow(clippy::too_many_arguments)]
    pub(super) fn rect(
        &mut self,
        id: &str,
        group: &str,
        size: [f64; 2],
        pos: [f64; 2],
        mass: f64,
        friction: f64,
        restitution: f64,
    ) {
        self.moving_rect(
            id,
            group,
            size,
            pos,
            [0.0, 0.0],
            mass,
            friction,
            restitution,
        );
    }

    /// A box moving at `vel` (written only when it moves).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn moving_rect(
        &mut self,
        id: &str,
        group: &str,
        size: [f64; 2],
        pos: [f64; 2],
        vel: [f64; 2],
        mass: f64,
        friction: f64,
        restitution: f64,
    ) {
        let vel = if vel == [0.0, 0.0] {
            String::new()
        } else {
            format!("vel = [{}, {}]\n", n(vel[0]), n(vel[1]))
        };
        let _ = writeln!(
            self.text,
            "[[body]]\nid = \"{id}\"\ngroup = \"{group}\"\nshape = \"rect\"\nsize = [{}, {}]\npos = [{}, {}]\n{vel}mass = {}\nfriction = {}\nrestitution = {}\n",
            n(size[0]), n(size[1]), n(pos[0]), n(pos[1]), n(mass), n(friction), n(restitution)
        );
    }

    #[allow(clippy::too_many_arguments)]
    pub(super) fn circle(
        &mut self,
        id: &str,
        group: &str,
        radius: f64,
        pos: [f64; 2],
        vel: [f64; 2],
        mass: f64,
        friction: f64,
        restitution: f64,
    ) {
        let _ = writeln!(
            self.text,
            "[[body]]\nid = \"{id}\"\ngroup = \"{group}\"\nshape = \"circle\"\nradius = {}\npos = [{}, {}]\nvel = [{}, {}]\nmass = {}\nfriction = {}\nrestitution = {}\n",
            n(radius), n(pos[0]), n(pos[1]), n(vel[0]), n(vel[1]), n(mass), n(friction), n(restitution)
        );
    }

    /// A closed box of four static walls `t` thick around `[lo, hi]` (its inside).
    pub(super) fn walls(&mut self, lo: [f64; 2], hi: [f64; 2], t: f64, group: &str) {
        let (w, h) = (hi[0] - lo[0], hi[1] - lo[1]);
        let (cx, cy) = ((lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0);
        self.rect(
            "wall/bottom",
            group,
            [w + 2.0 * t, t],
            [cx, lo[1] - t / 2.0],
            0.0,
            0.5,
            0.0,
        );
        self.rect(
            "wall/top",
            group,
            [w + 2.0 * t, t],
            [cx, hi[1] + t / 2.0],
            0.0,
            0.5,
            0.0,
        );
        self.rect(
            "wall/left",
            group,
            [t, h],
            [lo[0] - t / 2.0, cy],
            0.0,
            0.5,
            0.0,
        );
        self.rect(
            "wall/right",
            group,
            [t, h],
            [hi[0] + t / 2.0, cy],
            0.0,
            0.5,
            0.0,
        );
    }

    pub(super) fn interact(&mut self, a: &str, b: &str) {
        let _ = writeln!(self.text, "[[interact]]\na = \"{a}\"\nb = \"{b}\"\n");
    }
}

/// A number as TOML writes it (always with a decimal point or exponent).
fn n(v: f64) -> String {
    let s = format!("{v:?}");
    if s.contains(['.', 'e', 'E']) || s.contains("inf") || s.contains("NaN") {
        s
    } else {
        format!("{s}.0")
    }
}

/// A limit, to four significant digits.
pub(super) fn limit(v: f64) -> String {
    n(format!("{v:.3e}").parse().expect("a number"))
}

/// Log-uniform in [lo, hi].
pub(super) fn log_uniform(rng: &mut ChaCha8Rng, lo: f64, hi: f64) -> f64 {
    (rng.random_range(lo.ln()..=hi.ln())).exp()
}

pub(super) const STEPS_DT: [(f64, &str); 5] = [
    (1.0 / 240.0, "1/240"),
    (1.0 / 120.0, "1/120"),
    (1.0 / 60.0, "1/60"),
    (1.0 / 30.0, "1/30"),
    (1.0 / 15.0, "1/15"),
];

pub(super) fn world(s: &mut Scene, dt: f64, gravity: [f64; 2], bounds: ([f64; 2], [f64; 2])) {
    s.line("[world]");
    s.line(format!("dt = {}", n(dt)));
    s.line(format!("gravity = [{}, {}]", n(gravity[0]), n(gravity[1])));
    s.line("mass_scaled_acceleration = false");
    let (lo, hi) = bounds;
    s.line(format!(
        "bounds = [[{}, {}], [{}, {}]]\n",
        n(lo[0]),
        n(lo[1]),
        n(hi[0]),
        n(hi[1])
    ));
}

pub(super) fn criteria(s: &mut Scene, lines: &[String]) {
    s.line("[criteria]");
    for l in lines {
        s.line(l);
    }
    s.line("");
}

pub(super) fn piles(rng: &mut ChaCha8Rng, s: &mut Scene) {
    let size = log_uniform(rng, 0.05, 20.0);
    let aspect = log_uniform(rng, 0.25, 4.0);
    let (w, h) = (size, size * aspect);
    let gap = rng.random_range(0.0..=0.01) * w.min(h);
    let friction = rng.random_range(0.1..=1.0);
    let mass = log_uniform(rng, 0.01, 1000.0);
    let far = if rng.random_bool(0.5) {
        log_uniform(rng, 1.0, 1e6)
    } else {
        0.0
    };
    let (dt, dt_name) = STEPS_DT[rng.random_range(0..STEPS_DT.len())];
    let kind = rng.random_range(0..3);
    let levels: u32 = match kind {
        0 => rng.random_range(2..=40),
        1 => rng.random_range(2..=100),
        _ => rng.random_range(2..=20),
    };
    let width = match kind {
        0 => levels as f64 * (w + gap),
        1 => w,
        _ => 10.0 * (w + gap),
    };
    let origin = [far, far];
    let ground = [width * 3.0 + 4.0 * w, h.max(w)];
    let top = origin[1] + levels as f64 * (h + gap) + h;
    world(
        s,
        dt,
        [0.0, -10.0],
        (
            [origin[0] - ground[0], origin[1] - 2.0 * ground[1]],
            [origin[0] + ground[0], top + h],
        ),
    );
    s.rect(
        "ground",
        "ground",
        ground,
        [origin[0], origin[1] - ground[1] / 2.0],
        0.0,
        friction,
        0.0,
    );
    let mut count = 0;
    for level in 0..levels {
        let y = origin[1] + h / 2.0 + gap + level as f64 * (h + gap);
        let row = match kind {
            0 => levels - level,
            1 => 1,
            _ => 10,
        };
        // A wall's rows are laid in a running bond, each offset by half a box.
        let offset = if kind == 2 && level % 2 == 1 {
            (w + gap) / 2.0
        } else {
            0.0
        };
        for k in 0..row {
            let x =
                origin[0] - (row as f64 - 1.0) * (w + gap) / 2.0 + k as f64 * (w + gap) + offset;
            s.rect(
                &format!("box/{count}"),
                "boxes",
                [w, h],
                [x, y],
                mass,
                friction,
                0.0,
            );
            count += 1;
        }
    }
    s.interact("boxes", "boxes");
    s.interact("boxes", "ground");
    let steps = (4.0 / dt).round() as u64;
    // The top box settles by the gaps below it: that much drift is the scene's, not the
    // engine's.
    let settle = levels as f64 * gap / w.min(h);
    criteria(
        s,
        &[
            format!("steps = {steps}"),
            format!("drift = {}", limit(0.02 + settle)),
            "final_overlap = 0.01".into(),
            format!("final_speed = {}", limit(0.05 * w.min(h))),
        ],
    );
    s.note = format!(
        "{} of {levels} levels, boxes {w:.3} x {h:.3}, gap {gap:.2e}, friction {friction:.2}, mass {mass:.3}, {far:.3e} from the origin, dt {dt_name}",
        ["a pyramid", "a column", "a wall"][kind],
    );
}

pub(super) fn heavy_on_light(rng: &mut ChaCha8Rng, s: &mut Scene) {
    let ratio = log_uniform(rng, 10.0, 1e5);
    let light = 1.0;
    world(s, 1.0 / 60.0, [0.0, -10.0], ([-30.0, -2.0], [30.0, 40.0]));
    s.rect("ground", "ground", [60.0, 2.0], [0.0, -1.0], 0.0, 0.6, 0.0);
    if rng.random_bool(0.5) {
        let size = rng.random_range(0.5..=2.0);
        s.rect(
            "light",
            "boxes",
            [size, size],
            [0.0, size / 2.0],
            light,
            0.6,
            0.0,
        );
        let big = rng.random_range(1.0..=4.0) * size;
        s.rect(
            "heavy",
            "boxes",
            [big, big],
            [0.0, size + big / 2.0],
            light * ratio,
            0.6,
            0.0,
        );
        s.note = format!("a box of {big:.2} and mass ratio {ratio:.3e} on a box of {size:.2}");
    } else {
        let r: f64 = rng.random_range(0.15..=0.4);
        let cols = (16.0 / (2.0 * r)).floor() as usize;
        let rows = rng.random_range(3..=8);
        s.rect(
            "bin/left",
            "ground",
            [1.0, 30.0],
            [-8.5, 15.0],
            0.0,
            0.6,
            0.0,
        );
        s.rect(
            "bin/right",
            "ground",
            [1.0, 30.0],
            [8.5, 15.0],
            0.0,
            0.6,
            0.0,
        );
        let mut k = 0;
        for row in 0..rows {
            for col in 0..cols {
                let x = -8.0 + r + col as f64 * 2.0 * r + if row % 2 == 1 { r * 0.5 } else { 0.0 };
                if x + r > 8.0 {
                    continue;
                }
                let y = r + row as f64 * 2.0 * r * 0.9 + row as f64 * 0.01;
                s.circle(
                    &format!("grain/{k}"),
                    "grains",
                    r,
                    [x, y + 0.001],
                    [0.0, 0.0],
                    light * 0.1,
                    0.4,
                    0.0,
                );
                k += 1;
            }
        }
        let big: f64 = rng.random_range(2.0..=5.0);
        let count = rng.random_range(1..=3);
        let bed = rows as f64 * 2.0 * r;
        for b in 0..count {
            let x = -8.0 + (b as f64 + 0.5) * 16.0 / count as f64;
            s.rect(
                &format!("heavy/{b}"),
                "boxes",
                [big.min(16.0 / count as f64 - 0.1), big],
                [x, bed + big + 1.0],
                light * 0.1 * ratio,
                0.6,
                0.0,
            );
        }
        s.interact("grains", "grains");
        s.interact("grains", "ground");
        s.interact("grains", "boxes");
        s.note = format!(
            "{count} boxes of {big:.2}, mass ratio {ratio:.3e}, dropped on {k} circles of {r:.2}"
        );
    }
    s.interact("boxes", "boxes");
    s.interact("boxes", "ground");
    criteria(
        s,
        &[
            "steps = 480".into(),
            "final_overlap = 0.01".into(),
            "final_speed = 0.05".into(),
        ],
    );
}

pub(super) fn crowds(rng: &mut ChaCha8Rng, s: &mut Scene) {
    let r = rng.random_range(0.2..=1.0);
    let fill = rng.random_range(0.5..=1.1);
    let count = rng.random_range(50..=400) as f64;
    // The box's inside holds `count` circles at `fill` of its area.
    let area = count * std::f64::consts::PI * r * r / fill;
    let side = area.sqrt();
    let t = log_uniform(rng, 0.1, 5.0) * 2.0 * r;
    world(s, 1.0 / 60.0, [0.0, 0.0], ([-side, -side], [side, side]));
    let half = side / 2.0;
    s.walls([-half, -half], [half, half], t, "walls");
    // On a square grid as many as fit, the rest on a second grid between them.
    let per_row = (side / (2.0 * r)).floor().max(1.0) as usize;
    let pitch = side / per_row as f64;
    let mut placed = 0;
    'grid: for layer in 0..2 {
        let shift = if layer == 0 { pitch / 2.0 } else { pitch };
        for i in 0..per_row {
            for j in 0..per_row {
                if placed as f64 >= count {
                    break 'grid;
                }
                let (x, y) = (
                    -half + shift + i as f64 * pitch,
                    -half + shift + j as f64 * pitch,
                );
                if x + r * 0.5 > half || y + r * 0.5 > half {
                    continue;
                }
                s.circle(
                    &format!("c/{placed}"),
                    "crowd",
                    r,
                    [x, y],
                    [0.0, 0.0],
                    1.0,
                    0.2,
                    0.2,
                );
                placed += 1;
            }
        }
    }
    s.interact("crowd", "crowd");
    s.interact("crowd", "walls");
    let inside = half - r * 0.5;
    criteria(
        s,
        &[
            "steps = 150".into(),
            format!(
                "inside = [[{}, {}], [{}, {}]]",
                n(-inside),
                n(-inside),
                n(inside),
                n(inside)
            ),
            "final_speed = 2.0".into(),
            "energy_rise = 0.01".into(),
        ],
    );
    s.note = format!(
        "{placed} circles of {r:.2} at {:.0}% of a box {side:.2} wide, walls {t:.3} thick",
        fill * 100.0
    );
}

pub(super) fn rains(rng: &mut ChaCha8Rng, s: &mut Scene) {
    let count = rng.random_range(100..=5000);
    let size = rng.random_range(0.2..=0.6);
    let layers = rng.random_range(5..=50) as f64;
    // A bin as wide as `count / layers` bodies.
    let width = (count as f64 / layers * size * 1.1).max(4.0 * size);
    let drop = rng.random_range(2.0..=10.0) * size;
    let rows = (count as f64 * size / width).ceil() as usize + 1;
    let height = rows as f64 * (size + drop * 0.1) + drop;
    world(
        s,
        1.0 / 60.0,
        [0.0, -10.0],
        ([-width, -2.0], [width, height + 4.0]),
    );
    s.rect(
        "floor",
        "bin",
        [width + 2.0, 1.0],
        [0.0, -0.5],
        0.0,
        0.4,
        0.0,
    );
    s.rect(
        "bin/left",
        "bin",
        [1.0, height + 4.0],
        [-width / 2.0 - 0.5, height / 2.0],
        0.0,
        0.4,
        0.0,
    );
    s.rect(
        "bin/right",
        "bin",
        [1.0, height + 4.0],
        [width / 2.0 + 0.5, height / 2.0],
        0.0,
        0.4,
        0.0,
    );
    let per_row = ((width / (size * 1.2)).floor() as usize).max(1);
    let mut placed = 0;
    let mut row = 0;
    while placed < count {
        for k in 0..per_row {
            if placed >= count {
                break;
            }
            let x = -width / 2.0
                + size * 0.6
                + k as f64 * size * 1.2
                + rng.random_range(-0.05..=0.05) * size;
            let y = drop + size + row as f64 * size * 1.3;
            if rng.random_bool(0.5) {
                s.circle(
                    &format!("r/{placed}"),
                    "rain",
                    size / 2.0,
                    [x, y],
                    [0.0, 0.0],
                    1.0,
                    0.3,
                    0.0,
                );
            } else {
                s.rect(
                    &format!("r/{placed}"),
                    "rain",
                    [size, size],
                    [x, y],
                    1.0,
                    0.3,
                    0.0,
                );
            }
            placed += 1;
        }
        row += 1;
    }
    s.interact("rain", "rain");
    s.interact("rain", "bin");
    let fall = (2.0 * (drop + row as f64 * size * 1.3) / 10.0).sqrt();
    let steps = ((fall + 6.0) * 60.0).round() as u64;
    criteria(
        s,
        &[
            format!("steps = {steps}"),
            format!(
                "inside = [[{}, -0.5], [{}, 1e6]]",
                n(-width / 2.0),
                n(width / 2.0)
            ),
            "final_overlap = 0.01".into(),
            "final_speed = 0.05".into(),
        ],
    );
    s.note = format!("{count} bodies of {size:.2} into a bin {width:.2} wide (about {layers} layers), from {drop:.2} up");
}

pub(super) fn impacts(rng: &mut ChaCha8Rng, s: &mut Scene) {
    let ratio = log_uniform(rng, 10.0, 1000.0);
    let speed = log_uniform(rng, 10.0, 300.0);
    let small = 0.5;
    let big = small * rng.random_range(1.0..=8.0);
    let side = rng.random_range(8..=30);
    let circles = rng.random_bool(0.5);
    let block = side as f64 * small;
    world(
        s,
        1.0 / 60.0,
        [0.0, 0.0],
        ([-block * 3.0, -block * 2.0], [block * 3.0, block * 2.0]),
    );
    let mut k = 0;
    for i in 0..side {
        for j in 0..side {
            let (x, y) = (
                i as f64 * small - block / 2.0 + small / 2.0,
                j as f64 * small - block / 2.0 + small / 2.0,
            );
            if circles {
                s.circle(
                    &format!("b/{k}"),
                    "block",
                    small / 2.0,
                    [x, y],
                    [0.0, 0.0],
                    0.25,
                    0.3,
                    0.0,
                );
            } else {
                s.rect(
                    &format!("b/{k}"),
                    "block",
                    [small, small],
                    [x, y],
                    0.25,
                    0.3,
                    0.0,
                );
            }
            k += 1;
        }
    }
    let start = -block / 2.0 - big - 1.0;
    s.circle(
        "heavy",
        "heavy",
        big / 2.0,
        [start, 0.0],
        [speed, 0.0],
        0.25 * ratio,
        0.3,
        0.0,
    );
    s.interact("block", "block");
    s.interact("block", "heavy");
    let steps = (((block + big + 1.0) / speed + 3.0) * 60.0).round() as u64;
    criteria(
        s,
        &[
            format!("steps = {steps}"),
            "final_overlap = 0.01".into(),
            "energy_rise = 0.01".into(),
        ],
    );
    s.note = format!(
        "a circle of {big:.2}, mass ratio {ratio:.1}, at {speed:.1} u/s into {} {}",
        side * side,
        if circles { "circles" } else { "boxes" }
    );
}

pub(super) fn overlaps(rng: &mut ChaCha8Rng, s: &mut Scene) {
    let overlap = rng.random_range(0.1..=0.5);
    let size = log_uniform(rng, 0.2, 5.0);
    let pyramid = rng.random_bool(0.5);
    let levels: u32 = rng.random_range(3..=15);
    let pitch = size * (1.0 - overlap);
    world(
        s,
        1.0 / 60.0,
        [0.0, -10.0],
        ([-size * 30.0, -size * 2.0], [size * 30.0, size * 30.0]),
    );
    s.rect(
        "ground",
        "ground",
        [size * 60.0, size],
        [0.0, -size / 2.0],
        0.0,
        0.6,
        0.0,
    );
    let mut k = 0;
    for level in 0..levels {
        let row = if pyramid { levels - level } else { 1 };
        let y = size / 2.0 + level as f64 * pitch;
        for i in 0..row {
            let x = -(row as f64 - 1.0) * pitch / 2.0 + i as f64 * pitch;
            s.rect(
                &format!("box/{k}"),
                "boxes",
                [size, size],
                [x, y],
                1.0,
                0.6,
                0.0,
            );
            k += 1;
        }
    }
    s.interact("boxes", "boxes");
    s.interact("boxes", "ground");
    criteria(
        s,
        &[
            "steps = 480".into(),
            format!("speed = {}", n(5.0)),
            "final_overlap = 0.01".into(),
        ],
    );
    s.note = format!(
        "a {} of {levels} levels of boxes {size:.2} wide, started {:.0}% overlapped",
        if pyramid { "pyramid" } else { "column" },
        overlap * 100.0
    );
}
