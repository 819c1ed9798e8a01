//! How a step's cost grows with the work: three series of scenes, each varying one thing,
//! written as scene files the peer benchmark runs in every engine in one run
//! (`lab/peers`), and the chart drawn from its `peers.csv`.
//!
//! - `count-N`: N boxes 0.5 wide resting in 10 rows on the ground (N = 100 to 50 000);
//! - `ratio-R`: 1 500 resting circles of radius 0.25 without gravity, and one circle R
//!   times their radius (mass 500) thrown into them at 100 u/s (R = 1 to 1 000);
//! - `depth-D`: a pyramid of D levels of unit boxes (D = 5 to 100).
//!
//! A scene's name ends in the number it varies, so the chart reads its x from it.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use plotters::prelude::*;

/// The series and the values each takes.
pub const COUNTS: [u64; 7] = [100, 300, 1_000, 3_000, 10_000, 30_000, 50_000];
pub const RATIOS: [u64; 7] = [1, 3, 10, 30, 100, 300, 1_000];
pub const DEPTHS: [u64; 6] = [5, 10, 20, 40, 70, 100];

fn header(s: &mut String, note: &str, gravity: f64, bounds: [f64; 4], criteria: &str) {
    let _ = writeln!(
        s,
        "# {note}\n[world]\ngravity = [0.0, {gravity:?}]\nmass_scaled_acceleration = false\n\
         bounds = [[{:?}, {:?}], [{:?}, {:?}]]\n\n[criteria]\n{criteria}\n",
        bounds[0], bounds[1], bounds[2], bounds[3]
    );
}

fn rect(s: &mut String, id: &str, group: &str, size: [f64; 2], pos: [f64; 2], mass: f64) {
    let _ = writeln!(
        s,
        "[[body]]\nid = \"{id}\"\ngroup = \"{group}\"\nshape = \"rect\"\nsize = [{:?}, {:?}]\n\
         pos = [{:?}, {:?}]\nmass = {mass:?}\nfriction = 0.6\nrestitution = 0.0\n",
        size[0], size[1], pos[0], pos[1]
    );
}

fn circle(s: &mut String, id: &str, group: &str, r: f64, pos: [f64; 2], vel: f64, mass: f64) {
    let _ = writeln!(
        s,
        "[[body]]\nid = \"{id}\"\ngroup = \"{group}\"\nshape = \"circle\"\nradius = {r:?}\n\
         pos = [{:?}, {:?}]\nvel = [{vel:?}, 0.0]\nmass = {mass:?}\nfriction = 0.3\nrestitution = 0.0\n",
        pos[0], pos[1]
    );
}

fn interact(s: &mut String, a: &str, b: &str) {
    let _ = writeln!(s, "[[interact]]\na = \"{a}\"\nb = \"{b}\"\n");
}

/// A pile's scene up to its boxes: gravity, the criteria of a pile at rest, and the
/// ground, `width` either side of 0, the bounds up to `top`.
fn pile(note: &str, width: f64, top: f64) -> String {
    let mut s = String::new();
    header(
        &mut s,
        note,
        -10.0,
        [-width, -2.0, width, top],
        "steps = 300\ndrift = 0.05\nfinal_overlap = 0.01",
    );
    rect(
        &mut s,
        "ground",
        "ground",
        [width * 2.0, 2.0],
        [0.0, -1.0],
        0.0,
    );
    s
}

/// `n` boxes 0.5 wide in 10 rows on the ground, 0.01 apart side by side.
pub fn count(n: u64) -> String {
    let rows = 10u64;
    let cols = n.div_ceil(rows);
    let width = cols as f64 * 0.51;
    let mut s = pile(
        &format!("{n} boxes 0.5 wide resting in 10 rows on the ground"),
        width,
        20.0,
    );
    let mut k = 0;
    'rows: for row in 0..rows {
        for col in 0..cols {
            if k == n {
                break 'rows;
            }
            let x = (col as f64 - (cols as f64 - 1.0) / 2.0) * 0.51;
            rect(
                &mut s,
                &format!("b/{k}"),
                "boxes",
                [0.5, 0.5],
                [x, 0.25 + row as f64 * 0.5],
                1.0,
            );
            k += 1;
        }
    }
    interact(&mut s, "boxes", "ground");
    interact(&mut s, "boxes", "boxes");
    s
}

