//! The excitation search: the eigenvalue bundle behind the
//! epigraph refinement against finite differences and the spectrum, the
//! epigraph refinement against the direct one, and the parallel / restarted
//! refinements against the sequential ones (bit-identical per start), the
//! epigraph refinement with collision constraints on one thread and on two.

use approx::assert_relative_eq;
use idexp::excitation::design::ExciteDesign;
use idexp::excitation::objective::{BaseColumns, Criterion, Objective, Scaling, Scoring};
use idexp::excitation::{refine, run, Problem};
use idexp::optim::Control;
use idexp::params::{BaseOptions, BaseParams};
use idexp::robot::{self, Robot};
use idexp::trajectory::{period_grid, FourierLayout};
use rand::{RngExt, SeedableRng};
use std::path::{Path, PathBuf};

fn root(p: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(p)
}

fn ur5() -> Robot {
    robot::load(&root("designs/robots/ur5.toml")).unwrap()
}

fn objective(r: &Robot, lay: &FourierLayout, crit: Criterion, scaling: Scaling) -> Objective {
    let b = BaseParams::compute(r, &BaseOptions::default()).unwrap();
    let th = r.nominal_params();
    let nom: Vec<f64> = b.base_values(th.as_slice()).iter().copied().collect();
    let times = period_grid(std::f64::consts::TAU / lay.omega, 8.0).unwrap();
    Objective::new(
        r.clone(),
        lay.clone(),
        BaseColumns {
            indices: b.independent.clone(),
            names: b.names.clone(),
            nominal: nom,
        },
        times,
        Scoring {
            criterion: crit,
            scaling,
            noise: vec![1.0; r.dof()],
        },
    )
    .unwrap()
}

#[test]
fn eigenvalue_bundle_matches_the_spectrum_and_finite_differences() {
    let r = ur5();
    let lay = FourierLayout::new(vec![0.0; 6], 3, std::f64::consts::TAU * 0.2, false, false).unwrap();
    for scaling in [Scaling::UnitColumn, Scaling::None] {
        let o = objective(&r, &lay, Criterion::Cond, scaling);
        let mut w = o.workspace();
        let nv = lay.n_vars();
        let mut g = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let x: Vec<f64> = (0..nv).map(|_| g.random_range(-0.5..0.5)).collect();
        let (top, bottom) = (3, 4);
        let nt = top + bottom;
        let mut vals = vec![0.0; nt];
        let mut grads = vec![0.0; nt * nv];
        let j = o.log_eigen_bundle(&x, &mut w, top, bottom, &mut vals, Some(&mut grads));
        // values: ln σ_i² of the spectrum, and J the exact criterion
        let sp = o.spectrum(&lay.trajectory(&x).into(), &mut w).unwrap();
        let m = sp.singular_values.len();
        let which: Vec<usize> = (0..top).chain(m - bottom..m).collect();
        for (t, &i) in which.iter().enumerate() {
            let want = 2.0 * sp.singular_values[i].ln();
            assert!((vals[t] - want).abs() < 1e-10, "{scaling:?} λ_{i}: {} vs {want}", vals[t]);
        }
        assert_eq!(j, sp.cond);
        // without gradients (the line search's evaluations, the GA's: the
        // eigenvalues without the eigenvectors): the same bits
        let mut only = vec![0.0; nt];
        assert_eq!(o.log_eigen_bundle(&x, &mut w, top, bottom, &mut only, None).to_bits(), j.to_bits());
        assert_eq!(o.value(&x, &mut w).to_bits(), j.to_bits());
        assert_eq!(
            only.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
            vals.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
        );
        // gradients: central differences of ln λ_i
        let (mut vp, mut vm) = (vec![0.0; nt], vec![0.0; nt]);
        let mut gt = vec![0.0; nt * nv];
        let h = 1e-6;
        for k in 0..nv {
            let (mut xp, mut xm) = (x.clone(), x.clone());
            xp[k] += h;
            xm[k] -= h;
            o.log_eigen_bundle(&xp, &mut w, top, bottom, &mut vp, Some(&mut gt));
            o.log_eigen_bundle(&xm, &mut w, top, bottom, &mut vm, Some(&mut gt));
            for t in 0..nt {
                let fd = (vp[t] - vm[t]) / (2.0 * h);
                let an = grads[t * nv + k];
                let gmax = grads[t * nv..(t + 1) * nv].iter().fold(0.0f64, |a, v| a.max(v.abs()));
                assert!((fd - an).abs() < 1e-5 * gmax.max(1e-3), "{scaling:?} eigenvalue {t}, var {k}: {an} vs {fd}");
            }
        }
        // the direct gradient of cond is the chain rule of the bundle's ends:
        // d ln κ = (d ln λ_1 − d ln λ_m)/2
        let mut gc = vec![0.0; nv];
        let c = o.value_grad(&x, &mut w, &mut gc);
        for k in 0..nv {
            let from_bundle = c * 0.5 * (grads[k] - grads[(nt - 1) * nv + k]);
            assert_relative_eq!(gc[k], from_bundle, epsilon = 1e-9, max_relative = 1e-9);
        }
    }
}

