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
    /// Names of the categories at x = 1, 2, …, n (e.g. parameter names):
    /// when not empty, the x axis is ticked at those integers only and
    /// labelled with the names, rotated by 90° so that long names fit.
    pub x_names: Vec<String>,
}

/// The axis range drawn for data spanning [lo, hi] on a linear axis: 5 %
/// padding on either side; a constant (or floating-point noise: a span below
/// 1e-9 of the magnitude, e.g. coordinates 1e-16 and -2e-17 of points on a
/// plane) gets a symmetric range of ±0.5·max(|centre|, 1) around its centre
/// (0 when the centre itself is noise), so its ticks read 0, ±0.25, … rather
/// than a row of "0".
pub fn linear_range(lo: f64, hi: f64) -> (f64, f64) {
    let scale = lo.abs().max(hi.abs()).max(1.0);
    if hi - lo > 1e-9 * scale {
        let pad = 0.05 * (hi - lo);
        return (lo - pad, hi + pad);
    }
    let mid = 0.5 * (lo + hi);
    let mid = if mid.abs() < 1e-9 { 0.0 } else { mid };
    let half = 0.5 * mid.abs().max(1.0);
    (mid - half, mid + half)
}

/// A tick label: at most 4 significant digits without trailing zeros
/// ("0.25", "40", "1500"), exponent form outside [1e-3, 1e5) ("1e-4",
/// "2.5e6"); never "-0" nor a 17-digit rounding artefact.
pub fn tick_label(v: f64) -> String {
    if !v.is_finite() {
        return String::new();
    }
    let a = v.abs();
    if a < 1e-12 * 1.0f64.max(a) || a == 0.0 {
        return "0".into();
    }
    let trim = |t: String| -> String {
        if t.contains('.') {
            t.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            t
        }
    };
    if (1e-3..1e5).contains(&a) {
        let digits = (3 - a.log10().floor() as i32).clamp(0, 6) as usize;
        let t = trim(format!("{v:.digits$}"));
        if t == "-0" {
            "0".into()
        } else {
            t
        }
    } else {
        let t = format!("{v:.3e}");
        let (m, e) = t.split_once('e').unwrap_or((&t, "0"));
        format!("{}e{e}", trim(m.to_string()))
    }
}

/// The corner of a panel where the legend covers the fewest data points:
/// 0 upper left, 1 upper right, 2 lower left, 3 lower right (ties: the
/// first). Each corner is the box of 40 % of the width and 35 % of the height
/// in axis coordinates (log axes in decades); `x`, `y` are (lo, hi, log).
pub fn emptiest_corner(pts: impl Iterator<Item = (f64, f64)>, x: (f64, f64, bool), y: (f64, f64, bool)) -> usize {
    legend_place(pts, x, y, (0.4, 0.35)).0
}

/// Where a legend box of `frac` = (width, height), in fractions of the
/// plotting area, goes so that it covers no data point: the corner (0 upper
/// left, 1 upper right, 2 lower left, 3 lower right) and the y range to draw.
/// A corner already empty keeps the range (ties: the first). Otherwise the
/// y range grows away from the data on the side of the corner that needs the
/// least growth, until every point under (or over) the legend's columns lies
/// outside the box: the legend then sits in a band of its own, never on the
/// data. Log axes work in decades; `x`, `y` are (lo, hi, log).
pub fn legend_place(pts: impl Iterator<Item = (f64, f64)>, x: (f64, f64, bool), y: (f64, f64, bool), frac: (f64, f64)) -> (usize, (f64, f64)) {
    let to = |v: f64, log: bool| {
        if log {
            if v > 0.0 {
                v.log10()
            } else {
                f64::NAN
            }
        } else {
            v
        }
    };
    let (ux0, ux1) = (to(x.0, x.2), to(x.1, x.2));
    let (uy0, uy1) = (to(y.0, y.2), to(y.1, y.2));
    let (bw, bh) = (frac.0.clamp(0.05, 0.95), frac.1.clamp(0.05, 0.9));
    // per corner: count inside the box, and the extreme y of the points in
    // the legend's columns (max for an upper corner, min for a lower one)
    let mut count = [0usize; 4];
    let mut ext = [f64::NEG_INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::INFINITY];
    for (a, b) in pts {
        let (a, b) = (to(a, x.2), to(b, y.2));
        let u = (a - ux0) / (ux1 - ux0);
        let w = (b - uy0) / (uy1 - uy0);
        if !(u.is_finite() && w.is_finite() && (0.0..=1.0).contains(&u)) {
            continue;
        }
        let (left, right, top, bottom) = (u <= bw, u >= 1.0 - bw, w >= 1.0 - bh, w <= bh);
        for (k, (col, row)) in [(left, top), (right, top), (left, bottom), (right, bottom)].into_iter().enumerate() {
            if col {
                if row {
                    count[k] += 1;
                }
                ext[k] = if k < 2 { ext[k].max(b) } else { ext[k].min(b) };
            }
        }
    }
    let from = |v: f64| if y.2 { 10f64.powf(v) } else { v };
    if let Some(k) = (0..4).find(|&k| count[k] == 0) {
        return (k, (y.0, y.1));
    }
    // growth needed per corner so that the box is above (below) the data
    let grow = |k: usize| -> (f64, f64, f64) {
        if k < 2 {
            // (hi' − m) = bh (hi' − lo)
            let hi = (ext[k] - bh * uy0) / (1.0 - bh);
            (hi - uy1, uy0, hi.max(uy1))
        } else {
            let lo = (ext[k] - bh * uy1) / (1.0 - bh);
            (uy0 - lo, lo.min(uy0), uy1)
        }
    };
    let best = (0..4).min_by(|&a, &b| grow(a).0.total_cmp(&grow(b).0)).unwrap_or(1);
    let (_, lo, hi) = grow(best);
    // a small pad so the box does not touch the outermost point
    let pad = 0.02 * (hi - lo);
    let (lo, hi) = if best < 2 { (lo, hi + pad) } else { (lo - pad, hi) };
    (best, (from(lo), from(hi)))
}

