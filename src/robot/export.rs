//! Writers of identified models: a URDF with new inertials (everything else
//! copied byte for byte from the input URDF) and a robot TOML with new drive
//! parameters (and, for DH robots, new inertials), both read back by
//! [`crate::robot::load`]; and the physical-consistency check of a robot's
//! inertials ([`inertial_warnings`]).

use crate::error::{Error, Result};
use crate::robot::{Friction, Inertial, Robot};
use nalgebra::{Matrix3, Matrix4, SymmetricEigen};
use quick_xml::events::Event;
use std::path::{Path, PathBuf};

pub use super::mjcf::{mjcf_string, write_mjcf};

/// Where a robot's geometry and inertia came from.
#[derive(Debug, Clone, PartialEq)]
pub enum Source {
    /// A URDF (`urdf`), given directly or referenced by a robot TOML (`toml`).
    Urdf {
        /// The URDF file.
        urdf: PathBuf,
        /// The robot TOML that references it, if any.
        toml: Option<PathBuf>,
    },
    /// A DH table in a robot TOML.
    Dh {
        /// The robot TOML.
        toml: PathBuf,
    },
}

/// The source of the robot file `path` (`.urdf`, or a `.toml` with `urdf = ...` or `dh = ...`).
pub fn source_of(path: &Path) -> Result<Source> {
    if path.extension().is_some_and(|e| e == "urdf") {
        return Ok(Source::Urdf {
            urdf: path.to_path_buf(),
            toml: None,
        });
    }
    let text = crate::io::read_to_string(path)?;
    let t: toml::Table = text.parse().map_err(|e: toml::de::Error| Error::parse(path, e.to_string()))?;
    match t.get("urdf").and_then(|v| v.as_str()) {
        Some(u) => Ok(Source::Urdf {
            urdf: path.parent().unwrap_or(Path::new(".")).join(u),
            toml: Some(path.to_path_buf()),
        }),
        None => Ok(Source::Dh { toml: path.to_path_buf() }),
    }
}

/// The `<inertial>` element of an inertial (link frame): mass, centre of mass
/// and the inertia about it in link axes (zero mass: the inertia about the origin).
/// Centre of mass and inertia about it (link axes) of an inertial given about
/// the link origin; zero mass: the origin and the inertia about it.
pub(crate) fn com_inertia(ine: &Inertial) -> (nalgebra::Vector3<f64>, Matrix3<f64>) {
    let m = ine.mass;
    if m > 0.0 {
        let c = ine.first_moment / m;
        (c, ine.inertia - m * (c.norm_squared() * Matrix3::identity() - c * c.transpose()))
    } else {
        (nalgebra::Vector3::zeros(), ine.inertia)
    }
}

fn inertial_xml(ine: &Inertial, indent: &str) -> String {
    let m = ine.mass;
    let (c, ic) = com_inertia(ine);
    format!(
        "<inertial>\n{indent}  <origin xyz=\"{} {} {}\" rpy=\"0 0 0\"/>\n{indent}  <mass value=\"{m}\"/>\n{indent}  <inertia ixx=\"{}\" ixy=\"{}\" ixz=\"{}\" iyy=\"{}\" iyz=\"{}\" izz=\"{}\"/>\n{indent}</inertial>",
        c.x,
        c.y,
        c.z,
        ic[(0, 0)],
        ic[(0, 1)],
        ic[(0, 2)],
        ic[(1, 1)],
        ic[(1, 2)],
        ic[(2, 2)]
    )
}