/// The like-for-like bench design without its time limit and with a small
/// GA, so that the runs below are reproducible.
fn bench_problem(edit: impl FnOnce(&mut ExciteDesign)) -> Problem {
    shipped_problem("excite_ur5_bench_pi", edit)
}

/// A shipped design without time limit, with a GA of 12 × 3, edited.
fn shipped_problem(name: &str, edit: impl FnOnce(&mut ExciteDesign)) -> Problem {
    let mut d = ExciteDesign::load(&root(&format!("designs/{name}.toml"))).unwrap();
    d.time_limit = None;
    d.ga.population = 12;
    d.ga.generations = 3;
    edit(&mut d);
    let robot = robot::load(&d.robot).unwrap();
    Problem::new(d, robot, name).unwrap()
}

/// The GA's best point of the bench problem (no refinement): the start of
/// the refinements below.
fn ga_point() -> Vec<f64> {
    let d = bench_problem(|d| d.refine.algorithm = idexp::excitation::design::RefineAlgorithm::None);
    run(&d, &Control::new()).unwrap().x
}

#[test]
fn epigraph_refinement_reaches_a_lower_cond_than_the_direct_one() {
    let p = bench_problem(|_| {});
    let x0 = ga_point();
    let ctl = Control::new();
    let mut spec = p.design.refine.clone();
    spec.max_evals = 300;
    spec.bundle = 0;
    let direct = refine::refine(&p.objective, &p.constraints, &x0, &spec, &p.lower, &p.upper, &ctl);
    spec.bundle = 6;
    let epi = refine::refine(&p.objective, &p.constraints, &x0, &spec, &p.lower, &p.upper, &ctl);
    // the reported value is the exact cond of the returned point, which is feasible
    let mut w = p.objective.workspace();
    assert_eq!(epi.f, p.objective.value(&epi.x, &mut w));
    assert_eq!(epi.violation, 0.0, "{epi:?}");
    assert!(epi.f < epi.start_f, "{} → {}", epi.start_f, epi.f);
    assert!(
        epi.f < direct.f,
        "epigraph {} ({} evaluations) vs direct {} ({} evaluations) from {}",
        epi.f,
        epi.evaluations,
        direct.f,
        direct.evaluations,
        epi.start_f
    );
}

#[test]
fn parallel_and_restarted_refinements_do_not_change_a_starts_result() {
    let edit = |par: usize| {
        move |d: &mut ExciteDesign| {
            d.refine.starts = 2;
            d.refine.max_evals = 40;
            d.refine.bundle = 4;
            d.refine.restarts = 3;
            d.refine.parallel = par;
        }
    };
    let a = run(&bench_problem(edit(1)), &Control::new()).unwrap();
    let b = run(&bench_problem(edit(2)), &Control::new()).unwrap();
    assert_eq!(a.refinements.len(), 5);
    assert_eq!(b.refinements.len(), 5);
    for (ra, rb) in a.refinements.iter().zip(&b.refinements) {
        assert_eq!(ra.start.to_bits(), rb.start.to_bits());
        assert_eq!(ra.end.to_bits(), rb.end.to_bits());
        assert_eq!(ra.evaluations, rb.evaluations);
    }
    assert_eq!(a.x, b.x);
    // the restarts start from perturbed copies of the best refined point
    let x = vec![0.5; 4];
    let (lo, hi) = (vec![0.0; 4], vec![1.0; 4]);
    let y = refine::perturb(&x, &lo, &hi, 0.1, 3);
    assert_eq!(y, refine::perturb(&x, &lo, &hi, 0.1, 3));
    assert_ne!(y, refine::perturb(&x, &lo, &hi, 0.1, 4));
    assert!(y.iter().all(|v| (v - 0.5).abs() <= 0.05 + 1e-15), "{y:?}");
}

