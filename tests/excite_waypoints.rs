//! FIGAROH's waypoint form and given end poses in an excitation design
//! (`[trajectory] waypoints = 7`, `start = [..]`, `end = [..]`) on FIGAROH's
//! UR10 problem (designs/excite_ur10_figaroh.toml with 7 waypoints 2 s
//! apart): what is played (trajectory.csv as written, 1 kHz) is checked
//! without idexp's derivatives or limits: at rest at home at both ends, at
//! the given start and end poses and at rest at every waypoint (central
//! differences of the written positions), every row within 80 % of the
//! URDF's position ranges and velocities (read from the URDF text here); and
//! the design fields' validation.

use idexp::excitation::design::ExciteDesign;
use idexp::excitation::{self, Problem};
use idexp::optim::Control;
use std::path::{Path, PathBuf};

mod excite_fd;
use excite_fd::values;

fn root(p: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(p)
}

const START: [f64; 6] = [0.5, -1.3, 0.4, -1.8, 0.3, 0.2];
const END: [f64; 6] = [-0.4, -1.7, -0.3, -1.4, -0.2, -0.3];
const HOME: [f64; 6] = [0.0, -std::f64::consts::FRAC_PI_2, 0.0, -std::f64::consts::FRAC_PI_2, 0.0, 0.0];

/// designs/excite_ur10_figaroh.toml with `extra` lines in `[trajectory]`
/// (its `segments = 11` replaced by `segments`), the robot path absolute.
fn design_text(segments: &str, extra: &str) -> String {
    let base = std::fs::read_to_string(root("designs/excite_ur10_figaroh.toml")).unwrap();
    let robot = root("designs/robots/ur10.toml");
    base.replace("robot = \"robots/ur10.toml\"", &format!("robot = \"{}\"", robot.display()))
        .replace("segments = 11\n", &format!("{segments}{extra}"))
}

fn pose(q: &[f64]) -> String {
    format!("[{}]", q.iter().map(|v| format!("{v:?}")).collect::<Vec<_>>().join(", "))
}

/// (lower, upper, velocity) per revolute joint, from the URDF's `<limit>` tags.
fn urdf_limits() -> Vec<[f64; 3]> {
    let text = std::fs::read_to_string(root("designs/robots/ur10.urdf")).unwrap();
    let attr = |tag: &str, name: &str| -> f64 {
        let k = tag.find(&format!("{name}=\"")).unwrap() + name.len() + 2;
        tag[k..k + tag[k..].find('"').unwrap()].parse().unwrap()
    };
    text.split("<limit ")
        .skip(1)
        .map(|s| {
            let tag = &s[..s.find("/>").unwrap()];
            [attr(tag, "lower"), attr(tag, "upper"), attr(tag, "velocity")]
        })
        .collect()
}

/// Rows of a trajectory.csv: (t, q, segment).
fn read_rows(path: &Path) -> Vec<(f64, Vec<f64>, i64)> {
    let text = std::fs::read_to_string(path).unwrap();
    text.lines()
        .skip(1)
        .map(|l| {
            let v: Vec<&str> = l.split(',').collect();
            let q = v[1..7].iter().map(|s| s.parse::<f64>().unwrap()).collect();
            (v[0].parse().unwrap(), q, v[v.len() - 1].parse().unwrap())
        })
        .collect()
}

