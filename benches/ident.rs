//! Benchmarks of the identification hot paths: WLS (thin SVD) on a large
//! stacked base regressor, building that regressor, and the closed-loop
//! simulator (controller periods with RK4 forward dynamics).

use criterion::{criterion_group, criterion_main, Criterion};
use idexp::ident::estimate::{base_design, wls, Dataset, Weights};
use idexp::params::{BaseOptions, BaseParams};
use idexp::sim::{SimDesign, SimSetup};
use nalgebra::DVector;
use std::path::Path;

fn root(p: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(p)
}

fn bench_wls(c: &mut Criterion) {
    let robot = idexp::robot::load(&root("designs/robots/puma560.toml")).unwrap();
    let base = BaseParams::compute(&robot, &BaseOptions::default()).unwrap();
    let traj = idexp::trajectory::reference::random_fourier(&robot, 5, 0.1, 0.8, None, 3, "bench").unwrap();
    let s = traj.sample(100.0).unwrap(); // 1000 samples × 6 joints = 6000 rows
    c.bench_function("ident/base_design puma560 1000 samples", |b| {
        b.iter(|| base_design(&robot, &base, &s.q, &s.qd, &s.qdd))
    });
    let cmat = base_design(&robot, &base, &s.q, &s.qd, &s.qdd);
    let theta = base.base_values(robot.nominal_params().as_slice());
    let y = &cmat * &theta;
    let rows = cmat.nrows();
    let ds = Dataset {
        n: 6,
        n_samples: 1000,
        var: Some(DVector::from_fn(rows, |i, _| 0.01 * (1.0 + (i % 7) as f64))),
        y,
        names: base.names.clone(),
        joint: (0..rows).map(|r| r / 1000).collect(),
        sample: (0..rows).map(|r| r % 1000).collect(),
        c: cmat,
    };
    c.bench_function("ident/wls 6000x52 (thin SVD, covariance)", |b| b.iter(|| wls(&ds, Weights::Sample).unwrap()));
}

/// The consistent fit on the industrial 6-axis robot (≈ 90 standard
/// parameters with drives, 6 × 5,000 rows): the whole fit (blockwise QR of the
/// weighted regressor + Clarabel), and Clarabel's own solve time is printed.
fn bench_consistent(c: &mut Criterion) {
    let robot = idexp::robot::load(&root("designs/robots/industrial6.toml")).unwrap();
    let base = BaseParams::compute(&robot, &BaseOptions::default()).unwrap();
    let traj = idexp::trajectory::reference::random_fourier(&robot, 5, 0.1, 0.8, None, 3, "bench").unwrap();
    let s = traj.sample(500.0).unwrap(); // 5000 samples × 6 joints
    let cmat = base_design(&robot, &base, &s.q, &s.qd, &s.qdd);
    let theta = base.base_values(robot.nominal_params().as_slice());
    let rows = cmat.nrows();
    let m = rows / 6;
    let y = &cmat * &theta + DVector::from_fn(rows, |i, _| 0.05 * ((i * 7919 % 1000) as f64 / 500.0 - 1.0));
    let ds = Dataset {
        n: 6,
        n_samples: m,
        var: Some(DVector::from_element(rows, 0.01)),
        y,
        names: base.names.clone(),
        joint: (0..rows).map(|r| r / m).collect(),
        sample: (0..rows).map(|r| r % m).collect(),
        c: cmat,
    };
    let fit = wls(&ds, Weights::Sample).unwrap();
    // the one-run --consistent: the Euclidean pull toward the nominal model of
    // weight 1e-6 × the fit's smallest curvature, every parameter known
    let whole = || {
        let r = idexp::ident::estimate::r_factor(&(&ds.c * 10.0));
        let (kinds, links) = idexp::ident::consistent::kinds_of(&robot);
        let (theta0, scale) = idexp::ident::prior::prior_of(&robot, None, 1.0).unwrap();
        let names: Vec<String> = robot.links.iter().map(|l| l.name.clone()).collect();
        let tb = DVector::from_column_slice(&fit.theta);
        let pb = idexp::ident::prior::PriorProblem {
            r: &r,
            theta_b: &tb,
            k: &base.k,
            links: &links,
            link_names: &names,
            kinds: &kinds,
            prior: &theta0,
            scale: &scale,
        };
        idexp::ident::prior::solve(
            &pb,
            idexp::ident::prior::PriorMetric::Euclidean,
            idexp::ident::prior::relative_weight(&r, 1e-6),
            0.0,
            &idexp::optim::Control::new(),
        )
        .unwrap()
    };
    let sol = whole();
    eprintln!(
        "consistent fit industrial6: {} standard parameters, {rows} rows, Clarabel {:?} in {} iterations, solver time {:.1} ms",
        robot.n_params(),
        sol.status,
        sol.iterations,
        1e3 * sol.solve_time
    );
    c.bench_function(&format!("ident/consistent industrial6 {} params {rows} rows", robot.n_params()), |b| {
        b.iter(whole)
    });
}

