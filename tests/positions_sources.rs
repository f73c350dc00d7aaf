//! Information sources, candidate generation and design-file validation.

mod common;

use idexp::positions::candidates::{CandidateKind, CandidateSpec};
use idexp::positions::{InformationFile, InformationSource, PositionsDesign, RigidSource};
use idexp::robot::cartesian::{CartesianConstraint, Shape};
use idexp::robot::{self, frame_pose, Workspace};
use nalgebra::DMatrix;
use std::path::Path;

fn grid(joints: Vec<usize>, points: Vec<usize>) -> CandidateSpec {
    CandidateSpec {
        kind: CandidateKind::Grid,
        joints,
        points: Some(points),
        count: None,
        lower: None,
        upper: None,
        fixed: Some(vec![0.0, -1.0, 0.5, 0.0, 0.5, 0.0]),
        path: None,
        workspace: vec![],
        collision: Default::default(),
    }
}

#[test]
fn rigid_information_is_the_stacked_base_regressor_gram_matrix() {
    let r = robot::load(&common::root("designs/robots/industrial6.toml")).unwrap();
    let n = r.dof();
    let cands = grid(vec![2, 3], vec![4, 3]).generate(&r, &[0.1; 6], 1, Path::new("."), "test").unwrap();
    let amp = vec![0.1, 0.08, 0.12, 0.1, 0.1, 0.1];
    let sig = vec![2.0, 2.0, 1.0, 0.5, 0.5, 0.2];
    let src = RigidSource::new(r.clone(), &cands.q, true, amp.clone(), 2.0, 16, sig.clone()).unwrap();
    let p = src.n_params();
    assert!((20..=36).contains(&p), "p = {p}");
    // independent computation: the trajectory formula, robot::regressor, base columns
    let q0 = &cands.q[5];
    let mut ws = Workspace::new(&r);
    let mut y = DMatrix::zeros(n, r.n_params());
    let mut f = DMatrix::zeros(p, p);
    let om = 2.0 * std::f64::consts::PI / 2.0;
    for k in 0..16 {
        let t = k as f64 * 2.0 / 16.0;
        let q: Vec<f64> = (0..n).map(|j| q0[j] + amp[j] * ((j + 1) as f64 * om * t).sin()).collect();
        let qd: Vec<f64> = (0..n).map(|j| amp[j] * (j + 1) as f64 * om * ((j + 1) as f64 * om * t).cos()).collect();
        let qdd: Vec<f64> = (0..n)
            .map(|j| -amp[j] * ((j + 1) as f64 * om).powi(2) * ((j + 1) as f64 * om * t).sin())
            .collect();
        robot::regressor(&r, &mut ws, &q, &qd, &qdd, &mut y);
        let yb = DMatrix::from_fn(n, p, |i, c| y[(i, src.base.independent[c])] / sig[i]);
        f += yb.transpose() * &yb;
    }
    let g = src.information(q0).unwrap();
    let err = (&g - &f).norm() / f.norm();
    assert!(err < 1e-9, "relative difference {err}");
    // all candidates together identify every base parameter
    let mut total = DMatrix::zeros(p, p);
    for q in &cands.q {
        total += src.information(q).unwrap();
    }
    assert!(total.cholesky().is_some());
}

