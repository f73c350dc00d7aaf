//! The sensor chain between a robot's logged positions and its logged
//! currents: a delay (one per log, sub-sample), per-joint offsets and signs.
//! The kernels here are the delay's: reading a uniformly sampled series at a
//! fractional sample index (cubic Catmull–Rom), minimising a scalar function
//! of the delay (a grid, then golden section), and the delay's σ from the
//! curvature of χ²(δ). The offsets and signs are unknowns of the gain
//! calibration's least squares ([`super::gains`]).

/// The value of column `j` of the uniformly sampled series `x` (one row per
/// sample) at the fractional sample index `u`, by cubic Catmull–Rom
/// interpolation (exact for quadratics; the end samples are repeated past the ends).
pub fn sample_at(x: &[Vec<f64>], j: usize, u: f64) -> f64 {
    let m = x.len();
    if m == 0 {
        return f64::NAN;
    }
    let last = (m - 1) as f64;
    let u = u.clamp(0.0, last);
    let i = (u.floor() as usize).min(m.saturating_sub(2));
    let f = u - i as f64;
    let at = |k: isize| x[(k.max(0) as usize).min(m - 1)][j];
    let ii = i as isize;
    let (p0, p1, p2, p3) = (at(ii - 1), at(ii), at(ii + 1), at(ii + 2));
    let f2 = f * f;
    let f3 = f2 * f;
    0.5 * ((2.0 * p1) + (-p0 + p2) * f + (2.0 * p0 - 5.0 * p1 + 4.0 * p2 - p3) * f2 + (-p0 + 3.0 * p1 - 3.0 * p2 + p3) * f3)
}

/// Minimises `f` on [a, b]: `grid` equally spaced points (at least 3), then
/// golden-section search in the interval around the best one down to `tol`.
/// Returns (x, f(x)).
pub fn minimise(mut f: impl FnMut(f64) -> f64, a: f64, b: f64, grid: usize, tol: f64) -> (f64, f64) {
    let grid = grid.max(3);
    let step = (b - a) / (grid - 1) as f64;
    let (mut best, mut fb) = (a, f64::INFINITY);
    let mut ib = 0;
    for i in 0..grid {
        let x = a + step * i as f64;
        let v = f(x);
        if v < fb {
            (best, fb, ib) = (x, v, i);
        }
    }
    let (mut lo, mut hi) = (a + step * ib.saturating_sub(1) as f64, a + step * (ib + 1).min(grid - 1) as f64);
    let g = 0.5 * (5f64.sqrt() - 1.0);
    let mut x1 = hi - g * (hi - lo);
    let mut x2 = lo + g * (hi - lo);
    let (mut f1, mut f2) = (f(x1), f(x2));
    while hi - lo > tol {
        if f1 < f2 {
            hi = x2;
            (x2, f2) = (x1, f1);
            x1 = hi - g * (hi - lo);
            f1 = f(x1);
        } else {
            lo = x1;
            (x1, f1) = (x2, f2);
            x2 = lo + g * (hi - lo);
            f2 = f(x2);
        }
    }
    for (x, v) in [(x1, f1), (x2, f2)] {
        if v < fb {
            (best, fb) = (x, v);
        }
    }
    (best, fb)
}

/// σ of the minimiser of a χ² profile from its curvature: χ²(x ± h) and
/// χ²(x) give χ²'' by central differences, and σ = √(2/χ²'') (∞ when the
/// profile is not convex there).
pub fn sigma_from_curvature(minus: f64, centre: f64, plus: f64, h: f64) -> f64 {
    let c = (minus - 2.0 * centre + plus) / (h * h);
    if c > 0.0 && c.is_finite() {
        (2.0 / c).sqrt()
    } else {
        f64::INFINITY
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn catmull_rom_is_exact_on_quadratics_and_shifts_a_sine() {
        let x: Vec<Vec<f64>> = (0..50).map(|s| vec![0.3 * (s as f64).powi(2) - 2.0 * s as f64 + 1.0]).collect();
        for u in [3.25, 10.5, 20.9] {
            let want = 0.3 * u * u - 2.0 * u + 1.0;
            assert!((sample_at(&x, 0, u) - want).abs() < 1e-9, "{u}");
        }
        // a 1 Hz sine at 100 Hz read 0.4 samples later: within 1e-5 of the sine
        let s: Vec<Vec<f64>> = (0..200).map(|k| vec![(std::f64::consts::TAU * k as f64 / 100.0).sin()]).collect();
        let v = sample_at(&s, 0, 50.4);
        assert!((v - (std::f64::consts::TAU * 50.4 / 100.0).sin()).abs() < 1e-5, "{v}");
    }

    #[test]
    fn minimise_finds_the_minimum_of_a_parabola_and_its_sigma() {
        let (x, fx) = minimise(|x| 4.0 * (x - 0.0031).powi(2) + 2.0, -0.02, 0.02, 17, 1e-7);
        assert!((x - 0.0031).abs() < 1e-6 && (fx - 2.0).abs() < 1e-9, "{x} {fx}");
        // χ² = (x − x0)²/σ² has σ = 0.5
        let chi = |x: f64| (x / 0.5).powi(2);
        assert!((sigma_from_curvature(chi(-0.1), chi(0.0), chi(0.1), 0.1) - 0.5).abs() < 1e-12);
    }
}
