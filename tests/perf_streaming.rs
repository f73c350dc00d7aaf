//! Streaming `assess` and per-state tables (block-wise reading,
//! incremental QR) against the direct computations, and the `base_columns`
//! option (a named base set is checked; the dependent names are reported).

mod common;

use common::root;
use idexp::excitation::report::{assess, assess_file};
use idexp::io::States;
use idexp::params::stream::{stream_table, TableKind};
use idexp::params::{BaseOptions, BaseParams};
use idexp::robot::{self, Workspace};
use nalgebra::DMatrix;
use rand::RngExt;

fn ur5() -> robot::Robot {
    robot::load(&root("designs/robots/ur5.toml")).unwrap()
}

/// A states CSV of `k` random states (more rows than one accumulator block).
fn random_states(r: &robot::Robot, k: usize, path: &std::path::Path) -> States {
    let mut g = common::rng(3);
    let n = r.dof();
    let mut s = States {
        t: Some(Vec::new()),
        q: Vec::new(),
        qd: Vec::new(),
        qdd: Vec::new(),
    };
    for i in 0..k {
        s.t.as_mut().unwrap().push(i as f64 * 0.01);
        s.q.push((0..n).map(|_| g.random_range(-3.0..3.0)).collect());
        s.qd.push((0..n).map(|_| g.random_range(-2.0..2.0)).collect());
        s.qdd.push((0..n).map(|_| g.random_range(-5.0..5.0)).collect());
    }
    s.write(path).unwrap();
    States::read(path, n).unwrap()
}

/// The streamed report (incremental QR of the weighted base regressor) equals
/// the direct one: singular values, cond and σ_i of an SVD of the full
/// stacked, weighted, unit-column matrix computed here, to 1e-9.
#[test]
fn streamed_assess_equals_the_direct_svd() {
    let r = ur5();
    let (n, p) = (r.dof(), r.n_params());
    let base = BaseParams::compute(&r, &BaseOptions::default()).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("s.csv");
    let s = random_states(&r, 2500, &path);
    let noise = [1.0, 2.0, 0.5, 1.0, 0.3, 0.7];
    let a = assess(&r, &base, &s, &noise).unwrap();
    let b = assess_file(&r, &base, &path, None, 1, &noise).unwrap();
    assert_eq!(a.samples, 2500);
    assert_eq!(b.samples, 2500);
    // the direct computation
    let m = base.n_base();
    let mut ws = Workspace::new(&r);
    let mut y = vec![0.0; n * p];
    let mut c = DMatrix::zeros(s.len() * n, m);
    for i in 0..s.len() {
        robot::regressor_rows(&r, &mut ws, &s.q[i], &s.qd[i], &s.qdd[i], &mut y);
        for row in 0..n {
            for (j, &col) in base.independent.iter().enumerate() {
                c[(i * n + row, j)] = y[row * p + col] / noise[row];
            }
        }
    }
    let norms: Vec<f64> = (0..m).map(|j| c.column(j).norm()).collect();
    for j in 0..m {
        c.column_mut(j).scale_mut(1.0 / norms[j]);
    }
    let svd = c.svd(false, true);
    let mut sv: Vec<f64> = svd.singular_values.iter().copied().collect();
    sv.sort_by(|x, y| y.total_cmp(x));
    for id in [&a, &b] {
        for (k, (x, y)) in id.singular_values.iter().zip(&sv).enumerate() {
            assert!((x - y).abs() <= 1e-9 * sv[0], "σ_{k}: {x} vs {y}");
        }
        assert!((id.cond - sv[0] / sv[m - 1]).abs() <= 1e-9 * id.cond);
        // σ_i = ‖row i of V Σ⁻¹‖ / ‖column i‖
        let vt = svd.v_t.as_ref().unwrap();
        for i in 0..m {
            let var: f64 = (0..m).map(|k| (vt[(k, i)] / svd.singular_values[k]).powi(2)).sum();
            let want = var.sqrt() / norms[i];
            assert!(
                (id.std_dev[i] - want).abs() <= 1e-9 * want,
                "σ of {}: {} vs {want}",
                base.names[i],
                id.std_dev[i]
            );
        }
    }
    for (x, y) in a.sensitivity.iter().zip(&b.sensitivity) {
        assert!((x - y).abs() <= 1e-12 * x.abs().max(1e-300));
    }
    // every k-th row
    let c3 = assess_file(&r, &base, &path, None, 3, &noise).unwrap();
    assert_eq!(c3.samples, 2500_usize.div_ceil(3));
}

/// A bad cell far down a long file is reported with its row and column.
#[test]
fn streamed_reader_names_the_bad_row() {
    let r = ur5();
    let base = BaseParams::compute(&r, &BaseOptions::default()).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("s.csv");
    random_states(&r, 5000, &path);
    let text = std::fs::read_to_string(&path).unwrap();
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    let mut cells: Vec<String> = lines[4500].split(',').map(String::from).collect();
    cells[3] = "abc".into();
    lines[4500] = cells.join(",");
    std::fs::write(&path, lines.join("\n")).unwrap();
    let e = assess_file(&r, &base, &path, None, 1, &[1.0; 6]).unwrap_err().to_string();
    assert!(e.contains("4500") && e.contains("q3") && e.contains("abc"), "{e}");
    let mut out = Vec::new();
    let e = stream_table(&r, &path, TableKind::Torques, &mut out).unwrap_err().to_string();
    assert!(e.contains("4500") && e.contains("q3"), "{e}");
}

