//! The speed/error plot of `rttest shadows` (plotters): frame time against visibility RMSE,
//! one point per method, the Pareto front joined and drawn in red. SVG with labels; PNG
//! (through the bitmap backend and `scenes::Image`) with the same points and lines (the
//! light plotters build has no font rasteriser, so the PNG carries no text; the SVG and the
//! CSV name the points).

use std::path::{Path, PathBuf};

use plotters::coord::Shift;
use plotters::prelude::*;
use scenes::Image;

use crate::Error;

/// One method's point on the plot: its frame time against its visibility error.
#[derive(Clone, Debug, PartialEq)]
pub struct Point {
    /// Scene name (the caption).
    pub scene: String,
    /// The method's label.
    pub method: String,
    /// Milliseconds per frame (x, log scale).
    pub ms_per_frame: f64,
    /// RMSE of the visible fraction against the reference (y).
    pub visibility_rmse: f64,
    /// On the Pareto front (drawn red, joined by a line).
    pub pareto: bool,
}

/// Writes `pareto.svg` and `pareto.png` into `dir`; returns their paths, in that order.
pub fn plot(dir: &Path, reports: &[Point]) -> Result<[PathBuf; 2], Error> {
    let svg = dir.join("pareto.svg");
    let fail = |path: &Path, e: String| Error::File { path: path.to_path_buf(), message: e };
    {
        let root = SVGBackend::new(&svg, (900, 600)).into_drawing_area();
        draw(&root, reports, true).map_err(|e| fail(&svg, e))?;
        root.present().map_err(|e| fail(&svg, e.to_string()))?;
    }
    let (w, h) = (900u32, 600u32);
    let mut buf = vec![255u8; (w * h * 3) as usize];
    let png = dir.join("pareto.png");
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        draw(&root, reports, false).map_err(|e| fail(&png, e))?;
        root.present().map_err(|e| fail(&png, e.to_string()))?;
    }
    // `Image::save_png` encodes with gamma 2.2: decode the 8-bit sRGB-ish bytes first.
    let pixels = buf
        .chunks(3)
        .map(|c| glam::Vec3::new(c[0] as f32, c[1] as f32, c[2] as f32).map(|v| (v / 255.0).powf(2.2)))
        .collect();
    Image { width: w, height: h, pixels }.save_png(&png)?;
    Ok([svg, png])
}

fn draw<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, reports: &[Point], text: bool) -> Result<(), String> {
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    root.fill(&WHITE).map_err(e)?;
    let lo = reports.iter().map(|r| r.ms_per_frame).fold(f64::INFINITY, f64::min).max(1e-3);
    let hi = reports.iter().map(|r| r.ms_per_frame).fold(0.0, f64::max).max(lo * 1.01);
    let top = reports.iter().map(|r| r.visibility_rmse).fold(0.0, f64::max).max(1e-6) * 1.15;
    let scene = reports.first().map_or("", |r| r.scene.as_str());
    let mut builder = ChartBuilder::on(root);
    builder.margin(25).x_label_area_size(if text { 45 } else { 5 }).y_label_area_size(if text { 70 } else { 5 });
    if text {
        builder.caption(format!("{scene}: frame time against visibility error"), ("sans-serif", 22));
    }
    let mut chart = builder.build_cartesian_2d((lo * 0.8..hi * 1.25).log_scale(), 0.0..top).map_err(e)?;
    if text {
        chart.configure_mesh().x_desc("ms per frame (log)").y_desc("visibility RMSE vs reference").draw().map_err(e)?;
    }
    let mut front: Vec<(f64, f64)> =
        reports.iter().filter(|r| r.pareto).map(|r| (r.ms_per_frame, r.visibility_rmse)).collect();
    front.sort_by(|a, b| a.0.total_cmp(&b.0));
    chart.draw_series(LineSeries::new(front, RED.stroke_width(2))).map_err(e)?;
    for r in reports {
        let color = if r.pareto { RED } else { BLUE };
        chart
            .draw_series(std::iter::once(Circle::new((r.ms_per_frame, r.visibility_rmse), 6, color.filled())))
            .map_err(e)?;
        if text {
            chart
                .draw_series(std::iter::once(Text::new(
                    r.method.clone(),
                    (r.ms_per_frame * 1.04, r.visibility_rmse),
                    ("sans-serif", 14),
                )))
                .map_err(e)?;
        }
    }
    Ok(())
}