#[test]
fn a_refinement_stopped_by_its_budget_evaluates_nothing_more() {
    // once the run-control says stop (here: its evaluation budget; Ctrl-C
    // and the deadline take the same path), the callbacks return without
    // evaluating, so nlopt's remaining iterations cost nothing: the run
    // counts exactly the budget, and the point it returns was evaluated
    let p = bench_problem(|_| {});
    let x0 = ga_point();
    for bundle in [0, 4] {
        let mut spec = p.design.refine.clone();
        spec.max_evals = 300;
        spec.bundle = bundle;
        let free = refine::refine(&p.objective, &p.constraints, &x0, &spec, &p.lower, &p.upper, &Control::new());
        assert!(free.evaluations > 40, "bundle {bundle}: {} evaluations without a budget", free.evaluations);
        let ctl = Control::new().with_max_evals(Some(25));
        let r = refine::refine(&p.objective, &p.constraints, &x0, &spec, &p.lower, &p.upper, &ctl);
        assert_eq!(ctl.evaluations(), 25, "bundle {bundle}: {r:?}");
        let mut w = p.objective.workspace();
        assert_eq!(r.f, p.objective.value(&r.x, &mut w), "bundle {bundle}");
        assert!(r.f <= r.start_f, "bundle {bundle}: {} → {}", r.start_f, r.f);
    }
}

#[test]
fn restarts_leave_a_stalled_basin_for_the_next_ga_individuals() {
    let edit = |stall: usize, par: usize| {
        move |d: &mut ExciteDesign| {
            d.refine.starts = 2;
            d.refine.max_evals = 40;
            d.refine.bundle = 4;
            d.refine.restarts = 6;
            d.refine.stall = stall;
            d.refine.parallel = par;
        }
    };
    let never = run(&bench_problem(edit(0, 2)), &Control::new()).unwrap();
    assert_eq!(never.refinements.len(), 8);
    // a stall limit the restarts never reach changes nothing, to the bit
    let late = run(&bench_problem(edit(4, 2)), &Control::new()).unwrap();
    assert_eq!(late.x, never.x);
    assert_eq!(late.refinements.len(), 8);
    // after every round without a better point, two fresh GA individuals
    // are refined: more refinements than restarts, the same for any
    // `parallel`, and the design is the best of them all
    let a = run(&bench_problem(edit(1, 1)), &Control::new()).unwrap();
    let b = run(&bench_problem(edit(1, 2)), &Control::new()).unwrap();
    assert!(a.refinements.len() > 8, "{} refinements", a.refinements.len());
    assert_eq!(a.refinements.len() % 2, 0);
    assert_eq!(a.x, b.x);
    for (ra, rb) in a.refinements.iter().zip(&b.refinements) {
        assert_eq!(ra.end.to_bits(), rb.end.to_bits());
    }
    let best = a.refinements.iter().filter(|r| r.violation == 0.0).map(|r| r.end).fold(f64::INFINITY, f64::min);
    assert!(a.criterion <= best * (1.0 + 1e-9), "design {} vs best refinement {best}", a.criterion);
    // the first restarts are the same (same centre, same seeds) until the first stall
    assert_eq!(a.refinements[2].end.to_bits(), never.refinements[2].end.to_bits());
}