/// The URDF text `text` (file `path`, for messages) with the inertials of
/// `robot`'s moving links: each moving link's `<inertial>` is replaced (or
/// inserted) by the identified one, which lumps the fixed links merged into
/// it (their own `<inertial>` blocks are removed, so the model is counted
/// once). Everything else is copied byte for byte.
pub fn urdf_with_inertials(path: &Path, text: &str, robot: &Robot) -> Result<String> {
    let merged: Vec<&str> = robot.frames.iter().filter(|f| f.link.is_some()).map(|f| f.name.as_str()).collect();
    let mut reader = quick_xml::Reader::from_str(text);
    // edits: (start, end, replacement)
    let mut edits: Vec<(usize, usize, String)> = Vec::new();
    let mut link: Option<(String, bool)> = None; // (name, saw inertial)
    let mut inertial_start = 0usize;
    loop {
        let before = reader.buffer_position() as usize;
        let ev = reader.read_event().map_err(|e| Error::parse(path, format!("XML at byte {before}: {e}")))?;
        let after = reader.buffer_position() as usize;
        let name_of = |e: &quick_xml::events::BytesStart| -> Option<String> {
            e.try_get_attribute("name")
                .ok()
                .flatten()
                .and_then(|a| a.unescape_value().ok().map(|v| v.into_owned()))
        };
        match ev {
            Event::Start(e) if e.name().as_ref() == b"link" => link = name_of(&e).map(|n| (n, false)),
            Event::Empty(e) if e.name().as_ref() == b"link" => {
                if let Some(n) = name_of(&e) {
                    if let Some(i) = robot.links.iter().position(|l| l.name == n) {
                        let tag = &text[before..after];
                        let open = tag.trim_end_matches("/>").trim_end();
                        edits.push((
                            before,
                            after,
                            format!("{open}>\n    {}\n  </link>", inertial_xml(&robot.links[i].inertial, "    ")),
                        ));
                    }
                }
            }
            Event::Start(e) if e.name().as_ref() == b"inertial" && link.is_some() => inertial_start = before,
            Event::Empty(e) if e.name().as_ref() == b"inertial" && link.is_some() => {
                inertial_start = before;
                if let Some((n, saw)) = link.as_mut() {
                    *saw = true;
                    replace_inertial(robot, &merged, n, inertial_start, after, &mut edits);
                }
            }
            Event::End(e) if e.name().as_ref() == b"inertial" => {
                if let Some((n, saw)) = link.as_mut() {
                    *saw = true;
                    replace_inertial(robot, &merged, n, inertial_start, after, &mut edits);
                }
            }
            Event::End(e) if e.name().as_ref() == b"link" => {
                if let Some((n, saw)) = link.take() {
                    if !saw {
                        if let Some(i) = robot.links.iter().position(|l| l.name == n) {
                            edits.push((before, before, format!("  {}\n  ", inertial_xml(&robot.links[i].inertial, "    "))));
                        }
                    }
                }
            }
            Event::Eof => break,
            _ => {}
        }
    }
    let missing: Vec<&str> = robot
        .links
        .iter()
        .map(|l| l.name.as_str())
        .filter(|n| !text.contains(&format!("name=\"{n}\"")) && !text.contains(&format!("name='{n}'")))
        .collect();
    if !missing.is_empty() {
        return Err(Error::invalid(
            path.display().to_string(),
            "link",
            format!("the URDF has no link named {missing:?}: it is not the URDF the robot was built from"),
        ));
    }
    let mut out = String::with_capacity(text.len() + 1024);
    let mut pos = 0;
    edits.sort_by_key(|e| e.0);
    for (a, b, r) in edits {
        out.push_str(&text[pos..a]);
        out.push_str(&r);
        pos = b;
    }
    out.push_str(&text[pos..]);
    Ok(out)
}

fn replace_inertial(robot: &Robot, merged: &[&str], link: &str, a: usize, b: usize, edits: &mut Vec<(usize, usize, String)>) {
    if let Some(i) = robot.links.iter().position(|l| l.name == link) {
        edits.push((a, b, inertial_xml(&robot.links[i].inertial, "    ")));
    } else if merged.contains(&link) {
        edits.push((a, b, "<!-- inertial lumped into its moving parent link by the idexp identify export -->".into()));
    }
}