/// `text` shortened to at most `max` characters by an ellipsis in the middle
/// (a long path keeps its start and its file name); unchanged when it fits.
pub fn fit_text(text: &str, max: usize) -> String {
    let n = text.chars().count();
    if n <= max || max < 5 {
        return text.to_string();
    }
    let keep = max - 1;
    let (head, tail) = (keep * 2 / 5, keep - keep * 2 / 5);
    let start: String = text.chars().take(head).collect();
    let end: String = text.chars().skip(n - tail).collect();
    format!("{start}…{end}")
}

/// A line's points split where the abscissa jumps: for increasing x, at
/// every step longer than 5× the median step (points left out there); any
/// other line is one segment.
pub fn line_segments(pts: &[(f64, f64)]) -> Vec<Vec<(f64, f64)>> {
    let steps: Vec<f64> = pts.windows(2).map(|w| w[1].0 - w[0].0).collect();
    if steps.len() < 4 || !steps.iter().all(|d| d.is_finite() && *d > 0.0) {
        return vec![pts.to_vec()];
    }
    let mut sorted = steps.clone();
    sorted.sort_by(f64::total_cmp);
    let gap = 5.0 * sorted[sorted.len() / 2];
    let mut out = Vec::new();
    let mut seg = vec![pts[0]];
    for (d, pt) in steps.iter().zip(&pts[1..]) {
        if *d > gap {
            out.push(std::mem::take(&mut seg));
        }
        seg.push(*pt);
    }
    out.push(seg);
    out
}

/// The smallest positive gap between distinct finite abscissae (None for
/// fewer than two distinct values).
#[cfg(feature = "plots")]
fn min_spacing(x: &[f64]) -> Option<f64> {
    let mut v: Vec<f64> = x.iter().copied().filter(|a| a.is_finite()).collect();
    v.sort_by(f64::total_cmp);
    v.windows(2).map(|w| w[1] - w[0]).filter(|d| *d > 0.0).min_by(f64::total_cmp)
}

/// Tick positions of a log axis over [lo, hi] (lo > 0): every 1..9 on a
/// range of at most 0.6 decades, 1, 2, 3, 5 up to 1.5 decades, 1, 2, 5 up to
/// 3.5 decades, the decades beyond (every k-th decade over 8 decades).
pub fn log_ticks(lo: f64, hi: f64) -> Vec<f64> {
    if !(lo > 0.0 && hi > lo && lo.is_finite() && hi.is_finite()) {
        return vec![];
    }
    let (d0, d1) = (lo.log10().floor() as i32, hi.log10().ceil() as i32);
    let span = d1 - d0;
    // subdivisions by the decades the range really spans (0.25…2.3 is one
    // decade, though it touches three)
    let decades = (hi / lo).log10();
    let mults: &[f64] = if decades <= 0.6 {
        &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0]
    } else if decades <= 1.5 {
        &[1.0, 2.0, 3.0, 5.0]
    } else if decades <= 3.5 {
        &[1.0, 2.0, 5.0]
    } else {
        &[1.0]
    };
    let step = (span / 8 + 1).max(1);
    let mut v = Vec::new();
    for d in (d0..=d1).filter(|d| (d - d0) % step == 0) {
        for m in mults {
            let t = m * 10f64.powi(d);
            if t >= lo * (1.0 - 1e-12) && t <= hi * (1.0 + 1e-12) {
                v.push(t);
            }
        }
    }
    v
}

