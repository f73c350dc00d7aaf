//! `idexp positions` end to end, and rounding.

mod common;

use idexp::positions::{efficient_rounding, round_design, solve_relaxed, Criterion, Problem, SolverOptions};
use nalgebra::DMatrix;
use rand::{RngExt, SeedableRng};
#[cfg(feature = "cli")]
use std::process::Command;

#[cfg(feature = "cli")]
fn run_cli(design: &str, out: &std::path::Path) -> serde_json::Value {
    let st = Command::new(env!("CARGO_BIN_EXE_idexp"))
        .args(["positions", design, "--out"])
        .arg(out)
        .env("IDEXP_NO_PROGRESS", "1")
        .current_dir(common::root(""))
        .output()
        .unwrap();
    assert!(st.status.success(), "{}", String::from_utf8_lossy(&st.stderr));
    for f in [
        "plan.csv",
        "plan.json",
        "candidates.csv",
        "report.json",
        "report.txt",
        "design.json",
        "status.json",
        "weights.svg",
    ] {
        assert!(out.join(f).exists(), "{f} missing");
    }
    serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap()
}

#[cfg(feature = "cli")]
#[test]
fn shipped_file_designs_run() {
    let dir = tempfile::tempdir().unwrap();
    for c in ["d", "a", "e"] {
        let out = dir.path().join(c);
        let rep = run_cli(&format!("designs/positions_file_{c}.toml"), &out);
        assert_eq!(rep["status"], "optimal", "{c}: {rep}");
        assert_eq!(rep["certificate"]["holds"], true);
        assert_eq!(rep["rounded"]["total"], 10);
        assert!(out.join("poses.svg").exists());
        // plan.csv: the m column sums to the number of experiments
        let t = idexp::io::Table::read(&out.join("plan.csv")).unwrap();
        let m = t.require("m").unwrap();
        assert_eq!(t.rows.iter().map(|r| r[m]).sum::<f64>(), 10.0);
        let eff = rep["rounded"]["efficiency"].as_f64().unwrap();
        assert!(eff > 0.5 && eff <= 1.0 + 1e-9, "{c}: rounded efficiency {eff}");
    }
}

#[cfg(feature = "cli")]
#[test]
fn rigid_design_runs_end_to_end() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(common::root("designs/positions_industrial6_rigid.toml"))
        .unwrap()
        .replace("points = [9, 9, 5]", "points = [5, 5, 3]")
        .replace(
            "robots/industrial6.toml",
            &common::root("designs/robots/industrial6.toml").display().to_string(),
        );
    let d = dir.path().join("small.toml");
    std::fs::write(&d, text).unwrap();
    let out = dir.path().join("out");
    let rep = run_cli(d.to_str().unwrap(), &out);
    assert_eq!(rep["certificate"]["holds"], true, "{rep}");
    assert_eq!(rep["parameters"], 36);
    let support = rep["support"].as_u64().unwrap();
    assert!((1..=60).contains(&support), "support {support}");
    let plan: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out.join("plan.json")).unwrap()).unwrap();
    let rows = plan["rows"].as_array().unwrap();
    assert!(rows.iter().all(|r| r["q"].as_array().unwrap().len() == 6 && r["position"].is_array()));
}

#[cfg(feature = "cli")]
/// cargo test --release --test positions_cli -- --ignored
#[test]
#[ignore]
fn shipped_rigid_design_runs() {
    let dir = tempfile::tempdir().unwrap();
    let rep = run_cli("designs/positions_industrial6_rigid.toml", dir.path());
    assert_eq!(rep["status"], "optimal", "{rep}");
}

