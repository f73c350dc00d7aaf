//! The run-control seam: a stop request on one [`Control`] ends its task with
//! status interrupted and a valid partial result, while a task with another
//! control in the same process (same test binary, concurrently) runs to its
//! end. No process-wide stop flag exists any more, so these tests share one
//! binary with each other.

use idexp::optim::Control;
use idexp::positions::{solve_relaxed, Criterion, Problem, SolverOptions, Status};
use nalgebra::DMatrix;
use rand::{RngExt, SeedableRng};

fn problem() -> Problem {
    let mut g = rand_chacha::ChaCha8Rng::seed_from_u64(51);
    let h: Vec<DMatrix<f64>> = (0..300).map(|_| DMatrix::from_fn(10, 2, |_, _| g.random_range(-1.0..1.0))).collect();
    Problem::from_factors(10, &h, None).unwrap()
}

#[test]
fn two_controls_in_one_process_stop_independently() {
    let pb = problem();
    let stopped = Control::new();
    stopped.stop_flag().request();
    let free = Control::new();
    let (a, b) = std::thread::scope(|s| {
        let a = s.spawn(|| solve_relaxed(&pb, Criterion::D, &SolverOptions::default(), &stopped));
        let b = s.spawn(|| solve_relaxed(&pb, Criterion::D, &SolverOptions::default(), &free));
        (a.join().unwrap().unwrap(), b.join().unwrap().unwrap())
    });
    assert_eq!(a.status, Status::Interrupted);
    assert!((a.weights.iter().sum::<f64>() - 1.0).abs() < 1e-12);
    assert!(a.certificate.efficiency_bound > 0.0 && a.certificate.efficiency_bound <= 1.0);
    assert_eq!(b.status, Status::Optimal);
}

/// A simulation long enough to take many seconds (rate 20 kHz, 100
/// repetitions), stopped from another thread after 0.3 s: it returns the
/// repetitions finished so far, marked interrupted.
#[test]
fn a_stop_from_another_thread_interrupts_a_simulation() {
    let designs = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("designs");
    let text = std::fs::read_to_string(designs.join("sim_rpr_fourier.toml")).unwrap();
    assert!(text.contains("rate = 1000.0") && text.contains("repetitions = 50 "));
    let text = text
        .replace("rate = 1000.0", "rate = 20000.0")
        .replace("repetitions = 50 ", "repetitions = 100 ");
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("sim.toml");
    std::fs::write(&p, text).unwrap();
    let d = idexp::sim::SimDesign::read(&p).unwrap();
    let setup = idexp::sim::SimSetup::from_design(&d, &designs, "sim").unwrap();
    let ctl = Control::new();
    let flag = ctl.stop_flag().clone();
    let stopper = std::thread::spawn(move || {
        std::thread::sleep(std::time::Duration::from_millis(300));
        flag.request();
    });
    let r = setup.run(&ctl);
    stopper.join().unwrap();
    match r {
        Ok(res) => {
            assert_eq!(res.status.status, idexp::sim::RunStatus::Interrupted);
            assert!(res.status.repetitions < 100);
            assert_eq!(res.reps.len(), res.status.repetitions);
        }
        // stopped during the lead-in period: nothing to return
        Err(e) => assert!(matches!(e, idexp::error::Error::Interrupted), "{e}"),
    }
}

/// Stops after the second repetition through the observer (deterministic):
/// exactly two complete repetitions come back, marked interrupted.
#[test]
fn a_simulation_stopped_after_two_repetitions_returns_them() {
    let designs = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("designs");
    let d = idexp::sim::SimDesign::read(&designs.join("sim_rpr_fourier.toml")).unwrap();
    let setup = idexp::sim::SimSetup::from_design(&d, &designs, "sim").unwrap();
    let res = setup.run(&stopping_after(2)).unwrap();
    assert_eq!(res.status.status, idexp::sim::RunStatus::Interrupted);
    assert_eq!(res.status.repetitions, 2);
    assert_eq!(res.reps.len(), 2);
}

/// An observer that requests a stop once a phase reports `after` steps done.
struct StopAfter(idexp::optim::StopFlag, u64);
impl idexp::optim::Observer for StopAfter {
    fn progress(&self, done: u64, _: &str) {
        if done >= self.1 {
            self.0.request();
        }
    }
}

