//! Collision geometry (robot::collision) and the collision constraints of the
//! excitation design: distances against independent computations, gradients
//! against finite differences, the pair list, errors, INFEASIBLE designs, and
//! the shipped designs checked on the 1 kHz grid.

use clarabel::algebra::CscMatrix;
use clarabel::solver::{DefaultSettingsBuilder, DefaultSolver, IPSolver, SupportedConeT};
use idexp::robot::collision::{CollisionScene, CollisionSpec, PairClass};
use idexp::robot::kinematics::{forward_kinematics, Kin};
use idexp::robot::Robot;
use nalgebra::Point3;
use rand::{RngExt, SeedableRng};
use std::path::{Path, PathBuf};
use std::process::Command;

fn designs() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("designs")
}

fn robot(name: &str) -> Robot {
    idexp::robot::load(&designs().join("robots").join(name)).unwrap()
}

fn scene(r: &Robot, spec: &CollisionSpec) -> CollisionScene {
    CollisionScene::new(r, spec, &designs(), "test").unwrap().unwrap()
}

fn random_q(r: &Robot, rng: &mut rand_chacha::ChaCha8Rng) -> Vec<f64> {
    r.joints
        .iter()
        .map(|j| rng.random_range(j.limits.lower.max(-3.1)..j.limits.upper.min(3.1)))
        .collect()
}

/// Distance between the convex hulls of two point sets by a second-order
/// cone program (Clarabel): min t s.t. ‖Σλ_i a_i − Σμ_k b_k‖ ≤ t, λ, μ in
/// the simplex. Independent of GJK.
fn hull_distance_socp(a: &[Point3<f64>], b: &[Point3<f64>]) -> f64 {
    let (na, nb) = (a.len(), b.len());
    let nv = na + nb + 1;
    let (mut ii, mut jj, mut vv) = (Vec::new(), Vec::new(), Vec::new());
    let mut bvec = Vec::new();
    let mut row = 0;
    // Σλ = 1, Σμ = 1
    for i in 0..na {
        ii.push(row);
        jj.push(i);
        vv.push(1.0);
    }
    bvec.push(1.0);
    row += 1;
    for k in 0..nb {
        ii.push(row);
        jj.push(na + k);
        vv.push(1.0);
    }
    bvec.push(1.0);
    row += 1;
    // λ, μ ≥ 0
    for v in 0..na + nb {
        ii.push(row);
        jj.push(v);
        vv.push(-1.0);
        bvec.push(0.0);
        row += 1;
    }
    // (t, Aλ − Bμ) ∈ SOC
    ii.push(row);
    jj.push(na + nb);
    vv.push(-1.0);
    bvec.push(0.0);
    row += 1;
    for c in 0..3 {
        for i in 0..na {
            ii.push(row);
            jj.push(i);
            vv.push(-a[i][c]);
        }
        for k in 0..nb {
            ii.push(row);
            jj.push(na + k);
            vv.push(b[k][c]);
        }
        bvec.push(0.0);
        row += 1;
    }
    let amat = CscMatrix::new_from_triplets(row, nv, ii, jj, vv);
    let p = CscMatrix::zeros((nv, nv));
    let mut q = vec![0.0; nv];
    q[nv - 1] = 1.0;
    let cones = [
        SupportedConeT::ZeroConeT(2),
        SupportedConeT::NonnegativeConeT(na + nb),
        SupportedConeT::SecondOrderConeT(4),
    ];
    let settings = DefaultSettingsBuilder::default()
        .verbose(false)
        .tol_gap_abs(1e-10)
        .tol_gap_rel(1e-10)
        .build()
        .unwrap();
    let mut s = DefaultSolver::new(&p, &q, &amat, &bvec, &cones, settings).unwrap();
    s.solve();
    s.solution.x[nv - 1]
}

#[test]
fn distances_match_an_independent_socp_on_the_convex_hulls() {
    let r = robot("ur5.toml");
    let sc = scene(&r, &CollisionSpec::default());
    let mut kin = Kin::new(r.dof());
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    let mut checked = 0;
    for _ in 0..6 {
        let q = random_q(&r, &mut rng);
        forward_kinematics(&r, &q, &mut kin);
        let mut poses = Vec::new();
        sc.poses(&kin, &mut poses);
        for (k, p) in sc.pairs.iter().enumerate() {
            if p.class != PairClass::SelfCollision {
                continue;
            }
            let d = sc.pair_proximity(k, &poses, 10.0).unwrap().distance;
            if d <= 1e-3 {
                continue;
            }
            let body = |name: &str| sc.bodies().iter().position(|b| b.name == name).unwrap();
            let (ia, ib) = (body(&p.a), body(&p.b));
            let pts = |i: usize| -> Vec<Point3<f64>> { sc.bodies()[i].polyhedron_points().concat().iter().map(|x| poses[i] * x).collect() };
            let (pa, pb) = (pts(ia), pts(ib));
            if sc.bodies()[ia].n_parts() != 1 || sc.bodies()[ib].n_parts() != 1 {
                continue;
            }
            // the hulls grown by the robot file's collision_padding: the SOCP
            // distance of the bare hulls less both paddings
            let pads = sc.bodies()[ia].padding() + sc.bodies()[ib].padding();
            let ds = hull_distance_socp(&pa, &pb) - pads;
            // the vertex-pair distance bounds the hull distance from above
            let dv = pa.iter().flat_map(|x| pb.iter().map(move |y| (x - y).norm())).fold(f64::INFINITY, f64::min) - pads;
            assert!((d - ds).abs() < 1e-5, "{} at {q:?}: GJK {d}, SOCP {ds}", p.label());
            assert!(d <= dv + 1e-9, "{}: GJK {d} above the vertex distance {dv}", p.label());
            checked += 1;
        }
    }
    assert!(checked >= 20, "only {checked} pairs compared");
}

