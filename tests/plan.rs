//! `idexp plan`: the planner against brute force, its refusals, and its
//! prediction against rehearsal (simulated studies with many noise seeds).
//!
//! The scenario (docs/plan.md, "Acceptance"): the RPR test arm, three
//! experiments of different kinds and noise — a 10 s Fourier excitation
//! (σ_τ = 0.05), a 5 s one with three times the noise (0.15) and slow
//! gravity slopes of the wrist (0.05) — the study's Euclidean prior, and
//! targets on σ(MX3R), σ(Fv3) and the RMS prediction error on a validation
//! trajectory. The simulate designs are the shipped ones with the position
//! noise set to 0 (with it, the controller's reaction to encoder noise is the
//! dominant, slide-heavy equation error the plan estimates; the scenario
//! keeps the noise levels 3× apart).

use idexp::optim::Control;
use idexp::plan::{build, plan, rehearse, solve, PlanDesign, PlanRun, PlanStatus};
use std::path::{Path, PathBuf};
use std::process::Command;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// A folder with the scenario's simulate designs and `plan.toml` (targets replaced by `targets`).
fn scenario(max_reps: usize, consistent: bool, targets: &str) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let r = root();
    for f in ["sim_rpr_fourier", "sim_rpr_study_b", "sim_rpr_study_gravity", "sim_rpr_fourier_validate"] {
        let text = std::fs::read_to_string(r.join("designs").join(format!("{f}.toml"))).unwrap();
        let text: String = text
            .lines()
            .map(|l| {
                if l.starts_with("robot = ") {
                    format!("robot = \"{}\"", r.join("tests/data/ident/rpr_drives.toml").display())
                } else if l.starts_with("position = ") {
                    "position = 0.0".to_string()
                } else {
                    l.to_string()
                }
            })
            .collect::<Vec<_>>()
            .join("\n");
        std::fs::write(dir.path().join(format!("{f}.toml")), text).unwrap();
    }
    let prior = if consistent {
        "[consistent]\nmetric = \"euclidean\"\nweight = 1.0\nscale = 0.5\n"
    } else {
        ""
    };
    let plan = format!(
        r#"name = "scenario"
robot = "{robot}"
max_repetitions = {max_reps}
[[experiment]]
name = "fourier_a"
simulate = "sim_rpr_fourier.toml"
cost = 14.0
identify = {{ harmonics = 20 }}
[[experiment]]
name = "fourier_b"
simulate = "sim_rpr_study_b.toml"
cost = 8.0
identify = {{ harmonics = 16 }}
[[experiment]]
name = "gravity_wrist"
simulate = "sim_rpr_study_gravity.toml"
cost = 30.0
identify = {{ kind = "gravity" }}
{prior}
{targets}
"#,
        robot = r.join("tests/data/ident/rpr_drives.toml").display()
    );
    let path = dir.path().join("plan.toml");
    std::fs::write(&path, plan).unwrap();
    (dir, path)
}

const TARGETS: &str = r#"
[[target]]
parameter = "MX3R"
relative = 0.0003
[[target]]
parameter = "Fv3"
relative = 0.02
[[target]]
task = "sim_rpr_fourier_validate.toml"
rms = 0.003
"#;

fn planned(path: &Path) -> PlanRun {
    let design = PlanDesign::read(path).unwrap();
    idexp::plan::run_design(&design, path.parent().unwrap(), &Control::new()).unwrap()
}

/// `idexp plan <design> --out <out>`.
fn plan_command(design: &Path, out: &Path) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_idexp"))
        .arg("plan")
        .arg(design)
        .arg("--out")
        .arg(out)
        .output()
        .unwrap()
}

