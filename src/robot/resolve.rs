//! Mesh file names of robot descriptions, resolved as ROS tools resolve them,
//! and mesh files read (STL, Wavefront OBJ, Collada) by `mesh-loader`.
//!
//! A URDF names its meshes as
//!
//! * `package://PKG/path/in/package.stl`: the package PKG is looked up, in
//!   this order, in
//!   1. `ROS_PACKAGE_PATH` (ROS 1, `rospack`): each folder is a package (its
//!      `package.xml` names PKG, or its name is PKG) or holds packages below
//!      it (searched down to [`CRAWL_DEPTH`] levels, hidden folders and those
//!      with a `CATKIN_IGNORE`, `COLCON_IGNORE` or `AMENT_IGNORE` skipped, a
//!      package's own subfolders not entered). A package is found by its
//!      `package.xml` name or by its folder's name: example-robot-data's
//!      `package.xml` says `example_robot_descriptions` while its URIs (and
//!      its install folder `share/example-robot-data`) say `example-robot-data`;
//!   2. `AMENT_PREFIX_PATH` (ROS 2, the ament index): `<prefix>/share/PKG`;
//!   3. the folder holding the URDF and every folder above it: a folder named
//!      PKG, a folder whose `package.xml` names PKG, or a folder holding a
//!      package folder PKG (`PKG/package.xml`, a sibling package of a source
//!      workspace, or `share/PKG` of an install prefix);
//!   4. the robot file's `mesh_path` folders (idexp's own key: the longest
//!      tail of `PKG/path/in/package.stl` that exists below one of them).
//!
//!   The first package folder that holds the file wins; when none does, the
//!   error lists every folder searched.
//! * `file:///absolute/path.stl` or `file://relative/path.stl` (relative to
//!   the URDF's folder), or a plain path (absolute, or relative to the URDF's
//!   folder, then below `mesh_path`).
//!
//! Other schemes (`model://`, `http://`) are refused with the scheme named.

use crate::error::{Error, Result};
use nalgebra::Point3;
use std::path::{Path, PathBuf};

/// How deep below a `ROS_PACKAGE_PATH` entry packages are searched.
pub const CRAWL_DEPTH: usize = 4;

/// Most folders visited below one `ROS_PACKAGE_PATH` entry.
const CRAWL_MAX_DIRS: usize = 20_000;

/// Largest mesh file read (bytes).
pub const MAX_MESH_BYTES: u64 = 512 << 20;

/// The package search folders of the environment (`ROS_PACKAGE_PATH`,
/// `AMENT_PREFIX_PATH`).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PackageSearch {
    /// `ROS_PACKAGE_PATH` entries (`None`: the variable is not set).
    pub ros_package_path: Option<Vec<PathBuf>>,
    /// `AMENT_PREFIX_PATH` entries (`None`: not set).
    pub ament_prefix_path: Option<Vec<PathBuf>>,
}

fn split_env(name: &str) -> Option<Vec<PathBuf>> {
    std::env::var_os(name).map(|v| std::env::split_paths(&v).filter(|p| !p.as_os_str().is_empty()).collect())
}

impl PackageSearch {
    /// The search folders of this process's environment.
    pub fn from_env() -> PackageSearch {
        PackageSearch {
            ros_package_path: split_env("ROS_PACKAGE_PATH"),
            ament_prefix_path: split_env("AMENT_PREFIX_PATH"),
        }
    }
}

/// Resolves the mesh names of one robot description.
#[derive(Debug, Clone)]
pub struct MeshResolver {
    /// Folder of the URDF (or of the robot file naming a mesh).
    pub urdf_dir: PathBuf,
    /// The robot file's `mesh_path` folders (absolute or relative to the working folder).
    pub mesh_path: Vec<PathBuf>,
    /// `ROS_PACKAGE_PATH` and `AMENT_PREFIX_PATH`.
    pub packages: PackageSearch,
}

/// The `<name>` of a `package.xml`.
#[derive(serde::Deserialize)]
struct PackageXml {
    name: String,
}

/// The package name declared by `dir/package.xml`, if there is one.
pub fn package_name(dir: &Path) -> Option<String> {
    let p = dir.join("package.xml");
    let meta = std::fs::metadata(&p).ok()?;
    if !meta.is_file() || meta.len() > 1 << 20 {
        return None;
    }
    let text = std::fs::read_to_string(&p).ok()?;
    quick_xml::de::from_str::<PackageXml>(&text).ok().map(|x| x.name.trim().to_string())
}

fn is_package(dir: &Path, pkg: &str) -> bool {
    package_name(dir).as_deref() == Some(pkg)
}

fn list(v: &[PathBuf]) -> String {
    v.iter().map(|p| p.display().to_string()).collect::<Vec<_>>().join(", ")
}