/// Writes `robot.urdf` (the source URDF with `robot`'s inertials) into `dir`.
/// A DH robot has no URDF to copy the kinematics from: the error says to
/// export the TOML instead.
pub fn write_urdf(src: &Source, robot: &Robot, dir: &Path) -> Result<PathBuf> {
    match src {
        Source::Dh { toml } => Err(Error::invalid(
            toml.display().to_string(),
            "dh",
            "this robot is a DH table, not a URDF: there is no URDF to copy the kinematics from; export \"toml\" (robot.toml: the DH table with the identified inertials and drives)",
        )),
        Source::Urdf { urdf, .. } => {
            let text = crate::io::read_to_string(urdf)?;
            let out = urdf_with_inertials(urdf, &text, robot)?;
            let p = dir.join("robot.urdf");
            crate::io::write_atomic(&p, out.as_bytes())?;
            Ok(p)
        }
    }
}

/// The drive entries of `robot` as TOML tables (`joint`, `ia`, friction terms).
fn drive_tables(robot: &Robot, old: Option<&toml::value::Array>) -> toml::value::Array {
    let mut out = toml::value::Array::new();
    for (i, d) in robot.drives.iter().enumerate() {
        let jn = &robot.joints[i].name;
        let mut t = old
            .and_then(|a| a.iter().find(|v| v.get("joint").and_then(|x| x.as_str()) == Some(jn.as_str())))
            .and_then(|v| v.as_table().cloned())
            .unwrap_or_default();
        t.insert("joint".into(), jn.clone().into());
        for k in [
            "ia", "fc", "fv", "f0", "fc_pos", "fc_neg", "fv_pos", "fv_neg", "friction", "fs", "fs_pos", "fs_neg",
        ] {
            t.remove(k);
        }
        let params = super::dynamics::drive_params(d);
        if let Some(ia) = d.rotor_inertia {
            t.insert("ia".into(), ia.into());
        }
        let name = match d.friction {
            Friction::None => "none",
            Friction::Symmetric { .. } => "symmetric",
            Friction::Asymmetric { .. } => "asymmetric",
        };
        t.insert("friction".into(), name.into());
        for &(k, v) in params.friction() {
            t.insert(k.drive_key().expect("a drive parameter").into(), v.into());
        }
        out.push(toml::Value::Table(t));
    }
    out
}

/// `target` as a path relative to the folder `dir` (both made absolute,
/// symbolic links resolved where they exist); absolute if there is no such path.
fn relative_to(dir: &Path, target: &Path) -> String {
    let abs = |p: &Path| std::fs::canonicalize(p).or_else(|_| std::path::absolute(p)).unwrap_or_else(|_| p.to_path_buf());
    let (d, t) = (abs(dir), abs(target));
    match pathdiff::diff_paths(&t, &d) {
        Some(r) if r.as_os_str().is_empty() => ".".into(),
        Some(r) => r.display().to_string(),
        None => t.display().to_string(),
    }
}

/// The folders that resolve the `<collision>` mesh names of the URDF `urdf`
/// (with the robot file's `mesh_path`): for each name found, the file's path
/// without the name's package-relative part (a package's folder, or the
/// URDF's folder for a relative name), so that the names resolve below them
/// from anywhere. Names not found add nothing.
fn mesh_roots(urdf: &Path, mesh_path: &[PathBuf]) -> Vec<PathBuf> {
    let Ok(text) = crate::io::read_to_string(urdf) else { return Vec::new() };
    let Ok(u) = urdf_rs::read_from_string(&text) else { return Vec::new() };
    let resolver = super::resolve::MeshResolver::new(urdf.parent().unwrap_or(Path::new(".")), mesh_path);
    let mut roots: Vec<PathBuf> = Vec::new();
    for l in &u.links {
        for c in &l.collision {
            let urdf_rs::Geometry::Mesh { filename, .. } = &c.geometry else { continue };
            let rel = match filename.strip_prefix("package://") {
                Some(r) => r.split_once('/').map_or("", |(_, r)| r),
                None => filename.strip_prefix("file://").unwrap_or(filename),
            };
            if Path::new(rel).is_absolute() || rel.is_empty() {
                continue;
            }
            // a name resolved through mesh_path's longest-tail search is found there again
            if let Some(f) = resolver.resolve(filename).ok().filter(|f| f.ends_with(rel)) {
                if let Some(root) = f.ancestors().nth(Path::new(rel).components().count()) {
                    if !roots.iter().any(|r| r == root) {
                        roots.push(root.to_path_buf());
                    }
                }
            }
        }
    }
    roots
}

