//! The SVG figures: singular values, joint trajectories, the end-effector path.

use crate::error::Result;
use crate::excitation::ExciteResult;
use crate::excitation::Problem;
use crate::io::plot::{write_svg, Panel, Series};
use crate::robot::Workspace;
use std::path::Path;

pub(super) fn spectrum_svg(path: &Path, s: &[f64], title: &str) -> Result<()> {
    let x: Vec<f64> = (1..=s.len()).map(|i| i as f64).collect();
    let panel = Panel {
        title: "singular values of the unit-column regressor".into(),
        x_label: "index".into(),
        y_label: "σ".into(),
        series: vec![Series::bars("σ_i", x, s.to_vec())],
        log_y: true,
        ..Default::default()
    };
    write_svg(path, title, &[panel], 1)
}

/// The search's best feasible criterion over the criterion evaluations
/// (result.progress), as steps held until the end of the search. Over
/// evaluations, not seconds: the figure is the same for any thread count
/// and machine load (the seconds of each improvement are in report.json's
/// `result.progress` and report.txt).
pub(super) fn progress_svg(path: &Path, r: &ExciteResult, criterion: &str, title: &str) -> Result<()> {
    let pts = &r.progress;
    let steps = |x: &dyn Fn(&crate::excitation::ProgressPoint) -> f64, end: f64| -> (Vec<f64>, Vec<f64>) {
        let (mut xs, mut ys) = (Vec::new(), Vec::new());
        for (k, q) in pts.iter().enumerate() {
            if k > 0 {
                xs.push(x(q));
                ys.push(pts[k - 1].best);
            }
            xs.push(x(q));
            ys.push(q.best);
        }
        if let Some(q) = pts.last() {
            xs.push(end.max(x(q)));
            ys.push(q.best);
        }
        (xs, ys)
    };
    let log_y = pts.iter().all(|q| q.best > 0.0);
    let evaluations = r.ga.evaluations + r.refinements.iter().map(|f| f.evaluations).sum::<u64>();
    let (e, ye) = steps(&|q| q.evaluations as f64, evaluations as f64);
    let panel = |x_label: &str, x: Vec<f64>, y: Vec<f64>| Panel {
        title: format!("best feasible {criterion} found (design grid)"),
        x_label: x_label.into(),
        y_label: criterion.into(),
        series: vec![
            Series::line("best so far", x, y),
            Series::points(
                "improvements",
                pts.iter().map(|q| q.evaluations as f64).collect(),
                pts.iter().map(|q| q.best).collect(),
            ),
        ],
        log_y,
        ..Default::default()
    };
    write_svg(path, title, &[panel("criterion evaluations", e, ye)], 1)
}

/// The trajectory the plots show: the delivered one (lead-in, periods,
/// lead-out) when there is one, else one period. Samples at `rate` Hz with
/// their phase names; each phase as its own run of samples, the first sample
/// of the next phase repeated at its end so that the curve is continuous.
struct PlotPhases {
    names: Vec<String>,
    t: Vec<Vec<f64>>,
    q: Vec<Vec<Vec<f64>>>,
    qd: Vec<Vec<Vec<f64>>>,
}

fn plot_phases(r: &ExciteResult, rate: f64) -> Result<PlotPhases> {
    let mut out = PlotPhases {
        names: Vec::new(),
        t: Vec::new(),
        q: Vec::new(),
        qd: Vec::new(),
    };
    match &r.execution.delivered {
        Some(d) => {
            let s = d.sample(rate)?;
            let mut k = 0;
            while k < s.len() {
                let seg = s.segment[k];
                let mut e = k;
                while e < s.len() && s.segment[e] == seg {
                    e += 1;
                }
                let last = e.min(s.len() - 1);
                out.names.push(match seg {
                    0 => "lead-in".to_string(),
                    -1 => "lead-out".to_string(),
                    p => format!("period {p}"),
                });
                out.t.push(s.t[k..=last].to_vec());
                out.q.push(s.q[k..=last].to_vec());
                out.qd.push(s.qd[k..=last].to_vec());
                k = e;
            }
        }
        None => {
            let s = r.trajectory.sample(rate)?;
            out.names.push("one period (no delivered trajectory)".into());
            out.t.push(s.t.clone().unwrap_or_default());
            out.q.push(s.q.clone());
            out.qd.push(s.qd.clone());
        }
    }
    Ok(out)
}

