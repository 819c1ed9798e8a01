//! The families of bodies in motion: elastic gases and rows of balls, bullets against thin
//! walls, and bodies sliding to rest under friction (the writer is [`super::draw`]'s).

use rand::Rng;
use rand_chacha::ChaCha8Rng;

use super::draw::{criteria, limit, log_uniform, world, Scene, STEPS_DT};

pub(super) fn elastic(rng: &mut ChaCha8Rng, s: &mut Scene) {
    let kind = rng.random_range(0..3u32);
    if kind == 2 {
        elastic_pile(rng, s);
    } else if kind == 0 {
        let count = rng.random_range(50..=1000);
        let r = 0.5;
        let side = (count as f64 * 4.0 * r * r / 0.2).sqrt();
        world(s, 1.0 / 60.0, [0.0, 0.0], ([-side, -side], [side, side]));
        let half = side / 2.0;
        let t = 2.0;
        for (id, size, pos) in [
            ("wall/bottom", [side + 2.0 * t, t], [0.0, -half - t / 2.0]),
            ("wall/top", [side + 2.0 * t, t], [0.0, half + t / 2.0]),
            ("wall/left", [t, side], [-half - t / 2.0, 0.0]),
            ("wall/right", [t, side], [half + t / 2.0, 0.0]),
        ] {
            s.rect(id, "walls", size, pos, 0.0, 0.0, 1.0);
        }
        let per_row = (side / (3.0 * r)).floor() as usize;
        let pitch = side / per_row as f64;
        for k in 0..count {
            let (i, j) = (k % per_row, k / per_row);
            let pos = [
                -half + pitch * (i as f64 + 0.5),
                -half + pitch * (j as f64 + 0.5),
            ];
            let angle = rng.random_range(0.0..std::f64::consts::TAU);
            let v = rng.random_range(1.0..=10.0);
            s.circle(
                &format!("g/{k}"),
                "gas",
                r,
                pos,
                [v * angle.cos(), v * angle.sin()],
                1.0,
                0.0,
                1.0,
            );
        }
        s.interact("gas", "gas");
        s.interact("gas", "walls");
        s.note = format!("a gas of {count} circles in a box {side:.1} wide");
    } else {
        let count = rng.random_range(3..=12);
        let r = 0.5;
        let gap = if rng.random_bool(0.5) {
            0.0
        } else {
            log_uniform(rng, 1e-4, 1e-2)
        };
        let v = rng.random_range(1.0..=20.0);
        let length = count as f64 * (2.0 * r + gap) + 40.0;
        world(
            s,
            1.0 / 60.0,
            [0.0, 0.0],
            ([-length, -10.0], [length, 10.0]),
        );
        s.rect(
            "wall/left",
            "walls",
            [1.0, 4.0],
            [-length / 2.0 - 0.5, 0.0],
            0.0,
            0.0,
            1.0,
        );
        s.rect(
            "wall/right",
            "walls",
            [1.0, 4.0],
            [length / 2.0 + 0.5, 0.0],
            0.0,
            0.0,
            1.0,
        );
        s.circle(
            "ball/0",
            "balls",
            r,
            [-length / 2.0 + 2.0, 0.0],
            [v, 0.0],
            1.0,
            0.0,
            1.0,
        );
        for k in 1..count {
            let x = k as f64 * (2.0 * r + gap);
            s.circle(
                &format!("ball/{k}"),
                "balls",
                r,
                [x, 0.0],
                [0.0, 0.0],
                1.0,
                0.0,
                1.0,
            );
        }
        s.interact("balls", "balls");
        s.interact("balls", "walls");
        s.note = format!("a row of {count} balls {gap:.1e} apart, the first at {v:.2} u/s");
    }
    criteria(s, &["steps = 1200".into(), "energy_change = 0.02".into()]);
}