#[cfg(feature = "plots")]
mod draw {
    use super::{Mark, Panel, Result};
    use crate::error::Error;
    use plotters::prelude::*;
    use plotters::style::text_anchor::{HPos, Pos, VPos};
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
        super::linear_range(lo, hi)
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
            // a title wider than the figure (e.g. one naming a long path) is
            // shortened in the middle, never cut by the canvas edge
            let title = super::fit_text(title, ((w as f64 - 20.0) / 7.5) as usize);
            let root = root.titled(&title, ("sans-serif", 20)).map_err(perr(path))?;
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
        // a categorical axis: one slot per name
        let names = !p.x_names.is_empty() && !p.log_x;
        let (x0, x1) = if names { (0.4, p.x_names.len() as f64 + 0.6) } else { (x0, x1) };
        let longest = p.x_names.iter().map(|n| n.chars().count()).max().unwrap_or(0);
        let x_area = if names { (34 + 6 * longest as u32).clamp(40, 160) } else { 32 };
        // the legend: its box (10 px font: ~6 px per character, 15 px per
        // row, 50 px of key and padding) against the plotting area, and the
        // y range that keeps it off the data
        let labels: Vec<&str> = p
            .series
            .iter()
            .map(|s| s.label.as_str())
            .chain(p.hlines.iter().map(|h| h.1.as_str()))
            .filter(|l| !l.is_empty())
            .collect();
        let (pw, ph) = area.dim_in_pixel();
        let plot_w = (pw as f64 - 16.0 - 56.0 - 8.0).max(50.0);
        let plot_h = (ph as f64 - 16.0 - 24.0 - x_area as f64).max(50.0);
        let widest = labels.iter().map(|l| l.chars().count()).max().unwrap_or(0);
        let frac = ((6.0 * widest as f64 + 50.0) / plot_w, (15.0 * labels.len() as f64 + 22.0) / plot_h);
        let (corner, (y0, y1)) = if labels.is_empty() {
            (1, (y0, y1))
        } else {
            // the data and the reference lines (sampled across the panel)
            let lines: Vec<(f64, f64)> = p
                .hlines
                .iter()
                .flat_map(|h| (0..=40).map(move |k| (x0 + (x1 - x0) * k as f64 / 40.0, h.0)))
                .collect();
            let pts = p.series.iter().flat_map(|s| s.x.iter().copied().zip(s.y.iter().copied())).chain(lines);
            super::legend_place(pts, (x0, x1, p.log_x), (y0, y1, p.log_y), frac)
        };
        let caption = super::fit_text(&p.title, ((pw as f64 - 16.0) / 5.6) as usize);
        let mut b = ChartBuilder::on(area);
        b.caption(&caption, ("sans-serif", 14))
            .margin(8)
            .x_label_area_size(x_area)
            .y_label_area_size(56);
        let x_fmt = |v: &f64| -> String {
            if !names {
                return super::tick_label(*v);
            }
            // the names are drawn below, rotated and starting under the axis
            String::new()
        };
        macro_rules! body {
            ($chart:expr) => {{
                let mut chart = $chart;
                chart
                    .configure_mesh()
                    .x_desc(p.x_label.as_str())
                    .y_desc(p.y_label.as_str())
                    .label_style(("sans-serif", 11))
                    .axis_desc_style(("sans-serif", 11))
                    .x_label_style(("sans-serif", 11))
                    // a categorical axis: a tick at every integer (the names are drawn below)
                    .x_labels(if names { p.x_names.len() + 1 } else { 10 })
                    .x_label_formatter(&x_fmt)
                    .y_label_formatter(&|v: &f64| super::tick_label(*v))
                    .light_line_style(WHITE.mix(0.0))
                    .draw()
                    .map_err(perr(path))?;
                let ok = |x: f64, y: f64| x.is_finite() && y.is_finite() && (!p.log_x || x > 0.0) && (!p.log_y || y > 0.0);
                let mut any_label = false;
                for (k, s) in p.series.iter().enumerate() {
                    let c = COLORS[k % COLORS.len()];
                    let pts: Vec<(f64, f64)> = s.x.iter().zip(&s.y).map(|(a, b)| (*a, *b)).filter(|(a, b)| ok(*a, *b)).collect();
                    let anno = match s.mark {
                        Mark::Line => {
                            // a gap in the abscissae (rows left out, e.g. the
                            // slow rows of an estimate) is a break in the line,
                            // not a straight segment across it
                            let mut segs = super::line_segments(&pts).into_iter();
                            let first = segs.next().unwrap_or_default();
                            for seg in segs {
                                chart.draw_series(LineSeries::new(seg, c.stroke_width(1))).map_err(perr(path))?;
                            }
                            chart.draw_series(LineSeries::new(first, c.stroke_width(1))).map_err(perr(path))?
                        }
                        Mark::Points => chart
                            .draw_series(pts.iter().map(|&(a, b)| Circle::new((a, b), 2, c.filled())))
                            .map_err(perr(path))?,
                        Mark::Bars => {
                            let base = if p.log_y { y0 } else { 0.0 };
                            // bars 60 % of the spacing of the abscissae wide
                            let half = 0.3 * super::min_spacing(&s.x).unwrap_or(0.05 * (x1 - x0)).min(0.1 * (x1 - x0));
                            chart
                                .draw_series(pts.iter().map(|&(a, b)| Rectangle::new([(a - half, base), (a + half, b)], c.filled())))
                                .map_err(perr(path))?
                        }
                    };
                    if !s.label.is_empty() {
                        any_label = true;
                        let a = anno.label(s.label.clone());
                        // the legend's glyph is the series' mark: a dot for points
                        if s.mark == Mark::Points {
                            a.legend(move |(x, y)| Circle::new((x + 7, y), 3, c.filled()));
                        } else {
                            a.legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 14, y)], c.stroke_width(2)));
                        }
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
                        .draw_series(DashedLineSeries::new(vec![(x0, *v), (x1, *v)], 4, 3, RED.stroke_width(2)))
                        .map_err(perr(path))?;
                    if !label.is_empty() {
                        any_label = true;
                        // dashed in the legend too: two strokes with a gap
                        anno.label(label.clone()).legend(|(x, y)| {
                            EmptyElement::at((x, y))
                                + PathElement::new(vec![(0, 0), (5, 0)], RED.stroke_width(2))
                                + PathElement::new(vec![(9, 0), (14, 0)], RED.stroke_width(2))
                        });
                        // one legend entry per label is enough
                    }
                }
                if names {
                    // the category names, rotated by 90°, each starting 6 px
                    // under the axis at its slot (plotters centres rotated
                    // tick labels on the tick, half of them inside the plot)
                    let base = area.get_base_pixel();
                    let style = ("sans-serif", 10)
                        .into_font()
                        .transform(FontTransform::Rotate90)
                        .color(&BLACK)
                        .pos(Pos::new(HPos::Left, VPos::Center));
                    for (i, name) in p.x_names.iter().enumerate() {
                        let (px, py) = chart.backend_coord(&((i + 1) as f64, y0));
                        area.draw(&Text::new(name.clone(), (px - base.0, py - base.1 + 6), style.clone()))
                            .map_err(perr(path))?;
                    }
                }
                if any_label {
                    let corner = match corner {
                        0 => SeriesLabelPosition::UpperLeft,
                        1 => SeriesLabelPosition::UpperRight,
                        2 => SeriesLabelPosition::LowerLeft,
                        _ => SeriesLabelPosition::LowerRight,
                    };
                    chart
                        .configure_series_labels()
                        .position(corner)
                        .background_style(WHITE.mix(0.8))
                        .border_style(BLACK.mix(0.3))
                        .label_font(("sans-serif", 10))
                        .draw()
                        .map_err(perr(path))?;
                }
            }};
        }
        // log axes: ticks at the decades (and 2, 5 between them on short
        // ranges) instead of plotters' default points, whose labels collide
        let lx = || (x0..x1).log_scale().with_key_points(super::log_ticks(x0, x1));
        let ly = || (y0..y1).log_scale().with_key_points(super::log_ticks(y0, y1));
        match (p.log_x, p.log_y) {
            (false, false) => body!(b.build_cartesian_2d(x0..x1, y0..y1).map_err(perr(path))?),
            (false, true) => body!(b.build_cartesian_2d(x0..x1, ly()).map_err(perr(path))?),
            (true, false) => body!(b.build_cartesian_2d(lx(), y0..y1).map_err(perr(path))?),
            (true, true) => body!(b.build_cartesian_2d(lx(), ly()).map_err(perr(path))?),
        }
        Ok(())
    }
}