pub(super) fn joints_svg(p: &Problem, r: &ExciteResult, path: &Path) -> Result<()> {
    let n = p.robot.dof();
    let rate = (400.0 * p.design.trajectory.frequency).max(50.0 * p.design.trajectory.frequency * p.design.trajectory.harmonics as f64);
    let ph = plot_phases(r, rate)?;
    let unit = |j: usize, d: &str| -> String {
        let lin = p.robot.joints[j].kind == crate::robot::JointKind::Prismatic;
        format!("{}{d}", if lin { "m" } else { "rad" })
    };
    // one legend (first panel) names the phases; the colours repeat in every panel
    let series = |j: usize, first: bool, get: &dyn Fn(usize, usize) -> Vec<f64>| -> Vec<Series> {
        (0..ph.names.len())
            .map(|k| Series::line(if first { ph.names[k].clone() } else { String::new() }, ph.t[k].clone(), get(k, j)))
            .collect()
    };
    let mut panels = Vec::new();
    for j in 0..n {
        let name = &p.robot.joints[j].name;
        let mut hl = Vec::new();
        let [lo, hi] = p.limits.position[j];
        // one legend in all (first panel): the phases and the limit lines
        let lim = if j == 0 { "limit".to_string() } else { String::new() };
        if lo.is_finite() {
            hl.push((lo, lim.clone()));
        }
        if hi.is_finite() {
            hl.push((hi, if lo.is_finite() { String::new() } else { lim.clone() }));
        }
        panels.push(Panel {
            title: format!("q{} ({name})", j + 1),
            x_label: "t (s)".into(),
            y_label: unit(j, ""),
            series: series(j, j == 0, &|k, j| ph.q[k].iter().map(|v| v[j]).collect()),
            hlines: hl,
            ..Default::default()
        });
        let mut hv = Vec::new();
        let v = p.limits.velocity[j];
        if v.is_finite() {
            hv.push((v, String::new()));
            hv.push((-v, String::new()));
        }
        panels.push(Panel {
            title: format!("qd{} ({name})", j + 1),
            x_label: "t (s)".into(),
            y_label: unit(j, "/s"),
            series: series(j, false, &|k, j| ph.qd[k].iter().map(|v| v[j]).collect()),
            hlines: hv,
            ..Default::default()
        });
    }
    let what = if r.execution.delivered.is_some() {
        "delivered joint trajectory (lead-in, periods, lead-out), limits dashed red"
    } else {
        "joint trajectory (one period), limits dashed red"
    };
    write_svg(path, &format!("{}: {what}", p.design.name), &panels, 2)
}

pub(super) fn ee_svg(p: &Problem, r: &ExciteResult, path: &Path) -> Result<()> {
    let frame = match p.design.workspace.first() {
        Some(c) => c.resolve(&p.robot, "design", "workspace[0]")?,
        None => p.robot.end_effector(),
    };
    let mut ph = plot_phases(r, (200.0 * p.design.trajectory.frequency).max(20.0))?;
    // the periods trace the same closed path: one series for all of them
    let periods: Vec<usize> = (0..ph.names.len()).filter(|&k| ph.names[k].starts_with("period ")).collect();
    if periods.len() > 1 {
        let (k0, n) = (periods[0], periods.len());
        ph.names[k0] = format!("periods 1–{n} (one closed path)");
        for &k in periods[1..].iter().rev() {
            ph.names.remove(k);
            ph.t.remove(k);
            ph.q.remove(k);
            ph.qd.remove(k);
        }
    }
    let mut ws = Workspace::new(&p.robot);
    let paths: Vec<Vec<[f64; 3]>> =
        ph.q.iter()
            .map(|qs| {
                qs.iter()
                    .map(|q| {
                        let v = crate::excitation::constraints::frame_point(&p.robot, &mut ws, q, &frame);
                        [v.x, v.y, v.z]
                    })
                    .collect()
            })
            .collect();
    let all: Vec<[f64; 3]> = paths.iter().flatten().copied().collect();
    let ax = ["x", "y", "z"];
    let mut panels = Vec::new();
    for (pi, (a, b)) in [(0usize, 1usize), (0, 2), (1, 2)].into_iter().enumerate() {
        let mut series: Vec<Series> = paths
            .iter()
            .enumerate()
            .map(|(k, pts)| {
                Series::line(
                    if pi == 0 { ph.names[k].clone() } else { String::new() },
                    pts.iter().map(|v| v[a]).collect(),
                    pts.iter().map(|v| v[b]).collect(),
                )
            })
            .collect();
        let (lo, hi) = bounds(&all);
        for (ci, c) in p.design.workspace.iter().enumerate() {
            for (k, (xs, ys)) in outline(&c.shape, a, b, lo, hi).into_iter().enumerate() {
                series.push(Series::line(if k == 0 { format!("constraint {}", ci + 1) } else { String::new() }, xs, ys));
            }
        }
        panels.push(Panel {
            title: format!("{}–{} projection", ax[a], ax[b]),
            x_label: format!("{} (m)", ax[a]),
            y_label: format!("{} (m)", ax[b]),
            series,
            ..Default::default()
        });
    }
    write_svg(
        path,
        &format!(
            "{}: {} path (delivered trajectory by phase) and workspace constraints",
            p.design.name, frame.name
        ),
        &panels,
        3,
    )
}

