//! Collision geometry, distances, gradients, pair lists, and the collision
//! constraints of the excitation design.

use idexp::robot::collision::{CollisionScene, CollisionSpec};
use idexp::robot::kinematics::Kin;
use std::path::Path;

fn designs() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/designs"))
}

#[test]
fn scratch_distances() {
    for r in ["robots/ur5.toml", "robots/panda.toml"] {
        let robot = idexp::robot::load(&designs().join(r)).unwrap();
        let scene = CollisionScene::new(&robot, &CollisionSpec::default(), designs(), "t").unwrap().unwrap();
        let mut kin = Kin::new(robot.dof());
        let q = vec![0.0; robot.dof()];
        for d in scene.distances(&robot, &mut kin, &q, 10.0) {
            println!("{r} {} {:.4}", d.label, d.distance);
        }
        for e in &scene.excluded {
            println!("excl {} {} {}", e.a, e.b, e.reason);
        }
    }
}

#[test]
fn scratch_sweep() {
    use rand::{RngExt, SeedableRng};
    for r in ["robots/ur5.toml", "robots/panda.toml"] {
        let robot = idexp::robot::load(&designs().join(r)).unwrap();
        let scene = CollisionScene::new(&robot, &CollisionSpec::default(), designs(), "t").unwrap().unwrap();
        let mut kin = Kin::new(robot.dof());
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        let np = scene.len();
        let (mut lo, mut hi) = (vec![f64::INFINITY; np], vec![f64::NEG_INFINITY; np]);
        for _ in 0..3000 {
            let q: Vec<f64> = robot.joints.iter().map(|j| {
                let (a, b) = (j.limits.lower.max(-3.14), j.limits.upper.min(3.14));
                rng.random_range(a..b)
            }).collect();
            for d in scene.distances(&robot, &mut kin, &q, 10.0) {
                lo[d.pair] = lo[d.pair].min(d.distance);
                hi[d.pair] = hi[d.pair].max(d.distance);
            }
        }
        for k in 0..np {
            println!("{r} {:<45} min {:.4} max {:.4}", scene.pairs[k].label(), lo[k], hi[k]);
        }
    }
}