#[test]
fn epigraph_refinement_with_collision_is_the_same_on_one_thread_and_on_two() {
    // the epigraph stage computes the design's constraints (collision
    // distances, parallel over the pairs) beside the eigenvalue bundle
    // (parallel over the samples): neither may depend on the threads
    let in_pool = |threads: usize| {
        let p = shipped_problem("excite_ur5", |d| {
            d.refine.starts = 2;
            d.refine.max_evals = 60;
            d.refine.bundle = 2;
        });
        assert!(p.constraints.scene().is_some(), "the UR5 design checks collisions");
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| run(&p, &Control::new()).unwrap())
    };
    let (one, two) = (in_pool(1), in_pool(2));
    assert_eq!(one.refinements.len(), 2);
    assert!(one.refinements.iter().any(|r| r.end < r.start), "no refinement moved: {:?}", one.refinements);
    for (a, b) in one.refinements.iter().zip(&two.refinements) {
        assert_eq!(a.end.to_bits(), b.end.to_bits());
        assert_eq!(a.evaluations, b.evaluations);
    }
    assert_eq!(
        one.x.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
        two.x.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
    );
}

/// The bench problem with a restart budget that outlasts any evaluation budget below.
fn budget_problem(max_evaluations: Option<u64>, elites: usize) -> Problem {
    bench_problem(|d| {
        d.refine.starts = 2;
        d.refine.max_evals = 40;
        d.refine.restarts = 1000;
        d.refine.parallel = 1;
        d.refine.elites = elites;
        d.max_evaluations = max_evaluations;
    })
}

fn total_evaluations(r: &idexp::excitation::ExciteResult) -> u64 {
    r.ga.evaluations + r.refinements.iter().map(|f| f.evaluations).sum::<u64>()
}

#[test]
fn more_evaluations_never_give_a_worse_design_and_the_progress_says_when_it_improved() {
    // an evaluation budget (max_evaluations) cuts one deterministic sequence
    // of refinements: four times the budget runs the same refinements first,
    // so its design is never worse; the progress is the running minimum of
    // the GA's feasible best and the feasible refinements
    let short = run(&budget_problem(Some(400), 1), &Control::new()).unwrap();
    let long = run(&budget_problem(Some(1600), 1), &Control::new()).unwrap();
    for (r, budget) in [(&short, 400), (&long, 1600)] {
        let n = total_evaluations(r);
        assert!((budget..=budget + 12).contains(&n), "{n} evaluations for a budget of {budget}");
        let said = r.stopped_by.as_ref().map(|s| s.to_string()).unwrap_or_default();
        assert!(said.contains("evaluation budget"), "stopped by: {said}");
        // the running minimum, recomputed from the GA's history and the refinements
        let mut best = f64::INFINITY;
        let mut expected = Vec::new();
        for g in &r.ga.history {
            if g.best_feasible < best {
                best = g.best_feasible;
                expected.push((g.evaluations, best));
            }
        }
        let mut e = r.ga.evaluations;
        for f in &r.refinements {
            e += f.evaluations;
            if f.violation == 0.0 && f.end < best {
                best = f.end;
                expected.push((e, best));
            }
        }
        let got: Vec<(u64, f64)> = r.progress.iter().map(|q| (q.evaluations, q.best)).collect();
        assert_eq!(got, expected);
        assert!(r
            .progress
            .windows(2)
            .all(|w| w[1].seconds >= w[0].seconds && w[1].evaluations > w[0].evaluations));
        assert!(r.progress.last().unwrap().seconds <= r.seconds);
        assert!(r
            .ga
            .history
            .windows(2)
            .all(|w| w[1].evaluations > w[0].evaluations && w[1].seconds >= w[0].seconds));
    }
    // the same refinements up to the one the short budget cut (the last:
    // none starts once the budget is spent)
    assert!(short.refinements.last().unwrap().evaluations > 0);
    let whole = short.refinements.len() - 1;
    assert!(whole >= 3, "{} refinements", short.refinements.len());
    for (a, b) in short.refinements[..whole].iter().zip(&long.refinements) {
        assert_eq!(a.end.to_bits(), b.end.to_bits());
        assert_eq!(a.evaluations, b.evaluations);
    }
    assert!(long.refinements.len() > short.refinements.len());
    assert!(long.criterion <= short.criterion, "4x the budget: {} vs {}", long.criterion, short.criterion);
}