#[test]
fn floor_and_attached_sphere_distances_are_exact() {
    // A robot without geometry of its own (the DH Puma 560) carrying a ball
    // on link6, a ball on link2 and a box on link3, in a cell with a box
    // pillar: every checked distance has a closed form from the frame poses
    // (ball–floor z − r, box–floor the lowest corner, ball–ball centre
    // distance − radii, ball–box the point–box distance − r, signed), so a
    // wrong sign, offset, frame or cap shows.
    let r = robot("puma560.toml");
    let spec: CollisionSpec = toml::from_str(
        r#"
        margin = 0.0
        [[attached]]
        name = "ball"
        frame = "tool0"
        shape = { type = "sphere", radius = 0.05 }
        xyz = [0.0, 0.0, 0.1]
        [[attached]]
        name = "knob"
        frame = "link2"
        shape = { type = "sphere", radius = 0.04 }
        xyz = [0.1, 0.0, 0.02]
        [[attached]]
        name = "block"
        frame = "link3"
        shape = { type = "box", size = [0.1, 0.2, 0.3] }
        xyz = [0.0, 0.05, 0.2]
        rpy = [0.3, -0.2, 0.7]
        [[obstacle]]
        name = "pillar"
        shape = { type = "box", size = [0.2, 0.3, 1.0] }
        xyz = [0.45, 0.1, 0.2]
        rpy = [0.0, 0.0, 0.4]
        "#,
    )
    .unwrap();
    let sc = scene(&r, &spec);
    let labels: Vec<String> = sc.pairs.iter().map(|p| p.label()).collect();
    let mut expect = vec![
        "self: link2 – link6",
        "self: link3 – link6",
        "world: link2 – floor",
        "world: link3 – floor",
        "world: link6 – floor",
        "world: link2 – pillar",
        "world: link3 – pillar",
        "world: link6 – pillar",
    ];
    let mut got: Vec<&str> = labels.iter().map(|s| s.as_str()).collect();
    expect.sort();
    got.sort();
    assert_eq!(got, expect, "checked pairs");
    let mut ws = idexp::robot::Workspace::new(&r);
    let mut kin = Kin::new(r.dof());
    let pose_of = |ws: &mut idexp::robot::Workspace, q: &[f64], frame: &str, xyz: [f64; 3], rpy: [f64; 3]| {
        let f = r.find_frame(frame).unwrap();
        idexp::robot::frame_pose(&r, ws, q, &f) * idexp::robot::collision::pose(xyz, rpy)
    };
    let pillar = idexp::robot::collision::pose([0.45, 0.1, 0.2], [0.0, 0.0, 0.4]);
    let pillar_half = nalgebra::Vector3::new(0.1, 0.15, 0.5);
    // signed distance of a point to a box (pose, half extents)
    let to_box = |x: &nalgebra::Isometry3<f64>, half: &nalgebra::Vector3<f64>, p: &Point3<f64>| {
        let l = x.inverse_transform_point(p).coords.abs() - half;
        let out = l.map(|v| v.max(0.0)).norm();
        if out > 0.0 {
            out
        } else {
            l.max()
        }
    };
    let to_pillar = |p: &Point3<f64>| to_box(&pillar, &pillar_half, p);
    let block_half = nalgebra::Vector3::new(0.05, 0.1, 0.15);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    let (mut below, mut inside, mut near, mut far) = (0, 0, 0, 0);
    let cap = 10.0;
    for _ in 0..200 {
        let q = random_q(&r, &mut rng);
        let ball = pose_of(&mut ws, &q, "tool0", [0.0, 0.0, 0.1], [0.0; 3]) * Point3::origin();
        let knob = pose_of(&mut ws, &q, "link2", [0.1, 0.0, 0.02], [0.0; 3]) * Point3::origin();
        let block = pose_of(&mut ws, &q, "link3", [0.0, 0.05, 0.2], [0.3, -0.2, 0.7]);
        let corners: Vec<Point3<f64>> = (0..8)
            .map(|c| {
                block
                    * Point3::new(
                        if c & 1 == 0 { -0.05 } else { 0.05 },
                        if c & 2 == 0 { -0.1 } else { 0.1 },
                        if c & 4 == 0 { -0.15 } else { 0.15 },
                    )
            })
            .collect();
        let lowest = corners.iter().map(|c| c.z).fold(f64::INFINITY, f64::min);
        let truth = |label: &str| -> Option<f64> {
            Some(match label {
                "world: link6 – floor" => ball.z - 0.05,
                "world: link2 – floor" => knob.z - 0.04,
                "world: link3 – floor" => lowest,
                "self: link2 – link6" => (ball - knob).norm() - 0.09,
                "self: link3 – link6" => to_box(&block, &block_half, &ball) - 0.05,
                "world: link6 – pillar" => to_pillar(&ball) - 0.05,
                "world: link2 – pillar" => to_pillar(&knob) - 0.04,
                _ => return None,
            })
        };
        for d in sc.distances(&r, &mut kin, &q, cap) {
            if let Some(t) = truth(&d.label) {
                assert!((d.distance - t).abs() < 1e-9, "{} at {q:?}: {} vs exact {t}", d.label, d.distance);
            }
        }
        // the cap: a pair farther than the cap reports the cap
        for d in sc.distances(&r, &mut kin, &q, 0.05) {
            if let Some(t) = truth(&d.label) {
                if t > 0.05 {
                    assert_eq!(d.distance, 0.05, "{} beyond the cap", d.label);
                } else {
                    assert!((d.distance - t).abs() < 1e-9, "{} below the cap: {} vs {t}", d.label, d.distance);
                }
            }
        }
        below += usize::from(ball.z < 0.05 || lowest < 0.0);
        inside += usize::from(to_pillar(&ball) < 0.0 || to_pillar(&knob) < 0.0);
        near += usize::from((ball - knob).norm() < 0.09 || to_box(&block, &block_half, &ball) < 0.05);
        far += usize::from(to_pillar(&ball) > 0.05);
    }
    // the sample reaches every regime: through the floor, inside the pillar,
    // balls overlapping, and clear
    assert!(
        below > 0 && inside > 0 && near > 0 && far > 0,
        "below {below}, inside {inside}, near {near}, far {far}"
    );
}

