//! SVG plots (plotters): one figure made of panels, each with line or point
//! series, optional horizontal reference lines (limits) and a log y axis.
//! Every picture idexp writes goes through [`write_svg`], atomically.
//!
//! The figure types ([`Panel`], [`Series`], [`Mark`]) are always available;
//! drawing needs the cargo feature `plots` (on by default). Without it
//! [`write_svg`] writes nothing and returns `Ok(())`, so every output writer
//! of the library produces its numeric files and skips its SVG figures.

use crate::error::Result;
#[cfg(not(feature = "plots"))]
use std::path::Path;

#[cfg(feature = "plots")]
pub use draw::write_svg;

/// Without the `plots` feature: writes no figure (the numeric outputs beside
/// it are unaffected) and returns `Ok(())`.
#[cfg(not(feature = "plots"))]
pub fn write_svg(_path: &Path, _title: &str, _panels: &[Panel], _cols: usize) -> Result<()> {
    Ok(())
}

/// How a series is drawn.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Mark {
    /// Connected line.
    Line,
    /// Dots.
    Points,
    /// Vertical bars from zero (for spectra, weights).
    Bars,
}

/// One data series in a panel.
#[derive(Debug, Clone)]
pub struct Series {
    /// Legend label (empty: no legend entry).
    pub label: String,
    /// Abscissae.
    pub x: Vec<f64>,
    /// Ordinates (same length as `x`).
    pub y: Vec<f64>,
    /// Drawing style.
    pub mark: Mark,
    /// Optional symmetric error bars (same length as `y`).
    pub err: Option<Vec<f64>>,
}

impl Series {
    /// A line series.
    pub fn line(label: impl Into<String>, x: Vec<f64>, y: Vec<f64>) -> Self {
        Series {
            label: label.into(),
            x,
            y,
            mark: Mark::Line,
            err: None,
        }
    }
    /// A point series.
    pub fn points(label: impl Into<String>, x: Vec<f64>, y: Vec<f64>) -> Self {
        Series {
            label: label.into(),
            x,
            y,
            mark: Mark::Points,
            err: None,
        }
    }
    /// A bar series.
    pub fn bars(label: impl Into<String>, x: Vec<f64>, y: Vec<f64>) -> Self {
        Series {
            label: label.into(),
            x,
            y,
            mark: Mark::Bars,
            err: None,
        }
    }
}

/// One panel (axes) of a figure.
#[derive(Debug, Clone, Default)]
pub struct Panel {
    /// Panel title.
    pub title: String,
    /// x-axis label.
    pub x_label: String,
    /// y-axis label.
    pub y_label: String,
    /// Series to draw.
    pub series: Vec<Series>,
    /// Horizontal reference lines (value, label), drawn dashed red (limits).
    pub hlines: Vec<(f64, String)>,
    /// Logarithmic y axis (non-positive values are dropped).
    pub log_y: bool,
    /// Logarithmic x axis (non-positive values are dropped).
    pub log_x: bool,
}

#[cfg(feature = "plots")]
mod draw {
    use super::{Mark, Panel, Result};
    use crate::error::Error;
    use plotters::prelude::*;
    use std::path::Path;

    const COLORS: [RGBColor; 8] = [
        RGBColor(31, 119, 180),
        RGBColor(255, 127, 14),
        RGBColor(44, 160, 44),
        RGBColor(214, 39, 40),
        RGBColor(148, 103, 189),
        RGBColor(140, 86, 75),
        RGBColor(227, 119, 194),
        RGBColor(127, 127, 127),
    ];

    fn range(vals: impl Iterator<Item = f64>, log: bool) -> (f64, f64) {
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for v in vals.filter(|v| v.is_finite() && (!log || *v > 0.0)) {
            lo = lo.min(v);
            hi = hi.max(v);
        }
        if !lo.is_finite() {
            return if log { (0.1, 10.0) } else { (-1.0, 1.0) };
        }
        if log {
            if hi <= lo * 1.0001 {
                return (lo / 2.0, hi * 2.0);
            }
            return (lo / 1.3, hi * 1.3);
        }
        let pad = if hi > lo { 0.05 * (hi - lo) } else { 0.5 * lo.abs().max(1.0) };
        (lo - pad, hi + pad)
    }

