//! Robot descriptions as they come from ROS packages: `package://` mesh
//! names resolved as ROS tools do (the URDF's folder and those above it,
//! `ROS_PACKAGE_PATH`, `AMENT_PREFIX_PATH`), geometry that cannot be loaded
//! (a warning where no geometry is needed, an error where a design checks
//! collisions), exported robot files that load from their own folder, MJCF.
//!
//! The URDFs are example-robot-data's, byte for byte, with their meshes in
//! the package's own layout (`tests/data/ros/`, README there).

mod common;

use common::root;
use idexp::robot::resolve::{MeshResolver, PackageSearch};
use idexp::robot::{self, rnea, Robot, Workspace};
use rand::{RngExt, SeedableRng};
use std::path::{Path, PathBuf};
use std::process::Command;

fn erd() -> PathBuf {
    root("tests/data/ros/example-robot-data")
}

fn ur10_urdf() -> PathBuf {
    erd().join("robots/ur_description/urdf/ur10_robot.urdf")
}

fn idexp(args: &[&str], env: &[(&str, &str)]) -> (i32, String, String) {
    let mut c = Command::new(env!("CARGO_BIN_EXE_idexp"));
    c.args(args)
        .env("IDEXP_NO_PROGRESS", "1")
        .env_remove("ROS_PACKAGE_PATH")
        .env_remove("AMENT_PREFIX_PATH");
    for (k, v) in env {
        c.env(k, v);
    }
    let o = c.output().unwrap();
    (
        o.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

/// A copy of the UR10 URDF in `dir` (outside its package): its meshes are then found only through the environment.
fn ur10_outside(dir: &Path) -> PathBuf {
    let p = dir.join("ur10_robot.urdf");
    std::fs::copy(ur10_urdf(), &p).unwrap();
    p
}

fn bodies_with_geometry(r: &Robot) -> usize {
    r.collision.as_ref().map_or(0, |g| g.bodies.iter().filter(|b| !b.is_empty()).count())
}

#[test]
fn package_urdf_used_directly_finds_its_meshes_above_its_folder() {
    // the URDF inside its package: `package://example-robot-data/...` is the
    // folder named example-robot-data above it
    let r = robot::load(&ur10_urdf()).unwrap();
    assert_eq!(r.dof(), 6);
    assert!(r.geometry_error.is_none(), "{:?}", r.geometry_error);
    assert_eq!(bodies_with_geometry(&r), 7, "base and six links");
    // the Panda of the same package, cut before its mimic finger joints
    let d = tempfile::tempdir().unwrap();
    let t = d.path().join("panda.toml");
    std::fs::write(
        &t,
        format!(
            "urdf = \"{}\"\ntip_link = \"panda_hand\"\n",
            erd().join("robots/panda_description/urdf/panda.urdf").display()
        ),
    )
    .unwrap();
    let p = robot::load(&t).unwrap();
    assert_eq!(p.dof(), 7);
    assert!(p.geometry_error.is_none(), "{:?}", p.geometry_error);
    assert_eq!(bodies_with_geometry(&p), 8, "link0 and seven links (hand merged into link 7)");
}

#[test]
fn ros_package_path_and_ament_prefix_path_find_the_package() {
    let d = tempfile::tempdir().unwrap();
    let uri = "package://example-robot-data/robots/ur_description/meshes/ur10/collision/base.stl";
    let want = erd().join("robots/ur_description/meshes/ur10/collision/base.stl");
    let none = MeshResolver {
        urdf_dir: d.path().to_path_buf(),
        mesh_path: vec![],
        packages: PackageSearch::default(),
    };
    let e = none.resolve(uri).unwrap_err();
    assert!(e.contains("ROS_PACKAGE_PATH (not set)") && e.contains("AMENT_PREFIX_PATH (not set)"), "{e}");
    assert!(e.contains("found nowhere") && e.contains(&d.path().display().to_string()), "{e}");
    assert!(e.contains("mesh_path (none given)"), "{e}");
    // ROS 1: the package folder itself on the path
    let ros1 = MeshResolver {
        packages: PackageSearch {
            ros_package_path: Some(vec![erd()]),
            ament_prefix_path: None,
        },
        ..none.clone()
    };
    assert_eq!(ros1.resolve(uri).unwrap(), want);
    // ROS 2: <prefix>/share/example-robot-data
    let prefix = d.path().join("install");
    std::fs::create_dir_all(prefix.join("share")).unwrap();
    std::os::unix::fs::symlink(erd(), prefix.join("share/example-robot-data")).unwrap();
    let ros2 = MeshResolver {
        packages: PackageSearch {
            ros_package_path: None,
            ament_prefix_path: Some(vec![d.path().join("elsewhere"), prefix.clone()]),
        },
        ..none.clone()
    };
    assert_eq!(
        ros2.resolve(uri).unwrap(),
        prefix.join("share/example-robot-data/robots/ur_description/meshes/ur10/collision/base.stl")
    );
    // a package found but without the file: both said
    let e = ros2.resolve("package://example-robot-data/robots/nothing.stl").unwrap_err();
    assert!(
        e.contains("found at") && e.contains("(from AMENT_PREFIX_PATH)") && e.contains("robots/nothing.stl"),
        "{e}"
    );
    // file:// absolute and relative to the URDF's folder; other schemes named
    let abs = format!("file://{}", want.display());
    assert_eq!(none.resolve(&abs).unwrap(), want);
    let rel = MeshResolver {
        urdf_dir: erd().join("robots/ur_description/urdf"),
        ..none.clone()
    };
    assert!(rel.resolve("file://../meshes/ur10/collision/base.stl").unwrap().is_file());
    assert!(rel.resolve("../meshes/ur10/collision/base.stl").unwrap().is_file());
    let e = none.resolve("model://ur10/meshes/base.stl").unwrap_err();
    assert!(e.contains("`model://`"), "{e}");
}

#[test]
fn a_source_workspace_is_crawled_and_sibling_packages_are_found() {
    let d = tempfile::tempdir().unwrap();
    let ws = d.path().join("ws/src");
    // a package whose folder name differs from its <name>, two levels down
    let pkg = ws.join("vendor/ur_meshes_folder");
    std::fs::create_dir_all(pkg.join("meshes")).unwrap();
    std::fs::write(
        pkg.join("package.xml"),
        "<?xml version=\"1.0\"?>\n<package format=\"3\">\n  <name>my_ur_meshes</name>\n  <version>1.0.0</version>\n</package>\n",
    )
    .unwrap();
    std::fs::copy(erd().join("robots/ur_description/meshes/ur10/collision/base.stl"), pkg.join("meshes/base.stl")).unwrap();
    // an ignored package of the same name is not taken
    let ign = ws.join("attic/old");
    std::fs::create_dir_all(&ign).unwrap();
    std::fs::write(ws.join("attic/COLCON_IGNORE"), "").unwrap();
    std::fs::write(ign.join("package.xml"), "<package><name>my_ur_meshes</name></package>").unwrap();
    let r = MeshResolver {
        urdf_dir: d.path().to_path_buf(),
        mesh_path: vec![],
        packages: PackageSearch {
            ros_package_path: Some(vec![ws.clone()]),
            ament_prefix_path: None,
        },
    };
    assert_eq!(r.resolve("package://my_ur_meshes/meshes/base.stl").unwrap(), pkg.join("meshes/base.stl"));
    // a URDF in a sibling package of the same workspace: found by walking up, no environment
    let urdf_dir = ws.join("vendor/my_robot_description/urdf");
    std::fs::create_dir_all(&urdf_dir).unwrap();
    let sib = MeshResolver {
        urdf_dir,
        mesh_path: vec![],
        packages: PackageSearch::default(),
    };
    // vendor/ holds ur_meshes_folder/package.xml named my_ur_meshes: a folder named like the package is not required
    std::os::unix::fs::symlink(&pkg, ws.join("vendor/my_ur_meshes")).unwrap();
    assert!(sib.resolve("package://my_ur_meshes/meshes/base.stl").unwrap().is_file());
}

#[test]
fn the_environment_of_the_command_line_is_read() {
    let d = tempfile::tempdir().unwrap();
    let urdf = ur10_outside(d.path());
    let u = urdf.to_str().unwrap();
    // no environment: the robot loads, with a warning naming the link, the URI and the folders
    let (code, out, err) = idexp(&["robot", "info", u], &[]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("ur10"), "{out}");
    assert!(
        err.contains("warning")
            && err.contains("link `base_link`")
            && err.contains("package://example-robot-data/robots/ur_description/meshes/ur10/collision/base.stl"),
        "{err}"
    );
    assert!(
        err.contains("ROS_PACKAGE_PATH (not set)") && !err.contains("[]") && !err.contains("  "),
        "{err}"
    );
    // ROS_PACKAGE_PATH: no warning
    let rpp = erd();
    let (code, _, err) = idexp(&["robot", "info", u], &[("ROS_PACKAGE_PATH", rpp.to_str().unwrap())]);
    assert_eq!(code, 0, "{err}");
    assert!(!err.contains("warning"), "{err}");
}

fn write(path: &Path, text: &str) {
    std::fs::write(path, text).unwrap();
}

const DESIGN: &str =
    "trajectory = { harmonics = 2, frequency = 0.1 }\n[ga]\npopulation = 4\ngenerations = 1\n[refine]\nalgorithm = \"none\"\n[limits]\nmissing = \"skip\"\n";

#[test]
fn a_design_checking_collisions_stops_when_the_geometry_is_missing() {
    let d = tempfile::tempdir().unwrap();
    let urdf = ur10_outside(d.path());
    let design = d.path().join("ur10.toml");
    write(
        &design,
        &format!("robot = \"{}\"\nname = \"ur10\"\n{DESIGN}[collision]\nmargin = 0.01\n", urdf.display()),
    );
    let out = d.path().join("out");
    let (code, _, err) = idexp(&["excite", design.to_str().unwrap(), "--out", out.to_str().unwrap()], &[]);
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("link `base_link`") && err.contains("package://example-robot-data/") && err.contains("ROS_PACKAGE_PATH"),
        "{err}"
    );
    assert!(err.contains("enabled = false"), "{err}");
    assert!(!out.exists(), "no output folder for a refused design");
    // the same without a [collision] section: collisions are checked by default, so refused as well
    write(&design, &format!("robot = \"{}\"\nname = \"ur10\"\n{DESIGN}", urdf.display()));
    let (code, _, err) = idexp(&["excite", design.to_str().unwrap(), "--out", out.to_str().unwrap()], &[]);
    assert_eq!(code, 1, "{err}");
    // a DH robot without any collision geometry and a design that asks for a margin
    let dh = d.path().join("puma.toml");
    write(
        &dh,
        &format!(
            "robot = \"{}\"\nname = \"puma\"\n{DESIGN}[collision]\nmargin = 0.01\n",
            root("designs/robots/puma560.toml").display()
        ),
    );
    let (code, _, err) = idexp(&["excite", dh.to_str().unwrap(), "--out", out.to_str().unwrap()], &[]);
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("no collision geometry") && err.contains("margin 0.01 m") && err.contains("puma560"),
        "{err}"
    );
}

