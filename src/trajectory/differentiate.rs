//! Numerical differentiation of uniformly sampled signals (rows: samples,
//! columns: joints), shared by the reference motions and the processing of
//! measured runs.

/// Central differences of a uniformly sampled signal: (first, second) derivative.
/// Periodic signals wrap around; otherwise the ends use one-sided differences.
pub fn differentiate(q: &[Vec<f64>], dt: f64, periodic: bool) -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
    let m = q.len();
    let n = q.first().map_or(0, |v| v.len());
    let mut qd = vec![vec![0.0; n]; m];
    let mut qdd = vec![vec![0.0; n]; m];
    if m < 3 {
        return (qd, qdd);
    }
    for i in 0..m {
        // centre of the stencil: i itself, or its inner neighbour at the ends of a non-periodic signal
        let c = if periodic { i } else { i.clamp(1, m - 2) };
        let (cm, cp) = ((c + m - 1) % m, (c + 1) % m);
        for j in 0..n {
            qdd[i][j] = (q[cp][j] - 2.0 * q[c][j] + q[cm][j]) / (dt * dt);
            qd[i][j] = if periodic || (i > 0 && i < m - 1) {
                (q[cp][j] - q[cm][j]) / (2.0 * dt)
            } else if i == 0 {
                (q[1][j] - q[0][j]) / dt
            } else {
                (q[m - 1][j] - q[m - 2][j]) / dt
            };
        }
    }
    (qd, qdd)
}