/// Breadth-first search for a package named `pkg` below `root`.
fn crawl(root: &Path, pkg: &str) -> Option<PathBuf> {
    let mut level = vec![root.to_path_buf()];
    let mut visited = 0usize;
    for _ in 0..=CRAWL_DEPTH {
        let mut next = Vec::new();
        for d in level {
            visited += 1;
            if visited > CRAWL_MAX_DIRS {
                return None;
            }
            if d.join("package.xml").is_file() {
                if d.file_name().is_some_and(|n| n == pkg) || is_package(&d, pkg) {
                    return Some(d);
                }
                continue; // a package's subfolders hold no other package
            }
            if ["CATKIN_IGNORE", "COLCON_IGNORE", "AMENT_IGNORE"].iter().any(|f| d.join(f).exists()) {
                continue;
            }
            let Ok(rd) = std::fs::read_dir(&d) else { continue };
            let mut subs: Vec<PathBuf> = rd
                .filter_map(|e| e.ok())
                .filter(|e| e.path().is_dir()) // links to folders followed, as rospack does
                .filter(|e| !e.file_name().to_string_lossy().starts_with('.'))
                .map(|e| e.path())
                .collect();
            subs.sort();
            next.extend(subs);
        }
        level = next;
    }
    None
}

/// The candidate folders of package `pkg` in search order, each with where it came from.
fn package_candidates(r: &MeshResolver, pkg: &str) -> Vec<(PathBuf, &'static str)> {
    let mut out: Vec<(PathBuf, &'static str)> = Vec::new();
    let mut push = |p: PathBuf, from: &'static str| {
        if !out.iter().any(|(q, _)| *q == p) {
            out.push((p, from));
        }
    };
    for e in r.packages.ros_package_path.iter().flatten() {
        if is_package(e, pkg) || (e.file_name().is_some_and(|n| n == pkg) && e.is_dir()) {
            push(e.clone(), "ROS_PACKAGE_PATH");
        } else if let Some(p) = crawl(e, pkg) {
            push(p, "ROS_PACKAGE_PATH");
        }
    }
    for prefix in r.packages.ament_prefix_path.iter().flatten() {
        let p = prefix.join("share").join(pkg);
        if p.is_dir() {
            push(p, "AMENT_PREFIX_PATH");
        }
    }
    let start = std::path::absolute(&r.urdf_dir).unwrap_or_else(|_| r.urdf_dir.clone());
    for a in start.ancestors() {
        if (a.file_name().is_some_and(|n| n == pkg) && a.is_dir()) || is_package(a, pkg) {
            push(a.to_path_buf(), "the URDF's folder");
        } else if a.join(pkg).join("package.xml").is_file() {
            push(a.join(pkg), "the URDF's folder");
        } else if a.join("share").join(pkg).join("package.xml").is_file() {
            push(a.join("share").join(pkg), "the URDF's folder");
        }
    }
    out
}

/// The longest tail of `rel` that exists as a file below one of `dirs`.
fn below(dirs: &[PathBuf], rel: &Path) -> Option<PathBuf> {
    let comps: Vec<&std::ffi::OsStr> = rel.iter().collect();
    for dir in dirs {
        for start in 0..comps.len() {
            let mut p = dir.clone();
            for c in &comps[start..] {
                p.push(c);
            }
            if p.is_file() {
                return Some(p);
            }
        }
    }
    None
}

impl MeshResolver {
    /// A resolver for a URDF in `urdf_dir`, with the environment's package
    /// folders and the robot file's `mesh_path`.
    pub fn new(urdf_dir: &Path, mesh_path: &[PathBuf]) -> MeshResolver {
        MeshResolver {
            urdf_dir: urdf_dir.to_path_buf(),
            mesh_path: mesh_path.to_vec(),
            packages: PackageSearch::from_env(),
        }
    }

    /// The root folder of package `pkg`, as [`resolve`](Self::resolve) finds it first.
    pub fn package_root(&self, pkg: &str) -> Option<PathBuf> {
        package_candidates(self, pkg).into_iter().next().map(|(p, _)| p)
    }

    fn mesh_path_text(&self) -> String {
        if self.mesh_path.is_empty() {
            "the robot file's mesh_path (none given)".into()
        } else {
            format!("below the robot file's mesh_path [{}]", list(&self.mesh_path))
        }
    }

