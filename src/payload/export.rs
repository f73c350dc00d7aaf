//! The payload written where controllers and simulators read it.
//!
//! | format | file | content |
//! |---|---|---|
//! | URScript | `payload.script` | `set_target_payload(m, [cx, cy, cz], [Ixx, Iyy, Izz, Ixy, Ixz, Iyz])` (tool flange frame, inertia about the centre of gravity) |
//! | Franka | `franka_load.json` | `mass`, `F_x_Cload` (flange frame, m), `load_inertia` (3×3 about the centre of mass, column-major), the arguments of `setLoad`; `frame`: the frame they are in |
//! | KUKA | `kuka_load.txt` | `LOAD_DATA[n] = {M …, CM {X …, Y …, Z …, A …, B …, C …}, J {X …, Y …, Z …}}`: M (kg), X, Y, Z (mm), A, B, C (deg: the principal axes, Z-Y'-X'' Euler angles), JX, JY, JZ (kg·m², principal moments), each a KRL REAL of at most 7 significant digits |
//! | URDF | `payload.urdf` | a `payload` link with the inertial and a fixed joint to the frame |
//! | MJCF | `payload_mjcf.xml` | a MuJoCo `<body>` with the payload's `<inertial>`, to place in the frame's body (see [`mjcf_inertia`]) |
//!
//! Every number is in the axes of the payload's frame (the design's `frame`,
//! e.g. `tool0`, the identification's frame): the controllers take the
//! flange frame (UR: `tool0` of UR's descriptions; Franka: the flange, `panda_link8`;
//! KUKA: `$FLANGE`), so identify on that frame. Each file names its frame.

use crate::robot::mjcf::{mujoco_inertia, TRIANGLE_MARGIN};
use crate::robot::payload::Payload;
use nalgebra::{Matrix3, Rotation3, SymmetricEigen};
use serde::Serialize;
use std::fmt::Write;

/// The principal axes of a payload's inertia about its centre of mass.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Principal {
    /// Principal moments (kg·m²) about the axes (the columns of `axes`).
    pub moments: [f64; 3],
    /// Rotation frame → principal axes (columns: the axes in frame coordinates), proper (det = +1).
    pub axes: [[f64; 3]; 3],
    /// KUKA A, B, C (deg): axes = Rz(A) Ry(B) Rx(C).
    pub abc_deg: [f64; 3],
}

/// The principal axes of `p`'s inertia: of the 24 proper rotations that
/// diagonalise it, the one closest to the identity (so a nearly diagonal
/// tensor gives small angles and JX ≈ Ixx).
pub fn principal(p: &Payload) -> Principal {
    let eig = SymmetricEigen::new(p.inertia_matrix());
    let mut best: Option<(f64, Matrix3<f64>, [f64; 3])> = None;
    const PERMS: [[usize; 3]; 6] = [[0, 1, 2], [0, 2, 1], [1, 0, 2], [1, 2, 0], [2, 0, 1], [2, 1, 0]];
    for perm in PERMS {
        for signs in 0..8u8 {
            let mut r = Matrix3::zeros();
            for (c, &k) in perm.iter().enumerate() {
                let s = if signs & (1 << c) != 0 { -1.0 } else { 1.0 };
                r.set_column(c, &(eig.eigenvectors.column(k) * s));
            }
            if r.determinant() < 0.0 {
                continue;
            }
            let tr = r.trace();
            if best.as_ref().is_none_or(|(t, _, _)| tr > *t + 1e-12) {
                best = Some((tr, r, [eig.eigenvalues[perm[0]], eig.eigenvalues[perm[1]], eig.eigenvalues[perm[2]]]));
            }
        }
    }
    let (_, r, moments) = best.unwrap_or((3.0, Matrix3::identity(), [p.inertia[0], p.inertia[3], p.inertia[5]]));
    let rot = Rotation3::from_matrix_unchecked(r);
    let (c, b, a) = rot.euler_angles();
    let mut axes = [[0.0; 3]; 3];
    for (i, row) in axes.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v = r[(i, j)];
        }
    }
    Principal {
        moments,
        axes,
        abc_deg: [a.to_degrees(), b.to_degrees(), c.to_degrees()],
    }
}

/// A number with enough digits to read back (shortest round trip).
fn num(v: f64) -> String {
    let v = if v == 0.0 { 0.0 } else { v };
    format!("{v:?}")
}