/// Random states and the torques of two robots on them agree to 1e-9 relative.
fn same_torques(a: &Robot, b: &Robot, seed: u64) {
    let n = a.dof();
    assert_eq!(n, b.dof());
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let (mut wa, mut wb) = (Workspace::new(a), Workspace::new(b));
    for _ in 0..30 {
        let q: Vec<f64> = (0..n).map(|_| rng.random_range(-3.0..3.0)).collect();
        let qd: Vec<f64> = (0..n).map(|_| rng.random_range(-2.0..2.0)).collect();
        let qdd: Vec<f64> = (0..n).map(|_| rng.random_range(-5.0..5.0)).collect();
        let (mut ta, mut tb) = (vec![0.0; n], vec![0.0; n]);
        rnea(a, &mut wa, &q, &qd, &qdd, &mut ta);
        rnea(b, &mut wb, &q, &qd, &qdd, &mut tb);
        let scale = ta.iter().map(|x| x.abs()).fold(1.0, f64::max);
        for j in 0..n {
            assert!((ta[j] - tb[j]).abs() <= 1e-9 * scale, "joint {j}: {} vs {}", ta[j], tb[j]);
        }
    }
}

#[test]
fn exported_robot_files_load_from_their_own_folder_with_geometry() {
    let d = tempfile::tempdir().unwrap();
    for (src_file, seed) in [
        (root("designs/robots/ur5.toml"), 1u64),
        (root("designs/robots/panda.toml"), 2),
        (ur10_urdf(), 3),
    ] {
        let robot = robot::load(&src_file).unwrap();
        assert!(robot.collision.is_some(), "{}", src_file.display());
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        // one factor per link's inertial parameters (a scaled body stays
        // physically consistent), one per drive parameter
        let link_factor: Vec<f64> = (0..robot.dof()).map(|_| rng.random_range(0.9..1.1)).collect();
        let theta: Vec<f64> = robot
            .nominal_params()
            .iter()
            .zip(robot.params())
            .map(|(&x, p)| {
                x * if p.kind.is_inertial() {
                    link_factor[p.joint]
                } else {
                    rng.random_range(0.9..1.1)
                }
            })
            .collect();
        let src = robot::export::source_of(&src_file).unwrap();
        for with_urdf in [true, false] {
            // without the URDF export the TOML points at the source URDF, whose
            // inertials it does not change: the nominal model then
            let ident = if with_urdf { robot.with_params(&theta).unwrap() } else { robot.clone() };
            let out = d.path().join(format!("s{seed}_{with_urdf}/deeper"));
            std::fs::create_dir_all(&out).unwrap();
            let urdf_ref = if with_urdf {
                robot::export::write_urdf(&src, &ident, &out).unwrap();
                "robot.urdf".to_string()
            } else {
                // as identify passes the source URDF: absolute, written relative
                let robot::export::Source::Urdf { urdf, .. } = &src else { unreachable!() };
                std::path::absolute(urdf).unwrap().display().to_string()
            };
            let p = robot::export::write_robot_toml(&src, &ident, &out, Some(&urdf_ref)).unwrap();
            let text = std::fs::read_to_string(&p).unwrap();
            assert!(!text.contains(&d.path().display().to_string()), "paths relative to the folder:\n{text}");
            let back = robot::load(&p).unwrap_or_else(|e| panic!("{}: {e}\n{text}", p.display()));
            assert!(back.geometry_error.is_none(), "{:?}\n{text}", back.geometry_error);
            assert_eq!(bodies_with_geometry(&back), bodies_with_geometry(&robot), "{text}");
            same_torques(&ident, &back, seed);
            // the robot file works the same from the command line (another working folder)
            let (code, _, err) = idexp(&["robot", "info", p.to_str().unwrap()], &[]);
            assert_eq!(code, 0, "{err}");
            assert!(!err.contains("warning"), "{err}");
        }
    }
}