#[test]
fn waypoints_with_given_ends_are_played_from_home_at_rest_and_within_the_urdf_limits() {
    let dir = tempfile::tempdir().unwrap();
    let f = dir.path().join("wp.toml");
    // FIGAROH's form: 7 waypoints 2 s apart, one quintic piece between two
    // (the waypoints are the only variables), from and to given poses
    let extra = format!("waypoints = 7\nstart = {}\nend = {}\n", pose(&START), pose(&END));
    std::fs::write(&f, design_text("segments = 6\n", &extra)).unwrap();
    let mut p = Problem::from_file(&f).unwrap();
    // 5 interior waypoints per joint
    assert_eq!(p.lower.len(), 6 * 5);
    // a short search: what is played, not the optimum, is under test
    p.design.time_limit = None;
    p.design.ga.population = 12;
    p.design.ga.generations = 4;
    p.design.refine.algorithm = idexp::excitation::design::RefineAlgorithm::None;
    p.design.refine.polish = 0;
    let r = excitation::run(&p, &Control::new()).unwrap();
    assert!(r.execution.verified, "{:?}", r.execution.problem);
    let out = dir.path().join("out");
    excitation::report::write_outputs(&p, &r, &out).unwrap();
    let rows = read_rows(&out.join("trajectory.csv"));
    let dt = 1e-3;
    let at_rest = |i: usize, what: &str, want: &[f64]| {
        let (qm, q, qp) = (&rows[i.saturating_sub(1)].1, &rows[i].1, &rows[(i + 1).min(rows.len() - 1)].1);
        for j in 0..6 {
            assert!((q[j] - want[j]).abs() < 1e-9, "{what} (row {i}): joint {j} at {} not {}", q[j], want[j]);
            if i == 0 || i + 1 == rows.len() {
                // one-sided: at rest, one step moves by the jerk's dt³/6 alone
                let step = if i == 0 { qp[j] - q[j] } else { q[j] - qm[j] };
                assert!(step.abs() < 1e-7, "{what} (row {i}): joint {j} moves {step:e} in the first/last millisecond");
                continue;
            }
            let v = (qp[j] - qm[j]) / (2.0 * dt);
            let a = (qp[j] - 2.0 * q[j] + qm[j]) / (dt * dt);
            // at rest the differences see only the jerk, which may step
            // there (a lead's or piece's end): |Δj|·dt²/12 and |Δj|·dt/6
            assert!(
                v.abs() < 1e-4 && a.abs() < 0.1,
                "{what} (row {i}): joint {j}: velocity {v:e}, acceleration {a:e} by differences"
            );
        }
    };
    // home at rest at both ends of what is played (one-sided there)
    at_rest(0, "first row", &HOME);
    at_rest(rows.len() - 1, "last row", &HOME);
    // the motion: rows of segment 1, from the given start to the given end
    let first = rows.iter().position(|r| r.2 == 1).unwrap();
    let last = rows.iter().rposition(|r| r.2 == 1).unwrap();
    assert!(first > 0 && last + 1 < rows.len(), "lead-in and lead-out expected");
    assert!((rows[last].0 - rows[first].0 - 11.999).abs() < 1e-9, "{} … {}", rows[first].0, rows[last].0);
    at_rest(first, "the start", &START);
    // the end: the first lead-out row is the motion at t = 12 s
    at_rest(last + 1, "the end", &END);
    // the interior waypoints, 2 s apart, each at rest where the motion says
    for k in 1..6 {
        let i = first + 2000 * k;
        let here = rows[i].1.clone();
        at_rest(i, &format!("waypoint {k} at {} s", rows[i].0), &here);
    }
    // it moves in between
    let moved = (first..last)
        .map(|i| (0..6).map(|j| (rows[i + 1].1[j] - rows[i].1[j]).abs() / dt).fold(0.0, f64::max))
        .fold(0.0, f64::max);
    assert!(moved > 0.05, "{moved}");
    // every row within 80 % of the URDF's position half range about its
    // centre and 80 % of its velocity limit (velocities by differences)
    let lim = urdf_limits();
    assert_eq!(lim.len(), 6);
    for i in 0..rows.len() {
        for j in 0..6 {
            let [lo, hi, v] = lim[j];
            let (c, h) = (0.5 * (lo + hi), 0.5 * (hi - lo));
            let q = rows[i].1[j];
            assert!((q - c).abs() <= 0.8 * h + 1e-9, "row {i}: joint {j} at {q}");
            if i + 1 < rows.len() {
                let vel = (rows[i + 1].1[j] - rows[i].1[j]) / dt;
                assert!(vel.abs() <= 0.8 * v + 1e-3, "row {i}: joint {j} at {vel} rad/s");
            }
        }
    }
}