/// σ of every target from Φ by an explicit inverse (not the planner's Cholesky path).
fn sigmas_by_inverse(pre: &solve::Prepared, r: &[usize]) -> Vec<f64> {
    let phi = pre.phi(&r.iter().map(|&x| x as f64).collect::<Vec<_>>());
    match phi.clone().try_inverse() {
        Some(inv) if phi.clone().cholesky().is_some() => pre.b.iter().map(|b| (b.transpose() * &inv * b).trace().max(0.0).sqrt()).collect(),
        _ => vec![f64::INFINITY; pre.b.len()],
    }
}

#[test]
fn brute_force_enumeration_confirms_the_optimum_and_the_relaxed_bound() {
    let targets = "[[target]]\nparameter = \"MX3R\"\nrelative = 0.0006\n[[target]]\ntask = \"sim_rpr_fourier_validate.toml\"\nrms = 0.004\n";
    let (_d, path) = scenario(8, true, targets);
    let run = planned(&path);
    let sol = &run.solution;
    assert_eq!(sol.status, PlanStatus::Planned, "{}", idexp::plan::output::report_text(&run));
    let pre = solve::Prepared::new(&run.model);
    // every vector of the box [0, 8]³
    let mut best: Option<(f64, Vec<usize>)> = None;
    for a in 0..=8 {
        for b in 0..=8 {
            for c in 0..=8 {
                let r = vec![a, b, c];
                let ok = sigmas_by_inverse(&pre, &r).iter().zip(&pre.bound).all(|(s, t)| *s <= t * (1.0 + 1e-9));
                let cost = 14.0 * a as f64 + 8.0 * b as f64 + 30.0 * c as f64;
                if ok && best.as_ref().is_none_or(|(bc, _)| cost < *bc) {
                    best = Some((cost, r));
                }
            }
        }
    }
    let (bc, br) = best.expect("a feasible vector in the box");
    assert!(
        (sol.cost - bc).abs() < 1e-9,
        "planned {:?} ({} s), brute force {:?} ({bc} s)",
        sol.repetitions,
        sol.cost,
        br
    );
    assert!(sol.relaxed_cost <= bc + 1e-6, "relaxed bound {} above the optimum {bc}", sol.relaxed_cost);
    assert!(sol.relaxed_upper >= sol.relaxed_cost - 1e-9);
    // the supporting-hyperplane relaxation against the one semidefinite program
    let (r_sdp, st, _) = solve::relax_sdp(&pre, &Control::new());
    assert!(st.is_solved(), "SDP: {st}");
    let sdp_cost: f64 = r_sdp.iter().zip(&pre.cost).map(|(x, c)| x * c).sum();
    assert!(
        (sdp_cost - sol.relaxed_cost).abs() <= 1e-4 * sdp_cost,
        "relaxed cost: hyperplanes {} vs SDP {sdp_cost}",
        sol.relaxed_cost
    );
    // the plan meets every target by the independent inverse too
    let s = sigmas_by_inverse(&pre, &sol.repetitions);
    for (i, v) in s.iter().enumerate() {
        assert!((v - sol.values[i]).abs() <= 1e-9 * v, "target {i}: {v} vs {}", sol.values[i]);
    }
}