#[test]
fn gradient_matches_central_differences() {
    for name in ["ur5.toml", "panda.toml"] {
        let r = robot(name);
        let sc = scene(&r, &CollisionSpec::default());
        let n = r.dof();
        let mut kin = Kin::new(n);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let dist = |q: &[f64], k: usize, kin: &mut Kin<f64>| {
            forward_kinematics(&r, q, kin);
            let mut poses = Vec::new();
            sc.poses(kin, &mut poses);
            sc.pair_proximity(k, &poses, 10.0).unwrap().distance
        };
        let mut checked = 0;
        for _ in 0..8 {
            let q = random_q(&r, &mut rng);
            for k in 0..sc.len() {
                forward_kinematics(&r, &q, &mut kin);
                let mut poses = Vec::new();
                sc.poses(&kin, &mut poses);
                let p = sc.pair_proximity(k, &poses, 10.0).unwrap();
                if p.distance < 1e-3 {
                    continue; // penetration and contact: EPA, tested by sign elsewhere
                }
                let mut g = vec![0.0; n];
                sc.add_gradient(&r, &kin, k, &p, 1.0, &mut g);
                let h = 1e-6;
                for j in 0..n {
                    let (mut qp, mut qm) = (q.clone(), q.clone());
                    qp[j] += h;
                    qm[j] -= h;
                    let fd = (dist(&qp, k, &mut kin) - dist(&qm, k, &mut kin)) / (2.0 * h);
                    assert!(
                        (fd - g[j]).abs() < 1e-4 * (1.0 + fd.abs()),
                        "{name} {} joint {j}: analytic {} fd {fd}",
                        sc.pairs[k].label(),
                        g[j]
                    );
                }
                checked += 1;
            }
        }
        assert!(checked > 50, "{name}: only {checked} pairs");
    }
}

#[test]
fn pair_list_excludes_adjacent_and_allowed_and_ignores_srdf_never() {
    let r = robot("ur5.toml");
    let sc = scene(&r, &CollisionSpec::default());
    let labels: Vec<String> = sc.pairs.iter().map(|p| p.label()).collect();
    assert!(!labels.iter().any(|l| l == "self: forearm_link – wrist_1_link"), "adjacent pair checked");
    assert!(labels.iter().any(|l| l == "self: forearm_link – wrist_2_link"));
    assert_eq!(sc.pairs.iter().filter(|p| p.class == PairClass::SelfCollision).count(), 21 - 6);
    assert_eq!(sc.pairs.iter().filter(|p| p.class == PairClass::World).count(), 6);
    // an SRDF with a sampled `Never` and an `Adjacent` entry, plus an allowed pair
    let dir = tempfile::tempdir().unwrap();
    let srdf = dir.path().join("ur5.srdf");
    std::fs::write(
        &srdf,
        r#"<?xml version="1.0"?>
<robot name="ur5">
  <disable_collisions link1="forearm_link" link2="wrist_2_link" reason="Never"/>
  <disable_collisions link1="wrist_1_link" link2="wrist_3_link" reason="Adjacent"/>
</robot>"#,
    )
    .unwrap();
    let rd = designs().join("robots");
    let toml = format!(
        "urdf = \"{}/ur5.urdf\"\nbase_link = \"base_link\"\ntip_link = \"tool0\"\nmesh_path = [\"{}/meshes/ur5\"]\nsrdf = \"ur5.srdf\"\n\
         [[allowed_collision]]\na = \"base_link\"\nb = \"wrist_3_link\"\nreason = \"test\"\n",
        rd.display(),
        rd.display()
    );
    let rf = dir.path().join("ur5.toml");
    std::fs::write(&rf, toml).unwrap();
    let r2 = idexp::robot::load(&rf).unwrap();
    let sc2 = scene(&r2, &CollisionSpec::default());
    let l2: Vec<String> = sc2.pairs.iter().map(|p| p.label()).collect();
    assert!(
        l2.iter().any(|l| l == "self: forearm_link – wrist_2_link"),
        "SRDF Never must be ignored by default"
    );
    assert!(!l2.iter().any(|l| l == "self: wrist_1_link – wrist_3_link"), "SRDF Adjacent taken");
    assert!(!l2.iter().any(|l| l == "self: base_link – wrist_3_link"), "allowed pair checked");
    assert!(sc2.excluded.iter().any(|e| e.reason.contains("test")));
}