#[test]
fn grid_random_and_workspace_filter() {
    let r = robot::load(&common::root("designs/robots/industrial6.toml")).unwrap();
    let g = grid(vec![2, 3, 5], vec![5, 4, 3]).generate(&r, &[0.0; 6], 1, Path::new("."), "t").unwrap();
    assert_eq!(g.q.len(), 60);
    assert_eq!(g.generated, 60);
    // varied joints span the limits, the others stay fixed
    let lim = &r.joints[1].limits;
    let q2: Vec<f64> = g.q.iter().map(|q| q[1]).collect();
    assert!((q2.iter().cloned().fold(f64::INFINITY, f64::min) - lim.lower).abs() < 1e-12);
    assert!(g.q.iter().all(|q| q[0] == 0.0 && q[3] == 0.0));
    // random: reproducible from the seed
    let mut spec = grid(vec![1, 2, 3], vec![1]);
    spec.kind = CandidateKind::Random;
    spec.count = Some(300);
    let a = spec.generate(&r, &[0.1; 6], 7, Path::new("."), "t").unwrap();
    let b = spec.generate(&r, &[0.1; 6], 7, Path::new("."), "t").unwrap();
    let c = spec.generate(&r, &[0.1; 6], 8, Path::new("."), "t").unwrap();
    assert_eq!(a.q, b.q);
    assert_ne!(a.q, c.q);
    // margins: every candidate keeps 0.1 rad from the limits
    for q in &a.q {
        for j in 0..6 {
            let l = &r.joints[j].limits;
            assert!(q[j] >= l.lower + 0.1 - 1e-12 && q[j] <= l.upper - 0.1 + 1e-12);
        }
    }
    // workspace: flange above z = 0.6 m
    spec.workspace = vec![CartesianConstraint {
        frame: None,
        shape: Shape::HalfSpace {
            normal: [0.0, 0.0, 1.0],
            offset: 0.6,
        },
    }];
    let w = spec.generate(&r, &[0.1; 6], 7, Path::new("."), "t").unwrap();
    assert!(w.rejected_workspace > 0 && !w.q.is_empty());
    assert_eq!(w.q.len() + w.rejected_workspace, a.q.len());
    let ee = r.end_effector();
    let mut ws = Workspace::new(&r);
    for q in &w.q {
        assert!(frame_pose(&r, &mut ws, q, &ee).translation.vector.z >= 0.6);
    }
    let rejected = a.q.iter().filter(|q| frame_pose(&r, &mut ws, q, &ee).translation.vector.z < 0.6).count();
    assert_eq!(rejected, w.rejected_workspace);
}

#[test]
fn candidate_errors_name_the_field() {
    let r = robot::load(&common::root("designs/robots/industrial6.toml")).unwrap();
    let e = grid(vec![7], vec![3]).generate(&r, &[0.0; 6], 1, Path::new("."), "d.toml").unwrap_err();
    assert!(e.to_string().contains("candidates.joints"), "{e}");
    let e = grid(vec![2, 3], vec![3, 3, 3])
        .generate(&r, &[0.0; 6], 1, Path::new("."), "d.toml")
        .unwrap_err();
    assert!(e.to_string().contains("candidates.points"), "{e}");
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("c.csv"), "q1,q2,q3,q4,q5\n0,0,0,0,0\n").unwrap();
    let mut spec = grid(vec![], vec![1]);
    spec.kind = CandidateKind::File;
    spec.path = Some("c.csv".into());
    let e = spec.generate(&r, &[0.0; 6], 1, dir.path(), "d.toml").unwrap_err();
    assert!(e.to_string().contains("q6"), "{e}");
    std::fs::write(dir.path().join("c.csv"), "q1,q2,q3,q4,q5,q6,cost\n0,-1,0.5,0,0.5,0,2\n0,-1,0.6,0,0.5,0,1.5\n").unwrap();
    let c = spec.generate(&r, &[0.0; 6], 1, dir.path(), "d.toml").unwrap();
    assert_eq!(c.q.len(), 2);
    assert_eq!(c.costs, Some(vec![2.0, 1.5]));
}

fn parse(text: &str) -> idexp::Result<InformationFile> {
    InformationFile::parse(Path::new("info.json"), text)
}

