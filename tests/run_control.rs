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

/// A simulation long enough to take many seconds (rate 20 kHz, 200
/// repetitions), stopped from another thread after 0.3 s: it returns the
/// repetitions finished so far, marked interrupted.
#[test]
fn a_stop_from_another_thread_interrupts_a_simulation() {
    let designs = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("designs");
    let text = std::fs::read_to_string(designs.join("sim_rpr_fourier.toml")).unwrap();
    assert!(text.contains("rate = 1000.0") && text.contains("repetitions = 50 "));
    let text = text
        .replace("rate = 1000.0", "rate = 20000.0")
        .replace("repetitions = 50 ", "repetitions = 200 ");
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
            assert!(res.status.repetitions < 200);
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
    struct StopAfter(idexp::optim::StopFlag, u64);
    impl idexp::optim::Observer for StopAfter {
        fn progress(&self, done: u64, _: &str) {
            if done >= self.1 {
                self.0.request();
            }
        }
    }
    let designs = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("designs");
    let d = idexp::sim::SimDesign::read(&designs.join("sim_rpr_fourier.toml")).unwrap();
    let setup = idexp::sim::SimSetup::from_design(&d, &designs, "sim").unwrap();
    let ctl = Control::new();
    let ctl = ctl.clone().with_observer(std::sync::Arc::new(StopAfter(ctl.stop_flag().clone(), 2)));
    let res = setup.run(&ctl).unwrap();
    assert_eq!(res.status.status, idexp::sim::RunStatus::Interrupted);
    assert_eq!(res.status.repetitions, 2);
    assert_eq!(res.reps.len(), 2);
}
