//! The sensor chain between a robot's logged positions and its logged
//! currents: a delay (one per log, sub-sample), per-joint offsets and signs.
//! The kernels here are the delay's: reading a uniformly sampled series a
//! fraction of a sample later (a Fourier phase shift), minimising a scalar function
//! of the delay (a grid, then golden section), and the delay's σ from the
//! curvature of χ²(δ). The offsets and signs are unknowns of the gain
//! calibration's least squares ([`super::gains`]).

/// The series `x` (uniform samples) read `shift` samples later, x(s + shift),
/// by a phase shift of its discrete Fourier transform: a unitary operation,
/// so white noise keeps its variance at every fractional shift (cubic
/// interpolation would smooth it by up to 36 % at half a sample and pull a
/// least-squares delay estimate there). The straight line through the end
/// samples is taken out first and shifted exactly, so that a run that is not
/// periodic has no jump at the wrap; its first and last samples are still
/// the least exact (leave a margin there).
pub fn shifted(x: &[f64], shift: f64) -> Vec<f64> {
    use rustfft::num_complex::Complex;
    let m = x.len();
    if m < 2 || shift == 0.0 {
        return x.to_vec();
    }
    let slope = (x[m - 1] - x[0]) / (m - 1) as f64;
    let line = |s: f64| x[0] + slope * s;
    let mut buf: Vec<Complex<f64>> = x.iter().enumerate().map(|(s, v)| Complex::new(v - line(s as f64), 0.0)).collect();
    let mut planner = rustfft::FftPlanner::new();
    planner.plan_fft_forward(m).process(&mut buf);
    for (k, b) in buf.iter_mut().enumerate() {
        let f = if 2 * k < m {
            k as f64
        } else if 2 * k == m {
            // the Nyquist bin: its real part shifted (keeps the series real)
            *b *= (std::f64::consts::PI * shift).cos();
            continue;
        } else {
            k as f64 - m as f64
        };
        *b *= Complex::from_polar(1.0, std::f64::consts::TAU * f * shift / m as f64);
    }
    planner.plan_fft_inverse(m).process(&mut buf);
    buf.iter().enumerate().map(|(s, c)| c.re / m as f64 + line(s as f64 + shift)).collect()
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
    fn a_fourier_shift_moves_a_periodic_series_and_keeps_white_noise_power() {
        let m = 500;
        let s: Vec<f64> = (0..m)
            .map(|k| (std::f64::consts::TAU * 3.0 * k as f64 / m as f64).sin() + 0.01 * k as f64)
            .collect();
        let y = shifted(&s, 0.4);
        for k in 100..400 {
            let want = (std::f64::consts::TAU * 3.0 * (k as f64 + 0.4) / m as f64).sin() + 0.01 * (k as f64 + 0.4);
            assert!((y[k] - want).abs() < 1e-3, "{k}: {} vs {want}", y[k]);
        }
        // pseudo-random ±1 noise: the power is the same at every shift (Parseval)
        let mut r = 12345u64;
        let noise: Vec<f64> = (0..m)
            .map(|_| {
                r = r.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                if r >> 63 == 0 {
                    1.0
                } else {
                    -1.0
                }
            })
            .collect();
        let p = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>();
        let p0 = p(&noise);
        let p5 = p(&shifted(&noise, 0.5));
        let p3 = p(&shifted(&noise, 0.3));
        assert!((p3 - p0).abs() / p0 < 0.05 && (p5 - p0).abs() / p0 < 0.05, "{p0} {p3} {p5}");
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