fn stopping_after(n: u64) -> Control {
    let ctl = Control::new();
    let flag = ctl.stop_flag().clone();
    ctl.with_observer(std::sync::Arc::new(StopAfter(flag, n)))
}

/// Clarabel's termination callback asks the control at every interior-point
/// iteration: a stopped control ends the SDP at once with a valid design.
#[test]
fn a_stopped_control_ends_a_clarabel_sdp_at_once() {
    use idexp::positions::conic::{solve_d_sdp, ConicStatus};
    let pb = problem();
    let free = solve_d_sdp(&pb, &SolverOptions::default(), &Control::new());
    assert!(free.ok && free.iterations > 1, "{:?}", free.status);
    let ctl = Control::new();
    ctl.stop_flag().request();
    let r = solve_d_sdp(&pb, &SolverOptions::default(), &ctl);
    assert_eq!(r.status, ConicStatus::Solver(idexp::optim::conic::SolverStatus::CallbackTerminated));
    assert_eq!(r.status.termination(), idexp::optim::Termination::Interrupted);
    assert_eq!(r.status.to_string(), "CallbackTerminated");
    assert!(r.iterations < free.iterations);
    assert!((r.w.iter().sum::<f64>() - 1.0).abs() < 1e-12 && r.w.iter().all(|v| *v >= 0.0));
}

/// The excitation GA stopped after its third generation: the result is the
/// verified best individual so far, marked interrupted, with no refinement.
#[test]
fn an_excitation_stopped_during_the_ga_returns_its_best_so_far() {
    let designs = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("designs");
    let p = idexp::excitation::Problem::from_file(&designs.join("excite_ur5.toml")).unwrap();
    assert!(p.design.ga.generations > 3);
    let r = idexp::excitation::run(&p, &stopping_after(3)).unwrap();
    assert_eq!(r.ga.stop, idexp::excitation::ga::GaStop::Interrupted);
    assert_eq!(r.ga.generations, 3);
    assert!(r.refinements.is_empty());
    let s = serde_json::to_value(&r.stopped_by).unwrap();
    assert_eq!(s, serde_json::json!("interrupted (Ctrl-C)"));
    assert!(r.criterion.is_finite());
}

/// A multistart-style LM fit: a stopped control returns the start point, marked interrupted.
#[test]
fn a_levenberg_marquardt_fit_stops_on_request() {
    use idexp::optim::lm::{run, LmProblem, LmStatus, LmTolerances};
    use nalgebra::DVector;
    struct Line;
    impl LmProblem for Line {
        fn dim(&self) -> usize {
            1
        }
        fn normal_equations(&self, z: &[f64]) -> idexp::error::Result<(f64, DVector<f64>, DMatrix<f64>)> {
            Ok(((z[0] - 3.0).powi(2), DVector::from_element(1, z[0] - 3.0), DMatrix::from_element(1, 1, 1.0)))
        }
        fn cost(&self, z: &[f64]) -> f64 {
            (z[0] - 3.0).powi(2)
        }
        fn clamp(&self, _: usize, zi: f64) -> f64 {
            zi
        }
    }
    let tol = LmTolerances { ftol: 1e-12, xtol: 1e-12 };
    let ok = run(Line, vec![0.0], 100, tol, &Control::new()).unwrap();
    assert!((ok.z[0] - 3.0).abs() < 1e-9, "{ok:?}");
    let ctl = Control::new();
    ctl.stop_flag().request();
    let r = run(Line, vec![0.0], 100, tol, &ctl).unwrap();
    assert_eq!((r.status, r.z, r.iterations), (LmStatus::Interrupted, vec![0.0], 0));
}

/// A phase: its name, its number of steps and the progress reported in it.
type Phase = (String, Option<u64>, Vec<(u64, String)>);

/// Records the phases and the progress of a run; requests a stop once the
/// GA reports `after` generations.
struct PhaseLog {
    stop: idexp::optim::StopFlag,
    after: u64,
    log: std::sync::Mutex<Vec<Phase>>,
}
impl idexp::optim::Observer for PhaseLog {
    fn phase(&self, name: &str, total: Option<u64>) {
        self.log.lock().unwrap().push((name.to_string(), total, Vec::new()));
    }
    fn progress(&self, done: u64, msg: &str) {
        let mut log = self.log.lock().unwrap();
        let last = log.last_mut().expect("progress outside a phase");
        if last.0 == "excite GA" && done >= self.after {
            self.stop.request();
        }
        last.2.push((done, msg.to_string()));
    }
}

