//! The rows of a delivered trajectory's periods 2, 3, … repeat those of
//! period 1 bitwise when a period is a whole number of samples
//! (`idexp::trajectory::lead::RowPlan`): each repeated row is the series at
//! its own time to rounding, what is computed once from period 1 (the CSV
//! text, the identifiability, the collision count) equals what computing
//! every row gives, and a period of a fractional number of samples is
//! evaluated row by row as before.

use idexp::excitation::{assess, assess_delivered};
use idexp::io::States;
use idexp::params::{BaseOptions, BaseParams};
use idexp::trajectory::lead::{Delivered, Quintic, State};
use idexp::trajectory::FourierTrajectory;
use std::path::Path;

/// A 6-joint periodic trajectory of 0.2 Hz (5 s), 3 harmonics, with quintic
/// leads from and back to home at rest.
fn delivered(periods: usize, frequency: f64) -> Delivered {
    let n = 6;
    let a: Vec<Vec<f64>> = (0..n).map(|j| (0..3).map(|k| 0.11 * ((j + 2 * k) as f64).sin()).collect()).collect();
    let b: Vec<Vec<f64>> = (0..n).map(|j| (0..3).map(|k| 0.09 * ((3 * j + k) as f64).cos()).collect()).collect();
    let q0: Vec<f64> = (0..n).map(|j| 0.1 * j as f64 - 0.2).collect();
    let tr = FourierTrajectory::new(2.0 * std::f64::consts::PI * frequency, q0.clone(), a, b).unwrap();
    let home = vec![0.0; n];
    let start = State::of(&tr, 0.0);
    let lead_in = Quintic::new(&State::rest(&home), &start, 1.32);
    let end = State::of(&tr, periods as f64 * tr.period());
    let lead_out = Quintic::new(&end, &State::rest(&home), 0.96);
    Delivered {
        home,
        lead_in: Some(lead_in),
        periodic: tr.into(),
        periods,
        lead_out: Some(lead_out),
    }
}

#[test]
fn rows_of_later_periods_repeat_period_one_bitwise_and_are_the_series_at_their_time() {
    let d = delivered(4, 0.2);
    let rate = 1000.0;
    let s = d.sample(rate).unwrap();
    assert_eq!(d.rows(rate).period_rows, Some(5000));
    let n = 6;
    let (mut q, mut qd, mut qdd) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    let mut repeated = 0;
    for k in 0..s.len() {
        let src = s.source[k];
        // the series evaluated at this row's own time
        let seg = d.eval(s.t[k], &mut q, &mut qd, &mut qdd);
        assert_eq!(seg, s.segment[k], "row {k}");
        for (got, want) in [(&s.q[k], &q), (&s.qd[k], &qd), (&s.qdd[k], &qdd)] {
            for j in 0..n {
                assert!((got[j] - want[j]).abs() <= 1e-11, "row {k} joint {j}: {} vs {}", got[j], want[j]);
            }
        }
        if src != k {
            repeated += 1;
            assert!(s.segment[k] >= 2 && s.segment[src] == 1, "row {k} repeats row {src}");
            assert_eq!(k - src, (s.segment[k] as usize - 1) * 5000);
            assert_eq!((&s.q[k], &s.qd[k], &s.qdd[k]), (&s.q[src], &s.qd[src], &s.qdd[src]));
        } else {
            assert!(s.segment[k] <= 1, "row {k} of period {} is evaluated", s.segment[k]);
        }
    }
    // periods 2, 3 and 4: every row repeats one of period 1
    assert_eq!(repeated, 3 * 5000);
    // multiplicities: every row counted once
    let plan = d.rows(rate);
    let total: usize = (0..s.len()).map(|k| plan.multiplicity(&d, k)).sum();
    assert_eq!(total, s.len());
    for k in 0..s.len() {
        let copies = s.source.iter().filter(|&&src| src == k).count();
        if k % 997 == 0 || copies > 1 && k % 101 == 0 {
            assert_eq!(plan.multiplicity(&d, k), copies, "row {k}");
        }
    }
}

