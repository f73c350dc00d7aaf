//! The extrema of a joint's position, velocity or acceleration over the
//! continuous motion of a trajectory shape: a scan, then Newton steps on
//! the analytic derivatives.

use crate::trajectory::{Motion, TimeGrid, TrajectoryShape};

/// m-th time derivative of q_j at t (m = 0 is q_j itself).
pub fn series_derivative<M: Motion + ?Sized>(tr: &M, j: usize, m: usize, t: f64) -> f64 {
    series_derivatives(tr, j, m, t)[0]
}

/// Time derivatives of orders m, m+1, m+2 of q_j at t ([`Motion::derivatives`]:
/// for a Fourier series with one sin_cos and the angle-addition recurrence).
pub fn series_derivatives<M: Motion + ?Sized>(tr: &M, j: usize, m: usize, t: f64) -> [f64; 3] {
    tr.derivatives(j, m, t)
}

/// Extremum of q_j^(order) over the continuous motion: (value, time).
/// `upper`: maximum, else minimum. `scan` is the shape's uniform grid over
/// the motion ([`TrajectoryShape::scan_times`], taken as periodic: a
/// rest-to-rest motion ends where it starts): the best two grid local
/// extrema are refined by Newton steps on d/dt q_j^(order) = 0.
pub fn joint_extremum<S: TrajectoryShape>(shape: &S, tr: &S::Motion, scan: &S::Grid, j: usize, order: usize, upper: bool) -> (f64, f64) {
    let mut raw = Vec::new();
    shape.grid_series(scan, tr, j, order, &mut raw);
    joint_extremum_scanned(tr, scan, &raw, j, order, upper)
}

/// [`joint_extremum`] from the scan's values of q_j^(order) (`raw`,
/// [`TrajectoryShape::grid_series`]), which serve both the maximum and the
/// minimum.
pub fn joint_extremum_scanned<G: TimeGrid, M: Motion + ?Sized>(tr: &M, scan: &G, raw: &[f64], j: usize, order: usize, upper: bool) -> (f64, f64) {
    let sgn = if upper { 1.0 } else { -1.0 };
    let ns = raw.len();
    let val = |i: usize| sgn * raw[i];
    let scan = scan.times();
    let mut cand: [Option<usize>; 2] = [None, None];
    for i in 0..ns {
        let vi = val(i);
        if vi >= val((i + ns - 1) % ns) && vi >= val((i + 1) % ns) {
            match cand {
                [None, _] => cand[0] = Some(i),
                [Some(a), None] => {
                    if vi > val(a) {
                        cand = [Some(i), Some(a)];
                    } else {
                        cand[1] = Some(i);
                    }
                }
                [Some(a), Some(b)] => {
                    if vi > val(a) {
                        cand = [Some(i), Some(a)];
                    } else if vi > val(b) {
                        cand[1] = Some(i);
                    }
                }
            }
        }
    }
    if cand[0].is_none() {
        return (sgn * val(0), scan[0]);
    }
    let h = if ns > 1 { scan[1] - scan[0] } else { 1.0 };
    let (mut best, mut tbest) = (f64::NEG_INFINITY, 0.0);
    for i in cand.iter().flatten().copied() {
        let (mut t, mut fv) = (scan[i], val(i));
        let t_grid = t;
        let mut d = series_derivatives(tr, j, order, t);
        for _ in 0..8 {
            let (d1, d2) = (sgn * d[1], sgn * d[2]);
            if d2 >= 0.0 {
                break;
            }
            let step = -d1 / d2;
            let tn = t + step;
            if (tn - t_grid).abs() > 1.5 * h {
                break;
            }
            let dn = series_derivatives(tr, j, order, tn);
            let fnv = sgn * dn[0];
            if fnv < fv - 1e-15 * fv.abs().max(1.0) {
                break;
            }
            t = tn;
            fv = fnv;
            d = dn;
            if step.abs() < 1e-9 * h {
                break;
            }
        }
        if fv > best {
            best = fv;
            tbest = t;
        }
    }
    (sgn * best, tbest)
}