/// `payload.script`: URScript's `set_target_payload` (the payload's frame is
/// taken as UR's tool flange; `header` lines become comments).
pub fn urscript(p: &Payload, frame: &str, header: &[String]) -> String {
    let mut s = comments(header, "# ", "");
    let _ = writeln!(
        s,
        "# mass (kg), centre of gravity in the {frame} frame (m), inertia about it in {frame}'s axes [Ixx, Iyy, Izz, Ixy, Ixz, Iyz] (kg·m²)"
    );
    let _ = writeln!(
        s,
        "# set_target_payload takes the tool flange frame (tool0 of UR's descriptions){}",
        if frame == "tool0" {
            ""
        } else {
            ": identify on tool0 if this frame is not the flange"
        }
    );
    let i = &p.inertia;
    let _ = writeln!(
        s,
        "set_target_payload({}, [{}, {}, {}], [{}, {}, {}, {}, {}, {}])",
        num(p.mass),
        num(p.com[0]),
        num(p.com[1]),
        num(p.com[2]),
        num(i[0]),
        num(i[3]),
        num(i[5]),
        num(i[1]),
        num(i[2]),
        num(i[4])
    );
    s
}

/// Franka's load (`setLoad(load_mass, F_x_Cload, load_inertia)`).
#[derive(Debug, Clone, PartialEq, Serialize, serde::Deserialize)]
pub struct FrankaLoad {
    /// Mass (kg).
    pub mass: f64,
    /// Centre of mass in the flange frame (m).
    #[serde(rename = "F_x_Cload")]
    pub f_x_cload: [f64; 3],
    /// Inertia about the centre of mass, 3×3 column-major (kg·m²).
    pub load_inertia: [f64; 9],
    /// The frame `F_x_Cload` and `load_inertia` are in (the identification's;
    /// `setLoad` takes the flange frame).
    #[serde(default)]
    pub frame: String,
}

/// The Franka load of `p` identified on `frame`.
pub fn franka(p: &Payload, frame: &str) -> FrankaLoad {
    let m = p.inertia_matrix();
    let mut li = [0.0; 9];
    for c in 0..3 {
        for r in 0..3 {
            li[c * 3 + r] = m[(r, c)];
        }
    }
    FrankaLoad {
        mass: p.mass,
        f_x_cload: p.com,
        load_inertia: li,
        frame: frame.to_string(),
    }
}

/// A KRL REAL literal: at most 7 significant digits (KRL's REAL is a 32-bit
/// float), plain decimal notation (no exponent), at least one digit after the point.
pub fn krl_real(v: f64) -> String {
    // below 1e-12 (kg·m², mm, deg) a value is rounding noise: 0
    if !v.is_finite() || v.abs() < 1e-12 {
        return "0.0".into();
    }
    let mag = |x: f64| x.abs().log10().floor() as i32;
    let scale = 10f64.powi(6 - mag(v));
    let r = (v * scale).round() / scale;
    let decimals = (6 - mag(r)).clamp(1, 20) as usize;
    let t = format!("{r:.decimals$}");
    let t = t.trim_end_matches('0');
    if t.ends_with('.') {
        format!("{t}0")
    } else {
        t.to_string()
    }
}

/// `kuka_load.txt`: the load data as KUKA's KRL statement
/// `LOAD_DATA[tool] = {M …, CM {X …, Y …, Z …, A …, B …, C …}, J {X …, Y …, Z …}}`
/// (the tool's entry of the `LOAD_DATA` array of `$config.dat`), each value a
/// KRL REAL ([`krl_real`]); the centre of mass in `frame`'s axes (KUKA's
/// `$FLANGE` when identified on the flange).
pub fn kuka(p: &Payload, tool: u32, frame: &str, header: &[String]) -> String {
    let pr = principal(p);
    let mm = |v: f64| v * 1000.0;
    let mut s = comments(header, "; ", "");
    let _ = writeln!(
        s,
        "; tool {tool}: M (kg), X Y Z centre of mass in the {frame} frame (mm), A B C orientation of the principal axes (deg, Z-Y'-X''), JX JY JZ principal moments (kg·m²)"
    );
    let _ = writeln!(s, "; KUKA takes the centre of mass in the flange frame ($FLANGE)");
    let r = krl_real;
    let _ = writeln!(
        s,
        "LOAD_DATA[{tool}] = {{M {}, CM {{X {}, Y {}, Z {}, A {}, B {}, C {}}}, J {{X {}, Y {}, Z {}}}}}",
        r(p.mass),
        r(mm(p.com[0])),
        r(mm(p.com[1])),
        r(mm(p.com[2])),
        r(pr.abc_deg[0]),
        r(pr.abc_deg[1]),
        r(pr.abc_deg[2]),
        r(pr.moments[0]),
        r(pr.moments[1]),
        r(pr.moments[2])
    );
    s
}

