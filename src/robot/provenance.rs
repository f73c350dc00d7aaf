//! Where a robot model came from, beyond its numbers (`idexp robot info`):
//! what of its URDF is not part of the model and why (joints off the chain
//! to `tip_link`, `<mimic>` groups such as a gripper's fingers, locked), and
//! the file each link's collision geometry was read from.

use super::collision::ShapeSpec;
use super::resolve::MeshResolver;
use super::urdf::{load_collision, load_urdf, CollisionSource};
use crate::error::Result;
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// What [`provenance`] tells about a robot file.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Provenance {
    /// What of the URDF is not in the model, one sentence each (empty: all of it is).
    pub left_out: Vec<String>,
    /// Every collision shape: the body it belongs to, where it is written,
    /// and for a mesh the name as written and the file read.
    pub collision: Vec<CollisionSource>,
}

/// The keys of a robot file that say where its parts come from (the others
/// are read by [`super::load`]).
#[derive(Debug, Deserialize)]
struct Sources {
    urdf: Option<String>,
    base_link: Option<String>,
    tip_link: Option<String>,
    #[serde(default)]
    mesh_path: Vec<String>,
    #[serde(default)]
    collision: Vec<ShapeEntry>,
}

#[derive(Debug, Deserialize)]
struct ShapeEntry {
    link: String,
    shape: ShapeSpec,
}

fn shape_name(s: &ShapeSpec) -> &'static str {
    match s {
        ShapeSpec::Box { .. } => "box",
        ShapeSpec::Cylinder { .. } => "cylinder",
        ShapeSpec::Capsule { .. } => "capsule",
        ShapeSpec::Sphere { .. } => "sphere",
        ShapeSpec::Plane { .. } => "plane",
        ShapeSpec::Mesh { .. } => "mesh",
    }
}

/// What of a robot file's URDF is left out of the model, and where each
/// collision shape comes from (a `.urdf` or a `.toml` robot file; the file is
/// read again, so call it after [`super::load`] succeeded on it).
pub fn provenance(path: &Path) -> Result<Provenance> {
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
    let dir = path.parent().unwrap_or(Path::new("."));
    let (urdf, base, tip, mesh_path, shapes) = if ext == "toml" {
        let f: Sources = toml::from_str(&crate::io::read_to_string(path)?).map_err(|e| crate::Error::parse(path, e.message().to_string()))?;
        let urdf = match &f.urdf {
            Some(u) => Some(crate::io::design_path(path, "urdf", Path::new(u))?),
            None => None,
        };
        let mp: Vec<PathBuf> = f.mesh_path.iter().map(|m| dir.join(m)).collect();
        (urdf, f.base_link, f.tip_link, mp, f.collision)
    } else {
        (Some(path.to_path_buf()), None, None, Vec::new(), Vec::new())
    };
    let mut out = Provenance {
        left_out: Vec::new(),
        collision: Vec::new(),
    };
    if let Some(u) = urdf {
        let parts = load_urdf(&u, base.as_deref(), tip.as_deref())?;
        let resolver = MeshResolver::new(u.parent().unwrap_or(Path::new(".")), &mesh_path);
        let g = load_collision(&u, &parts, base.as_deref(), &resolver, super::collision::MeshMode::Hull)?;
        out.left_out = parts.left_out;
        out.collision = g.sources;
    }
    for (k, c) in shapes.iter().enumerate() {
        let (uri, file) = match &c.shape {
            ShapeSpec::Mesh { file, .. } => (Some(file.display().to_string()), Some(dir.join(file))),
            _ => (None, None),
        };
        let problem = file.as_ref().filter(|f| !f.is_file()).map(|f| format!("no file {}", f.display()));
        out.collision.push(CollisionSource {
            body: c.link.clone(),
            link: c.link.clone(),
            written_in: format!("robot file [[collision]] {}", k + 1),
            shape: shape_name(&c.shape).into(),
            uri,
            file: file.filter(|f| f.is_file()),
            problem,
        });
    }
    Ok(out)
}

impl Provenance {
    /// The text `robot info` prints: what was left out, then one line per
    /// collision shape (a mesh with the file it was read from).
    pub fn text(&self) -> String {
        use std::fmt::Write;
        let mut s = String::new();
        if !self.left_out.is_empty() {
            let _ = writeln!(s, "\nLeft out of the model:");
            for l in &self.left_out {
                let _ = writeln!(s, "  {l}");
            }
        }
        if !self.collision.is_empty() {
            let _ = writeln!(s, "\nCollision geometry (body: link, where written, shape, file):");
            for c in &self.collision {
                let what = match (&c.file, &c.uri, &c.problem) {
                    (_, Some(uri), Some(p)) => format!("`{uri}` NOT LOADED: {p}"),
                    (Some(f), Some(uri), None) if uri != &f.display().to_string() => format!("{} (from `{uri}`)", f.display()),
                    (Some(f), _, None) => f.display().to_string(),
                    (None, None, Some(p)) => format!("NOT LOADED: {p}"),
                    _ => String::new(),
                };
                let _ = writeln!(s, "  {}: {}, {}, {} {what}", c.body, c.link, c.written_in, c.shape);
            }
        }
        s
    }
}