#[test]
fn elite_restarts_perturb_the_best_points_in_turn() {
    let budget = Some(900);
    let default = run(&budget_problem(budget, 1), &Control::new()).unwrap();
    let three = run(&budget_problem(budget, 3), &Control::new()).unwrap();
    // the two GA starts and the first round (from the best point: the first
    // elite) are the same; the second round perturbs the second-best point
    for k in 0..4 {
        assert_eq!(default.refinements[k].end.to_bits(), three.refinements[k].end.to_bits(), "refinement {}", k + 1);
    }
    assert!(three.refinements.len() > 6);
    // the restarts of round 2 start near the second-best point, not at the best one
    assert_ne!(default.refinements[4].start.to_bits(), three.refinements[4].start.to_bits());
    // elites = 1 (the default) is the search as before the field
    assert_eq!(idexp::excitation::RefineSpec::default().elites, 1);
    let mut d = ExciteDesign::load(&root("designs/excite_ur5_bench_pi.toml")).unwrap();
    for (field, edit) in [
        (
            "refine.elites",
            Box::new(|d: &mut ExciteDesign| d.refine.elites = 0) as Box<dyn Fn(&mut ExciteDesign)>,
        ),
        ("max_evaluations", Box::new(|d: &mut ExciteDesign| d.max_evaluations = Some(0))),
    ] {
        edit(&mut d);
        let e = d.validate("bench.toml").unwrap_err().to_string();
        assert!(e.contains("bench.toml") && e.contains(field) && e.contains('0'), "{e}");
        d = ExciteDesign::load(&root("designs/excite_ur5_bench_pi.toml")).unwrap();
    }
}

#[test]
fn the_report_records_the_progress_and_draws_it() {
    let p = budget_problem(Some(300), 1);
    let r = run(&p, &Control::new()).unwrap();
    let dir = tempfile::tempdir().unwrap();
    idexp::excitation::report::write_outputs(&p, &r, dir.path()).unwrap();
    let rep: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.path().join("report.json")).unwrap()).unwrap();
    let prog = rep["result"]["progress"].as_array().unwrap();
    assert_eq!(prog.len(), r.progress.len());
    for (j, q) in prog.iter().zip(&r.progress) {
        assert_eq!(j["best"].as_f64().unwrap(), q.best);
        assert_eq!(j["evaluations"].as_u64().unwrap(), q.evaluations);
        assert!(j["seconds"].as_f64().unwrap() >= 0.0 && j["from"].as_str().is_some());
    }
    let h = &rep["result"]["ga"]["history"][0];
    assert!(h["seconds"].as_f64().is_some() && h["evaluations"].as_u64() == Some(12), "{h}");
    assert_eq!(rep["design"]["max_evaluations"].as_u64(), Some(300));
    let svg = std::fs::read_to_string(dir.path().join("search_progress.svg")).unwrap();
    assert!(svg.contains("<svg") && svg.contains("evaluations"), "{}", &svg[..svg.len().min(300)]);
    let txt = std::fs::read_to_string(dir.path().join("report.txt")).unwrap();
    assert!(txt.contains("search progress"), "{txt}");
}

#[test]
fn patience_ends_a_refinement_where_it_stopped_improving() {
    // `refine.patience = k`: a stage ends once its best feasible value has
    // not fallen by 1e-4 (relative) in k evaluations. Ending early does not
    // change the path before: the result is, bit for bit, that of the run
    // without patience cut by an evaluation budget at the same count, and
    // the same run cut k evaluations earlier was within 1e-4 of it
    let p = bench_problem(|_| {});
    let x0 = ga_point();
    let mut spec = p.design.refine.clone();
    spec.max_evals = 300;
    let plain = |budget: u64| {
        let ctl = Control::new().with_max_evals(Some(budget));
        refine::refine(&p.objective, &p.constraints, &x0, &spec, &p.lower, &p.upper, &ctl)
    };
    let full = plain(300);
    assert!(!full.status.stalled, "{full:?}");
    let mut stalled = 0;
    for k in [10, 20, 40] {
        let mut s = spec.clone();
        s.patience = k;
        let r = refine::refine(&p.objective, &p.constraints, &x0, &s, &p.lower, &p.upper, &Control::new());
        if !r.status.stalled {
            assert_eq!(r.f.to_bits(), full.f.to_bits(), "patience {k}: {r:?}");
            continue;
        }
        stalled += 1;
        assert!(r.status.to_string().contains("(stalled)"), "{}", r.status);
        let n = r.evaluations;
        assert!(n < 300 && n > k as u64, "patience {k}: {n} evaluations");
        let cut = plain(n);
        assert_eq!((cut.f.to_bits(), cut.x.clone()), (r.f.to_bits(), r.x.clone()), "patience {k}");
        let before = plain(n - k as u64);
        assert!(before.f <= r.f * (1.0 + 1e-4) / (1.0 - 1e-4), "patience {k}: {} then {}", before.f, r.f);
        assert!(full.f <= r.f);
    }
    assert!(stalled > 0, "no patience in 10, 20, 40 ended the refinement early");
}