/// KUKA load data as written in `kuka_load.txt`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct KukaLoad {
    /// M (kg).
    pub m: f64,
    /// X, Y, Z: centre of mass (mm).
    pub xyz_mm: [f64; 3],
    /// A, B, C: the principal axes (deg).
    pub abc_deg: [f64; 3],
    /// JX, JY, JZ: principal moments (kg·m²).
    pub j: [f64; 3],
}

/// Reads back the `LOAD_DATA` line of [`kuka`].
pub fn parse_kuka(text: &str) -> Option<KukaLoad> {
    let line = text.lines().find(|l| l.trim_start().starts_with("LOAD_DATA"))?;
    let body = line.split_once('=')?.1;
    let mut vals: Vec<(String, f64)> = Vec::new();
    let cleaned: String = body.chars().map(|c| if matches!(c, '{' | '}' | ',') { ' ' } else { c }).collect();
    let toks: Vec<&str> = cleaned.split_whitespace().collect();
    let mut i = 0;
    let mut prefix = String::new();
    while i < toks.len() {
        match toks[i] {
            "CM" | "J" => {
                prefix = toks[i].to_string();
                i += 1;
            }
            key if i + 1 < toks.len() => {
                let v: f64 = toks[i + 1].parse().ok()?;
                let k = if key == "M" { key.to_string() } else { format!("{prefix}.{key}") };
                vals.push((k, v));
                i += 2;
            }
            _ => return None,
        }
    }
    let get = |k: &str| vals.iter().find(|(n, _)| n == k).map(|(_, v)| *v);
    Some(KukaLoad {
        m: get("M")?,
        xyz_mm: [get("CM.X")?, get("CM.Y")?, get("CM.Z")?],
        abc_deg: [get("CM.A")?, get("CM.B")?, get("CM.C")?],
        j: [get("J.X")?, get("J.Y")?, get("J.Z")?],
    })
}

/// The inertia tensor about the centre of mass from KUKA's principal data:
/// R diag(J) Rᵀ with R = Rz(A) Ry(B) Rx(C).
pub fn tensor_from_kuka(abc_deg: [f64; 3], j: [f64; 3]) -> Matrix3<f64> {
    let r = Rotation3::from_euler_angles(abc_deg[2].to_radians(), abc_deg[1].to_radians(), abc_deg[0].to_radians()).into_inner();
    r * Matrix3::from_diagonal(&j.into()) * r.transpose()
}

fn inertia_attrs(p: &Payload) -> String {
    let i = &p.inertia;
    format!(
        "ixx=\"{}\" ixy=\"{}\" ixz=\"{}\" iyy=\"{}\" iyz=\"{}\" izz=\"{}\"",
        num(i[0]),
        num(i[1]),
        num(i[2]),
        num(i[3]),
        num(i[4]),
        num(i[5])
    )
}

/// The header lines as comments: `open` text `close` on each line (`--`
/// shortened in XML comments, where it may not appear).
fn comments(header: &[String], open: &str, close: &str) -> String {
    header
        .iter()
        .map(|h| {
            let h = if open == "<!-- " { h.replace("--", "-") } else { h.clone() };
            format!("{open}{h}{close}\n")
        })
        .collect()
}

/// `payload.urdf`: a link `payload` fixed to `frame`, with the payload's
/// inertial (merge it into the robot's URDF, or include it with xacro).
pub fn urdf(p: &Payload, frame: &str, header: &[String]) -> String {
    format!(
        r#"<?xml version="1.0"?>
{c}<robot name="payload">
  <link name="{frame}"/>
  <link name="payload">
    <inertial>
      <origin xyz="{x} {y} {z}" rpy="0 0 0"/>
      <mass value="{m}"/>
      <inertia {i}/>
    </inertial>
  </link>
  <joint name="{frame}_payload" type="fixed">
    <parent link="{frame}"/>
    <child link="payload"/>
    <origin xyz="0 0 0" rpy="0 0 0"/>
  </joint>
</robot>
"#,
        c = comments(header, "<!-- ", " -->"),
        x = num(p.com[0]),
        y = num(p.com[1]),
        z = num(p.com[2]),
        m = num(p.mass),
        i = inertia_attrs(p)
    )
}