#[test]
fn efficient_rounding_apportions_exactly() {
    // exact apportionments are reproduced
    let w = [0.5, 0.25, 0.0, 0.25];
    assert_eq!(efficient_rounding(&w, 8), vec![4, 2, 0, 2]);
    let mut g = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    for _ in 0..200 {
        let n = g.random_range(2..12);
        let mut w: Vec<f64> = (0..n).map(|_| if g.random_bool(0.3) { 0.0 } else { g.random_range(0.01..1.0) }).collect();
        if w.iter().sum::<f64>() == 0.0 {
            w[0] = 1.0;
        }
        let s: f64 = w.iter().sum();
        w.iter_mut().for_each(|v| *v /= s);
        let total = g.random_range(1..40);
        let m = efficient_rounding(&w, total);
        assert_eq!(m.iter().sum::<usize>(), total);
        assert!(m.iter().zip(&w).all(|(m, w)| *w > 0.0 || *m == 0), "no experiments off the support");
        let l = w.iter().filter(|&&v| v > 0.0).count();
        if total >= l {
            // Pukelsheim–Rieder: every support point gets at least one, and m_i ≥ ⌊(M − l) w_i⌋
            assert!(m
                .iter()
                .zip(&w)
                .all(|(m, w)| *w == 0.0 || (*m >= 1 && *m as f64 >= ((total - l) as f64 * w).floor())));
        }
    }
}

#[test]
fn rounded_plan_is_no_better_than_relaxed_and_exchange_helps() {
    let mut g = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    let p = 5;
    let h: Vec<DMatrix<f64>> = (0..40).map(|_| DMatrix::from_fn(p, 1, |_, _| g.random_range(-1.0..1.0))).collect();
    let pb = Problem::from_factors(p, &h, None).unwrap();
    let r = solve_relaxed(&pb, Criterion::D, &SolverOptions::default(), &idexp::optim::Control::new()).unwrap();
    for total in [5usize, 7, 12, 30] {
        let rd = round_design(&pb, Criterion::D, &r, total as f64, None, &idexp::optim::Control::new()).unwrap();
        assert_eq!(rd.total, total);
        assert!(rd.efficiency <= 1.0 + 1e-7, "integer plans cannot beat the relaxed optimum: {}", rd.efficiency);
        assert!(rd.efficiency + 1e-12 >= rd.efficiency_apportionment);
        // the reported value is log det of (1/M) Σ m_i F_i
        let mut m = DMatrix::zeros(p, p);
        for (i, &k) in rd.m.iter().enumerate() {
            m += pb.matrix(i) * (k as f64 / total as f64);
        }
        let v = 2.0 * m.cholesky().unwrap().l().diagonal().iter().map(|x| x.ln()).sum::<f64>();
        assert!((v - rd.value).abs() < 1e-9);
        // local optimality after the exchange: no single move improves
        let base: Vec<usize> = rd.m.clone();
        for i in (0..40).filter(|&i| base[i] > 0) {
            for j in 0..40 {
                let mut mm = base.clone();
                mm[i] -= 1;
                mm[j] += 1;
                let mut m = DMatrix::zeros(p, p);
                for (k, &c) in mm.iter().enumerate() {
                    m += pb.matrix(k) * (c as f64 / total as f64);
                }
                if let Some(c) = m.cholesky() {
                    let v2 = 2.0 * c.l().diagonal().iter().map(|x| x.ln()).sum::<f64>();
                    // candidates outside the exchange pool may be skipped; only the pool is guaranteed
                    if r.weights[j] > 0.0 || base[j] > 0 {
                        assert!(v2 <= rd.value + 1e-9, "move {i}->{j} improves {v2} > {}", rd.value);
                    }
                }
            }
        }
    }
}

#[test]
fn budget_with_costs_is_respected() {
    let mut g = rand_chacha::ChaCha8Rng::seed_from_u64(9);
    let p = 4;
    let h: Vec<DMatrix<f64>> = (0..30).map(|_| DMatrix::from_fn(p, 2, |_, _| g.random_range(-1.0..1.0))).collect();
    let costs: Vec<f64> = (0..30).map(|_| g.random_range(0.5..3.0)).collect();
    let pb = Problem::from_factors(p, &h, None).unwrap().divided_by(&costs);
    let r = solve_relaxed(&pb, Criterion::D, &SolverOptions::default(), &idexp::optim::Control::new()).unwrap();
    assert!(r.certificate.holds);
    let rd = round_design(&pb, Criterion::D, &r, 20.0, Some(&costs), &idexp::optim::Control::new()).unwrap();
    let spent: f64 = rd.m.iter().zip(&costs).map(|(m, c)| *m as f64 * c).sum();
    assert!(spent <= 20.0 + 1e-9 && (spent - rd.cost).abs() < 1e-9);
    assert!(rd.efficiency <= 1.0 + 1e-7 && rd.efficiency > 0.5, "{}", rd.efficiency);
}