#[test]
fn a_robot_toml_with_missing_meshes_loads_for_what_needs_no_geometry() {
    let d = tempfile::tempdir().unwrap();
    let t = d.path().join("ur5.toml");
    let text = std::fs::read_to_string(root("designs/robots/ur5.toml")).unwrap();
    let text = text
        .replace("urdf = \"ur5.urdf\"", &format!("urdf = \"{}\"", root("designs/robots/ur5.urdf").display()))
        .replace("mesh_path = [\"meshes/ur5\"]", "mesh_path = [\"nowhere\"]");
    write(&t, &text);
    let r = robot::load(&t).unwrap();
    let why = r.geometry_error.clone().expect("the meshes are not found");
    assert!(why.contains("link `base_link`") && why.contains("nowhere") && why.contains("base.stl"), "{why}");
    assert!(r.collision.is_none());
    // torques and identification inputs as usual
    same_torques(&r, &robot::load(&root("designs/robots/ur5.toml")).unwrap(), 4);
    let (code, _, err) = idexp(&["robot", "info", t.to_str().unwrap()], &[]);
    assert_eq!(code, 0, "{err}");
    assert!(err.contains("warning") && err.contains("nowhere"), "{err}");
}

#[test]
fn mjcf_has_the_body_tree_the_drives_and_the_caveats() {
    let panda = robot::load(&root("designs/robots/panda.toml")).unwrap();
    let x = robot::export::mjcf_string(&panda);
    assert_eq!(x.matches("<body ").count(), 7);
    assert_eq!(x.matches("<joint ").count(), 7);
    assert_eq!(x.matches("<motor ").count(), 7);
    assert!(x.contains("<option gravity=\"0 0 -9.81\"/>"), "{x}");
    for (j, d) in panda.drives.iter().enumerate() {
        let ia = d.rotor_inertia.unwrap();
        let line = x.lines().find(|l| l.contains(&format!("<joint name=\"{}\"", panda.joints[j].name))).unwrap();
        // written exactly (shortest round-trip form)
        let v: f64 = line.split("armature=\"").nth(1).unwrap().split('"').next().unwrap().parse().unwrap();
        assert_eq!(v, ia, "{line}");
        assert!(
            line.contains("type=\"hinge\"") && line.contains("range=") && line.contains("frictionloss="),
            "{line}"
        );
    }
    // the coupled wrist is stated, not hidden
    let ind = robot::load(&root("designs/robots/industrial6.toml")).unwrap();
    let xi = robot::export::mjcf_string(&ind);
    assert!(xi.contains("NOT EXPRESSED: the coupling matrix"), "{xi}");
    // XML comments hold no `--`
    for c in xi.split("<!--").skip(1) {
        assert!(!c.split("-->").next().unwrap().contains("--"), "{c}");
    }
    // the CLI writes the same text
    let d = tempfile::tempdir().unwrap();
    let (code, out, err) = idexp(
        &[
            "robot",
            "mjcf",
            root("designs/robots/panda.toml").to_str().unwrap(),
            "--out",
            d.path().to_str().unwrap(),
        ],
        &[],
    );
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("robot.xml"), "{out}");
    assert_eq!(std::fs::read_to_string(d.path().join("robot.xml")).unwrap(), x);
}

