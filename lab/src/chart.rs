//! The trade-off charts' common part: time against error on log scales, one point per
//! setting labelled with its number, the front in red.

use std::fs::File;
use std::io::BufWriter;
use std::path::Path;

use anyhow::{Context, Result};
use plotters::coord::Shift;
use plotters::prelude::*;

/// Draws a picture of `width` x `height` with `draw` and writes it to `path` as a PNG.
/// plotters draws into memory and the `png` crate encodes it: plotters' own encoder would
/// bring a second `image` crate into the main job's build for nothing else.
pub fn write_png(
    path: &Path,
    (width, height): (u32, u32),
    draw: impl FnOnce(&DrawingArea<BitMapBackend<'_>, Shift>) -> Result<()>,
) -> Result<()> {
    let mut rgb = vec![0u8; width as usize * height as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut rgb, (width, height)).into_drawing_area();
        draw(&root)?;
        root.present()?;
    }
    let file = File::create(path).with_context(|| format!("cannot write {}", path.display()))?;
    let mut encoder = png::Encoder::new(BufWriter::new(file), width, height);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    encoder
        .write_header()
        .and_then(|mut writer| writer.write_image_data(&rgb))
        .with_context(|| format!("cannot write {}", path.display()))
}

/// Where the charts' font is looked for (Debian's fonts-dejavu-core).
pub const FONT: &str = "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf";

/// Registers [`FONT`] as the charts' sans-serif (once; later calls do nothing).
pub fn register_font() -> Result<()> {
    static REGISTERED: std::sync::OnceLock<Result<(), String>> = std::sync::OnceLock::new();
    REGISTERED
        .get_or_init(|| {
            let font = std::fs::read(FONT).map_err(|e| {
                format!("the chart needs the font {FONT} (Debian: fonts-dejavu-core): {e}")
            })?;
            plotters::style::register_font(
                "sans-serif",
                FontStyle::Normal,
                Box::leak(font.into_boxed_slice()),
            )
            .map_err(|_| format!("{FONT} is not a usable font"))
        })
        .clone()
        .map_err(|e| anyhow::anyhow!(e))
}

/// A setting as a point: mean ms per step over the run, error, whether it is on the front, and the
/// number the legend gives it.
pub struct Point {
    pub ms: f64,
    pub error: f64,
    pub front: bool,
    pub label: usize,
}

/// Draws `points` (none NaN) on `area`: time against error on log scales (errors below
/// 1e-15 drawn at it), the front joined in red.
pub fn panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    title: &str,
    error_name: &str,
    points: &[Point],
) -> Result<()>
where
    DB::ErrorType: 'static,
{
    let at = |p: &Point| (p.ms.max(1e-6), p.error.max(1e-15));
    let (xs, ys): (Vec<f64>, Vec<f64>) = points.iter().map(at).unzip();
    let x0 = xs.iter().cloned().fold(f64::MAX, f64::min) / 1.5;
    let x1 = xs.iter().cloned().fold(0.0, f64::max) * 1.5;
    let y0 = ys.iter().cloned().fold(f64::MAX, f64::min) / 3.0;
    let y1 = ys.iter().cloned().fold(0.0, f64::max) * 3.0;
    let mut chart = ChartBuilder::on(area)
        .caption(title, ("sans-serif", 22))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(70)
        .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())?;
    chart
        .configure_mesh()
        .x_desc("mean ms per step (whole run)")
        .y_desc(error_name)
        .axis_desc_style(("sans-serif", 13))
        .x_label_formatter(&|v| format!("{v:.2e}"))
        .y_label_formatter(&|v| format!("{v:.0e}"))
        .x_labels(5)
        .label_style(("sans-serif", 12))
        .draw()?;
    let mut front: Vec<(f64, f64)> = points.iter().filter(|p| p.front).map(at).collect();
    front.sort_by(|a, b| a.0.total_cmp(&b.0));
    chart.draw_series(LineSeries::new(front, RED.stroke_width(2)))?;
    for p in points {
        let colour = if p.front { RED } else { BLUE };
        chart.draw_series(std::iter::once(
            EmptyElement::at(at(p))
                + Circle::new((0, 0), 5, colour.filled())
                + Text::new(format!("{}", p.label), (7, -7), ("sans-serif", 13)),
        ))?;
    }
    Ok(())
}
