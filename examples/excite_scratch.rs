fn main() {
    for (f, q) in [
        ("designs/robots/industrial6.toml", vec![0.0, -1.047, 0.209, 0.0, 0.0, 0.0]),
        ("designs/robots/industrial6.toml", vec![0.0, -1.2, 0.5, 0.0, 0.8, 0.0]),
        ("designs/robots/panda.toml", vec![0.0, 0.0, 0.0, -1.5708, 0.0, 1.5708, 0.0]),
        ("designs/robots/ur5.toml", vec![0.0; 6]),
    ] {
        let r = idexp::robot::load(std::path::Path::new(f)).unwrap();
        let mut ws = idexp::robot::Workspace::new(&r);
        let ee = r.end_effector();
        let p = idexp::robot::frame_pose(&r, &mut ws, &q, &ee);
        println!("{f} {} at {:?}: {:?}", ee.name, q, p.translation.vector.as_slice());
        for j in &r.joints {
            print!(
                "[{:.3},{:.3}] v{:.2} a{:.1} e{:.1}; ",
                j.limits.lower, j.limits.upper, j.limits.velocity, j.limits.acceleration, j.limits.effort
            );
        }
        println!();
    }
}
