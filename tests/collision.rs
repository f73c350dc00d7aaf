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
