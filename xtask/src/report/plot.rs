//! Plots: knob curves and line plots as SVG through plotters (text stays `<text>`, so no fonts
//! are needed), cost matrices as PNG heat maps.

use std::path::Path;

use anyhow::{anyhow, Result};
use image::{Rgb, RgbImage};
use plotters::prelude::*;

use super::model::{Axis, Better, Curve, LinePlot};

const SIZE: (u32, u32) = (720, 440);

fn tx(axis: &Axis, v: f64) -> f64 {
    if axis.log {
        v.max(1e-12).log10()
    } else {
        v
    }
}

fn range(axis: &Axis, values: impl Iterator<Item = f64>) -> (f64, f64) {
    let vals: Vec<f64> = values
        .filter(|v| v.is_finite())
        .map(|v| tx(axis, v))
        .collect();
    let (mut lo, mut hi) = vals
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    if hi - lo < 1e-9 * (1.0 + lo.abs()) {
        let pad = if axis.log || lo == 0.0 {
            0.5
        } else {
            0.1 * lo.abs()
        };
        lo -= pad;
        hi += pad;
    }
    let pad = 0.08 * (hi - lo);
    (lo - pad, hi + pad)
}

/// [`range`] with room at the top for the legend.
fn range_with_legend(axis: &Axis, values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = range(axis, values);
    (lo, hi + 0.22 * (hi - lo))
}

fn fmt_tick(axis: &Axis, v: f64) -> String {
    let v = if axis.log { 10f64.powf(v) } else { v };
    let a = v.abs();
    if a == 0.0 {
        "0".into()
    } else if !(1e-3..1e5).contains(&a) {
        format!("{v:.1e}")
    } else if a >= 100.0 {
        format!("{v:.0}")
    } else if a >= 1.0 {
        format!("{v:.2}")
    } else {
        format!("{v:.3}")
    }
}

fn desc(axis: &Axis) -> String {
    let dir = match axis.better {
        Better::Lower => " (lower is better)",
        Better::Higher => " (higher is better)",
        Better::Neutral => "",
    };
    format!(
        "{}{}{dir}",
        axis.label,
        if axis.log { ", log scale" } else { "" }
    )
}

fn err<E: std::fmt::Debug>(e: E) -> anyhow::Error {
    anyhow!("plotting: {e:?}")
}

/// Draws a knob curve: every setting a labelled point, the Pareto front as a line, the default
/// as a larger red diamond.
pub fn curve_svg(c: &Curve, path: &Path) -> Result<()> {
    let root = SVGBackend::new(path, SIZE).into_drawing_area();
    root.fill(&WHITE).map_err(err)?;
    let (x0, x1) = range(&c.x, c.points.iter().map(|p| p.x));
    // Room on the right for the last points' labels.
    let x1 = x1 + 0.18 * (x1 - x0);
    let (y0, y1) = range_with_legend(&c.y, c.points.iter().map(|p| p.y));
    let mut chart = ChartBuilder::on(&root)
        .caption(&c.title, ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(44)
        .y_label_area_size(70)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc(desc(&c.x))
        .y_desc(desc(&c.y))
        .x_label_formatter(&|v| fmt_tick(&c.x, *v))
        .y_label_formatter(&|v| fmt_tick(&c.y, *v))
        .light_line_style(RGBColor(235, 235, 235))
        .draw()
        .map_err(err)?;
    let at = |i: usize| (tx(&c.x, c.points[i].x), tx(&c.y, c.points[i].y));
    let finite: Vec<usize> = (0..c.points.len())
        .filter(|&i| c.points[i].x.is_finite() && c.points[i].y.is_finite())
        .collect();
    chart
        .draw_series(LineSeries::new(
            c.pareto.iter().map(|&i| at(i)),
            ShapeStyle::from(&RGBColor(230, 120, 30)).stroke_width(2),
        ))
        .map_err(err)?
        .label("Pareto front")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], RGBColor(230, 120, 30)));
    chart
        .draw_series(
            finite
                .iter()
                .map(|&i| Circle::new(at(i), 4, RGBColor(40, 90, 180).filled())),
        )
        .map_err(err)?
        .label("setting")
        .legend(|(x, y)| Circle::new((x + 9, y), 4, RGBColor(40, 90, 180).filled()));
    let defaults: Vec<usize> = finite
        .iter()
        .copied()
        .filter(|&i| c.points[i].default)
        .collect();
    chart
        .draw_series(
            defaults
                .iter()
                .map(|&i| TriangleMarker::new(at(i), 9, RGBColor(200, 20, 20).filled())),
        )
        .map_err(err)?
        .label("default")
        .legend(|(x, y)| TriangleMarker::new((x + 9, y), 7, RGBColor(200, 20, 20).filled()));
    chart
        .draw_series(finite.iter().map(|&i| {
            EmptyElement::at(at(i))
                + Text::new(
                    c.points[i].label.clone(),
                    (6, -14),
                    ("sans-serif", 11).into_font().color(&RGBColor(60, 60, 60)),
                )
        }))
        .map_err(err)?;
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.85))
        .border_style(RGBColor(180, 180, 180))
        .draw()
        .map_err(err)?;
    root.present().map_err(err)?;
    Ok(())
}