/// A ball into a pile of touching bodies, in a closed box: a rack of circles (a triangle, as
/// on a billiard table) or a block of boxes, 0 to 1% of a size apart. Without gravity, so
/// that the kinetic energy is what an elastic world keeps.
fn elastic_pile(rng: &mut ChaCha8Rng, s: &mut Scene) {
    let gap = if rng.random_bool(0.5) {
        0.0
    } else {
        log_uniform(rng, 1e-4, 1e-2)
    };
    let v = rng.random_range(1.0..=20.0);
    let striker_mass = log_uniform(rng, 0.25, 4.0);
    let half = 20.0;
    world(
        s,
        1.0 / 60.0,
        [0.0, 0.0],
        ([-2.0 * half, -2.0 * half], [2.0 * half, 2.0 * half]),
    );
    let t = 2.0;
    for (id, size, pos) in [
        (
            "wall/bottom",
            [2.0 * half + 2.0 * t, t],
            [0.0, -half - t / 2.0],
        ),
        ("wall/top", [2.0 * half + 2.0 * t, t], [0.0, half + t / 2.0]),
        ("wall/left", [t, 2.0 * half], [-half - t / 2.0, 0.0]),
        ("wall/right", [t, 2.0 * half], [half + t / 2.0, 0.0]),
    ] {
        s.rect(id, "walls", size, pos, 0.0, 0.0, 1.0);
    }
    let (what, height) = if rng.random_bool(0.5) {
        // A triangle of circles r 0.5, its apex towards the striker.
        let levels = rng.random_range(3..=8);
        let pitch = 1.0 + gap;
        let dx = pitch * 3f64.sqrt() / 2.0;
        let mut k = 0;
        for col in 0..levels {
            for row in 0..=col {
                let y = (row as f64 - col as f64 / 2.0) * pitch;
                s.circle(
                    &format!("pile/{k}"),
                    "pile",
                    0.5,
                    [col as f64 * dx, y],
                    [0.0, 0.0],
                    1.0,
                    0.0,
                    1.0,
                );
                k += 1;
            }
        }
        (
            format!("a rack of {k} circles in {levels} rows"),
            levels as f64 * pitch,
        )
    } else {
        // A block of unit boxes, its left face towards the striker.
        let (cols, rows) = (rng.random_range(1..=8), rng.random_range(2..=8));
        let pitch = 1.0 + gap;
        for i in 0..cols {
            for j in 0..rows {
                let y = (j as f64 - (rows - 1) as f64 / 2.0) * pitch;
                s.rect(
                    &format!("pile/{}", i * rows + j),
                    "pile",
                    [1.0, 1.0],
                    [i as f64 * pitch, y],
                    1.0,
                    0.0,
                    1.0,
                );
            }
        }
        (
            format!("a block of {cols} x {rows} boxes"),
            rows as f64 * pitch,
        )
    };
    let aim = rng.random_range(-0.5..=0.5) * height;
    s.circle(
        "striker",
        "pile",
        0.5,
        [-10.0, aim],
        [v, 0.0],
        striker_mass,
        0.0,
        1.0,
    );
    s.interact("pile", "pile");
    s.interact("pile", "walls");
    s.note = format!(
        "a ball of mass {striker_mass:.2} at {v:.2} u/s into {what} {gap:.1e} apart, {aim:.2} off its middle"
    );
}

pub(super) fn bullets(rng: &mut ChaCha8Rng, s: &mut Scene) {
    let r = log_uniform(rng, 0.005, 0.05);
    let v = log_uniform(rng, 100.0, 2000.0);
    let t = log_uniform(rng, 0.02, 0.5);
    let count = rng.random_range(1..=20);
    world(s, 1.0 / 60.0, [0.0, 0.0], ([-20.0, -20.0], [20.0, 20.0]));
    s.rect(
        "wall",
        "wall",
        [t, 40.0],
        [10.0 + t / 2.0, 0.0],
        0.0,
        0.0,
        0.5,
    );
    for k in 0..count {
        let y = -10.0 + 20.0 * (k as f64 + 0.5) / count as f64;
        let angle: f64 = rng.random_range(-0.5..=0.5);
        s.circle(
            &format!("bullet/{k}"),
            "bullets",
            r,
            [0.0, y],
            [v * angle.cos(), v * angle.sin()],
            0.01,
            0.0,
            0.5,
        );
    }
    s.interact("bullets", "wall");
    criteria(
        s,
        &[
            "steps = 120".into(),
            "inside = [[-1e9, -1e9], [10.0, 1e9]]".into(),
        ],
    );
    s.note = format!("{count} circles of {r:.3} at {v:.0} u/s against a wall {t:.3} thick");
}

