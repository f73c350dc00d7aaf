//! `idexp plan`'s solver: 5 candidate experiments, 60 targets (every standard
//! and base parameter of the RPR arm with the prior, and three tasks); the
//! model (simulations, processing) is built once outside the timing.
//! `cargo bench --bench plan`; docs/performance.md.

use criterion::{criterion_group, criterion_main, Criterion};
use idexp::optim::Control;
use idexp::plan::{build, plan, PlanDesign};
use std::path::PathBuf;

fn design_text() -> String {
    let r = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let d = r.join("designs");
    let robot = idexp::robot::load(&r.join("tests/data/ident/rpr_drives.toml")).unwrap();
    let base = idexp::params::BaseParams::compute(&robot, &Default::default()).unwrap();
    let mut s = format!(
        "name = \"bench\"\nrobot = \"{}\"\nmax_repetitions = 50\n",
        r.join("tests/data/ident/rpr_drives.toml").display()
    );
    for (name, f, cost, extra) in [
        ("fourier_a", "sim_rpr_fourier", 14.0, "identify = { harmonics = 20 }"),
        ("fourier_b", "sim_rpr_study_b", 8.0, "identify = { harmonics = 16 }"),
        ("gravity", "sim_rpr_study_gravity", 30.0, "identify = { kind = \"gravity\" }"),
        ("validate_a", "sim_rpr_fourier_validate", 14.0, "identify = { harmonics = 20 }"),
        ("validate_b", "sim_rpr_study_validate", 14.0, "identify = { harmonics = 20 }"),
    ] {
        s += &format!(
            "[[experiment]]\nname = \"{name}\"\nsimulate = \"{}\"\ncost = {cost}\n{extra}\n",
            d.join(format!("{f}.toml")).display()
        );
    }
    s += "[consistent]\nmetric = \"euclidean\"\nweight = 1.0\nscale = 0.5\n";
    // 39 standard + 18 base parameters, loose enough to be reachable, one tighter
    for n in robot.param_names() {
        s += &format!("[[target]]\nparameter = \"{n}\"\nsigma = 3.0\n");
    }
    for n in &base.names {
        s += &format!("[[target]]\nparameter = \"{n}\"\nsigma = 0.5\n");
    }
    s += "[[target]]\nparameter = \"MX3R\"\nsigma = 1e-4\n";
    for f in ["sim_rpr_fourier_validate", "sim_rpr_study_validate"] {
        s += &format!("[[target]]\ntask = \"{}\"\nrms = 0.05\n", d.join(format!("{f}.toml")).display());
    }
    s
}

fn bench(c: &mut Criterion) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bench.toml");
    std::fs::write(&path, design_text()).unwrap();
    let design = PlanDesign::read(&path).unwrap();
    assert_eq!(design.experiment.len(), 5);
    assert_eq!(design.target.len(), 60);
    let model = build(&design, dir.path(), &Control::new()).unwrap();
    let sol = plan(&model, 2, &Control::new()).unwrap();
    assert_eq!(sol.status, idexp::plan::PlanStatus::Planned, "{:?}", sol.refused);
    c.bench_function("plan 5 candidates 60 targets", |b| b.iter(|| plan(&model, 2, &Control::new()).unwrap()));
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(10);
    targets = bench
}
criterion_main!(benches);