#[test]
fn identify_exports_the_consistent_model_as_mjcf_beside_its_toml() {
    let d = tempfile::tempdir().unwrap();
    let robot_file = root("tests/data/ident/rpr_drives.toml");
    let design = d.path().join("sim.toml");
    write(
        &design,
        &format!(
            "robot = \"{}\"\nrate = 500.0\ndecimate = 5\nrepetitions = 2\nseed = 3\n[truth]\nperturbation = 0.1\nseed = 7\n[noise]\ntorque = 0.05\n[reference]\nkind = \"random_fourier\"\nfrequency = 0.2\namplitude = 0.6\nseed = 3\n",
            robot_file.display()
        ),
    );
    let run = d.path().join("run");
    let (code, _, err) = idexp(&["simulate", design.to_str().unwrap(), "--out", run.to_str().unwrap()], &[]);
    assert_eq!(code, 0, "{err}");
    let out = d.path().join("id");
    let (code, _, err) = idexp(
        &[
            "identify",
            robot_file.to_str().unwrap(),
            run.to_str().unwrap(),
            "--consistent",
            "--export",
            "toml,mjcf",
            "--out",
            out.to_str().unwrap(),
        ],
        &[],
    );
    assert_eq!(code, 0, "{err}");
    // robot.xml is the MJCF of the identified model that robot.toml holds
    let model = robot::load(&out.join("robot.toml")).unwrap();
    let xml = std::fs::read_to_string(out.join("robot.xml")).unwrap();
    let body = |x: &str| x.lines().filter(|l| !l.contains("written by idexp")).collect::<Vec<_>>().join("\n");
    // the same text, numbers to 1e-12 relative: robot.toml's inertials are
    // written per link and read back through the centre of mass, which moves
    // the last digit of some products
    let (a, b) = (body(&xml), body(&robot::export::mjcf_string(&model)));
    let (ta, tb): (Vec<&str>, Vec<&str>) = (a.split('"').collect(), b.split('"').collect());
    assert_eq!(ta.len(), tb.len(), "{a}\n{b}");
    for (u, v) in ta.iter().zip(&tb) {
        let nums = |t: &str| t.split(' ').map(|w| w.parse::<f64>()).collect::<Result<Vec<f64>, _>>();
        match (nums(u), nums(v)) {
            (Ok(x), Ok(y)) if x.len() == y.len() => {
                for (p, q) in x.iter().zip(&y) {
                    assert!((p - q).abs() <= 1e-12 * p.abs().max(q.abs()).max(1e-3), "{u} vs {v}");
                }
            }
            _ => assert_eq!(u, v),
        }
    }
    // and not the nominal model's
    let nominal = robot::load(&robot_file).unwrap();
    assert_ne!(body(&xml), body(&robot::export::mjcf_string(&nominal)));
}

