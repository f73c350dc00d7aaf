//! A fuller end-to-end test on a 6-axis robot (PUMA 560 with drives: 52 base
//! parameters): WLS from a simulated closed-loop Fourier excitation recovers
//! every true base parameter within 3 reported standard deviations, and the
//! validation error on another excitation is at the noise floor.

mod ident_util;
use ident_util::*;

fn puma(seed: u64, traj_seed: u64) -> idexp::sim::SimDesign {
    design(&format!(
        r#"
robot = "designs/robots/puma560.toml"
rate = 1000.0
decimate = 10
repetitions = 30
seed = {seed}
[truth]
perturbation = 0.1
seed = 21
[controller]
bandwidth = 8.0
[noise]
torque = 0.1
position = 1e-5
[reference]
kind = "random_fourier"
n_h = 5
frequency = 0.1
amplitude = 0.8
seed = {traj_seed}
"#
    ))
}

#[test]
fn puma560_wls_within_3_sigma_and_validation_at_noise_floor() {
    let res = simulate(&puma(1, 31));
    let val = simulate(&puma(2, 32));
    let (id, base) = ident(&res, Some(&val), |d| d.experiment[0].harmonics = Some(20));
    let e = &id.estimate;
    println!("{}", e.text());
    assert_eq!(base.n_base(), e.names.len());
    assert_eq!(e.status, idexp::ident::EstimateStatus::Ok);
    for r in e.truth.as_ref().unwrap() {
        assert!(r.z.abs() < 3.0, "{} = {} vs truth {} (z = {:.2})", r.name, r.estimate, r.truth, r.z);
    }
    let v = &e.validation[0].errors;
    for j in 0..6 {
        let floor = v.noise_floor.as_ref().unwrap()[j];
        assert!(v.e[j] < 1.2 * floor, "joint {}: validation e_j {} vs floor {floor}", j + 1, v.e[j]);
    }
}