#[test]
fn missing_mesh_names_the_link_and_the_path() {
    // the robot loads (what needs no geometry runs); a collision check refuses
    // it, naming the link, the mesh, the robot file's mesh_path as resolved and
    // the other folders searched, with no empty field
    let dir = tempfile::tempdir().unwrap();
    let rd = designs().join("robots");
    let rf = dir.path().join("ur5.toml");
    std::fs::write(
        &rf,
        format!(
            "urdf = \"{}/ur5.urdf\"\nbase_link = \"base_link\"\ntip_link = \"tool0\"\nmesh_path = [\"nowhere\"]\n",
            rd.display()
        ),
    )
    .unwrap();
    let r = idexp::robot::load(&rf).unwrap();
    let e = CollisionScene::new(&r, &CollisionSpec::default(), &designs(), "test").unwrap_err().to_string();
    assert!(
        e.contains("link `base_link`") && e.contains("collision/base.stl") && e.contains("nowhere"),
        "{e}"
    );
    assert!(
        e.contains(&dir.path().join("nowhere").display().to_string()) && e.contains("ROS_PACKAGE_PATH"),
        "{e}"
    );
    assert!(e.contains("enabled = false"), "{e}");
    std::fs::write(
        &rf,
        format!("urdf = \"{}/ur5.urdf\"\nbase_link = \"base_link\"\ntip_link = \"tool0\"\n", rd.display()),
    )
    .unwrap();
    let r = idexp::robot::load(&rf).unwrap();
    let e = r.geometry_error.clone().unwrap();
    assert!(e.contains("mesh_path (none given)") && e.contains("base_link") && e.contains("ur5.urdf"), "{e}");
    assert!(!e.contains("[]") && !e.contains("  "), "no empty field: {e}");
    // a design with collisions off runs without them
    let off = CollisionSpec {
        enabled: false,
        ..CollisionSpec::default()
    };
    assert!(CollisionScene::new(&r, &off, &designs(), "test").unwrap().is_none());
}

fn excite(design: &str, out: &Path) -> (i32, String) {
    let o = Command::new(env!("CARGO_BIN_EXE_idexp"))
        .args(["excite", design, "--out"])
        .arg(out)
        .output()
        .unwrap();
    (
        o.status.code().unwrap_or(-1),
        format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr)),
    )
}

#[test]
fn impossible_obstacle_is_infeasible_with_pair_and_depth() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path().join("blocked.toml");
    std::fs::write(
        &d,
        format!(
            r#"robot = "{}/robots/ur5.toml"
[trajectory]
harmonics = 2
frequency = 0.2
q0 = [0.0, -1.5707963, 0.0, -1.5707963, 0.0, 0.0]
[objective]
sample_rate = 5.0
[collision]
margin = 0.01
[[collision.obstacle]]
name = "pillar"
shape = {{ type = "box", size = [0.3, 0.3, 0.3] }}
xyz = [0.0, 0.0, 0.1]
[ga]
population = 8
generations = 2
[refine]
algorithm = "none"
"#,
            designs().display()
        ),
    )
    .unwrap();
    let (code, text) = excite(d.to_str().unwrap(), &dir.path().join("out"));
    assert_eq!(code, 3, "{text}");
    assert!(text.contains("INFEASIBLE"), "{text}");
    let report = std::fs::read_to_string(dir.path().join("out/report.txt")).unwrap();
    assert!(
        report.contains("collision world: shoulder_link – pillar") && report.contains("penetration depth"),
        "{report}"
    );
}