/// The inertia tensor about the centre of mass written to MJCF, and how far
/// it moved (largest |ΔI| entry, kg·m²): the robot export's
/// [`crate::robot::mjcf::mujoco_inertia`] (one rule for every MJCF idexp
/// writes). MuJoCo refuses a body whose principal moments break A + B ≥ C
/// ("inertia must satisfy A + B >= C"); a consistent fit on the boundary (a
/// flat body: smallest eigenvalue of Σ = ½ tr(I) 1 − I, the second moment of
/// the mass, at 0 up to rounding, e.g. −3e-12) lands on either side. The
/// smallest δ is added to the three principal moments that keeps
/// A + B − C ≥ [`TRIANGLE_MARGIN`]·(A + B + C): zero for a tensor already
/// inside. (MuJoCo's own `balanceinertia` would replace all three moments by
/// their mean, a large change for a flat body.)
pub fn mjcf_inertia(p: &Payload) -> ([f64; 6], f64) {
    let i = p.inertia_matrix();
    let (i2, delta) = mujoco_inertia(&i);
    if delta == 0.0 {
        return (p.inertia, 0.0);
    }
    let out = [i2[(0, 0)], i2[(0, 1)], i2[(0, 2)], i2[(1, 1)], i2[(1, 2)], i2[(2, 2)]];
    (out, (i2 - i).abs().max())
}

/// `payload_mjcf.xml`: a MuJoCo model whose body `payload` (inside a body
/// named after the frame) carries the payload's inertial; copy the
/// `payload` body into the frame's body of the robot's MJCF. The tensor is
/// [`mjcf_inertia`]'s (a comment says when it moved).
pub fn mjcf(p: &Payload, frame: &str, header: &[String]) -> String {
    let (i, moved) = mjcf_inertia(p);
    let mut c = comments(header, "<!-- ", " -->");
    let _ = writeln!(c, "<!-- centre of mass and inertia in the {frame} frame's axes -->");
    if moved > 0.0 {
        let _ = writeln!(
            c,
            "<!-- the identified inertia lies on the triangle-inequality boundary (a flat body): moved by at most {moved:.1e} kg·m² so that A + B >= C holds with a relative margin of {TRIANGLE_MARGIN:e} (MuJoCo refuses it otherwise) -->"
        );
    }
    format!(
        r#"{c}<mujoco model="payload">
  <worldbody>
    <body name="{frame}">
      <body name="payload">
        <inertial pos="{x} {y} {z}" mass="{m}" fullinertia="{ixx} {iyy} {izz} {ixy} {ixz} {iyz}"/>
      </body>
    </body>
  </worldbody>
</mujoco>
"#,
        x = num(p.com[0]),
        y = num(p.com[1]),
        z = num(p.com[2]),
        m = num(p.mass),
        ixx = num(i[0]),
        iyy = num(i[3]),
        izz = num(i[5]),
        ixy = num(i[1]),
        ixz = num(i[2]),
        iyz = num(i[4])
    )
}

