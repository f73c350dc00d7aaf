//! The finite-difference checks shared by the excitation tests
//! (tests/excite_bspline.rs, tests/excite_free_ends.rs): the criterion's
//! gradient and the constraints' Jacobian against central differences.

use idexp::excitation::constraints::Constraints;
use idexp::excitation::objective::Objective;

/// Deterministic values in (−scale, scale).
pub fn values(n: usize, scale: f64, seed: f64) -> Vec<f64> {
    (0..n).map(|i| scale * ((i as f64 + 1.0) * 12.9898 + seed * 78.233).sin()).collect()
}

/// The criterion's analytic gradient at x against central differences
/// (step 1e-6): each entry within 1e-4 of the largest entry plus 1e-6 of
/// itself. Returns the criterion value (finite, > 1: a condition number or
/// a non-degenerate −log det checked by the caller).
pub fn check_objective_gradient(o: &Objective, x: &[f64], label: &str) -> f64 {
    let mut w = o.workspace();
    let mut g = vec![0.0; x.len()];
    let f = o.value_grad(x, &mut w, &mut g);
    assert!(f.is_finite(), "{label}: {f}");
    let gmax = g.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    assert!(gmax > 0.0, "{label}: a zero gradient");
    let h = 1e-6;
    for i in 0..x.len() {
        let (mut xp, mut xm) = (x.to_vec(), x.to_vec());
        xp[i] += h;
        xm[i] -= h;
        let fd = (o.value(&xp, &mut w) - o.value(&xm, &mut w)) / (2.0 * h);
        assert!(
            (fd - g[i]).abs() <= 1e-4 * gmax + 1e-6 * g[i].abs(),
            "{label} var {i}: analytic {} vs fd {fd}",
            g[i]
        );
    }
    f
}

/// The constraints' analytic Jacobian at x against central differences
/// (step 1e-7): entry (i, v) within `tol(name of constraint i)` of row i's
/// largest entry (at least 1e-6). Asserts that the Jacobian is not trivially
/// zero (more nonzero entries than constraints).
#[allow(dead_code)]
pub fn check_constraint_jacobian(c: &Constraints, x: &[f64], tol: impl Fn(&str) -> f64) {
    check_constraint_jacobian_floor(c, x, tol, 1e-6)
}

/// [`check_constraint_jacobian`] with the row scale at least `floor`: for
/// rows that hardly depend on x (a distance whose minimum sits where the
/// motion rests), whose parabola-refined gradient differs from the
/// difference quotient by amounts far below any step SLSQP takes.
#[allow(dead_code)]
pub fn check_constraint_jacobian_floor(c: &Constraints, x: &[f64], tol: impl Fn(&str) -> f64, floor: f64) {
    let nv = x.len();
    let mut cw = c.workspace();
    let mut val = vec![0.0; c.len()];
    let mut jac = vec![0.0; c.len() * nv];
    c.eval(x, &mut cw, &mut val, Some(&mut jac));
    let (mut vp, mut vm) = (vec![0.0; c.len()], vec![0.0; c.len()]);
    let h = 1e-7;
    let mut nonzero = 0;
    for v in 0..nv {
        let (mut xp, mut xm) = (x.to_vec(), x.to_vec());
        xp[v] += h;
        xm[v] -= h;
        c.eval(&xp, &mut cw, &mut vp, None);
        c.eval(&xm, &mut cw, &mut vm, None);
        for i in 0..c.len() {
            let fd = (vp[i] - vm[i]) / (2.0 * h);
            let an = jac[i * nv + v];
            nonzero += usize::from(an != 0.0);
            let rowmax = (0..nv).map(|k| jac[i * nv + k].abs()).fold(0.0, f64::max);
            assert!(
                (fd - an).abs() <= tol(&c.info[i].name) * rowmax.max(floor),
                "constraint `{}` var {v}: analytic {an} vs fd {fd}",
                c.info[i].name
            );
        }
    }
    assert!(nonzero > c.len(), "the Jacobian is not trivially zero");
}