/// Every constraint of a finished design on its 1 kHz grid, recomputed from
/// trajectory.csv with the collision scene (independent of the optimiser's grid).
fn check_delivered(design: &str, out: &Path) {
    let (code, text) = excite(design, out);
    assert_eq!(code, 0, "{text}");
    let p = idexp::excitation::Problem::from_file(Path::new(design)).unwrap();
    let sc = p.constraints.scene().expect("collision checked");
    let rep: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    let margins = rep["result"]["margins"].as_array().unwrap();
    let dist: Vec<&serde_json::Value> = margins.iter().filter(|m| m["kind"].as_str().unwrap().ends_with("collision")).collect();
    assert_eq!(dist.len(), sc.len());
    for m in margins {
        assert!(m["margin"].as_f64().unwrap() >= 0.0, "{design}: {m}");
    }
    // trajectory.csv at the controller rate: every row keeps the margin
    let mut rd = csv::Reader::from_path(out.join("trajectory.csv")).unwrap();
    let hdr = rd.headers().unwrap().clone();
    let qcols: Vec<usize> = (0..p.robot.dof())
        .map(|j| hdr.iter().position(|h| h == format!("q{}", j + 1)).unwrap())
        .collect();
    let mut kin = Kin::new(p.robot.dof());
    let mut worst = f64::INFINITY;
    for rec in rd.records() {
        let rec = rec.unwrap();
        let q: Vec<f64> = qcols.iter().map(|&c| rec[c].parse().unwrap()).collect();
        if let Some(w) = sc.worst_at(&p.robot, &mut kin, &q, 1.0) {
            worst = worst.min(w.distance);
        }
    }
    assert!(worst >= sc.margin - 1e-9, "{design}: {worst} < {}", sc.margin);
}

#[test]
fn excite_ur5_keeps_every_link_above_the_floor_and_apart() {
    let dir = tempfile::tempdir().unwrap();
    check_delivered(designs().join("excite_ur5.toml").to_str().unwrap(), dir.path());
}

/// The full shipped Panda design (about 9 s on 2 cores since the
/// support-function bound; it was ignored at about a minute).
#[test]
fn excite_panda_table_keeps_the_margin() {
    let dir = tempfile::tempdir().unwrap();
    check_delivered(designs().join("excite_panda_table.toml").to_str().unwrap(), dir.path());
}

#[test]
fn position_candidates_in_collision_are_dropped() {
    use idexp::positions::candidates::CandidateSpec;
    let r = robot("ur5.toml");
    let spec: CandidateSpec = toml::from_str(
        "kind = \"grid\"\njoints = [2, 3]\npoints = [9, 9]\nlower = [-3.0, -2.8]\nupper = [0.0, 2.8]\nfixed = [0.0, -1.57, 0.0, -1.57, 0.0, 0.0]\n[collision]\nmargin = 0.01\n",
    )
    .unwrap();
    let c = spec.generate(&r, &[0.0; 6], 1, &designs(), "test").unwrap();
    assert!(c.rejected_collision > 0 && !c.q.is_empty(), "{} dropped", c.rejected_collision);
    assert!(c.collision_reasons[0].contains("floor") || c.collision_reasons[0].contains("self:"));
    let sc = scene(&r, &toml::from_str("margin = 0.01").unwrap());
    let mut kin = Kin::new(6);
    for q in &c.q {
        assert!(sc.worst_at(&r, &mut kin, q, 1.0).unwrap().distance >= 0.01);
    }
    let off: CandidateSpec = toml::from_str(
        "kind = \"grid\"\njoints = [2, 3]\npoints = [9, 9]\nlower = [-3.0, -2.8]\nupper = [0.0, 2.8]\nfixed = [0.0, -1.57, 0.0, -1.57, 0.0, 0.0]\n[collision]\nenabled = false\n",
    )
    .unwrap();
    let c2 = off.generate(&r, &[0.0; 6], 1, &designs(), "test").unwrap();
    assert_eq!(c2.q.len(), c.q.len() + c.rejected_collision);
}

fn design_problem(design: &str) -> idexp::excitation::Problem {
    idexp::excitation::Problem::from_file(&designs().join(design)).unwrap()
}

#[test]
fn culled_constraints_equal_the_exhaustive_evaluation() {
    // the broad phase (bounding spheres and capsules, a running minimum per
    // pair) must give bit for bit the constraint values and Jacobian of
    // querying every pair at every grid time, on random trajectories from
    // gentle to wild (deep penetrations included)
    for design in ["excite_ur5.toml", "excite_panda_table.toml"] {
        let p = design_problem(design);
        assert!(p.constraints.scene().is_some());
        let nv = idexp::trajectory::TrajectoryShape::n_vars(&p.shape);
        let m = p.constraints.len();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(21);
        let mut culled = p.constraints.workspace();
        let mut brute = p.constraints.workspace();
        brute.set_exhaustive(true);
        let (mut c1, mut c2) = (vec![0.0; m], vec![0.0; m]);
        let (mut j1, mut j2) = (vec![0.0; m * nv], vec![0.0; m * nv]);
        let (mut saved, mut total, mut violated) = (0usize, 0usize, 0usize);
        for trial in 0..12 {
            let amp = [0.05, 0.2, 0.5, 1.0][trial % 4];
            let x: Vec<f64> = (0..nv).map(|i| rng.random_range(p.lower[i]..p.upper[i]) * amp).collect();
            let with_jac = trial % 2 == 0;
            p.constraints.eval(&x, &mut culled, &mut c1, with_jac.then_some(&mut j1[..]));
            p.constraints.eval(&x, &mut brute, &mut c2, with_jac.then_some(&mut j2[..]));
            for (inf, (a, b)) in p.constraints.info.iter().zip(c1.iter().zip(&c2)) {
                assert_eq!(a.to_bits(), b.to_bits(), "{design} trial {trial}: {}: {a} vs {b}", inf.name);
            }
            if with_jac {
                for (k, (a, b)) in j1.iter().zip(&j2).enumerate() {
                    assert_eq!(a.to_bits(), b.to_bits(), "{design} trial {trial}: jacobian entry {k}: {a} vs {b}");
                }
            }
            saved += brute.distance_queries() - culled.distance_queries();
            total += brute.distance_queries();
            violated += c1.iter().zip(&p.constraints.info).filter(|(v, inf)| inf.unit == "m" && **v > 0.0).count();
        }
        // the culling does cut queries, and the trials do reach collisions
        assert!(saved * 2 > total, "{design}: only {saved} of {total} queries saved");
        assert!(violated > 0, "{design}: no trial violates a distance constraint");
    }
}

