//! The text report of an identification (`report.txt`) and the blocks it
//! shares with the study report.

use super::{Consistent, Errors, Estimate, Filter, Implausible, TruthRow};

/// The report's table of the estimated base parameters (one-run and study reports).
pub(crate) fn parameter_table(names: &[String], theta: &[f64], std: &[f64], rel_std: &[f64], groupings: &[String]) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let _ = writeln!(s, "\n{:>3} {:<10} {:>14} {:>12} {:>9}  grouping", "i", "parameter", "estimate", "std", "σ* (%)");
    for i in 0..names.len() {
        let _ = writeln!(
            s,
            "{:>3} {:<10} {:>14.6} {:>12.4e} {:>9.3}  {}",
            i + 1,
            names[i],
            theta[i],
            std[i],
            100.0 * rel_std[i],
            groupings[i]
        );
    }
    s
}

/// The report's blocks on negative base parameters that must be positive and
/// on the comparison with the truth (shared by one-run and study reports).
pub(crate) fn plausibility_and_truth_text(implausible: &[Implausible], truth: Option<&[TruthRow]>) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    if implausible.is_empty() {
        let _ = writeln!(s, "\nphysical plausibility: every base parameter that must be positive is positive");
    } else {
        let _ = writeln!(s, "\nphysical plausibility: NEGATIVE estimates of parameters that must be positive:");
        for p in implausible {
            let _ = writeln!(s, "  {} = {:.6} (σ {:.3e}): {}", p.name, p.value, p.std, p.grouping);
        }
    }
    if let Some(t) = truth {
        let _ = writeln!(s, "\ncomparison with the true base parameters");
        let _ = writeln!(s, "{:<10} {:>14} {:>14} {:>8}", "parameter", "truth", "estimate", "z");
        for r in t {
            let _ = writeln!(s, "{:<10} {:>14.6} {:>14.6} {:>8.2}", r.name, r.truth, r.estimate, r.z);
        }
        let zmax = t.iter().map(|r| r.z.abs()).fold(0.0, f64::max);
        let _ = writeln!(s, "max |z| = {zmax:.2}");
    }
    s
}

impl Estimate {
    /// The consistent block of the text report.
    fn consistent_text(&self, c: &Consistent) -> String {
        use std::fmt::Write;
        let mut s = String::new();
        let _ = writeln!(
            s,
            "\nphysically consistent estimate (pseudo-inertias ⪰ {} I, drive signs; closest-to-nominal weight {}): {}",
            c.options.margin, c.options.regularization, c.status
        );
        let _ = writeln!(
            s,
            "  Clarabel: {} iterations, {:.1} ms; weighted SSR + {:.4e} over {} ({:.3} %); χ²/dof {:.4} (unconstrained {:.4})",
            c.iterations,
            1e3 * c.solve_time,
            c.extra_cost,
            self.method,
            100.0 * c.extra_cost_rel,
            c.chi2_dof,
            self.chi2_dof
        );
        let e_row = |s: &mut String, title: &str, a: &Errors, b: &Errors| {
            let _ = writeln!(s, "  {title}");
            let _ = writeln!(
                s,
                "  {:>5} {:>14} {:>14} {:>14} {:>14}",
                "joint", "e*_j uncons.", "e*_j consist.", "e_j uncons.", "e_j consist."
            );
            for j in 0..a.e.len().min(b.e.len()) {
                let _ = writeln!(
                    s,
                    "  {:>5} {:>13.3}% {:>13.3}% {:>14.4e} {:>14.4e}",
                    j + 1,
                    100.0 * a.e_rel[j],
                    100.0 * b.e_rel[j],
                    a.e[j],
                    b.e[j]
                );
            }
        };
        e_row(&mut s, "every sample of the identification run:", &self.errors_all, &c.errors_all);
        if let (Some(a), Some(b)) = (&self.validation_all, &c.validation_all) {
            e_row(&mut s, "every sample of the validation run:", a, b);
        }
        if c.active.is_empty() {
            let _ = writeln!(s, "  active constraints: none (the unconstrained estimate is consistent)");
        } else {
            let _ = writeln!(s, "  active constraints:");
            for a in &c.active {
                let what = if a.constraint == "pseudo_inertia" {
                    format!("pseudo-inertia of link `{}` (smallest eigenvalue − margin {:.3e})", a.what, a.value)
                } else {
                    format!("{} = {:.3e} at its sign bound", a.what, a.value)
                };
                let _ = writeln!(s, "    {what}");
            }
        }
        let _ = writeln!(
            s,
            "  smallest pseudo-inertia eigenvalues (kg·m²): [{}]",
            c.min_eigenvalue.iter().map(|x| format!("{x:.3e}")).collect::<Vec<_>>().join(", ")
        );
        let _ = writeln!(s, "  {:<10} {:>14} {:>14} {:>10}", "base", "unconstrained", "consistent", "Δ/σ");
        for i in 0..self.names.len() {
            let d = (c.base[i] - self.theta[i]) / self.std[i].max(1e-300);
            let _ = writeln!(s, "  {:<10} {:>14.6} {:>14.6} {:>10.2}", self.names[i], self.theta[i], c.base[i], d);
        }
        s
    }