#[test]
fn unreachable_targets_are_refused_with_the_reason_and_the_best_value() {
    // structurally unidentifiable (no prior): ZZ1 never reaches the torques
    let (_d, path) = scenario(10, false, "[[target]]\nparameter = \"ZZ1\"\nsigma = 0.01\n");
    let run = planned(&path);
    assert_eq!(run.solution.status, PlanStatus::Unreachable);
    assert!(
        run.solution.refused[0].reason.contains("structurally unidentifiable"),
        "{}",
        run.solution.refused[0].reason
    );
    assert!(run.solution.refused[0].best.is_infinite());
    // below the noise floor: the best value is σ with every experiment at 10
    let (_d2, path2) = scenario(
        10,
        true,
        "[[target]]\nparameter = \"Fv3\"\nrelative = 0.0001\n[[target]]\nparameter = \"MX3R\"\nrelative = 0.5\n",
    );
    let run2 = planned(&path2);
    assert_eq!(run2.solution.status, PlanStatus::Unreachable);
    assert_eq!(run2.solution.refused.len(), 1, "only Fv3 is refused");
    let r = &run2.solution.refused[0];
    assert!(r.reason.contains("below what the noise allows"), "{}", r.reason);
    let pre = solve::Prepared::new(&run2.model);
    let at_max = sigmas_by_inverse(&pre, &[10, 10, 10])[0];
    assert!(
        (r.best - at_max).abs() <= 1e-9 * at_max,
        "best {} vs σ at the largest repetitions {at_max}",
        r.best
    );
    // the command: exit 3, status.json `infeasible`, the reason on the report
    let out = path2.parent().unwrap().join("out");
    let o = plan_command(&path2, &out);
    assert_eq!(o.status.code(), Some(3), "{}", String::from_utf8_lossy(&o.stderr));
    let status = std::fs::read_to_string(out.join("status.json")).unwrap();
    assert!(status.contains("\"infeasible\""), "{status}");
    assert!(String::from_utf8_lossy(&o.stdout).contains("best reachable"));
    // an input error (a parameter the robot does not have): exit 1, naming it
    let (_d3, path3) = scenario(10, true, "[[target]]\nparameter = \"ZZ9\"\nsigma = 0.01\n");
    let o = plan_command(&path3, &out);
    assert_eq!(o.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&o.stderr).contains("ZZ9"));
}

/// The acceptance test with `seeds` seeds; `tol` on |empirical/predicted − 1|.
fn acceptance(seeds: usize, tol: f64) {
    let (_d, path) = scenario(40, true, TARGETS);
    let dir = path.parent().unwrap().to_path_buf();
    let run = planned(&path);
    assert_eq!(run.solution.status, PlanStatus::Planned);
    let reps = run.solution.repetitions.clone();
    let r = rehearse(&run, None, seeds, &dir, &Control::new()).unwrap();
    let mut text = String::new();
    for t in &r.targets {
        text += &format!(
            "{}: predicted {:.4e}, study σ {:.4e}, met {}/{}, empirical {:.4e} (ratio {:.3})\n",
            t.label, t.predicted, t.achieved_mean, t.met, seeds, t.empirical, t.ratio
        );
    }
    eprintln!("plan {reps:?}: every target met in {}/{seeds}\n{text}", r.all_met);
    assert!(r.all_met as f64 >= 0.9 * seeds as f64 - 1e-9, "{text}");
    for t in r.targets.iter().filter(|t| t.label.starts_with('σ')) {
        assert!(
            (t.ratio - 1.0).abs() <= tol,
            "{}: empirical spread / predicted = {:.3}\n{text}",
            t.label,
            t.ratio
        );
    }
    // one fewer repetition of the binding experiment misses a target in most seeds
    let pre = solve::Prepared::new(&run.model);
    let e = (0..reps.len())
        .filter(|&e| reps[e] > 0)
        .find(|&e| {
            let mut f = reps.clone();
            f[e] -= 1;
            pre.worst_ratio(&f) > 1.0
        })
        .expect("a binding experiment");
    let mut fewer = reps.clone();
    fewer[e] -= 1;
    let r2 = rehearse(&run, Some(&fewer), seeds, &dir, &Control::new()).unwrap();
    eprintln!(
        "one fewer of {}: {fewer:?}: every target met in {}/{seeds}",
        run.model.candidates[e].name, r2.all_met
    );
    assert!(
        (r2.all_met as f64) < 0.5 * seeds as f64,
        "one fewer repetition of {} still meets every target in {}/{seeds} seeds",
        run.model.candidates[e].name,
        r2.all_met
    );
}

#[test]
fn the_plan_rehearsed_with_ten_seeds_meets_its_targets_and_one_fewer_repetition_does_not() {
    // ten seeds: the spread's own sampling error is ~24 %, so the tolerance is 0.5 here; the 50-seed test below holds 15 %
    acceptance(10, 0.5);
}