/// The checks after the search have a phase of their own: one step per
/// candidate tried on the check grid, then the delivered trajectory, ending
/// at its total (an interrupted search still checks what it returns).
#[test]
fn an_excitation_reports_its_checks_as_a_phase() {
    let designs = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("designs");
    let p = idexp::excitation::Problem::from_file(&designs.join("excite_ur5.toml")).unwrap();
    let ctl = Control::new();
    let obs = std::sync::Arc::new(PhaseLog {
        stop: ctl.stop_flag().clone(),
        after: 2,
        log: Default::default(),
    });
    let r = idexp::excitation::run(&p, &ctl.with_observer(obs.clone())).unwrap();
    assert!(r.execution.delivered.is_some());
    let log = obs.log.lock().unwrap();
    let names: Vec<&str> = log.iter().map(|l| l.0.as_str()).collect();
    assert_eq!(names, ["excite GA", "excite check"], "{log:?}");
    let (_, total, steps) = &log[1];
    // the GA's best is the only candidate (no refinement after the stop)
    assert_eq!(*total, Some(2));
    let rate = p.design.limits.check_rate;
    assert_eq!(steps[0], (0, format!("ga on the {rate} Hz grid")));
    assert_eq!(steps[1], (1, format!("the delivered trajectory at {rate} Hz")));
    assert_eq!(steps.last().unwrap().0, 2);
}

/// The physically consistent fit runs through the Clarabel bridge under its
/// control: a stop request ends it with `CallbackTerminated` (reported as
/// `failed: CallbackTerminated`), a deadline already passed with `MaxTime`,
/// and a free control solves the same program.
#[test]
fn the_consistent_fit_stops_on_its_control() {
    use idexp::ident::consistent::{ConsistentStatus, Kind};
    use idexp::ident::prior::{relative_weight, solve, PriorMetric, PriorProblem};
    use idexp::optim::conic::{ConicStatus, SolverStatus};
    use nalgebra::DVector;
    // one link (a box of 2 kg) and one rotor inertia, seen through a random R
    let theta = DVector::from_vec(vec![0.05, 0.0, 0.0, 0.06, 0.0, 0.07, 0.02, -0.01, 0.03, 2.0, 0.1]);
    let p = theta.len();
    let kinds: Vec<Kind> = (0..10).map(Kind::Inertial).chain([Kind::NonNegative]).collect();
    let mut g = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    let r = DMatrix::from_fn(p, p, |i, j| {
        if i == j {
            10.0
        } else if j > i {
            g.random_range(-1.0..1.0)
        } else {
            0.0
        }
    });
    let k = DMatrix::identity(p, p);
    let ones = DVector::from_element(p, 1.0);
    let names = ["box".to_string()];
    let pb = PriorProblem {
        r: &r,
        theta_b: &theta,
        k: &k,
        links: &[0],
        link_names: &names,
        kinds: &kinds,
        prior: &theta,
        scale: &ones,
    };
    let w = relative_weight(&r, 1e-6);
    let solve = |pb: &PriorProblem, ctl: &Control| solve(pb, PriorMetric::Euclidean, w, 0.0, ctl);
    let free = solve(&pb, &Control::new()).unwrap();
    assert!(free.status.is_solved() && free.iterations > 1, "{}", free.status);
    let ctl = Control::new();
    ctl.stop_flag().request();
    let s = solve(&pb, &ctl).unwrap();
    assert_eq!(s.status, ConicStatus::Solver(SolverStatus::CallbackTerminated));
    assert_eq!(ConsistentStatus::of(&s.status).to_string(), "failed: CallbackTerminated");
    assert!(s.iterations < free.iterations);
    let late = Control::new().with_time_limit(Some(0.0));
    std::thread::sleep(std::time::Duration::from_millis(2));
    let s = solve(&pb, &late).unwrap();
    assert_eq!(s.status, ConicStatus::Solver(SolverStatus::MaxTime), "{}", s.status);
    assert_eq!(s.status.termination(), idexp::optim::Termination::TimeLimit);
}