#[test]
fn a_period_of_a_fractional_number_of_samples_is_evaluated_row_by_row() {
    // 0.3 Hz at 1 kHz: 3333.3… samples per period
    let d = delivered(3, 0.3);
    let s = d.sample(1000.0).unwrap();
    assert_eq!(d.rows(1000.0).period_rows, None);
    assert!(s.source.iter().enumerate().all(|(k, &src)| src == k));
    // one period: nothing to repeat
    let d = delivered(1, 0.2);
    assert_eq!(d.rows(1000.0).period_rows, None);
    assert!(d.sample(1000.0).unwrap().source.iter().enumerate().all(|(k, &src)| src == k));
}

#[test]
fn the_csv_of_repeated_rows_is_the_text_of_every_row_formatted() {
    let d = delivered(3, 0.2);
    let s = d.sample(250.0).unwrap();
    assert!(s.source.iter().enumerate().any(|(k, &src)| src != k));
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("trajectory.csv");
    s.write_csv(&path).unwrap();
    let got = std::fs::read_to_string(&path).unwrap();
    let mut want = String::from("t,q1,q2,q3,q4,q5,q6,qd1,qd2,qd3,qd4,qd5,qd6,qdd1,qdd2,qdd3,qdd4,qdd5,qdd6,segment\n");
    for k in 0..s.len() {
        want.push_str(&format!("{}", s.t[k]));
        for v in s.q[k].iter().chain(&s.qd[k]).chain(&s.qdd[k]) {
            want.push_str(&format!(",{v}"));
        }
        want.push_str(&format!(",{}\n", s.segment[k]));
    }
    assert!(got == want, "trajectory.csv differs from the rows formatted one by one");
}

#[test]
fn the_identifiability_of_repeated_rows_counted_equals_that_of_every_row_stacked() {
    let robot = idexp::robot::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("designs/robots/ur5.toml")).unwrap();
    let base = BaseParams::compute(&robot, &BaseOptions::default()).unwrap();
    let d = delivered(3, 0.2);
    let s = d.sample(100.0).unwrap();
    assert_eq!(s.source.iter().enumerate().filter(|(k, src)| *k != **src).count(), 2 * 500);
    let noise = [1.0, 2.0, 1.5, 0.5, 0.5, 0.25];
    let counted = assess_delivered(&robot, &base, &s, &noise).unwrap();
    let states = States {
        t: None,
        q: s.q.clone(),
        qd: s.qd.clone(),
        qdd: s.qdd.clone(),
    };
    let stacked = assess(&robot, &base, &states, &noise).unwrap();
    assert_eq!(counted.samples, stacked.samples);
    assert_eq!(counted.rows, stacked.rows);
    assert_eq!(counted.rank, stacked.rank);
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-10 * a.abs().max(b.abs()).max(1e-300);
    assert!(close(counted.cond, stacked.cond), "{} vs {}", counted.cond, stacked.cond);
    for (name, a, b) in [
        ("singular values", &counted.singular_values, &stacked.singular_values),
        ("column norms", &counted.column_norms, &stacked.column_norms),
        ("sensitivity", &counted.sensitivity, &stacked.sensitivity),
        ("std dev", &counted.std_dev, &stacked.std_dev),
    ] {
        assert_eq!(a.len(), b.len());
        for (x, y) in a.iter().zip(b) {
            assert!(close(*x, *y) || x.is_infinite() && y.is_infinite(), "{name}: {x} vs {y}");
        }
    }
    // a plan that names a later row, or a repeated row, as a source is refused
    let mut bad = s.clone();
    bad.source[10] = 11;
    assert!(assess_delivered(&robot, &base, &bad, &noise).is_err());
    let mut bad = s.clone();
    let k = bad.source.iter().enumerate().find(|(k, src)| *k != **src).unwrap().0;
    bad.source[k + 1] = k;
    assert!(assess_delivered(&robot, &base, &bad, &noise).is_err());
    // rows missing: an error, not a panic
    let mut bad = s.clone();
    bad.qd.pop();
    assert!(assess_delivered(&robot, &base, &bad, &noise).is_err());
}
