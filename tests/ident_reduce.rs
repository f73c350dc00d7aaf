//! Model reduction (paper 000 Algorithm 1) on simulated process motions:
//! pick-and-place (all joints move: friction essential) and a horizontal
//! square (the wrist of the RPR arm does not move: its parameters fail the
//! rank check and are removed first).

mod ident_util;
use ident_util::*;
use idexp::ident::study::ReduceSpec;

fn pick_place(seed: u64, points_seed: u64) -> idexp::sim::SimDesign {
    design(&format!(
        r#"
robot = "tests/data/ident/rpr_drives.toml"
rate = 1000.0
decimate = 5
repetitions = 10
seed = {seed}
[truth]
perturbation = 0.1
seed = 4
[noise]
torque = 0.05
position = 1e-5
[reference]
kind = "pick_and_place"
area_a = {{ center = [0.25, -0.38, 0.36], half_size = [0.04, 0.04, 0.01] }}
area_b = {{ center = [-0.25, -0.38, 0.36], half_size = [0.04, 0.04, 0.01] }}
cycles = 4
move_time = 0.8
dwell = 0.2
q_home = [0.0, 0.25, 0.0]
seed = {points_seed}
"#
    ))
}

#[test]
fn pick_and_place_reduction_lowers_cond_5x_within_tolerance() {
    let res = simulate(&pick_place(2, 5));
    let val = simulate(&pick_place(3, 6));
    let (id, _) = ident(&res, Some(&val), |d| d.reduce = Some(ReduceSpec::default()));
    let r = id.estimate.reduction.as_ref().unwrap();
    println!("{}", r.text());
    assert!(!r.steps.is_empty());
    // every joint moves: the friction parameters are essential
    assert!(r.essential.iter().any(|n| n.starts_with("Fc")));
    assert!(r.essential.iter().all(|n| n.starts_with("Fc") || n.starts_with("Fv")));
    let ratio = r.full.cond_normalized / r.reduced.cond_normalized;
    assert!(
        ratio >= 5.0,
        "condition number {} → {} (ratio {ratio:.2})",
        r.full.cond_normalized,
        r.reduced.cond_normalized
    );
    for j in 0..3 {
        let g = r.reduced_errors.e_rel[j] / r.full_errors.e_rel[j] - 1.0;
        assert!(g <= r.options.tol, "joint {}: e* grows by {:.2} %", j + 1, 100.0 * g);
    }
    // each step is reported with a decision consistent with the tolerance
    for s in &r.steps {
        assert_eq!(s.decision == "removed", s.growth <= r.options.tol, "step {}", s.k);
    }
    // the reduced model is what the estimate reports, and it predicts the validation process
    assert_eq!(id.estimate.names, r.names);
    let v = &id.estimate.validation[0].errors;
    for j in 0..3 {
        assert!(v.e_rel[j] < 0.5, "validation e*_{} = {}", j + 1, v.e_rel[j]);
    }
    assert!(r.text().contains("θ̂_0 (full)"));
}

#[test]
fn square_removes_the_still_joint_first_and_friction_is_not_essential() {
    let d = design(
        r#"
robot = "tests/data/ident/rpr_drives.toml"
rate = 1000.0
decimate = 5
repetitions = 6
seed = 9
[truth]
perturbation = 0.1
seed = 4
[noise]
torque = 0.05
position = 1e-5
[reference]
kind = "square"
center = [0.0, -0.4, 0.40]
side = 0.12
side_time = 1.0
laps = 2
q_home = [0.0, 0.25, 0.0]
"#,
    );
    let res = simulate(&d);
    let (id, _) = ident(&res, None, |d| d.reduce = Some(ReduceSpec::default()));
    let r = id.estimate.reduction.as_ref().unwrap();
    println!("{}", r.text());
    // joint 3 holds still on a horizontal square: its friction cannot be identified
    assert!(
        r.rank_removed.iter().any(|n| n == "Fc3" || n == "Fv3"),
        "rank check removed {:?}",
        r.rank_removed
    );
    assert!(r.essential.is_empty(), "not every joint moves: no essential set");
    assert!(r.full.cond_normalized / r.reduced.cond_normalized >= 1.0);
}