#[test]
fn culled_series_and_worst_pair_equal_the_exhaustive_ones() {
    // the verification grid (cap margin + 1 m) and the per-pose check: the
    // minimum over the sequence and its first index, the worst pair and its
    // distance, all exactly as when every pair is queried
    for name in ["ur5.toml", "panda.toml"] {
        let r = robot(name);
        let sc = scene(&r, &CollisionSpec::default());
        let mut kin = Kin::new(r.dof());
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(8);
        // a random walk in joint space: neighbouring poses as on a time grid
        let mut q = random_q(&r, &mut rng);
        let mut poses: Vec<Vec<nalgebra::Isometry3<f64>>> = Vec::new();
        for step in 0..400 {
            for v in q.iter_mut() {
                *v += rng.random_range(-0.05..0.05);
            }
            forward_kinematics(&r, &q, &mut kin);
            let mut x = Vec::new();
            sc.poses(&kin, &mut x);
            poses.push(x);
            let all = sc.distances(&r, &mut kin, &q, sc.cap);
            let brute = all.iter().min_by(|a, b| a.distance.total_cmp(&b.distance)).unwrap();
            let w = sc.worst_at(&r, &mut kin, &q, sc.cap).unwrap();
            assert_eq!((w.pair, w.distance.to_bits()), (brute.pair, brute.distance.to_bits()), "{name} step {step}");
        }
        for cap in [sc.cap, sc.margin + 1.0] {
            let mut culled = Default::default();
            let mut brute = Default::default();
            let mut queries = 0;
            for k in 0..sc.len() {
                sc.pair_series(k, &poses, cap, false, &mut culled);
                sc.pair_series(k, &poses, cap, true, &mut brute);
                let (a, b) = (culled.argmin().unwrap(), brute.argmin().unwrap());
                assert_eq!((a.0, a.1.to_bits()), (b.0, b.1.to_bits()), "{name} pair {k} cap {cap}");
                for (g, (v, e)) in culled.value.iter().zip(&culled.exact).enumerate() {
                    if *e {
                        assert_eq!(v.to_bits(), brute.value[g].to_bits());
                    } else {
                        // a lower bound, above the minimum
                        assert!(*v <= brute.value[g] + 1e-7 && *v > b.1, "{name} pair {k} at {g}: {v} vs {}", brute.value[g]);
                    }
                }
                queries += culled.queries;
            }
            assert!(queries < sc.len() * poses.len(), "{name}: no query saved");
        }
    }
}

#[test]
fn climbing_support_equals_the_scan_on_every_shipped_hull() {
    // hill climbing on the hull's vertex adjacency finds a vertex as far along
    // the direction as the scan over every vertex: from the seeds and, as GJK
    // calls it, from the previous direction's support vertex
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    let mut hulls = 0;
    for name in ["ur5.toml", "panda.toml"] {
        let r = robot(name);
        let sc = scene(&r, &CollisionSpec::default());
        for body in sc.bodies() {
            for (h, _) in body.climb_hulls() {
                hulls += 1;
                assert!(h.len() >= 4);
                let mut prev = None;
                for k in 0..3000 {
                    let mut d = nalgebra::Vector3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0));
                    if k % 7 == 0 {
                        // axis-aligned and exactly reversed directions: ties between coplanar vertices
                        d = nalgebra::Vector3::zeros();
                        d[k % 3] = if k % 2 == 0 { 1.0 } else { -1.0 };
                    }
                    let scan = h.points().iter().chain(h.orphans()).map(|p| p.coords.dot(&d)).fold(f64::NEG_INFINITY, f64::max);
                    let v = match prev {
                        Some(v) if k % 3 != 0 => h.support_from(&d, v),
                        _ => h.support_index(&d),
                    };
                    let got = h.support_point(&d, v).coords.dot(&d);
                    assert!(got >= scan - 1e-12, "{name} `{}`: climbing {got} < scan {scan} along {d:?}", body.name);
                    prev = Some(h.support_index(&d));
                }
            }
        }
    }
    assert!(hulls >= 15, "{hulls} hulls");
}