    fn perr<E: std::fmt::Debug>(path: &Path) -> impl Fn(E) -> Error + '_ {
        move |e| Error::Numerical(format!("plotting {}: {e:?}", path.display()))
    }

    /// Draws `panels` in a grid of `cols` columns under a common `title` and
    /// writes the SVG atomically to `path`.
    pub fn write_svg(path: &Path, title: &str, panels: &[Panel], cols: usize) -> Result<()> {
        let cols = cols.max(1).min(panels.len().max(1));
        let rows = panels.len().div_ceil(cols).max(1);
        let (w, h) = (460 * cols as u32, 300 * rows as u32 + 40);
        let mut svg = String::new();
        {
            let root = SVGBackend::with_string(&mut svg, (w, h)).into_drawing_area();
            root.fill(&WHITE).map_err(perr(path))?;
            let root = root.titled(title, ("sans-serif", 20)).map_err(perr(path))?;
            let areas = root.split_evenly((rows, cols));
            for (panel, area) in panels.iter().zip(areas.iter()) {
                draw_panel(path, panel, area)?;
            }
            root.present().map_err(perr(path))?;
        }
        crate::io::write_atomic(path, svg.as_bytes())
    }

    fn draw_panel<DB: DrawingBackend>(path: &Path, p: &Panel, area: &DrawingArea<DB, plotters::coord::Shift>) -> Result<()>
    where
        DB::ErrorType: 'static,
    {
        let xs = p.series.iter().flat_map(|s| s.x.iter().copied());
        let (x0, x1) = range(xs, p.log_x);
        let ys = p
            .series
            .iter()
            .flat_map(|s| {
                let e = s.err.clone().unwrap_or_else(|| vec![0.0; s.y.len()]);
                s.y.iter().zip(e).flat_map(|(y, e)| [y - e, y + e]).collect::<Vec<_>>()
            })
            .chain(p.hlines.iter().map(|h| h.0))
            .chain(p.series.iter().filter(|s| s.mark == Mark::Bars && !p.log_y).map(|_| 0.0));
        let (y0, y1) = range(ys, p.log_y);
        let mut b = ChartBuilder::on(area);
        b.caption(&p.title, ("sans-serif", 14)).margin(8).x_label_area_size(32).y_label_area_size(56);
        macro_rules! body {
            ($chart:expr) => {{
                let mut chart = $chart;
                chart
                    .configure_mesh()
                    .x_desc(p.x_label.as_str())
                    .y_desc(p.y_label.as_str())
                    .label_style(("sans-serif", 11))
                    .light_line_style(WHITE.mix(0.0))
                    .draw()
                    .map_err(perr(path))?;
                let ok = |x: f64, y: f64| x.is_finite() && y.is_finite() && (!p.log_x || x > 0.0) && (!p.log_y || y > 0.0);
                let mut any_label = false;
                for (k, s) in p.series.iter().enumerate() {
                    let c = COLORS[k % COLORS.len()];
                    let pts: Vec<(f64, f64)> = s.x.iter().zip(&s.y).map(|(a, b)| (*a, *b)).filter(|(a, b)| ok(*a, *b)).collect();
                    let anno = match s.mark {
                        Mark::Line => chart.draw_series(LineSeries::new(pts.clone(), c.stroke_width(1))).map_err(perr(path))?,
                        Mark::Points => chart
                            .draw_series(pts.iter().map(|&(a, b)| Circle::new((a, b), 2, c.filled())))
                            .map_err(perr(path))?,
                        Mark::Bars => {
                            let base = if p.log_y { y0 } else { 0.0 };
                            chart
                                .draw_series(pts.iter().map(|&(a, b)| PathElement::new(vec![(a, base), (a, b)], c.stroke_width(3))))
                                .map_err(perr(path))?
                        }
                    };
                    if !s.label.is_empty() {
                        any_label = true;
                        anno.label(s.label.clone())
                            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 14, y)], c.stroke_width(2)));
                    }
                    if let Some(err) = &s.err {
                        chart
                            .draw_series(
                                s.x.iter()
                                    .zip(&s.y)
                                    .zip(err)
                                    .filter(|((a, b), _)| ok(**a, **b))
                                    .map(|((a, b), e)| PathElement::new(vec![(*a, b - e), (*a, b + e)], BLACK.stroke_width(1))),
                            )
                            .map_err(perr(path))?;
                    }
                }
                for (v, label) in &p.hlines {
                    if p.log_y && *v <= 0.0 {
                        continue;
                    }
                    let anno = chart
                        .draw_series(DashedLineSeries::new(vec![(x0, *v), (x1, *v)], 4, 3, RED.stroke_width(1)))
                        .map_err(perr(path))?;
                    if !label.is_empty() {
                        any_label = true;
                        anno.label(label.clone())
                            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 14, y)], RED.stroke_width(1)));
                        // one legend entry per label is enough
                    }
                }
                if any_label {
                    chart
                        .configure_series_labels()
                        .background_style(WHITE.mix(0.8))
                        .border_style(BLACK.mix(0.3))
                        .label_font(("sans-serif", 10))
                        .draw()
                        .map_err(perr(path))?;
                }
            }};
        }
        match (p.log_x, p.log_y) {
            (false, false) => body!(b.build_cartesian_2d(x0..x1, y0..y1).map_err(perr(path))?),
            (false, true) => body!(b.build_cartesian_2d(x0..x1, (y0..y1).log_scale()).map_err(perr(path))?),
            (true, false) => body!(b.build_cartesian_2d((x0..x1).log_scale(), y0..y1).map_err(perr(path))?),
            (true, true) => body!(b.build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale()).map_err(perr(path))?),
        }
        Ok(())
    }
}