#[test]
#[ignore = "50 noise seeds × two rehearsals: ~3 min on 2 cores; run with --ignored"]
fn the_plan_rehearsed_with_fifty_seeds_meets_its_targets_and_the_spread_within_15_percent() {
    acceptance(50, 0.15);
}

#[test]
fn the_model_reads_the_scenario() {
    let (_d, path) = scenario(40, true, TARGETS);
    let design = PlanDesign::read(&path).unwrap();
    let model = build(&design, path.parent().unwrap(), &Control::new()).unwrap();
    // the effective noise from the study's residuals: the designs' σ_τ, 3× apart
    let a = &model.candidates[0].sigma;
    let b = &model.candidates[1].sigma;
    for j in 0..3 {
        assert!((a[j] / 0.05 - 1.0).abs() < 0.1, "fourier_a σ {a:?}");
        assert!((b[j] / 0.15 - 1.0).abs() < 0.1, "fourier_b σ {b:?}");
    }
    let sol = plan(&model, 2, &Control::new()).unwrap();
    assert_eq!(sol.status, PlanStatus::Planned);
}

/// The scenario's plan.toml with these costs and setup costs (s, per experiment in order) and a budget.
fn with_costs_setups_and_budget(path: &Path, costs: [f64; 3], setups: [f64; 3], budget: Option<f64>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut k = 0;
    let mut out = String::new();
    for l in text.lines() {
        if l.starts_with("cost = ") {
            out += &format!("cost = {}\nsetup = {}\n", costs[k], setups[k]);
            k += 1;
            continue;
        }
        out += l;
        out.push('\n');
        if l.starts_with("max_repetitions = ") {
            if let Some(b) = budget {
                out += &format!("budget = {b}\n");
            }
        }
    }
    std::fs::write(path, out).unwrap();
}

/// Every vector of [0, 8]³: (cost with setups, worst σ/asked-bound ratio by an explicit inverse, meets every planned bound).
fn brute_force_box(pre: &solve::Prepared, costs: [f64; 3], setups: [f64; 3], margin: f64) -> Vec<(Vec<usize>, f64, f64, bool)> {
    let mut all = Vec::new();
    for a in 0..=8 {
        for b in 0..=8 {
            for c in 0..=8 {
                let r = vec![a, b, c];
                let s = sigmas_by_inverse(pre, &r);
                let ok = s.iter().zip(&pre.bound).all(|(v, t)| *v <= t * (1.0 + 1e-9));
                let worst = s.iter().zip(&pre.bound).map(|(v, t)| v / (t * (1.0 + margin))).fold(0.0, f64::max);
                let cost: f64 = (0..3).filter(|&e| r[e] > 0).map(|e| r[e] as f64 * costs[e] + setups[e]).sum();
                all.push((r, cost, worst, ok));
            }
        }
    }
    all
}