/// 1 500 resting circles of radius 0.25 (a 30 x 50 block, no gravity) and one of `ratio`
/// times their radius, mass 500, thrown into them at 100 u/s.
pub fn ratio(ratio: u64) -> String {
    let r = 0.25;
    let big = r * ratio as f64;
    let (cols, rows) = (30, 50);
    let (w, h) = (cols as f64 * 2.0 * r, rows as f64 * 2.0 * r);
    let mut s = String::new();
    let reach = big * 2.0 + w + 50.0;
    header(
        &mut s,
        &format!("1 500 circles r 0.25 and one r {big} (ratio {ratio}) at 100 u/s, no gravity"),
        0.0,
        [-reach, -reach - h, reach, reach + h],
        "steps = 300\nfinal_overlap = 0.05",
    );
    let mut k = 0;
    for i in 0..cols {
        for j in 0..rows {
            let pos = [i as f64 * 2.0 * r + r, j as f64 * 2.0 * r + r - h / 2.0];
            circle(&mut s, &format!("c/{k}"), "bed", r, pos, 0.0, 0.1);
            k += 1;
        }
    }
    circle(
        &mut s,
        "heavy",
        "heavy",
        big,
        [-big - 1.0, 0.0],
        100.0,
        500.0,
    );
    interact(&mut s, "bed", "bed");
    interact(&mut s, "bed", "heavy");
    s
}

/// A pyramid of `levels` levels of unit boxes on the ground.
pub fn depth(levels: u64) -> String {
    let width = levels as f64 + 4.0;
    let mut s = pile(
        &format!("a pyramid of {levels} levels of unit boxes"),
        width,
        levels as f64 + 4.0,
    );
    let mut k = 0;
    for level in 0..levels {
        let n = levels - level;
        for i in 0..n {
            let x = i as f64 - (n as f64 - 1.0) / 2.0;
            rect(
                &mut s,
                &format!("b/{k}"),
                "boxes",
                [1.0, 1.0],
                [x, 0.5 + level as f64],
                1.0,
            );
            k += 1;
        }
    }
    interact(&mut s, "boxes", "ground");
    interact(&mut s, "boxes", "boxes");
    s
}

/// A series: its name, its values and the scene of a value.
type Series = (&'static str, &'static [u64], fn(u64) -> String);

/// Writes every series' scenes into `dir`, `<series>-<value>.toml`; returns their paths.
pub fn write(dir: &Path) -> Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let mut written = Vec::new();
    let series: [Series; 3] = [
        ("count", &COUNTS, count),
        ("ratio", &RATIOS, ratio),
        ("depth", &DEPTHS, depth),
    ];
    for (name, values, scene) in series {
        for &v in values {
            let path = dir.join(format!("{name}-{v}.toml"));
            std::fs::write(&path, scene(v))
                .with_context(|| format!("writing {}", path.display()))?;
            written.push(path);
        }
    }
    Ok(written)
}

/// One row of `peers.csv`: (series, value, engine, mean ms a step, holds).
type Row = (String, f64, String, f64, bool);

fn rows(csv: &Path) -> Result<Vec<Row>> {
    let mut reader =
        csv::Reader::from_path(csv).with_context(|| format!("reading {}", csv.display()))?;
    let heads = reader.headers()?.clone();
    let col = |name: &str| {
        heads
            .iter()
            .position(|h| h == name)
            .with_context(|| format!("{}: no column {name}", csv.display()))
    };
    let (scene, engine, mean, holds) = (
        col("scene")?,
        col("engine")?,
        col("mean_ms")?,
        col("holds")?,
    );
    let mut out = Vec::new();
    for record in reader.records() {
        let record = record?;
        let Some((series, value)) = record[scene].rsplit_once('-') else {
            continue;
        };
        let Ok(value) = value.parse::<f64>() else {
            continue;
        };
        out.push((
            series.to_string(),
            value,
            record[engine].to_string(),
            record[mean].parse().context("mean_ms")?,
            &record[holds] == "true",
        ));
    }
    Ok(out)
}