    /// The file a mesh name (`package://`, `file://` or a path) stands for,
    /// or an error that names the name and every folder searched.
    pub fn resolve(&self, uri: &str) -> std::result::Result<PathBuf, String> {
        if let Some(rest) = uri.strip_prefix("package://") {
            let (pkg, rel) = rest.split_once('/').unwrap_or((rest, ""));
            if pkg.is_empty() || rel.is_empty() {
                return Err(format!("`{uri}` is not a package URI: expected package://PACKAGE/path/to/file"));
            }
            let relp = Path::new(rel);
            let cands = package_candidates(self, pkg);
            for (root, _) in &cands {
                let p = root.join(relp);
                if p.is_file() {
                    return Ok(p);
                }
            }
            if let Some(p) = below(&self.mesh_path, Path::new(rest)) {
                return Ok(p);
            }
            let env = |name: &str, v: &Option<Vec<PathBuf>>| match v {
                None => format!("{name} (not set)"),
                Some(v) if v.is_empty() => format!("{name} (empty)"),
                Some(v) => format!("{name} [{}]", list(v)),
            };
            let found = if cands.is_empty() {
                format!("package `{pkg}` found nowhere")
            } else {
                format!(
                    "package `{pkg}` found at {} but `{rel}` is not there",
                    cands
                        .iter()
                        .map(|(p, from)| format!("{} (from {from})", p.display()))
                        .collect::<Vec<_>>()
                        .join(", ")
                )
            };
            let start = std::path::absolute(&self.urdf_dir).unwrap_or_else(|_| self.urdf_dir.clone());
            return Err(format!(
                "not found: {found}; searched {}, {} (as <prefix>/share/{pkg}), the URDF's folder {} and the folders above it (a folder named `{pkg}`, or with a package.xml naming it, or holding {pkg}/package.xml or share/{pkg}), and {}; set ROS_PACKAGE_PATH to the package folder `{pkg}` or a folder at most {CRAWL_DEPTH} levels above it, or AMENT_PREFIX_PATH to the install prefix holding share/{pkg} (or source the workspace's setup script), or give the robot file a mesh_path naming the package folder or the folder holding it",
                env("ROS_PACKAGE_PATH", &self.packages.ros_package_path),
                env("AMENT_PREFIX_PATH", &self.packages.ament_prefix_path),
                start.display(),
                self.mesh_path_text(),
            ));
        }
        let plain = match uri.strip_prefix("file://") {
            Some(p) => p,
            None => {
                if let Some((scheme, _)) = uri.split_once("://") {
                    return Err(format!(
                        "`{uri}`: the URI scheme `{scheme}://` is not read; expected package://, file:// or a file path"
                    ));
                }
                uri
            }
        };
        if plain.is_empty() {
            return Err("an empty mesh file name".into());
        }
        let relp = Path::new(plain);
        let direct = if relp.is_absolute() { relp.to_path_buf() } else { self.urdf_dir.join(relp) };
        if direct.is_file() {
            return Ok(direct);
        }
        if !relp.is_absolute() {
            if let Some(p) = below(&self.mesh_path, relp) {
                return Ok(p);
            }
        }
        Err(format!("not found: no file {}, nor {}", direct.display(), self.mesh_path_text()))
    }
}

/// Vertices and triangles of a mesh.
pub type MeshData = (Vec<Point3<f64>>, Vec<[u32; 3]>);

/// Reads the vertices and triangles of a mesh file, scaled per axis: STL
/// (binary or ASCII), Wavefront OBJ or Collada (`.dae`), by its extension,
/// every mesh of the file merged (read by the `mesh-loader` crate).
pub fn read_mesh(path: &Path, scale: [f64; 3]) -> Result<MeshData> {
    let meta = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    if !meta.is_file() {
        return Err(Error::parse(path, "not a regular file"));
    }
    if meta.len() > MAX_MESH_BYTES {
        return Err(Error::parse(
            path,
            format!("mesh of {} bytes is larger than the {} MiB allowed", meta.len(), MAX_MESH_BYTES >> 20),
        ));
    }
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
    if !matches!(ext.as_str(), "stl" | "obj" | "dae") {
        return Err(Error::parse(
            path,
            format!("mesh format `.{ext}` is not read: expected .stl, .obj or .dae (Collada)"),
        ));
    }
    let scene = mesh_loader::Loader::default()
        .merge_meshes(true)
        .load(path)
        .map_err(|e| Error::parse(path, format!("not a readable .{ext} mesh: {e}")))?;
    let mut pts = Vec::new();
    let mut tris = Vec::new();
    for m in &scene.meshes {
        let base = pts.len() as u32;
        pts.extend(
            m.vertices
                .iter()
                .map(|v| Point3::new(v[0] as f64 * scale[0], v[1] as f64 * scale[1], v[2] as f64 * scale[2])),
        );
        tris.extend(m.faces.iter().map(|f| [f[0] + base, f[1] + base, f[2] + base]));
    }
    if let Some(k) = pts.iter().position(|p| !(p.x.is_finite() && p.y.is_finite() && p.z.is_finite())) {
        return Err(Error::parse(path, format!("vertex {} is not finite", k + 1)));
    }
    if let Some(k) = tris.iter().position(|t| t.iter().any(|&i| i as usize >= pts.len())) {
        return Err(Error::parse(path, format!("triangle {} names a vertex that does not exist", k + 1)));
    }
    if pts.len() < 4 {
        return Err(Error::parse(path, format!("a mesh needs at least 4 vertices, found {}", pts.len())));
    }
    Ok((pts, tris))
}