#[test]
fn setup_costs_and_the_budget_against_brute_force() {
    let targets = "[[target]]\nparameter = \"MX3R\"\nrelative = 0.0006\n[[target]]\ntask = \"sim_rpr_fourier_validate.toml\"\nrms = 0.004\n";
    let (_d, path) = scenario(8, true, targets);
    let mut model = build(&PlanDesign::read(&path).unwrap(), path.parent().unwrap(), &Control::new()).unwrap();
    let margin = model.margin;
    let optimum = |pre: &solve::Prepared, costs: [f64; 3], setups: [f64; 3]| {
        let all = brute_force_box(pre, costs, setups, margin);
        let best = all
            .iter()
            .filter(|x| x.3)
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .map(|x| (x.0.clone(), x.1))
            .expect("a feasible vector");
        (best, all)
    };
    let cost_with = |r: &[usize], c: [f64; 3], s: [f64; 3]| -> f64 { (0..3).filter(|&e| r[e] > 0).map(|e| r[e] as f64 * c[e] + s[e]).sum() };
    // costs and setups under which the setup-blind optimum is not the optimum (the first of a few that change it)
    let cases = [
        ([14.0, 8.0, 30.0], [200.0, 0.0, 0.0]),
        ([14.0, 8.0, 30.0], [0.0, 0.0, 200.0]),
        ([5.0, 8.0, 30.0], [50.0, 0.0, 0.0]),
    ];
    let mut blind = Vec::new();
    let (costs, setups) = cases
        .into_iter()
        .find(|&(c, s)| {
            for (e, cand) in model.candidates.iter_mut().enumerate() {
                cand.cost = c[e];
                cand.setup = 0.0;
            }
            blind = optimum(&solve::Prepared::new(&model), c, [0.0; 3]).0 .0;
            for (e, cand) in model.candidates.iter_mut().enumerate() {
                cand.setup = s[e];
            }
            let ((_, bc), _) = optimum(&solve::Prepared::new(&model), c, s);
            cost_with(&blind, c, s) > bc + 1.0
        })
        .expect("costs and setups that change the optimum");
    let sol = plan(&model, idexp::plan::WINDOW, &Control::new()).unwrap();
    assert_eq!(sol.status, PlanStatus::Planned);
    let pre = solve::Prepared::new(&model);
    let ((br, bc), all) = optimum(&pre, costs, setups);
    eprintln!(
        "costs {costs:?}, setups {setups:?}: setup-blind optimum {blind:?}, optimum {br:?} ({bc} s), planned {:?} ({} s, bound {})",
        sol.repetitions, sol.cost, sol.relaxed_cost
    );
    assert!(
        (sol.cost - bc).abs() < 1e-9,
        "planned {:?} ({} s), brute force {br:?} ({bc} s), rounding {}",
        sol.repetitions,
        sol.cost,
        sol.rounding
    );
    assert!(sol.relaxed_cost <= bc + 1e-6, "relaxed bound {} above the optimum {bc}", sol.relaxed_cost);
    let (_d2, path2) = (_d, path);
    // the budget below the optimum: the best plan within it minimises the worst ratio
    let budget = (bc * 0.6).round();
    with_costs_setups_and_budget(&path2, costs, setups, Some(budget));
    let run2 = planned(&path2);
    assert_eq!(run2.solution.status, PlanStatus::OverBudget, "{}", idexp::plan::output::report_text(&run2));
    assert!((run2.solution.cost - bc).abs() < 1e-9, "the cheapest plan is still reported");
    let w = run2.solution.within_budget.as_ref().unwrap();
    let (wr, wbest) = all
        .iter()
        .filter(|x| x.1 <= budget + 1e-9)
        .min_by(|a, b| a.2.total_cmp(&b.2))
        .map(|x| (x.0.clone(), x.2))
        .unwrap();
    assert!(w.cost <= budget + 1e-9);
    assert!(
        (w.worst_ratio - wbest).abs() <= 1e-9 * wbest,
        "within the budget: planned {:?} (worst ratio {}), brute force {wr:?} ({wbest})",
        w.repetitions,
        w.worst_ratio
    );
    assert!(
        w.lower_bound <= wbest + 1e-9 && w.lower_bound > 0.5 * wbest,
        "lower bound {} vs {wbest}",
        w.lower_bound
    );
    assert!(!w.missed.is_empty() && w.missed.iter().all(|m| m.ratio > 1.0 && m.ratio <= wbest + 1e-9));
    // the command: exit 3, `infeasible`, the best plan within the budget in the report
    let out = path2.parent().unwrap().join("out");
    let o = plan_command(&path2, &out);
    assert_eq!(o.status.code(), Some(3), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(std::fs::read_to_string(out.join("status.json")).unwrap().contains("\"infeasible\""));
    let json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out.join("plan.json")).unwrap()).unwrap();
    assert_eq!(json["solution"]["status"], "over_budget");
    assert_eq!(json["solution"]["budget"], budget);
    assert!(String::from_utf8_lossy(&o.stdout).contains("OVER BUDGET"));
    // the σ-vs-repetitions figures give each parameter its unit
    let svg = |f: &str| std::fs::read_to_string(out.join("sigma_vs_repetitions").join(f)).unwrap();
    assert!(svg("01_MX3R.svg").contains("predicted σ(MX3R) (kg·m)"), "{}", svg("01_MX3R.svg"));
    assert!(svg("02_rms_sim_rpr_fourier_validate.svg").contains("RMS prediction error (N·m)"));
}