#[test]
fn restarts_can_perturb_a_few_joints_only() {
    // the Fourier coefficients of k joints move, the others stay
    let p = bench_problem(|_| {});
    let x = ga_point();
    let n = p.robot.dof();
    let ranges: Vec<std::ops::Range<usize>> = (0..n).map(|j| idexp::trajectory::TrajectoryShape::joint_vars(&p.shape, j)).collect();
    for k in 1..n {
        for seed in 0..20u64 {
            let y = refine::perturb_joints(&x, &p.lower, &p.upper, 0.2, seed, k, &ranges);
            assert_eq!(y, refine::perturb_joints(&x, &p.lower, &p.upper, 0.2, seed, k, &ranges));
            let all = refine::perturb(&x, &p.lower, &p.upper, 0.2, seed);
            let moved: Vec<usize> = (0..n).filter(|&j| ranges[j].clone().any(|v| y[v] != x[v])).collect();
            assert_eq!(moved.len(), k, "k {k}, seed {seed}: joints {moved:?}");
            for (v, (&a, &b)) in y.iter().zip(&x).enumerate() {
                let mine = moved.iter().any(|&j| ranges[j].contains(&v));
                assert_eq!(a, if mine { all[v] } else { b }, "k {k}, seed {seed}, variable {v}");
            }
        }
    }
    for k in [0, n] {
        assert_eq!(
            refine::perturb_joints(&x, &p.lower, &p.upper, 0.2, 5, k, &ranges),
            refine::perturb(&x, &p.lower, &p.upper, 0.2, 5)
        );
    }
}

#[test]
fn the_search_fields_are_checked_with_their_names() {
    let load = || ExciteDesign::load(&root("designs/excite_ur5_bench_pi.toml")).unwrap();
    type Edit = Box<dyn Fn(&mut ExciteDesign)>;
    let cases: Vec<(&str, &str, Edit)> = vec![
        ("refine.patience", "2000000", Box::new(|d| d.refine.patience = 2_000_000)),
        ("refine.perturb_adapt", "0.5", Box::new(|d| d.refine.perturb_adapt = 0.5)),
        ("refine.perturb_adapt", "NaN", Box::new(|d| d.refine.perturb_adapt = f64::NAN)),
        ("refine.perturb_joints", "2000", Box::new(|d| d.refine.perturb_joints = 2000)),
    ];
    for (field, value, edit) in cases {
        let mut d = load();
        edit(&mut d);
        let e = d.validate("bench.toml").unwrap_err().to_string();
        assert!(e.contains("bench.toml") && e.contains(field) && e.contains(value), "{e}");
    }
    // more joints than the robot has: known once the robot is loaded
    let mut d = load();
    d.refine.perturb_joints = 7;
    let robot = robot::load(&d.robot).unwrap();
    let e = Problem::new(d, robot, "bench.toml").err().unwrap().to_string();
    assert!(
        e.contains("bench.toml") && e.contains("refine.perturb_joints") && e.contains("1..=6") && e.contains('7'),
        "{e}"
    );
}