#[test]
fn climbing_narrow_phase_matches_parry_scan() {
    // the default narrow phase (parry's GJK/EPA, support points by climbing)
    // against parry's query::contact as it is, every pair at random poses,
    // penetrations included
    use idexp::robot::collision::NarrowPhase;
    for name in ["ur5.toml", "panda.toml"] {
        let r = robot(name);
        let fast = scene(&r, &CollisionSpec::default());
        let mut slow = fast.clone();
        slow.set_narrow_phase(NarrowPhase::Scan);
        assert_eq!(fast.narrow_phase(), NarrowPhase::Climb);
        let mut kin = Kin::new(r.dof());
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(17);
        let (mut close, mut deep) = (0, 0);
        for _ in 0..300 {
            let q = random_q(&r, &mut rng);
            forward_kinematics(&r, &q, &mut kin);
            let mut poses = Vec::new();
            fast.poses(&kin, &mut poses);
            for k in 0..fast.len() {
                let a = fast.pair_proximity(k, &poses, fast.cap);
                let b = slow.pair_proximity(k, &poses, slow.cap);
                match (a, b) {
                    (None, None) => {}
                    (Some(a), Some(b)) => {
                        let tol = if b.distance < 0.0 { 1e-6 } else { 1e-9 };
                        assert!(
                            (a.distance - b.distance).abs() <= tol,
                            "{name} {}: {} vs {}",
                            fast.pairs[k].label(),
                            a.distance,
                            b.distance
                        );
                        if b.distance >= 0.0 {
                            assert!(
                                (a.normal - b.normal).norm() < 1e-4 || b.distance < 1e-6,
                                "{name} {}: normals",
                                fast.pairs[k].label()
                            );
                        }
                        close += 1;
                        deep += usize::from(b.distance < 0.0);
                    }
                    (a, b) => {
                        // only at the cap itself
                        let d = a.or(b).unwrap().distance;
                        assert!((d - fast.cap).abs() < 1e-9, "{name} {}: {a:?} vs {b:?}", fast.pairs[k].label());
                    }
                }
            }
        }
        assert!(close > 300 && deep > 20, "{name}: {close} pairs within the cap, {deep} penetrating");
    }
}

#[test]
fn selection_evaluation_gives_the_violation_of_the_full_one() {
    // the GA's evaluation (distances capped at the margin) against the full
    // one: every constraint equal, except a distance constraint that holds on
    // the grid (0 there); the violations agree but for a parabola dipping
    // below the margin between grid times
    for design in ["excite_ur5.toml", "excite_panda_table.toml"] {
        let p = design_problem(design);
        let nv = idexp::trajectory::TrajectoryShape::n_vars(&p.shape);
        let m = p.constraints.len();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(29);
        let mut cw = p.constraints.workspace();
        let (mut full, mut sel) = (vec![0.0; m], vec![0.0; m]);
        let (mut violating, mut fewer) = (0, 0);
        for trial in 0..16 {
            let amp = [0.05, 0.2, 0.5, 1.0][trial % 4];
            let x: Vec<f64> = (0..nv).map(|i| rng.random_range(p.lower[i]..p.upper[i]) * amp).collect();
            p.constraints.eval(&x, &mut cw, &mut full, None);
            let nq = cw.distance_queries();
            p.constraints.eval_selection(&x, &mut cw, &mut sel);
            fewer += usize::from(cw.distance_queries() < nq);
            for (inf, (a, b)) in p.constraints.info.iter().zip(full.iter().zip(&sel)) {
                let distance = inf.unit == "m" && inf.scale == idexp::excitation::constraints::DISTANCE_SCALE;
                if distance && *b == 0.0 {
                    // holds on the grid: the full value may only dip by the parabola (a few mm)
                    assert!(*a <= 0.02, "{design} trial {trial}: {}: full {a}, selection 0", inf.name);
                } else {
                    assert_eq!(a.to_bits(), b.to_bits(), "{design} trial {trial}: {}: full {a}, selection {b}", inf.name);
                }
                violating += usize::from(distance && *b > 0.0);
            }
            let (vf, vs) = (
                idexp::excitation::constraints::Constraints::violation(&full),
                idexp::excitation::constraints::Constraints::violation(&sel),
            );
            assert!(vs <= vf && vf - vs <= 0.02 * m as f64, "{design} trial {trial}: violation {vs} vs {vf}");
        }
        assert!(violating > 0, "{design}: no trial violates a distance constraint");
        assert!(fewer > 8, "{design}: the selection saves queries in only {fewer} of 16 trials");
    }
}