/// The streamed tables are the same text as the in-memory ones.
#[test]
fn streamed_tables_equal_the_in_memory_tables() {
    let r = ur5();
    let base = BaseParams::compute(&r, &BaseOptions::default()).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("s.csv");
    let s = random_states(&r, 5000, &path);
    let csv = |h: Vec<String>, rows: Vec<Vec<f64>>| {
        let p = dir.path().join("t.csv");
        idexp::io::write_csv(&p, &h, &rows).unwrap();
        std::fs::read_to_string(&p).unwrap()
    };
    let (h, rows) = idexp::params::info::torques_table(&r, &s);
    let mut out = Vec::new();
    assert_eq!(stream_table(&r, &path, TableKind::Torques, &mut out).unwrap(), 5000);
    assert_eq!(String::from_utf8(out).unwrap(), csv(h, rows));
    for b in [None, Some(&base)] {
        let (h, rows) = idexp::params::info::regressor_table(&r, &s, b);
        let mut out = Vec::new();
        stream_table(&r, &path, TableKind::Regressor(b), &mut out).unwrap();
        assert_eq!(String::from_utf8(out).unwrap(), csv(h, rows));
    }
}

fn names(v: &[&str]) -> Vec<String> {
    v.iter().map(|s| s.to_string()).collect()
}

/// idexp's own base set, named, gives the same base; a named set with a
/// dependent column, a short set, an unknown and a repeated name are errors
/// that say which names are at fault.
#[test]
fn base_columns_are_checked_and_the_dependent_ones_named() {
    let r = ur5();
    let opts = BaseOptions::default();
    let auto = BaseParams::compute(&r, &opts).unwrap();
    let info = r.params();
    let std_names: Vec<String> = auto.independent.iter().map(|&c| info[c].name.clone()).collect();
    let named = BaseParams::with_columns(&r, &std_names, &opts).unwrap();
    assert_eq!(named.independent, auto.independent);
    assert_eq!(named.names, auto.names);
    assert!((&named.k - &auto.k).amax() < 1e-12);
    // another valid base: ZZ2 instead of XX2 (XX2 − ZZ2 regroups either way)
    let mut other = std_names.clone();
    let i = other.iter().position(|n| n == "XX2").unwrap();
    other[i] = "ZZ2".into();
    let b = BaseParams::with_columns(&r, &other, &opts).unwrap();
    assert_eq!(b.n_base(), 48);
    // W K θ is the same torque for both bases: W_b θ_b = W θ
    let w = idexp::params::random_stack(&r, 30, 9);
    let theta = r.nominal_params();
    let t_std = &w * &theta;
    let t_b = b.select(&w) * b.base_values(theta.as_slice());
    assert!((&t_std - &t_b).amax() < 1e-8 * t_std.amax());
    // dependent: XX5 − YY5 + ZZ6 regroups; naming XX5, YY5 and ZZ6 … with ZZ5 too
    let mut dep = std_names.clone();
    dep.push("YY5".into());
    let e = BaseParams::with_columns(&r, &dep, &opts).unwrap_err().to_string();
    assert!(e.contains("not independent") && e.contains("YY5"), "{e}");
    // too few
    let e = BaseParams::with_columns(&r, &std_names[..40], &opts).unwrap_err().to_string();
    assert!(e.contains("8 more needed"), "{e}");
    // no effect on the torques (link 1 moves about a vertical axis)
    let mut nx = std_names.clone();
    nx.push("MX1".into());
    let e = BaseParams::with_columns(&r, &nx, &opts).unwrap_err().to_string();
    assert!(e.contains("MX1") && e.contains("no effect"), "{e}");
    // unknown / repeated
    let e = BaseParams::with_columns(&r, &names(&["ZZ1", "QQ7"]), &opts).unwrap_err().to_string();
    assert!(e.contains("QQ7") && e.contains("allowed"), "{e}");
    let e = BaseParams::with_columns(&r, &names(&["ZZ1", "ZZ1"]), &opts).unwrap_err().to_string();
    assert!(e.contains("twice"), "{e}");
}

/// The shipped like-for-like design loads with its named base set, the same
/// base as idexp's own choice, and the ±π ranges.
#[test]
fn bench_pi_design_uses_the_named_base_and_pi_limits() {
    let p = idexp::excitation::Problem::from_file(&root("designs/excite_ur5_bench_pi.toml")).unwrap();
    let auto = BaseParams::compute(&p.robot, &BaseOptions::default()).unwrap();
    assert_eq!(p.base.independent, auto.independent);
    let d = idexp::excitation::design::ExciteDesign::load(&root("designs/excite_ur5_bench_pi.toml")).unwrap();
    let r = d.limits.position_range.unwrap();
    assert!(r
        .iter()
        .all(|[lo, hi]| (*lo + std::f64::consts::PI).abs() < 1e-12 && (*hi - std::f64::consts::PI).abs() < 1e-12));
}