#[test]
fn information_file_format() {
    let f = parse(
        r#"{"parameters": ["a", "b"], "prior": [[1, 0], [0, 1]],
            "candidates": [{"q": [0, 1], "information": [[2, 1], [1, 2]]},
                           {"q": [1, 1], "jacobian": [[1, 2], [3, 4], [0, 1]], "cost": 2}]}"#,
    )
    .unwrap();
    assert_eq!(f.names, vec!["a", "b"]);
    assert!(f.has_costs && f.costs == vec![1.0, 2.0]);
    let h = &f.factors[0];
    assert!((h * h.transpose() - DMatrix::from_row_slice(2, 2, &[2.0, 1.0, 1.0, 2.0])).norm() < 1e-12);
    let h = &f.factors[1];
    let j = DMatrix::from_row_slice(3, 2, &[1.0, 2.0, 3.0, 4.0, 0.0, 1.0]);
    assert!((h * h.transpose() - j.transpose() * &j).norm() < 1e-12);
    assert!(f.prior.is_some());
    let cases = [
        (r#"{"parameters": ["a"], "candidates": [{"information": [[1]]}], "extra": 1}"#, "extra"),
        (
            r#"{"parameters": ["a", "b"], "candidates": [{"information": [[1, 0], [0]]}]}"#,
            "candidates[0].information",
        ),
        (
            r#"{"parameters": ["a", "b"], "candidates": [{"information": [[1, 0.5], [0, 1]]}]}"#,
            "not symmetric",
        ),
        (
            r#"{"parameters": ["a", "b"], "candidates": [{"information": [[1, 2], [2, 1]]}]}"#,
            "not positive semidefinite",
        ),
        (
            r#"{"parameters": ["a"], "candidates": [{"information": [[1]], "jacobian": [[1]]}]}"#,
            "exactly one",
        ),
        (
            r#"{"parameters": ["a"], "candidates": [{"q": [1], "information": [[1]]}, {"information": [[1]]}]}"#,
            "candidates[1].q",
        ),
        (
            r#"{"parameters": ["a"], "candidates": [{"information": [[1]], "cost": -1}]}"#,
            "candidates[0].cost",
        ),
        (r#"{"parameters": ["a", "a"], "candidates": [{"jacobian": [[1, 1]]}]}"#, "parameters"),
        (r#"{"parameters": ["a"], "candidates": []}"#, "candidates"),
        (r#"{"parameters": ["a"], "candidates": [{"information": [[1]]}], "prior": [[-1]]}"#, "prior"),
    ];
    for (text, needle) in cases {
        let e = parse(text).unwrap_err().to_string();
        assert!(e.contains(needle) && e.contains("info.json"), "expected {needle:?} in: {e}");
    }
}

#[test]
fn design_file_errors() {
    let dir = tempfile::tempdir().unwrap();
    let check = |text: &str, needle: &str| {
        let p = dir.path().join("d.toml");
        std::fs::write(&p, text).unwrap();
        let e = PositionsDesign::read(&p).unwrap_err().to_string();
        assert!(e.contains(needle), "expected {needle:?} in: {e}");
    };
    check(
        "name = \"x\"\ncriterion = \"d\"\ntypo = 1\n[information]\nsource = \"file\"\npath = \"a.json\"\n",
        "typo",
    );
    check(
        "name = \"x\"\ncriterion = \"q\"\n[information]\nsource = \"file\"\npath = \"a.json\"\n",
        "line 2",
    );
    check("name = \"x\"\n[information]\nsource = \"rigid\"\n", "robot");
    check("name = \"x\"\nrobot = \"r.toml\"\n[information]\nsource = \"rigid\"\n", "candidates");
    check(
        "name = \"x\"\n[information]\nsource = \"file\"\npath = \"a.json\"\n[candidates]\nkind = \"grid\"\n",
        "candidates",
    );
    check(
        "name = \"x\"\nexperiments = 0\n[information]\nsource = \"file\"\npath = \"a.json\"\n",
        "experiments",
    );
    check(
        "name = \"x\"\n[information]\nsource = \"file\"\npath = \"a.json\"\n[solver]\ntol = 2.0\n",
        "solver.tol",
    );
    check("name = \"x\"\n[information]\nsource = \"elastik\"\npath = \"a.json\"\n", "elastik");
}