#[test]
fn adaptive_perturbation_changes_the_restarts_after_their_first_round() {
    // `perturb_adapt = a`: the first round perturbs by `perturb` (the same
    // starts as without it); after it the size is `perturb`·a or /a, so
    // the second round's starts differ; whatever the size, the search stays
    // one sequence that more evaluations only extend
    let with = |a: f64, budget: u64| {
        let mut p = budget_problem(Some(budget), 1);
        p.design.refine.perturb_adapt = a;
        run(&p, &Control::new()).unwrap()
    };
    let plain = with(1.0, 900);
    let adapt = with(2.0, 900);
    for k in 0..4 {
        assert_eq!(plain.refinements[k].end.to_bits(), adapt.refinements[k].end.to_bits(), "refinement {}", k + 1);
    }
    assert!(adapt.refinements.len() > 5);
    assert_ne!(plain.refinements[4].start.to_bits(), adapt.refinements[4].start.to_bits());
    let long = with(2.0, 1800);
    let whole = adapt.refinements.len() - 1;
    for (a, b) in adapt.refinements[..whole].iter().zip(&long.refinements) {
        assert_eq!(a.end.to_bits(), b.end.to_bits());
    }
    assert!(long.criterion <= adapt.criterion);
}

#[test]
fn repair_near_turns_slsqps_infeasible_progress_into_a_feasible_better_point() {
    // SLSQP crosses infeasible regions and can end its budget there, its
    // result the best feasible point met (often its start) although it met
    // near-feasible points of a much lower cond. `repair_near` scales the
    // lowest of them into the joint limits (one evaluation) and keeps it if
    // feasible and better. Checked here against the motion itself sampled
    // at 1 kHz (not through the constraints' extremum search) and against
    // the criterion recomputed at the returned point.
    use idexp::trajectory::shape::{Motion, TrajectoryShape};
    let p = bench_problem(|_| {});
    let x0 = ga_point();
    let mut spec = p.design.refine.clone();
    spec.max_evals = 60;
    spec.bundle = 0;
    let (mut repaired, mut tried) = (0, 0);
    for seed in 0..6 {
        let mut x = refine::perturb(&x0, &p.lower, &p.upper, 0.2, seed);
        p.constraints.repair_joints(&mut x, &p.limits, 1e-6);
        let mut r = refine::refine(&p.objective, &p.constraints, &x, &spec, &p.lower, &p.upper, &Control::new());
        let Some((_, near_f)) = r.near.clone() else {
            continue;
        };
        tried += 1;
        let before = r.f;
        let ctl = Control::new();
        refine::repair_near(&mut r, &p.objective, &p.constraints, &p.limits, &ctl);
        assert_eq!(ctl.evaluations(), 1, "seed {seed}");
        assert!(r.near.is_none());
        if !r.status.repaired {
            assert_eq!(r.f.to_bits(), before.to_bits(), "seed {seed}");
            continue;
        }
        repaired += 1;
        assert!(r.status.to_string().ends_with("(repaired)"), "{}", r.status);
        assert!(r.f < before, "seed {seed}: {before} → {}", r.f);
        // the scaling moves cond little: within 2 % of the infeasible point's
        assert!(r.f < near_f * 1.02, "seed {seed}: near {near_f}, repaired {}", r.f);
        assert_eq!(r.f, p.objective.value(&r.x, &mut p.objective.workspace()));
        let tr = p.shape.motion(&r.x);
        let n = p.robot.dof();
        let (mut q, mut qd, mut qdd) = (vec![0.0f64; n], vec![0.0f64; n], vec![0.0f64; n]);
        let period = tr.duration();
        for i in 0..(period * 1000.0) as usize {
            tr.eval(i as f64 / 1000.0, &mut q, &mut qd, &mut qdd);
            for j in 0..n {
                let [lo, hi] = p.limits.position[j];
                assert!(
                    q[j] >= lo - 1e-9 && q[j] <= hi + 1e-9,
                    "seed {seed}: q{} = {} outside [{lo}, {hi}]",
                    j + 1,
                    q[j]
                );
                let v = p.limits.velocity[j];
                assert!(qd[j].abs() <= v + 1e-9, "seed {seed}: q̇{} = {} beyond {v}", j + 1, qd[j]);
            }
        }
    }
    assert!(
        repaired > 0,
        "no refinement repaired ({tried} ended with a near-feasible point below their result)"
    );
}