fn bounds(pts: &[[f64; 3]]) -> ([f64; 3], [f64; 3]) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in pts {
        for i in 0..3 {
            lo[i] = lo[i].min(p[i]);
            hi[i] = hi[i].max(p[i]);
        }
    }
    for i in 0..3 {
        let pad = 0.2 * (hi[i] - lo[i]).max(0.1);
        lo[i] -= pad;
        hi[i] += pad;
    }
    (lo, hi)
}

/// Outline(s) of a shape projected on axes (a, b), as polylines.
fn outline(shape: &crate::robot::cartesian::Shape, a: usize, b: usize, lo: [f64; 3], hi: [f64; 3]) -> Vec<(Vec<f64>, Vec<f64>)> {
    use crate::robot::cartesian::Shape;
    let rect = |mn: [f64; 3], mx: [f64; 3]| (vec![mn[a], mx[a], mx[a], mn[a], mn[a]], vec![mn[b], mn[b], mx[b], mx[b], mn[b]]);
    match shape {
        Shape::Box { min, max } => vec![rect(*min, *max)],
        Shape::OutsideBox { min, max, clearance } => {
            let mn = [min[0] - clearance, min[1] - clearance, min[2] - clearance];
            let mx = [max[0] + clearance, max[1] + clearance, max[2] + clearance];
            vec![rect(mn, mx)]
        }
        Shape::Sphere { center, radius } => {
            let k = 72;
            let th: Vec<f64> = (0..=k).map(|i| std::f64::consts::TAU * i as f64 / k as f64).collect();
            vec![(
                th.iter().map(|t| center[a] + radius * t.cos()).collect(),
                th.iter().map(|t| center[b] + radius * t.sin()).collect(),
            )]
        }
        Shape::HalfSpace { normal, offset } => {
            let nn = (normal[0] * normal[0] + normal[1] * normal[1] + normal[2] * normal[2]).sqrt();
            let nv = [normal[0] / nn, normal[1] / nn, normal[2] / nn];
            let third = 3 - a - b;
            if nv[third].abs() > 1e-9 {
                return vec![];
            }
            // n_a x + n_b y = offset
            if nv[b].abs() > 1e-9 {
                let xs = vec![lo[a], hi[a]];
                let ys = xs.iter().map(|x| (offset - nv[a] * x) / nv[b]).collect();
                vec![(xs, ys)]
            } else {
                let x = offset / nv[a];
                vec![(vec![x, x], vec![lo[b], hi[b]])]
            }
        }
        Shape::Sector { center, azimuth, radius, z } => {
            if (a, b) == (0, 1) {
                let k = 48;
                let arc = |r: f64| -> (Vec<f64>, Vec<f64>) {
                    let ph: Vec<f64> = (0..=k).map(|i| azimuth[0] + (azimuth[1] - azimuth[0]) * i as f64 / k as f64).collect();
                    (
                        ph.iter().map(|p| center[0] + r * p.cos()).collect(),
                        ph.iter().map(|p| center[1] + r * p.sin()).collect(),
                    )
                };
                let ray = |p: f64| {
                    (
                        vec![center[0] + radius[0] * p.cos(), center[0] + radius[1] * p.cos()],
                        vec![center[1] + radius[0] * p.sin(), center[1] + radius[1] * p.sin()],
                    )
                };
                vec![arc(radius[0]), arc(radius[1]), ray(azimuth[0]), ray(azimuth[1])]
            } else {
                let zz = [center[2] + z[0], center[2] + z[1]];
                zz.iter().map(|&h| (vec![lo[a], hi[a]], vec![h, h])).collect()
            }
        }
    }
}