    /// The text report (`report.txt`).
    pub fn text(&self) -> String {
        use std::fmt::Write;
        let mut s = String::new();
        let _ = writeln!(s, "identification: method {}, status {}", self.method.words(), self.status);
        let _ = writeln!(
            s,
            "data: {} repetitions {}, {} samples per joint, {} coordinates, filter {}",
            self.n_reps,
            if self.averaged {
                "(averaged upstream, per-sample variances given)"
            } else {
                "averaged"
            },
            self.n_samples,
            self.coordinates,
            match &self.filter {
                Filter::Fourier { omega, n_h } => format!("Fourier (ω = {omega:.6} rad/s, {n_h} harmonics)"),
                Filter::LowPass { cutoff } => format!("zero-phase low-pass {cutoff} Hz + central differences"),
                Filter::None => "none (central differences)".into(),
            }
        );
        let _ = writeln!(s, "velocities: {}", self.velocity.words(&self.filter));
        for w in &self.warnings {
            let _ = writeln!(s, "WARNING: {w}");
        }
        if let Some(t) = &self.torque_source {
            let _ = writeln!(s, "{}", t.text());
        }
        let _ = writeln!(s, "rows used for the estimate (standstill rule):");
        for r in &self.rows_used {
            let _ = writeln!(s, "  {:<12} {:>7} of {:>7}  {}", r.joint, r.used, r.total, r.reason);
        }
        let _ = writeln!(
            s,
            "design matrix: {} parameters, rank {}, cond {:.4e} (unit-norm columns {:.4}), χ²/dof {:.4}",
            self.names.len(),
            self.rank,
            self.cond,
            self.cond_normalized,
            self.chi2_dof
        );
        if let Some(p) = &self.projection {
            let _ = writeln!(
                s,
                "projection method: FIR lags M1 = {}, M2 = {} ({}), instrument rank {}, corr(û, ũ) = [{}], explained = [{}]",
                p.m1,
                p.m2,
                p.rule,
                p.instrument_rank,
                p.corr.iter().map(|x| format!("{x:.1e}")).collect::<Vec<_>>().join(", "),
                p.explained.iter().map(|x| format!("{x:.4}")).collect::<Vec<_>>().join(", ")
            );
        }
        if let Some(m) = &self.ml {
            let _ = writeln!(
                s,
                "maximum likelihood: {} after {} evaluations, cost {:.6e} → {:.6e}",
                m.status, m.evaluations, m.cost_start, m.cost_end
            );
        }
        s.push_str(&parameter_table(&self.names, &self.theta, &self.std, &self.rel_std, &self.groupings));
        let err_block = |s: &mut String, title: &str, e: &Errors| {
            let _ = writeln!(s, "\n{title}");
            let _ = writeln!(
                s,
                "{:>5} {:>12} {:>9} {:>12} {:>12}",
                "joint", "e_j (N·m)", "e*_j (%)", "rms (N·m)", "noise floor"
            );
            for j in 0..e.e.len() {
                let nf = e.noise_floor.as_ref().map(|v| format!("{:.4e}", v[j])).unwrap_or_else(|| "-".into());
                let _ = writeln!(s, "{:>5} {:>12.4e} {:>9.3} {:>12.4e} {:>12}", j + 1, e.e[j], 100.0 * e.e_rel[j], e.rms[j], nf);
            }
        };
        err_block(
            &mut s,
            "prediction errors on every sample of the identification run (eq. 11–12)",
            &self.errors_all,
        );
        err_block(
            &mut s,
            "prediction errors on the rows used for the estimate (identification run, rows chosen by the standstill rule above)",
            &self.errors,
        );
        if let Some(v) = &self.validation_all {
            err_block(&mut s, "prediction errors on every sample of the validation run", v);
        }
        if let Some(v) = &self.validation {
            err_block(&mut s, "prediction errors on the validation run's rows selected like the estimate's", v);
        }
        if let Some(c) = &self.consistent {
            s.push_str(&self.consistent_text(c));
        }
        s.push_str(&plausibility_and_truth_text(&self.implausible, self.truth.as_deref()));
        if let Some(r) = &self.reduction {
            let _ = writeln!(s);
            s.push_str(&r.text());
        }
        s
    }
}