#[test]
fn a_package_is_found_by_its_folder_name_and_the_hint_works_as_written() {
    // example-robot-data: package.xml names `example_robot_descriptions`, the
    // URIs and the folder say `example-robot-data`
    assert_eq!(idexp::robot::resolve::package_name(&erd()).as_deref(), Some("example_robot_descriptions"));
    let uri = "package://example-robot-data/robots/ur_description/meshes/ur10/collision/base.stl";
    let want = erd().join("robots/ur_description/meshes/ur10/collision/base.stl");
    let d = tempfile::tempdir().unwrap();
    let none = MeshResolver {
        urdf_dir: d.path().to_path_buf(),
        mesh_path: vec![],
        packages: PackageSearch::default(),
    };
    let hint = none.resolve(uri).unwrap_err();
    // what the hint advises, each followed as written
    assert!(
        hint.contains("set ROS_PACKAGE_PATH to the package folder `example-robot-data` or a folder at most 4 levels above it")
            && hint.contains("AMENT_PREFIX_PATH to the install prefix holding share/example-robot-data")
            && hint.contains("mesh_path naming the package folder or the folder holding it"),
        "{hint}"
    );
    let ros = |p: PathBuf| MeshResolver {
        packages: PackageSearch {
            ros_package_path: Some(vec![p]),
            ament_prefix_path: None,
        },
        ..none.clone()
    };
    // the package folder itself, and folders above it (crawled: the folder name, not package.xml's name)
    assert_eq!(ros(erd()).resolve(uri).unwrap(), want);
    assert_eq!(ros(root("tests/data/ros")).resolve(uri).unwrap(), want);
    assert_eq!(ros(root("tests/data")).resolve(uri).unwrap(), want);
    // an install prefix holding share/example-robot-data (as pip's cmeel.prefix does)
    let prefix = d.path().join("prefix");
    std::fs::create_dir_all(prefix.join("share")).unwrap();
    std::os::unix::fs::symlink(erd(), prefix.join("share/example-robot-data")).unwrap();
    let ament = MeshResolver {
        packages: PackageSearch {
            ros_package_path: None,
            ament_prefix_path: Some(vec![prefix.clone()]),
        },
        ..none.clone()
    };
    assert!(ament.resolve(uri).unwrap().is_file());
    // ROS_PACKAGE_PATH = the prefix's share/ folder (the folder holding the package): found by crawling
    assert!(ros(prefix.join("share")).resolve(uri).unwrap().is_file());
    // mesh_path: the package folder, or the folder holding it
    for m in [erd(), root("tests/data/ros")] {
        let r = MeshResolver {
            mesh_path: vec![m],
            ..none.clone()
        };
        assert_eq!(r.resolve(uri).unwrap(), want);
    }
    // a sibling of a URDF's ancestors named like the package, whose package.xml says otherwise
    let ws = d.path().join("ws");
    std::fs::create_dir_all(ws.join("robot/urdf")).unwrap();
    std::os::unix::fs::symlink(erd(), ws.join("example-robot-data")).unwrap();
    let walk = MeshResolver {
        urdf_dir: ws.join("robot/urdf"),
        ..none.clone()
    };
    assert!(walk.resolve(uri).unwrap().is_file());
}

