//! Bad robot files and bad states CSVs give errors that name the file, the
//! line or field, and what was expected.

mod common;
use idexp::io::States;
use idexp::robot;
use std::path::Path;

fn write(dir: &Path, name: &str, text: &str) -> std::path::PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

fn err_of(path: &Path) -> String {
    match robot::load(path) {
        Ok(_) => panic!("{} should not load", path.display()),
        Err(e) => e.to_string(),
    }
}

const JOINT: &str = r#"
[[joint]]
name = "j1"
d = 0.3
inertial = { mass = 1.0, com = [0.0, 0.0, 0.1], inertia = [0.01, 0.0, 0.0, 0.01, 0.0, 0.01] }
"#;

#[test]
fn malformed_toml_names_file_and_line() {
    let d = tempfile::tempdir().unwrap();
    let p = write(d.path(), "bad.toml", "name = \"x\"\ndh = \"standard\"\n[[joint]\nname = 1\n");
    let e = err_of(&p);
    assert!(e.contains("bad.toml") && e.contains("line 3"), "{e}");
}

#[test]
fn unknown_field_is_rejected() {
    let d = tempfile::tempdir().unwrap();
    let p = write(d.path(), "typo.toml", &format!("dh = \"standard\"\ngravty = [0, 0, -9.81]\n{JOINT}"));
    let e = err_of(&p);
    assert!(e.contains("typo.toml") && e.contains("gravty"), "{e}");
}

#[test]
fn missing_inertial_block_is_rejected() {
    let d = tempfile::tempdir().unwrap();
    let p = write(d.path(), "noinert.toml", "dh = \"modified\"\n[[joint]]\nname = \"j1\"\nd = 0.3\n");
    let e = err_of(&p);
    assert!(e.contains("noinert.toml") && e.contains("inertial") && e.contains("j1"), "{e}");
    let u = write(
        d.path(),
        "noinert.urdf",
        r#"<robot name="r"><link name="a"/><link name="b"/>
        <joint name="j" type="revolute"><parent link="a"/><child link="b"/><axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint></robot>"#,
    );
    let e = err_of(&u);
    assert!(e.contains("noinert.urdf") && e.contains("`b`") && e.contains("<inertial>"), "{e}");
}

#[test]
fn non_positive_mass_is_rejected() {
    let d = tempfile::tempdir().unwrap();
    let p = write(
        d.path(),
        "neg.toml",
        &format!("dh = \"standard\"\n{}", JOINT.replace("mass = 1.0", "mass = -2.0")),
    );
    let e = err_of(&p);
    assert!(e.contains("neg.toml") && e.contains("mass") && e.contains("-2"), "{e}");
    let u = write(
        d.path(),
        "neg.urdf",
        r#"<robot name="r"><link name="a"/><link name="b"><inertial><mass value="-1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>
        <joint name="j" type="revolute"><parent link="a"/><child link="b"/><axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint></robot>"#,
    );
    let e = err_of(&u);
    assert!(e.contains("neg.urdf") && e.contains("mass"), "{e}");
}

#[test]
fn unknown_joint_types_are_rejected() {
    let d = tempfile::tempdir().unwrap();
    let p = write(
        d.path(),
        "kind.toml",
        &format!("dh = \"standard\"\n{}", JOINT.replace("d = 0.3", "d = 0.3\ntype = \"spherical\"")),
    );
    let e = err_of(&p);
    assert!(e.contains("kind.toml") && e.contains("spherical"), "{e}");
    let u = write(
        d.path(),
        "kind.urdf",
        r#"<robot name="r"><link name="a"/><link name="b"><inertial><mass value="1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>
        <joint name="j" type="floating"><parent link="a"/><child link="b"/></joint></robot>"#,
    );
    let e = err_of(&u);
    assert!(e.contains("kind.urdf") && e.contains("Floating") && e.contains("expected revolute"), "{e}");
}