const PALETTE: [RGBColor; 6] = [
    RGBColor(40, 90, 180),
    RGBColor(220, 110, 30),
    RGBColor(40, 150, 60),
    RGBColor(190, 40, 40),
    RGBColor(120, 70, 170),
    RGBColor(90, 90, 90),
];

/// Draws several series against one x, each a line with point markers.
pub fn lines_svg(p: &LinePlot, path: &Path) -> Result<()> {
    let root = SVGBackend::new(path, SIZE).into_drawing_area();
    root.fill(&WHITE).map_err(err)?;
    let all = || p.series.iter().flat_map(|s| s.points.iter());
    let (x0, x1) = range(&p.x, all().map(|q| q.0));
    let (y0, y1) = range_with_legend(&p.y, all().map(|q| q.1));
    let mut chart = ChartBuilder::on(&root)
        .caption(&p.title, ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(44)
        .y_label_area_size(70)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc(desc(&p.x))
        .y_desc(desc(&p.y))
        .x_label_formatter(&|v| fmt_tick(&p.x, *v))
        .y_label_formatter(&|v| fmt_tick(&p.y, *v))
        .light_line_style(RGBColor(235, 235, 235))
        .draw()
        .map_err(err)?;
    for (k, s) in p.series.iter().enumerate() {
        let colour = PALETTE[k % PALETTE.len()];
        let pts: Vec<(f64, f64)> = s
            .points
            .iter()
            .filter(|q| q.0.is_finite() && q.1.is_finite())
            .map(|q| (tx(&p.x, q.0), tx(&p.y, q.1)))
            .collect();
        chart
            .draw_series(LineSeries::new(pts.clone(), colour.stroke_width(2)))
            .map_err(err)?
            .label(s.name.clone())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], colour));
        chart
            .draw_series(pts.iter().map(|&q| Circle::new(q, 3, colour.filled())))
            .map_err(err)?;
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.85))
        .border_style(RGBColor(180, 180, 180))
        .draw()
        .map_err(err)?;
    root.present().map_err(err)?;
    Ok(())
}

/// A cost matrix as a heat map (dark = low cost, log colour scale), one pixel per entry scaled up
/// to at least 300 px, with `mark` (row, column) circled in red; entries that are `None` (not
/// allowed by the constraints) are grey.
pub fn heatmap_png(costs: &[Vec<Option<u64>>], mark: (usize, usize), path: &Path) -> Result<()> {
    let n = costs.len();
    let m = costs.first().map_or(0, |r| r.len());
    if n == 0 || m == 0 {
        return Err(anyhow!("empty cost matrix"));
    }
    let scale = (300 / n.max(m)).max(1) as u32;
    let vals: Vec<f64> = costs
        .iter()
        .flatten()
        .flatten()
        .map(|&c| (1.0 + c as f64).ln())
        .collect();
    let lo = vals.iter().cloned().fold(f64::INFINITY, f64::min);
    let hi = vals.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
    let mut img = RgbImage::new(m as u32 * scale, n as u32 * scale);
    for (r, row) in costs.iter().enumerate() {
        for (c, v) in row.iter().enumerate() {
            let colour = match v {
                None => Rgb([200, 200, 200]),
                Some(v) => {
                    let t = if hi > lo {
                        (((1.0 + *v as f64).ln() - lo) / (hi - lo)).clamp(0.0, 1.0)
                    } else {
                        0.0
                    };
                    // A simple dark-blue -> yellow ramp.
                    Rgb([
                        (20.0 + 235.0 * t) as u8,
                        (20.0 + 200.0 * t) as u8,
                        (80.0 + 40.0 * (1.0 - t)) as u8,
                    ])
                }
            };
            for dy in 0..scale {
                for dx in 0..scale {
                    img.put_pixel(c as u32 * scale + dx, r as u32 * scale + dy, colour);
                }
            }
        }
    }
    let (cy, cx) = (
        (mark.0 as f64 + 0.5) * scale as f64,
        (mark.1 as f64 + 0.5) * scale as f64,
    );
    let radius = 6.0f64.max(2.0 * scale as f64);
    for k in 0..720 {
        let a = k as f64 / 720.0 * std::f64::consts::TAU;
        for dr in [0.0, 1.0, 2.0] {
            let (x, y) = (cx + (radius + dr) * a.cos(), cy + (radius + dr) * a.sin());
            if x >= 0.0 && y >= 0.0 && (x as u32) < img.width() && (y as u32) < img.height() {
                img.put_pixel(x as u32, y as u32, Rgb([255, 30, 30]));
            }
        }
    }
    img.save(path)?;
    Ok(())
}
