//! The text report of a study (`report.txt`, what `idexp identify study.toml` prints).

use super::{ConsistentReport, Estimate};
use crate::ident::estimate::Errors;
use std::fmt::Write;

fn pct(v: &[f64]) -> String {
    v.iter().map(|x| format!("{:>7.2}", 100.0 * x)).collect::<Vec<_>>().join(" ")
}

fn sci(v: &[f64]) -> String {
    v.iter().map(|x| format!("{x:>10.3e}")).collect::<Vec<_>>().join(" ")
}

fn err_line(s: &mut String, label: &str, e: &Errors) {
    let _ = writeln!(s, "  {label:<28} e*_j (%) [{}]   e_j (N·m) [{}]", pct(&e.e_rel), sci(&e.e));
}

impl Estimate {
    /// The text report.
    pub fn text(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(
            s,
            "identification study `{}` of {}: {} over {} experiment(s), status {}",
            self.name,
            self.robot,
            self.method.words(),
            self.experiments.len(),
            self.status
        );
        let _ = writeln!(
            s,
            "weights: {} ({} reweighting iteration(s){})",
            match self.weights {
                super::WeightSource::Auto => "from the repetitions where an experiment has them, else per experiment and joint from the residuals",
                super::WeightSource::Repetitions => "from the repetitions",
                super::WeightSource::Residuals => "per experiment and joint from the residuals",
            },
            self.iterations,
            if self.converged { ", settled" } else { ", NOT settled" }
        );
        let _ = writeln!(
            s,
            "Coulomb dead band: |q̇| < {} rad/s is rest for a sign(q̇) Coulomb term (no Coulomb torque), in every experiment and validation run (dead_band)",
            self.dead_band
        );
        for w in &self.warnings {
            let _ = writeln!(s, "WARNING: {w}");
        }
        let _ = writeln!(s, "\nexperiments");
        let _ = writeln!(
            s,
            "  {:<16} {:<10} {:>4} {:>8} {:>8} {:>10} {:>9} {:>11}  alone: rank, cond",
            "name", "kind", "reps", "samples", "time (s)", "χ²/row", "info (%)", "filter"
        );
        for e in &self.experiments {
            let filter = match &e.filter {
                crate::ident::Filter::Fourier { n_h, .. } => format!("Fourier {n_h}"),
                crate::ident::Filter::LowPass { cutoff } => format!("LP {cutoff} Hz"),
                crate::ident::Filter::None => "none".into(),
            };
            let _ = writeln!(
                s,
                "  {:<16} {:<10} {:>4} {:>8} {:>8.2} {:>10.4} {:>9.2} {:>11}  {} of {}, {:.4e}",
                e.name,
                e.kind.name(),
                e.n_reps,
                e.n_samples,
                e.duration,
                e.chi2_per_row,
                100.0 * e.information_share,
                filter,
                e.rank_alone,
                self.names.len(),
                e.cond_alone
            );
        }
        let _ = writeln!(s, "\nper experiment and joint");
        for e in &self.experiments {
            let _ = writeln!(s, "  {}: {}; {}", e.name, e.sampling.text(), e.torque_source.text());
            let w: Vec<String> = e
                .weights
                .iter()
                .zip(&e.sigma)
                .map(|(w, sg)| {
                    format!(
                        "{}:{sg:.3e}",
                        serde_json::to_value(w).ok().and_then(|v| v.as_str().map(String::from)).unwrap_or_default()
                    )
                })
                .collect();
            let _ = writeln!(s, "    weights (source: σ N·m) [{}]", w.join(", "));
            let _ = writeln!(s, "    velocities: {}", e.velocity.words(&e.filter));
            for r in &e.rows_used {
                let _ = writeln!(s, "    rows {:<12} {:>7} of {:>7}  {}", r.joint, r.used, r.total, r.reason);
            }
            err_line(&mut s, "  every sample", &e.errors_all);
            err_line(&mut s, "  rows used", &e.errors);
            for wn in &e.warnings {
                let _ = writeln!(s, "    WARNING: {wn}");
            }
        }
        let _ = writeln!(
            s,
            "\n{}: {} parameters, rank {}, cond {:.4e} (unit-norm columns {:.4}), χ²/dof {:.4}",
            if self.is_stacked() { "stacked design √W·C" } else { "design C" },
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
        let _ = writeln!(s, "\n{:>3} {:<10} {:>14} {:>12} {:>9}  grouping", "i", "parameter", "estimate", "std", "σ* (%)");
        for (i, name) in self.names.iter().enumerate() {
            let (t, sd, rs) = (self.theta[i], self.std[i], 100.0 * self.rel_std[i]);
            let _ = writeln!(s, "{:>3} {name:<10} {t:>14.6} {sd:>12.4e} {rs:>9.3}  {}", i + 1, self.groupings[i]);
        }
        if !self.validation.is_empty() {
            let _ = writeln!(
                s,
                "\nvalidation (every sample; least squares{})",
                if self.consistent.is_some() { " | consistent" } else { "" }
            );
            for v in &self.validation {
                let _ = writeln!(s, "  {} ({}, {} samples)", v.name, v.kind.name(), v.n_samples);
                err_line(&mut s, "  least squares", &v.errors_all);
                if let Some(c) = &v.consistent_all {
                    err_line(&mut s, "  consistent", c);
                }
            }
            if let Some(t) = &self.validation_total {
                let _ = writeln!(s, "  all validation runs: e*_j (%) [{}]   e_j (N·m) [{}]", pct(&t.e_rel), sci(&t.e));
                if let Some(c) = &t.consistent_e_rel {
                    let _ = writeln!(s, "  all, consistent:     e*_j (%) [{}]", pct(c));
                }
                let _ = writeln!(s, "  mean relative RMS over runs and joints: {:.4}", t.mean_relative_rms);
            }
        }
        if let Some(c) = &self.consistent {
            s.push_str(&consistent_text(c, self));
        }
        if self.implausible.is_empty() {
            let _ = writeln!(s, "\nphysical plausibility: every base parameter that must be positive is positive");
        } else {
            let _ = writeln!(s, "\nphysical plausibility: NEGATIVE estimates of parameters that must be positive:");
            for p in &self.implausible {
                let _ = writeln!(s, "  {} = {:.6} (σ {:.3e}): {}", p.name, p.value, p.std, p.grouping);
            }
        }
        if let Some(t) = &self.truth {
            let _ = writeln!(s, "\ncomparison with the true base parameters");
            let _ = writeln!(s, "{:<10} {:>14} {:>14} {:>8}", "parameter", "truth", "estimate", "z");
            for r in t {
                let _ = writeln!(s, "{:<10} {:>14.6} {:>14.6} {:>8.2}", r.name, r.truth, r.estimate, r.z);
            }
            let zmax = t.iter().map(|r| r.z.abs()).fold(0.0, f64::max);
            let _ = writeln!(s, "max |z| = {zmax:.2}");
        }
        if let Some(r) = &self.reduction {
            let _ = writeln!(s);
            s.push_str(&r.text());
        }
        s
    }
}

fn consistent_text(c: &ConsistentReport, e: &Estimate) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "\nphysically consistent estimate with a prior: {} (prior `{}`, {} metric, weight {:e}{}, scale {}, margin {})",
        c.status,
        c.prior,
        c.metric.name(),
        c.weight,
        if c.weight_curve.is_empty() { "" } else { ", chosen on the validation runs" },
        c.scale,
        c.margin
    );
    if let Some(tol) = c.weight_tolerance {
        let best = c.weight_curve.iter().map(|x| x.1).fold(f64::INFINITY, f64::min);
        let _ = writeln!(
            s,
            "  validation criterion: mean over runs and joints of RMS(τ − τ̂)/(the joint's torque range over all validation runs); chosen: the strongest prior within one standard error ({tol:.3e}) of the best ({best:.5e}), i.e. ≤ {:.5e}",
            best + tol
        );
    }
    for (w, score, extra) in &c.weight_curve {
        let within = c.weight_tolerance.is_some_and(|tol| {
            let best = c.weight_curve.iter().map(|x| x.1).fold(f64::INFINITY, f64::min);
            *score <= best + tol
        });
        let _ = writeln!(
            s,
            "  weight {w:>9.2e}: validation {score:.5e}{}, weighted SSR + {extra:.4e}{}",
            if within { " (within tolerance)" } else { "" },
            if *w == c.weight { "   <- chosen" } else { "" }
        );
    }
    let _ = writeln!(
        s,
        "  Clarabel: {} iterations, {:.1} ms; weighted SSR + {:.4e} over least squares; χ²/dof {:.4} (least squares {:.4})",
        c.iterations,
        1e3 * c.solve_time,
        c.extra_cost,
        c.chi2_dof,
        e.chi2_dof
    );
    let _ = writeln!(
        s,
        "  {:<14} {:>10} {:>10} {:>26} {:>26} {:>11} {:>11} {:>9}",
        "link", "mass", "prior", "COM (m)", "prior COM", "tr I_c", "prior", "D(J,J₀)"
    );
    for l in &c.links {
        let v = |x: &[f64; 3]| format!("[{:.3}, {:.3}, {:.3}]", x[0], x[1], x[2]);
        let _ = writeln!(
            s,
            "  {:<14} {:>10.4} {:>10.4} {:>26} {:>26} {:>11.4e} {:>11.4e} {:>9.3e}",
            l.link,
            l.mass[0],
            l.mass[1],
            v(&l.com[0]),
            v(&l.com[1]),
            l.inertia_trace[0],
            l.inertia_trace[1],
            l.divergence
        );
    }
    if c.flags.is_empty() {
        let _ = writeln!(s, "  plausibility against the prior: nothing flagged");
    } else {
        let _ = writeln!(s, "  IMPLAUSIBLE against the prior (physically possible):");
        for f in &c.flags {
            let _ = writeln!(s, "    {} = {:.4e}: {}", f.what, f.value, f.reason);
        }
    }
    if !c.active.is_empty() {
        let _ = writeln!(s, "  active constraints:");
        for a in &c.active {
            let _ = writeln!(s, "    {} `{}` ({:.3e})", a.constraint, a.what, a.value);
        }
    }
    let _ = writeln!(
        s,
        "  directions the prior decided: {} not seen by the data at all (null space of the fit), {} seen less than the prior (fit curvature below the weight {:e})",
        c.unidentifiable, c.n_prior_decided, c.weight
    );
    if c.unknown.is_empty() {
        let _ = writeln!(
            s,
            "  drive parameters without a known value: none (every drive parameter is pulled toward its prior value)"
        );
    } else {
        let _ = writeln!(
            s,
            "  drive parameters without a known value (unknown; not pulled toward the prior, pull {:e} of the weight): the data decide them",
            crate::ident::prior::UNKNOWN_PULL
        );
        for u in &c.unknown {
            let seen = if u.std_data.is_finite() {
                format!("σ from the data alone {:.3e}", u.std_data)
            } else {
                "not seen by the data: left at 0".to_string()
            };
            let _ = writeln!(s, "    {:<8} {:>13.6e}  ({seen})", u.name, u.value);
        }
    }
    for d in &c.prior_decided {
        let comp: Vec<String> = d.components.iter().map(|(n, v)| format!("{v:+.2}·{n}")).collect();
        let _ = writeln!(
            s,
            "    curvature {:>9.2e}: {} (estimate {:+.3} prior scales from the prior)",
            d.curvature,
            comp.join(" "),
            d.offset
        );
    }
    if c.n_prior_decided > c.prior_decided.len() {
        let _ = writeln!(s, "    ... {} more in estimate.json's count", c.n_prior_decided - c.prior_decided.len());
    }
    let _ = writeln!(s, "  {:<10} {:>14} {:>14} {:>10}", "base", "least squares", "consistent", "Δ/σ");
    for i in 0..e.names.len() {
        let d = (c.base[i] - e.theta[i]) / e.std[i].max(1e-300);
        let _ = writeln!(s, "  {:<10} {:>14.6} {:>14.6} {:>10.2}", e.names[i], e.theta[i], c.base[i], d);
    }
    s
}