#[test]
fn malformed_urdf_and_bad_references_are_rejected() {
    let d = tempfile::tempdir().unwrap();
    let u = write(d.path(), "broken.urdf", "<robot name=\"r\"><link name=\"a\">");
    let e = err_of(&u);
    assert!(e.contains("broken.urdf") && e.contains("malformed URDF"), "{e}");
    let p = write(d.path(), "ref.toml", "urdf = \"missing.urdf\"\n");
    let e = err_of(&p);
    assert!(e.contains("missing.urdf"), "{e}");
    let p = write(
        d.path(),
        "drive.toml",
        &format!("dh = \"standard\"\n{JOINT}\n[[drive]]\njoint = \"j9\"\nfc = 1.0\n"),
    );
    let e = err_of(&p);
    assert!(e.contains("drive.toml") && e.contains("j9") && e.contains("j1"), "{e}");
    let p = write(d.path(), "coup.toml", &format!("dh = \"standard\"\ncoupling = [[1.0, 0.0]]\n{JOINT}"));
    let e = err_of(&p);
    assert!(e.contains("coup.toml") && e.contains("coupling") && e.contains("1 rows of 1"), "{e}");
    let p = write(d.path(), "sing.toml", &format!("dh = \"standard\"\ncoupling = [[0.0]]\n{JOINT}"));
    let e = err_of(&p);
    assert!(e.contains("singular"), "{e}");
}

#[test]
fn states_csv_errors_name_file_row_and_column() {
    let d = tempfile::tempdir().unwrap();
    let p = write(d.path(), "nan.csv", "t,q1,qd1,qdd1\n0,0.1,0.2,0.3\n0.1,NaN,0.2,0.3\n");
    let e = States::read(&p, 1).unwrap_err().to_string();
    assert!(e.contains("nan.csv") && e.contains("row 2") && e.contains("q1") && e.contains("finite"), "{e}");
    let p = write(d.path(), "missing.csv", "q1,qd1\n0.1,0.2\n");
    let e = States::read(&p, 1).unwrap_err().to_string();
    assert!(e.contains("missing.csv") && e.contains("qdd1") && e.contains("missing column"), "{e}");
    let p = write(d.path(), "count.csv", "q1,q2,qd1,qd2,qdd1,qdd2\n0,0,0,0,0,0\n");
    let e = States::read(&p, 1).unwrap_err().to_string();
    assert!(e.contains("count.csv") && e.contains("q2") && e.contains("1 joints"), "{e}");
    let e = States::read(&p, 3).unwrap_err().to_string();
    assert!(e.contains("q3"), "{e}");
    let p = write(d.path(), "text.csv", "q1,qd1,qdd1\n0.1,abc,0\n");
    let e = States::read(&p, 1).unwrap_err().to_string();
    assert!(e.contains("row 1") && e.contains("qd1") && e.contains("\"abc\""), "{e}");
    let p = write(d.path(), "short.csv", "q1,qd1,qdd1\n0.1,0.2\n");
    let e = States::read(&p, 1).unwrap_err().to_string();
    assert!(e.contains("short.csv") && e.contains("row 1") && e.contains("expected 3 values"), "{e}");
}

#[cfg(feature = "cli")]
/// The CLI reports bad input with a non-zero exit and the message, never a panic.
#[test]
fn cli_reports_errors_without_panicking() {
    let d = tempfile::tempdir().unwrap();
    let p = write(d.path(), "nan.csv", "q1,q2,q3,qd1,qd2,qd3,qdd1,qdd2,qdd3\n0,0,0,0,0,0,0,inf,0\n");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_idexp"))
        .args([
            "robot",
            "torques",
            common::root("tests/data/rpr_standard.toml").to_str().unwrap(),
            "--states",
            p.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1), "an error in the input exits with 1");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("nan.csv") && err.contains("qdd2") && !err.contains("panicked"), "{err}");
}