#[test]
fn every_parameter_has_its_unit() {
    let robot = idexp::robot::load(&root().join("tests/data/ident/rpr_drives.toml")).unwrap();
    let unit = |name: &str| idexp::params::unit(&robot, robot.params().iter().position(|p| p.name == name).unwrap());
    // joints 1 and 3 revolute, joint 2 prismatic
    for (n, u) in [
        ("ZZ1", "kg·m²"),
        ("XY3", "kg·m²"),
        ("MX3", "kg·m"),
        ("M2", "kg"),
        ("Ia1", "kg·m²"),
        ("Ia2", "kg"),
        ("Fc1", "N·m"),
        ("Fc2", "N"),
        ("Fv2", "N·s/m"),
        ("Fv3", "N·m·s/rad"),
    ] {
        assert_eq!(unit(n), u, "{n}");
    }
}

/// `idexp` with `args`; panics with its stderr unless it exits 0.
fn idexp(args: &[&std::ffi::OsStr]) {
    let o = Command::new(env!("CARGO_BIN_EXE_idexp")).args(args).output().unwrap();
    assert!(o.status.success(), "idexp {args:?}: {}", String::from_utf8_lossy(&o.stderr));
}

#[test]
fn the_noise_from_a_finished_study_is_its_residual_sigma_times_the_root_of_its_repetitions() {
    // a real study (the command line): fourier_a with 4 repetitions (weights from them), fourier_b with one (weights from its residuals)
    let (_d, path) = scenario(10, true, TARGETS);
    let dir = path.parent().unwrap();
    let a = std::fs::read_to_string(dir.join("sim_rpr_fourier.toml")).unwrap();
    let a: String = a
        .lines()
        .map(|l| {
            if l.starts_with("repetitions = ") {
                "repetitions = 4".into()
            } else {
                l.to_string()
            }
        })
        .collect::<Vec<_>>()
        .join("\n");
    std::fs::write(dir.join("sim_a4.toml"), a).unwrap();
    for (design, out) in [("sim_a4.toml", "run_a"), ("sim_rpr_study_b.toml", "run_b")] {
        idexp(&["simulate".as_ref(), dir.join(design).as_os_str(), "--out".as_ref(), dir.join(out).as_os_str()]);
    }
    let study = format!(
        "name = \"s\"\nrobot = \"{}\"\nweights = \"auto\"\n[[experiment]]\nname = \"fourier_a\"\nfiles = [\"run_a\"]\nharmonics = 20\n[[experiment]]\nname = \"fourier_b\"\nfiles = [\"run_b\"]\nharmonics = 16\n",
        root().join("tests/data/ident/rpr_drives.toml").display()
    );
    std::fs::write(dir.join("study.toml"), study).unwrap();
    idexp(&[
        "identify".as_ref(),
        dir.join("study.toml").as_os_str(),
        "--out".as_ref(),
        dir.join("study_out").as_os_str(),
    ]);
    let est: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.join("study_out/estimate.json")).unwrap()).unwrap();
    // the plan with both candidates' noise from the study (fourier_b named explicitly)
    let text = std::fs::read_to_string(&path).unwrap();
    let text = text
        .replacen(
            "identify = { harmonics = 20 }",
            "identify = { harmonics = 20 }\nnoise = { from = \"study_out/estimate.json\" }",
            1,
        )
        .replacen(
            "identify = { harmonics = 16 }",
            "identify = { harmonics = 16 }\nnoise = { from = \"study_out/estimate.json\", experiment = \"fourier_b\" }",
            1,
        );
    std::fs::write(&path, &text).unwrap();
    let design = PlanDesign::read(&path).unwrap();
    let model = build(&design, dir, &Control::new()).unwrap();
    for (k, reps) in [(0usize, 4.0f64), (1, 1.0)] {
        let e = &est["experiments"][k];
        assert_eq!(e["n_reps"].as_f64().unwrap(), reps);
        for j in 0..3 {
            let s = e["sigma"][j].as_f64().unwrap() * reps.sqrt();
            let got = model.candidates[k].sigma[j];
            assert!((got - s).abs() <= 1e-12 * s, "candidate {k} joint {j}: {got} vs estimate.json {s}");
        }
        assert!(model.candidates[k].noise_source.contains("estimate.json"));
    }
    // the per-repetition σ from the 4 repetitions' spread agrees with the residuals of one simulated repetition (the default)
    let sim = build(
        &PlanDesign::read(&path)
            .map(|mut d| {
                d.experiment[0].noise = None;
                d
            })
            .unwrap(),
        dir,
        &Control::new(),
    )
    .unwrap();
    for j in 0..3 {
        let (from, simulated) = (model.candidates[0].sigma[j], sim.candidates[0].sigma[j]);
        assert!((from / simulated - 1.0).abs() < 0.15, "joint {j}: from the study {from}, simulated {simulated}");
    }
    // bad files: the error names the file and the field
    let bad = |json: &str, want: &[&str]| {
        std::fs::write(dir.join("bad.json"), json).unwrap();
        let t = text.replace("study_out/estimate.json", "bad.json");
        std::fs::write(&path, &t).unwrap();
        let e = build(&PlanDesign::read(&path).unwrap(), dir, &Control::new()).unwrap_err().to_string();
        for w in want {
            assert!(e.contains(w), "`{w}` not in: {e}");
        }
    };
    let exp = |sigma: &str| {
        format!("{{\"experiments\": [{{\"name\": \"fourier_a\", \"n_reps\": 2, \"sigma\": {sigma}, \"weights\": [\"residual\", \"residual\", \"residual\"]}}, {{\"name\": \"fourier_b\", \"n_reps\": 1, \"sigma\": [0.1, 0.1, 0.1]}}]}}")
    };
    bad(&exp("[0.1, 0.2]"), &["bad.json", "experiments[0].sigma", "3 joints"]);
    bad(&exp("[0.1, -0.2, 0.3]"), &["bad.json", "experiments[0].sigma[1]", "-0.2"]);
    bad(&exp("[0.1, 0.0, 0.3]"), &["bad.json", "experiments[0].sigma[1]"]);
    bad("{\"name\": \"x\"}", &["bad.json", "experiments"]);
    bad("not json", &["bad.json", "not JSON", "idexp identify"]);
    std::fs::remove_file(dir.join("bad.json")).unwrap();
    let e = build(&PlanDesign::read(&path).unwrap(), dir, &Control::new()).unwrap_err().to_string();
    assert!(e.contains("bad.json") && e.contains("noise.from"), "{e}");
    // a hand-written file: σ × √n_reps exactly
    std::fs::write(dir.join("hand.json"), exp("[0.1, 0.2, 0.3]")).unwrap();
    std::fs::write(&path, text.replace("study_out/estimate.json", "hand.json")).unwrap();
    let m = build(&PlanDesign::read(&path).unwrap(), dir, &Control::new()).unwrap();
    let r2 = 2f64.sqrt();
    assert_eq!(m.candidates[0].sigma, vec![0.1 * r2, 0.2 * r2, 0.3 * r2]);
    assert_eq!(m.candidates[1].sigma, vec![0.1, 0.1, 0.1]);
}