#[test]
fn the_panda_as_it_ships_loads_as_an_arm_with_its_fingers_locked() {
    // no tip_link: the <mimic> finger group on panda_hand is locked and merged
    let urdf = erd().join("robots/panda_description/urdf/panda.urdf");
    let p = robot::load(&urdf).unwrap();
    assert_eq!(p.dof(), 7);
    assert!(p.joints.iter().all(|j| !j.name.contains("finger")));
    let g = p.collision.as_ref().unwrap();
    assert!(g.members[7].iter().any(|m| m == "panda_leftfinger") && g.members[7].iter().any(|m| m == "panda_rightfinger"));
    let prov = idexp::robot::provenance::provenance(&urdf).unwrap();
    assert_eq!(prov.left_out.len(), 1, "{:?}", prov.left_out);
    assert!(
        prov.left_out[0].contains("`panda_finger_joint1`, `panda_finger_joint2` locked at 0")
            && prov.left_out[0].contains("`panda_finger_joint2` follows `panda_finger_joint1`")
            && prov.left_out[0].contains("merged into `panda_link7`"),
        "{}",
        prov.left_out[0]
    );
    // the hand with its fingers weighs more than the hand alone (tip_link = panda_hand leaves them out, and says so)
    let d = tempfile::tempdir().unwrap();
    let t = d.path().join("panda.toml");
    std::fs::write(&t, format!("urdf = {:?}\ntip_link = \"panda_hand\"\n", urdf.to_str().unwrap())).unwrap();
    let cut = robot::load(&t).unwrap();
    let fingers = p.links[6].inertial.mass - cut.links[6].inertial.mass;
    assert!((fingers - 2.0 * 0.015).abs() < 1e-12, "{fingers} kg");
    let prov = idexp::robot::provenance::provenance(&t).unwrap();
    assert!(
        prov.left_out.len() == 1
            && prov.left_out[0].contains("`panda_hand_tcp_joint`, `panda_finger_joint1`, `panda_finger_joint2` and everything below them")
            && prov.left_out[0].contains("tip_link `panda_hand`"),
        "{:?}",
        prov.left_out
    );
    // robot info says it, text and JSON, and names each link's mesh file
    let (code, out, err) = idexp(&["robot", "info", urdf.to_str().unwrap()], &[]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("Left out of the model:") && out.contains("panda_finger_joint2"), "{out}");
    let mesh = erd().join("robots/panda_description/meshes/collision/link3.stl");
    assert!(
        out.contains(&format!("panda_link3: panda_link3, URDF <collision>, mesh {}", mesh.display())),
        "{out}"
    );
    let (code, out, err) = idexp(&["robot", "info", urdf.to_str().unwrap(), "--json"], &[]);
    assert_eq!(code, 0, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(v["left_out"].as_array().unwrap().len(), 1);
    let c = v["collision_geometry"].as_array().unwrap();
    let l3 = c.iter().find(|c| c["link"] == "panda_link3").unwrap();
    assert_eq!(l3["file"].as_str().unwrap(), mesh.to_str().unwrap());
    assert_eq!(l3["uri"], "package://example-robot-data/robots/panda_description/meshes/collision/link3.stl");
    assert_eq!(c.iter().find(|c| c["link"] == "panda_leftfinger").unwrap()["body"], "panda_link7");
}