/// `payload.toml`: the `[payload]` table of idexp's excite and simulate
/// designs (the robot then carries the identified payload).
pub fn idexp_table(p: &Payload, frame: &str, header: &[String]) -> crate::error::Result<String> {
    let spec = crate::robot::payload::PayloadSpec {
        frame: Some(frame.to_string()),
        mass: p.mass,
        com: p.com,
        inertia: p.inertia,
    };
    #[derive(Serialize)]
    struct Table<'a> {
        payload: &'a crate::robot::payload::PayloadSpec,
    }
    let body = toml::to_string(&Table { payload: &spec }).map_err(|e| crate::error::Error::Numerical(e.to_string()))?;
    let mut s = comments(header, "# ", "");
    let _ = writeln!(s, "# paste into an idexp excite or simulate design: the robot then carries this payload");
    s.push_str(&body);
    Ok(s)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Payload {
        Payload {
            mass: 1.75,
            com: [0.012, -0.004, 0.071],
            inertia: [0.0081, 0.0007, -0.0004, 0.0064, 0.0011, 0.0042],
        }
    }

    #[test]
    fn kuka_principal_axes_recompose_the_tensor() {
        let p = sample();
        let text = kuka(&p, 1, "tool0", &["test".into()]);
        let k = parse_kuka(&text).unwrap();
        assert_eq!(k.m, p.mass);
        for i in 0..3 {
            assert!((k.xyz_mm[i] - 1000.0 * p.com[i]).abs() < 1e-5);
        }
        // KRL's 7 digits: the principal data re-compose the tensor to ~1e-6 relative
        let t = tensor_from_kuka(k.abc_deg, k.j);
        let e = (t - p.inertia_matrix()).abs().max();
        assert!(e < 1e-6 * p.inertia_matrix().abs().max(), "recomposed tensor off by {e}");
        // the full-precision principal data re-compose it exactly
        let pr = principal(&p);
        assert!((tensor_from_kuka(pr.abc_deg, pr.moments) - p.inertia_matrix()).abs().max() < 1e-12);
        // a diagonal tensor gives zero angles and JX, JY, JZ = Ixx, Iyy, Izz
        let d = Payload {
            inertia: [0.01, 0.0, 0.0, 0.02, 0.0, 0.03],
            ..p
        };
        let pr = principal(&d);
        assert!(pr.abc_deg.iter().all(|a| a.abs() < 1e-9), "{:?}", pr.abc_deg);
        assert_eq!(pr.moments, [0.01, 0.02, 0.03]);
    }

    #[test]
    fn krl_reals_have_at_most_seven_significant_digits() {
        for (v, want) in [
            (1.80019012345, "1.80019"),
            (11.8412345678, "11.84123"),
            (-0.0018173456789, "-0.001817346"),
            (9.99999996, "10.0"),
            (-20.85, "-20.85"),
            (0.0, "0.0"),
            (-1e-17, "0.0"),
            (2.5e-9, "0.0000000025"),
            (123456789.0, "123456800.0"),
        ] {
            assert_eq!(krl_real(v), want, "{v}");
        }
    }

    #[test]
    fn mjcf_inertia_moves_only_a_boundary_tensor() {
        let p = sample();
        assert_eq!(mjcf_inertia(&p), (p.inertia, 0.0));
        // a flat body (point masses in the z = 0 plane): Izz = Ixx + Iyy, then 1e-12 beyond it
        let flat = Payload {
            inertia: [0.004, 0.001, 0.0, 0.006, 0.0, 0.010 + 1e-12],
            ..p
        };
        let (i, moved) = mjcf_inertia(&flat);
        assert!(moved > 0.0 && moved < 1e-10, "{moved}");
        let m = Matrix3::new(i[0], i[1], i[2], i[1], i[3], i[4], i[2], i[4], i[5]);
        let e = SymmetricEigen::new(m).eigenvalues;
        let (a, b, c) = (e[0], e[1], e[2]);
        let slack = [a + b - c, a + c - b, b + c - a];
        // the margin is met to the rounding of the eigen-decomposition (δ solves it with equality)
        assert!(slack.iter().all(|s| *s >= 0.999 * TRIANGLE_MARGIN * (a + b + c)), "{slack:?}");
    }

    #[test]
    fn idexp_table_reads_back_as_the_payload_spec() {
        let p = sample();
        #[derive(serde::Deserialize)]
        struct T {
            payload: crate::robot::payload::PayloadSpec,
        }
        let t: T = toml::from_str(&idexp_table(&p, "tool0", &["h".into()]).unwrap()).unwrap();
        let back = Payload::from_spec(&t.payload, "t", "payload").unwrap();
        assert_eq!(back, p);
        assert_eq!(t.payload.frame.as_deref(), Some("tool0"));
    }

    #[test]
    fn franka_inertia_is_column_major() {
        let p = sample();
        let f = franka(&p, "tool0");
        // column-major = row-major for a symmetric tensor; the off-diagonal positions are the check
        assert_eq!(f.load_inertia[1], p.inertia[1]); // (1, 0) = Ixy
        assert_eq!(f.load_inertia[5], p.inertia[4]); // (2, 1) = Iyz
        assert_eq!(f.load_inertia[6], p.inertia[2]); // (0, 2) = Ixz
        assert_eq!(f.f_x_cload, p.com);
    }
}
