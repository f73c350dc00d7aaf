//! Payload benchmarks (docs/payload.md, issue goals: the payload excitation
//! design ≤ 5 s and the identification ≤ 0.5 s on 2 cores).
//!
//! * `payload/excite_ur5`: the whole design of designs/payload_ur5_excite.toml
//!   (UR5, 4 harmonics of 0.1 Hz, the payload link's ten columns, limits,
//!   self and floor collisions with the tool's box; GA 24 × 15, two SLSQP
//!   starts), the robot loaded once.
//! * `payload/identify_ur5`: `idexp::payload::identify` on two simulated UR5
//!   runs (5 repetitions of 10 s at 200 Hz, loaded and unloaded: 2 × 10,000
//!   samples × 6 joints read, filtered, differenced, stacked; WLS, consistent fit).
//! * `payload/gains_ur5`: `idexp::payload::gains::calibrate` of
//!   designs/gains_ur5.toml on its two shipped simulated runs (a 2 kg mass
//!   and none, each 50 s at 100 Hz: 5 periods of 10 s, 6 joints; gains,
//!   base parameters, the mass's 9 parameters and offsets in one weighted
//!   least squares; issue goal ≤ 1 s on 2 cores).
//!
//! Run: `cargo bench --bench payload`.

use criterion::{criterion_group, criterion_main, Criterion};
use idexp::excitation::design::ExciteDesign;
use idexp::excitation::{run, Problem};
use idexp::optim::Control;
use idexp::payload::PayloadDesign;
use idexp::sim::{SimDesign, SimSetup};
use std::hint::black_box;
use std::path::Path;
use std::time::Duration;

fn root(p: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(p)
}

fn ur5_run(dir: &Path, name: &str, payload: &str, seed: u64) {
    let text = format!(
        "name = \"{name}\"\nrobot = \"designs/robots/ur5.toml\"\nrate = 1000.0\ndecimate = 5\nrepetitions = 5\nseed = {seed}\n[truth]\nperturbation = 0.1\nseed = 7\n[controller]\nbandwidth = 10.0\n[noise]\ntorque = 0.2\nposition = 1e-5\n[reference]\nkind = \"random_fourier\"\nn_h = 4\nfrequency = 0.1\namplitude = 0.6\nseed = 5\n{payload}"
    );
    let d: SimDesign = idexp::io::parse_toml(Path::new("bench.toml"), &text).expect("sim design");
    let setup = SimSetup::from_design(&d, &root(""), "bench.toml").expect("sim setup");
    let res = setup.run(&Control::new()).expect("sim run");
    res.write(&dir.join(name), &d).expect("sim write");
}

fn bench(c: &mut Criterion) {
    let path = root("designs/payload_ur5_excite.toml");
    let design = ExciteDesign::load(&path).expect("payload excite design");
    let robot = idexp::robot::load(&design.robot).expect("UR5");
    let mut g = c.benchmark_group("payload");
    g.sample_size(10).measurement_time(Duration::from_secs(30));
    g.bench_function("excite_ur5", |b| {
        b.iter(|| {
            let p = Problem::new(design.clone(), robot.clone(), "bench").expect("problem");
            black_box(run(&p, &Control::new()).expect("run").spectrum.cond)
        })
    });
    let dir = tempfile::tempdir().expect("tempdir");
    ur5_run(
        dir.path(),
        "loaded",
        "[payload]\nframe = \"tool0\"\nmass = 1.8\ncom = [0.012, -0.008, 0.055]\ninertia = [0.0065, 0.0004, -0.0003, 0.0071, 0.0005, 0.0042]\n",
        11,
    );
    ur5_run(dir.path(), "unloaded", "", 12);
    let text = format!(
        "name = \"bench\"\nrobot = \"{}\"\nframe = \"tool0\"\n[[loaded]]\nname = \"loaded\"\nfiles = [\"loaded\"]\nharmonics = 4\n[[unloaded]]\nname = \"unloaded\"\nfiles = [\"unloaded\"]\nharmonics = 4\n",
        root("designs/robots/ur5.toml").display()
    );
    let pd: PayloadDesign = idexp::io::parse_toml(Path::new("bench.toml"), &text).expect("payload design");
    g.measurement_time(Duration::from_secs(10));
    g.bench_function("identify_ur5", |b| {
        b.iter(|| black_box(idexp::payload::identify(&pd, dir.path(), &Control::new()).expect("identify").payload))
    });
    // the drive gains with a known mass: the shipped designs' runs, simulated once
    let gdir = tempfile::tempdir().expect("tempdir");
    for name in ["sim_ur5_gains_loaded", "sim_ur5_gains_unloaded"] {
        let path = root(&format!("designs/{name}.toml"));
        let d = idexp::sim::SimDesign::read(&path).expect("sim design");
        let setup = SimSetup::from_design(&d, &root("designs"), &path.display().to_string()).expect("sim setup");
        setup
            .run(&Control::new())
            .expect("sim run")
            .write(&gdir.path().join(name), &d)
            .expect("sim write");
    }
    let mut gd = PayloadDesign::read(&root("designs/gains_ur5.toml")).expect("gains design");
    gd.loaded[0].files = vec![gdir.path().join("sim_ur5_gains_loaded")];
    gd.unloaded[0].files = vec![gdir.path().join("sim_ur5_gains_unloaded")];
    g.bench_function("gains_ur5", |b| {
        b.iter(|| {
            black_box(
                idexp::payload::gains::calibrate(&gd, &root("designs"), &Control::new())
                    .expect("calibrate")
                    .joints
                    .len(),
            )
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