/// Draws `png`: a panel a series, mean ms a step against its value (log scales), a line an
/// engine (Ricochet on one thread, Box2D v3, rapier2d); a hollow point where the engine
/// did not hold the scene's criteria.
pub fn chart(csv: &Path, png: &Path) -> Result<()> {
    crate::chart::register_font()?;
    let rows = rows(csv)?;
    let mut series: BTreeMap<&str, Vec<&Row>> = BTreeMap::new();
    for row in &rows {
        series.entry(row.0.as_str()).or_default().push(row);
    }
    anyhow::ensure!(
        !series.is_empty(),
        "{}: no scene named <series>-<number>",
        csv.display()
    );
    let engines = [("Ricochet", RED), ("Box2D v3", BLUE), ("rapier2d", GREEN)];
    let titles = |s: &str| match s {
        "count" => "bodies (boxes resting in 10 rows)",
        "ratio" => "largest radius over smallest (one heavy circle among 1 500)",
        "depth" => "pyramid levels",
        _ => "value",
    };
    let panels = series.len() as u32;
    crate::chart::write_png(png, (560 * panels, 460), |root| {
        root.fill(&WHITE)?;
        for (area, (name, rows)) in root.split_evenly((1, panels as usize)).iter().zip(&series) {
            let xs: Vec<f64> = rows.iter().map(|r| r.1).collect();
            let ys: Vec<f64> = rows.iter().map(|r| r.3.max(1e-4)).collect();
            let (x0, x1) = (
                xs.iter().cloned().fold(f64::MAX, f64::min) / 1.3,
                xs.iter().cloned().fold(0.0, f64::max) * 1.3,
            );
            let (y0, y1) = (
                ys.iter().cloned().fold(f64::MAX, f64::min) / 2.0,
                ys.iter().cloned().fold(0.0, f64::max) * 2.0,
            );
            let mut chart = ChartBuilder::on(area)
                .caption(*name, ("sans-serif", 22))
                .margin(12)
                .x_label_area_size(40)
                .y_label_area_size(60)
                .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())?;
            chart
                .configure_mesh()
                .x_desc(titles(name))
                .y_desc("mean ms per step (whole run)")
                .axis_desc_style(("sans-serif", 13))
                .label_style(("sans-serif", 12))
                .light_line_style(WHITE)
                .x_labels(6)
                .y_labels(6)
                .x_label_formatter(&|v| format!("{v:.0}"))
                .y_label_formatter(&|v| format!("{v:.2}"))
                .draw()?;
            for (engine, colour) in engines {
                let mut line: Vec<(f64, f64, bool)> = rows
                    .iter()
                    .filter(|r| r.2 == engine)
                    .map(|r| (r.1, r.3.max(1e-4), r.4))
                    .collect();
                line.sort_by(|a, b| a.0.total_cmp(&b.0));
                chart
                    .draw_series(LineSeries::new(
                        line.iter().map(|p| (p.0, p.1)),
                        colour.stroke_width(2),
                    ))?
                    .label(engine)
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 18, y)], colour.stroke_width(2))
                    });
                chart.draw_series(line.iter().map(|&(x, y, holds)| {
                    let style = if holds {
                        colour.filled()
                    } else {
                        colour.stroke_width(2)
                    };
                    Circle::new((x, y), 4, style)
                }))?;
            }
            chart
                .configure_series_labels()
                .background_style(WHITE.mix(0.8))
                .border_style(BLACK)
                .position(SeriesLabelPosition::UpperLeft)
                .label_font(("sans-serif", 12))
                .draw()?;
        }
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_scene_of_the_series_loads_with_its_criteria() {
        let dir = tempfile::tempdir().unwrap();
        let paths = write(dir.path()).unwrap();
        assert_eq!(paths.len(), COUNTS.len() + RATIOS.len() + DEPTHS.len());
        for path in paths {
            let text = std::fs::read_to_string(&path).unwrap();
            let world = ricochet_engine::scene::parse(&text, &path, &[])
                .unwrap_or_else(|e| panic!("{}: {e:#}", path.display()));
            let criteria = ricochet_engine::scene::criteria(&text, &path).unwrap();
            assert!(criteria.is_some(), "{}", path.display());
            let name = path.file_stem().unwrap().to_str().unwrap();
            let (series, value) = name.rsplit_once('-').unwrap();
            let value: usize = value.parse().unwrap();
            let dynamic = world.bodies().iter().filter(|b| b.inv_mass > 0.0).count();
            match series {
                "count" => assert_eq!(dynamic, value, "{name}"),
                "ratio" => assert_eq!(dynamic, 1_501, "{name}"),
                "depth" => assert_eq!(dynamic, value * (value + 1) / 2, "{name}"),
                _ => panic!("{name}"),
            }
        }
    }
}
