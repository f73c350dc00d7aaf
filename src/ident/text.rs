//! Blocks of the identification report (`report.txt`, [`super::study::report`]).

use super::{Implausible, TruthRow};

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