/// Bodies launched along the ground, or along a plank that rests on it, sliding to rest
/// under Coulomb friction: boxes (aspect 0.25 to 4) and circles 0.05 to 20 across, 0.5 to
/// 15 u/s (no faster than friction stops in 4 s), friction 0.1 to 1 each, gravity 2 to
/// 30, masses 0.01 to 1000, up to 1e6 from the origin, steps of 1/240 to 1/15 s. Each
/// slides on a lane of its own; a plank is heavy enough that its friction with the ground
/// holds it at twice the pull of the body on it.
pub(super) fn friction(rng: &mut ChaCha8Rng, s: &mut Scene) {
    let size = log_uniform(rng, 0.05, 20.0);
    let g = log_uniform(rng, 2.0, 30.0);
    let ground_friction: f64 = rng.random_range(0.1..=1.0);
    let far = if rng.random_bool(0.5) {
        log_uniform(rng, 1.0, 1e6)
    } else {
        0.0
    };
    let (dt, dt_name) = STEPS_DT[rng.random_range(0..STEPS_DT.len())];
    let count = rng.random_range(1..=8);
    let mut bodies = Scene::default();
    let (mut x, mut longest, mut planks) = (far, 0.0_f64, 0);
    for k in 0..count {
        let circle = rng.random_bool(0.3);
        let aspect = if circle {
            1.0
        } else {
            log_uniform(rng, 0.25, 4.0)
        };
        let (w, h) = (size * rng.random_range(0.5..=1.0), size * aspect);
        let (w, h) = if circle { (w, w) } else { (w, h) };
        let mass = log_uniform(rng, 0.01, 1000.0);
        let mu: f64 = rng.random_range(0.1..=1.0);
        let on_plank = rng.random_bool(0.4);
        let support_mu: f64 = if on_plank {
            rng.random_range(0.1..=1.0)
        } else {
            ground_friction
        };
        let pair = (mu * support_mu).sqrt();
        let v = log_uniform(rng, 0.5, 15.0).min(4.0 * pair * g);
        let distance = v * v / (2.0 * pair * g);
        longest = longest.max(v / (pair * g));
        let left = rng.random_bool(0.5);
        let lane = distance + 2.0 * w + 0.1 * size;
        // Where the body starts in its lane, and which way it goes.
        let (start, vel) = if left { (x + lane - w, -v) } else { (x + w, v) };
        let mut y = far;
        if on_plank {
            let thick = size * rng.random_range(0.2..=1.0);
            // The plank holds when its friction with the ground takes twice what the body
            // pulls it by: sqrt(mu_p mu_g) (m_p + m) g >= 2 sqrt(mu mu_p) m g.
            let hold = 2.0 * (mu / ground_friction).sqrt() - 1.0;
            let plank_mass = mass * log_uniform(rng, 1.0, 100.0).max(hold);
            bodies.rect(
                &format!("plank/{planks}"),
                "bodies",
                [lane, thick],
                [x + lane / 2.0, far + thick / 2.0],
                plank_mass,
                support_mu,
                0.0,
            );
            planks += 1;
            y += thick;
        }
        let id = format!("slider/{k}");
        if circle {
            bodies.circle(
                &id,
                "bodies",
                w / 2.0,
                [start, y + w / 2.0],
                [vel, 0.0],
                mass,
                mu,
                0.0,
            );
        } else {
            bodies.moving_rect(
                &id,
                "bodies",
                [w, h],
                [start, y + h / 2.0],
                [vel, 0.0],
                mass,
                mu,
                0.0,
            );
        }
        x += lane + size;
    }
    let length = x - far;
    let margin = 2.0 * size;
    world(
        s,
        dt,
        [0.0, -g],
        (
            [far - margin, far - 2.0 * size],
            [x + margin, far + 4.0 * size],
        ),
    );
    s.rect(
        "ground",
        "ground",
        [length + 2.0 * margin, size],
        [far + length / 2.0, far - size / 2.0],
        0.0,
        ground_friction,
        0.0,
    );
    s.text.push_str(&bodies.text);
    s.interact("bodies", "bodies");
    s.interact("bodies", "ground");
    let steps = ((longest + 1.5) / dt).ceil() as u64;
    criteria(
        s,
        &[
            format!("steps = {steps}"),
            "stopping = 0.02".into(),
            "final_overlap = 0.01".into(),
            format!("final_speed = {}", limit(0.05 * size * 0.25)),
        ],
    );
    s.note = format!(
        "{count} bodies ({planks} on planks) about {size:.3} across sliding to rest, gravity {g:.2}, ground friction {ground_friction:.2}, {far:.3e} from the origin, dt {dt_name}"
    );
}