/// The robot TOML of the identified `robot`, to be written into the folder
/// `dir`: the input robot TOML (if any) with new `[[drive]]` entries and, for
/// a DH robot, new `inertial` tables (about the link origin); for a URDF
/// robot it points at `urdf` (the exported URDF's name, or the source URDF:
/// an absolute path is written relative to `dir`). Everything else (limits,
/// coupling, frames, gravity) is copied from the input; the paths it names
/// (`mesh_path`, `srdf`, `[[collision]]` mesh files) are rewritten relative
/// to `dir`, and the folders that resolve the URDF's collision meshes
/// (ROS packages, the source URDF's folder) join `mesh_path`, so the file
/// loads from `dir` with its collision geometry.
pub fn robot_toml(src: &Source, robot: &Robot, urdf: Option<&str>, dir: &Path) -> Result<String> {
    let mut t: toml::Table = match src {
        Source::Urdf { toml: Some(p), .. } | Source::Dh { toml: p } => {
            let text = crate::io::read_to_string(p)?;
            text.parse().map_err(|e: toml::de::Error| Error::parse(p, e.to_string()))?
        }
        Source::Urdf { toml: None, .. } => {
            let mut t = toml::Table::new();
            t.insert("name".into(), robot.name.clone().into());
            t
        }
    };
    t.insert(
        "source".into(),
        format!("identified by idexp identify from {}", robot.source.replace('\n', " ")).into(),
    );
    // paths the input resolved against its own folder (mesh_path, SRDF,
    // [[collision]] mesh files) are rewritten relative to the folder written
    // to, so the exported file loads from there
    let src_dir = match src {
        Source::Urdf { toml: Some(p), .. } | Source::Dh { toml: p } => p.parent().map(Path::to_path_buf),
        Source::Urdf { toml: None, .. } => None,
    };
    let mut mesh_path: Vec<PathBuf> = Vec::new();
    if let Some(sd) = &src_dir {
        if let Some(toml::Value::Array(a)) = t.get("mesh_path") {
            mesh_path.extend(a.iter().filter_map(|v| v.as_str()).map(|x| sd.join(x)));
        }
        if let Some(toml::Value::String(x)) = t.get_mut("srdf") {
            *x = relative_to(dir, &sd.join(&*x));
        }
        if let Some(toml::Value::Array(shapes)) = t.get_mut("collision") {
            for c in shapes.iter_mut() {
                let shape = c.get_mut("shape").and_then(|s| s.as_table_mut());
                if let Some(toml::Value::String(f)) = shape.and_then(|s| s.get_mut("file")) {
                    *f = relative_to(dir, &sd.join(&*f));
                }
            }
        }
    }
    // the exported URDF keeps the source's mesh names: the package folders
    // (and the source URDF's folder) that resolved them join mesh_path
    if let Source::Urdf { urdf: u, .. } = src {
        for root in mesh_roots(u, &mesh_path) {
            if !mesh_path.contains(&root) {
                mesh_path.push(root);
            }
        }
    }
    if !mesh_path.is_empty() {
        let v: toml::value::Array = mesh_path.iter().map(|p| toml::Value::from(relative_to(dir, p))).collect();
        t.insert("mesh_path".into(), v.into());
    }
    if let Source::Urdf { .. } = src {
        let u = urdf.ok_or_else(|| Error::invalid("export", "urdf", "a URDF robot's TOML needs the exported URDF's name"))?;
        let u = if Path::new(u).is_absolute() {
            relative_to(dir, Path::new(u))
        } else {
            u.to_string()
        };
        t.insert("urdf".into(), u.into());
        if robot.coupling.is_some() && !t.contains_key("coupling") {
            let c = robot.coupling_matrix();
            let rows: toml::value::Array = c.row_iter().map(|r| toml::Value::Array(r.iter().map(|&x| x.into()).collect())).collect();
            t.insert("coupling".into(), rows.into());
        }
    } else if let Some(toml::Value::Array(joints)) = t.get_mut("joint") {
        for (i, j) in joints.iter_mut().enumerate() {
            if let (Some(tab), Some(l)) = (j.as_table_mut(), robot.links.get(i)) {
                let ine = &l.inertial;
                let mut it = toml::Table::new();
                let m = ine.mass;
                let c = if m > 0.0 { ine.first_moment / m } else { nalgebra::Vector3::zeros() };
                let io = &ine.inertia;
                it.insert("mass".into(), m.into());
                it.insert("com".into(), toml::Value::Array(vec![c.x.into(), c.y.into(), c.z.into()]));
                it.insert(
                    "inertia".into(),
                    toml::Value::Array(
                        [io[(0, 0)], io[(0, 1)], io[(0, 2)], io[(1, 1)], io[(1, 2)], io[(2, 2)]]
                            .iter()
                            .map(|&x| x.into())
                            .collect(),
                    ),
                );
                it.insert("inertia_at".into(), "origin".into());
                tab.insert("inertial".into(), toml::Value::Table(it));
            }
        }
    }
    let old = t.get("drive").and_then(|v| v.as_array()).cloned();
    t.insert("drive".into(), toml::Value::Array(drive_tables(robot, old.as_ref())));
    let body = toml::to_string(&t).map_err(|e| Error::invalid("export", "robot.toml", e.to_string()))?;
    Ok(format!(
        "# robot file written by idexp identify --export toml: identified drive parameters{}\n{body}",
        if matches!(src, Source::Dh { .. }) { " and inertials" } else { "" }
    ))
}