#[test]
fn waypoint_and_pose_fields_are_validated_with_the_field_named() {
    let dir = tempfile::tempdir().unwrap();
    let check = |text: String, field: &str, words: &str| {
        let f = dir.path().join("d.toml");
        std::fs::write(&f, text).unwrap();
        let e = match ExciteDesign::load(&f) {
            Err(e) => e.to_string(),
            Ok(_) => Problem::from_file(&f).map(|_| ()).unwrap_err().to_string(),
        };
        assert!(e.contains(field) && e.contains(words), "{field}: {e}");
    };
    let good = pose(&START);
    // a pose outside the design's position range (elbow: 80 % of ±π)
    let mut far = START;
    far[2] = 2.6;
    check(
        design_text("segments = 11\n", &format!("start = {}\n", pose(&far))),
        "trajectory.start[2]",
        "outside",
    );
    check(design_text("segments = 11\n", "end = [0.0, 0.0]\n"), "trajectory.end", "6 values");
    check(
        design_text("segments = 11\n", "start = \"anywhere\"\n"),
        "anywhere",
        "expected `q0` or `free` or a pose",
    );
    // an end of its own cannot be repeated back to back
    check(
        design_text("segments = 11\n", &format!("end = {good}\n")).replace("periods = 1", "periods = 2"),
        "execution.periods",
        "periods = 1",
    );
    // the segments must split evenly between the waypoints
    check(
        design_text("segments = 11\n", "waypoints = 7\n"),
        "trajectory.segments",
        "multiple of the 6 pieces",
    );
    check(design_text("segments = 6\n", "waypoints = 1\n"), "trajectory.waypoints", "2..=1000");
    check(
        design_text("degree = 3\nsegments = 6\n", "waypoints = 7\n").replace("degree = 5\n", ""),
        "trajectory.segments",
        "at least 3 per piece",
    );
    // the Fourier series has no waypoints
    let fourier = design_text("", "waypoints = 7\n")
        .replace("shape = \"bspline\"", "shape = \"fourier\"")
        .replace("degree = 5\n", "")
        .replace("duration = 12.0\n", "");
    check(fourier, "trajectory.waypoints", "bspline");
    // a given end equal to the start may be repeated
    let f = dir.path().join("same.toml");
    std::fs::write(
        &f,
        design_text("segments = 11\n", &format!("start = {good}\nend = {good}\n")).replace("periods = 1", "periods = 2"),
    )
    .unwrap();
    Problem::from_file(&f).unwrap();
}

/// The criterion's gradient and the constraints' Jacobian (limits, torques,
/// 1 cm self-collision) of a waypoint design with free ends against central
/// differences (two segments per piece: one inner control point each).
#[test]
fn waypoints_objective_and_constraint_gradients_match_finite_differences() {
    let dir = tempfile::tempdir().unwrap();
    let f = dir.path().join("wp.toml");
    std::fs::write(&f, design_text("segments = 12\n", "waypoints = 7\nstart = \"free\"\nend = \"free\"\n")).unwrap();
    let p = Problem::from_file(&f).unwrap();
    // 6 inner control points, 5 interior waypoints, start and end per joint
    let nv = p.lower.len();
    assert_eq!(nv, 6 * 13);
    let f = excite_fd::check_objective_gradient(&p.objective, &values(nv, 0.4, 1.0), "waypoints");
    assert!(f > 1.0, "{f}");
    // tolerances as tests/excite_free_ends.rs (distances: witness points;
    // torques: parabola), each row's scale at least 1e-4: the
    // upper arm–floor distance hardly depends on x here (its largest entry
    // is about 2e-6 m per unit of x), and its parabola-refined gradient
    // differs from the difference quotient by about as much
    excite_fd::check_constraint_jacobian_floor(
        &p.constraints,
        &values(nv, 0.3, 3.0),
        |name| if name.starts_with("distance") { 0.1 } else { 1e-3 },
        1e-4,
    );
}