fn bench_sim(c: &mut Criterion) {
    for (name, robot) in [("puma560", "designs/robots/puma560.toml"), ("rpr", "tests/data/ident/rpr_drives.toml")] {
        let text = format!(
            "robot = \"{}\"\nrate = 1000.0\nrepetitions = 1\n[noise]\ntorque = 0.1\nposition = 1e-5\n[reference]\nkind = \"random_fourier\"\nfrequency = 1.0\n",
            root(robot).display()
        );
        let d: SimDesign = idexp::io::parse_toml(Path::new("bench.toml"), &text).unwrap();
        let setup = SimSetup::from_design(&d, &root(""), "bench").unwrap();
        // a 1 s period: 1000 lead-in + 1000 recorded controller periods
        c.bench_function(&format!("sim/2000 controller periods {name}"), |b| {
            b.iter(|| setup.run(&idexp::optim::Control::new()).unwrap())
        });
    }
}

/// A five-experiment study on the industrial 6-axis robot: 25,000 samples
/// in all (five random Fourier trajectories of 3,000–7,000 samples × 6
/// joints = 150,000 rows), one with repetition variances, four weighted from
/// their residuals (iterated): the stacked WLS, then the consistent estimate
/// with the entropic prior (one weight).
fn bench_study(c: &mut Criterion) {
    use idexp::ident::study::stack::{estimate, Rows, StackOptions};
    let robot = idexp::robot::load(&root("designs/robots/industrial6.toml")).unwrap();
    let base = BaseParams::compute(&robot, &BaseOptions::default()).unwrap();
    let theta = base.base_values(robot.nominal_params().as_slice());
    let lens = [3000usize, 4000, 5000, 6000, 7000];
    let sets: Vec<Dataset> = lens
        .iter()
        .enumerate()
        .map(|(e, &m)| {
            let traj = idexp::trajectory::reference::random_fourier(&robot, 5, 0.1, 0.8, None, 10 + e as u64, "bench").unwrap();
            let s = traj.sample(m as f64 / 10.0).unwrap();
            let cmat = base_design(&robot, &base, &s.q, &s.qd, &s.qdd);
            let rows = cmat.nrows();
            let m = rows / 6;
            let noise = 0.02 * (1.0 + e as f64);
            let y = &cmat * &theta + DVector::from_fn(rows, |i, _| noise * ((i * 7919 % 1000) as f64 / 500.0 - 1.0));
            Dataset {
                n: 6,
                n_samples: m,
                var: (e == 0).then(|| DVector::from_element(rows, 1e-4)),
                y,
                names: base.names.clone(),
                joint: (0..rows).map(|r| r / m).collect(),
                sample: (0..rows).map(|r| r % m).collect(),
                c: cmat,
            }
        })
        .collect();
    let total: usize = sets.iter().map(|d| d.n_samples).sum();
    let rows: Vec<Rows> = sets
        .iter()
        .map(|d| Rows {
            name: "e",
            data: d,
            n_reps: 20,
        })
        .collect();
    let o = StackOptions::default();
    let mut g = c.benchmark_group("ident/study");
    g.sample_size(10);
    g.bench_function(format!("stacked wls 5 experiments {total} samples x 6"), |b| {
        b.iter(|| estimate(&rows, &o).unwrap())
    });
    let st = estimate(&rows, &o).unwrap();
    let (kinds, links) = idexp::ident::consistent::kinds_of(&robot);
    let (theta0, scale) = idexp::ident::prior::prior_of(&robot, None, 0.5).unwrap();
    let names: Vec<String> = robot.links.iter().map(|l| l.name.clone()).collect();
    let pb = idexp::ident::prior::PriorProblem {
        r: &st.r,
        theta_b: &st.theta,
        k: &base.k,
        links: &links,
        link_names: &names,
        kinds: &kinds,
        prior: &theta0,
        scale: &scale,
    };
    for metric in [idexp::ident::prior::PriorMetric::Entropic, idexp::ident::prior::PriorMetric::Euclidean] {
        g.bench_function(format!("consistent with {} prior {} params", metric.name(), robot.n_params()), |b| {
            b.iter(|| idexp::ident::prior::solve(&pb, metric, 1.0, 0.0, &idexp::optim::Control::new()).unwrap())
        });
    }
    g.finish();
}

criterion_group!(benches, bench_consistent, bench_wls, bench_sim, bench_study);
criterion_main!(benches);