/// Writes `robot.toml` into `dir` (see [`robot_toml`]).
pub fn write_robot_toml(src: &Source, robot: &Robot, dir: &Path, urdf: Option<&str>) -> Result<PathBuf> {
    let p = dir.join("robot.toml");
    crate::io::write_atomic(&p, robot_toml(src, robot, urdf, dir)?.as_bytes())?;
    Ok(p)
}

/// Physical-consistency warnings about a robot's inertials: a negative-definite
/// pseudo-inertia (no mass distribution has these moments: a principal moment
/// about the centre of mass above the sum of the other two, a negative
/// moment, or inertia without mass) and a zero mass with a non-zero inertia.
/// Warnings, not errors: published models (the Robotics Toolbox's PUMA 560)
/// have them and simulate.
pub fn inertial_warnings(robot: &Robot) -> Vec<String> {
    let mut w = Vec::new();
    for l in &robot.links {
        let ine = &l.inertial;
        let h = ine.first_moment;
        let io = ine.inertia;
        let tr = 0.5 * io.trace();
        let j = Matrix4::new(
            tr - io[(0, 0)],
            -io[(0, 1)],
            -io[(0, 2)],
            h.x,
            -io[(1, 0)],
            tr - io[(1, 1)],
            -io[(1, 2)],
            h.y,
            -io[(2, 0)],
            -io[(2, 1)],
            tr - io[(2, 2)],
            h.z,
            h.x,
            h.y,
            h.z,
            ine.mass,
        );
        let emin = SymmetricEigen::new(j).eigenvalues.min();
        let scale = j.norm().max(1e-300);
        if ine.mass == 0.0 && io != Matrix3::zeros() {
            w.push(format!(
                "link `{}`: zero mass with a non-zero inertia tensor (a rotor-only body; physically inconsistent, accepted)",
                l.name
            ));
        } else if emin < -1e-9 * scale {
            w.push(format!(
                "link `{}`: physically inconsistent inertia: the pseudo-inertia has eigenvalue {emin:.3e} < 0 (a principal moment about the centre of mass exceeds the sum of the other two, or one is negative)",
                l.name
            ));
        }
    }
    w
}
