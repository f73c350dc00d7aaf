//! A stop request (Ctrl-C) ends the relaxed solve cleanly with the best design
//! so far and its certificate. Own test binary: the stop flag is process-wide.

use idexp::positions::{solve_relaxed, Criterion, Problem, SolverOptions, Status};
use nalgebra::DMatrix;
use rand::{RngExt, SeedableRng};

#[test]
fn stop_request_returns_the_best_design_so_far() {
    let mut g = rand_chacha::ChaCha8Rng::seed_from_u64(51);
    let h: Vec<DMatrix<f64>> = (0..300).map(|_| DMatrix::from_fn(10, 2, |_, _| g.random_range(-1.0..1.0))).collect();
    let pb = Problem::from_factors(10, &h, None).unwrap();
    idexp::io::stop::request();
    let r = solve_relaxed(&pb, Criterion::D, &SolverOptions::default(), &idexp::optim::Control::new());
    idexp::io::stop::reset();
    let r = r.unwrap();
    assert_eq!(r.status, Status::Interrupted);
    assert!((r.weights.iter().sum::<f64>() - 1.0).abs() < 1e-12);
    assert!(r.certificate.efficiency_bound > 0.0 && r.certificate.efficiency_bound <= 1.0);
    // without the request the same problem certifies
    let r = solve_relaxed(&pb, Criterion::D, &SolverOptions::default(), &idexp::optim::Control::new()).unwrap();
    assert_eq!(r.status, Status::Optimal);
}