#[test]
fn support_bound_never_exceeds_the_exact_distance() {
    // the support-function bound along the normal of an exact query at a
    // nearby (or unrelated) configuration is a lower bound of the signed
    // distance there, penetrations included, and nearly tight for small steps
    for name in ["ur5.toml", "panda.toml"] {
        let r = robot(name);
        let sc = scene(&r, &CollisionSpec::default());
        let mut kin = Kin::new(r.dof());
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(31);
        let (mut checked, mut tight, mut deep) = (0usize, 0usize, 0usize);
        let far = 10.0;
        for trial in 0..600 {
            let q = random_q(&r, &mut rng);
            let step = [0.002, 0.02, 0.2, 3.0][trial % 4];
            let q2: Vec<f64> = q.iter().map(|v| v + rng.random_range(-step..step)).collect();
            let (mut x1, mut x2) = (Vec::new(), Vec::new());
            forward_kinematics(&r, &q, &mut kin);
            sc.poses(&kin, &mut x1);
            forward_kinematics(&r, &q2, &mut kin);
            sc.poses(&kin, &mut x2);
            for k in 0..sc.len() {
                let Some(p1) = sc.pair_proximity(k, &x1, far) else { continue };
                let n_a = sc.normal_in_first_body(k, &x1, &p1.normal);
                // at the query's own configuration: the bound is the distance
                let own = sc.pair_support_bound(k, &x1, &n_a);
                assert!(own <= p1.distance + 1e-9, "{name} pair {k}: own bound {own} > {}", p1.distance);
                let d2 = sc.pair_distance(k, &x2, far);
                let b = sc.pair_support_bound(k, &x2, &n_a);
                assert!(b <= d2 + 1e-9, "{name} trial {trial} pair {k}: bound {b} > exact {d2}");
                checked += 1;
                tight += usize::from(b.is_finite() && d2 - b < 1e-4);
                deep += usize::from(d2 < 0.0);
            }
        }
        assert!(
            checked > 5000 && tight > 1000 && deep > 50,
            "{name}: {checked} checked, {tight} within 0.1 mm, {deep} penetrating"
        );
    }
}

#[test]
fn collision_along_a_path_equals_the_per_pose_check() {
    // the per-pose check with the normals carried along a sampled path
    // (Constraints::collision_along) reports exactly what the check of each
    // pose alone reports (Constraints::collision_at): clear, or the worst pair
    // and its distance, on smooth paths into and out of collisions
    for design in ["excite_ur5.toml", "excite_panda_table.toml"] {
        let p = design_problem(design);
        let n = p.robot.dof();
        let mut ws = idexp::robot::Workspace::new(&p.robot);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(37);
        let mut hints = Vec::new();
        let (mut hits, mut clear) = (0usize, 0usize);
        for _path in 0..20 {
            let a = random_q(&p.robot, &mut rng);
            let b = random_q(&p.robot, &mut rng);
            for s in 0..=400 {
                let t = s as f64 / 400.0;
                let q: Vec<f64> = (0..n).map(|j| a[j] + t * (b[j] - a[j])).collect();
                let along = p.constraints.collision_along(&mut ws, &q, &mut hints);
                let alone = p.constraints.collision_at(&mut ws, &q);
                match (&along, &alone) {
                    (None, None) => clear += 1,
                    (Some(x), Some(y)) => {
                        assert_eq!((&x.pair, x.distance.to_bits()), (&y.pair, y.distance.to_bits()), "{design} at {q:?}");
                        hits += 1;
                    }
                    _ => panic!("{design} at {q:?}: along {along:?}, alone {alone:?}"),
                }
            }
        }
        assert!(hits > 100 && clear > 100, "{design}: {hits} poses in collision, {clear} clear");
    }
}

#[test]
fn support_bound_spares_exact_queries_on_the_design_grid() {
    // the culled evaluation (values equal to the exhaustive one: see
    // culled_constraints_equal_the_exhaustive_evaluation) rules grid times
    // out by the support-function bound, in the GA's selection and in the
    // refinement's evaluation
    for design in ["excite_ur5.toml", "excite_panda_table.toml"] {
        let p = design_problem(design);
        let nv = idexp::trajectory::TrajectoryShape::n_vars(&p.shape);
        let m = p.constraints.len();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(41);
        let mut cw = p.constraints.workspace();
        let mut c = vec![0.0; m];
        let (mut q_full, mut q_sel, mut skips) = (0usize, 0usize, 0usize);
        for trial in 0..8 {
            let amp = [0.05, 0.2, 0.5, 1.0][trial % 4];
            let mut x: Vec<f64> = (0..nv).map(|i| rng.random_range(p.lower[i]..p.upper[i]) * amp).collect();
            p.constraints.repair_joints(&mut x, &p.limits, 1e-6);
            p.constraints.eval(&x, &mut cw, &mut c, None);
            q_full += cw.distance_queries();
            skips += cw.support_skips_per_pair().iter().sum::<usize>();
            p.constraints.eval_selection(&x, &mut cw, &mut c);
            q_sel += cw.distance_queries();
            skips += cw.support_skips_per_pair().iter().sum::<usize>();
        }
        eprintln!("{design}: {q_full} exact queries (full), {q_sel} (selection), {skips} grid times ruled out by the support bound, in 8 evaluations");
        assert!(skips > 100, "{design}: the support bound ruled out only {skips} grid times");
    }
}
