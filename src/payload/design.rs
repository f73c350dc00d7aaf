//! The payload-identification design file (`idexp payload identify payload.toml`).
//!
//! ```toml
//! name = "payload_ur5"            # output folder (default: the file stem)
//! robot = "robots/ur5.toml"       # the robot's model: nominal, or idexp's identified robot.toml
//! frame = "tool0"                 # the payload's frame (default: the end effector)
//! truth = "../out/sim_payload"    # optional: a simulated run whose design carries the true [payload]
//! export = ["urscript", "franka", "kuka", "urdf", "mjcf", "idexp"]   # default: all
//! kuka_tool = 1                   # n of KUKA's LOAD_DATA[n] (1 … 16; default 1)
//!
//! [guess]                         # optional prior guess (CAD, datasheet): decides what the motion leaves open
//! mass = 2.0
//! com = [0.0, 0.0, 0.06]
//! inertia = [0.006, 0.0, 0.0, 0.006, 0.0, 0.004]
//!
//! [[loaded]]                      # runs with the payload (any number; keys of a study's [[experiment]])
//! files = ["../out/sim_payload"]
//! harmonics = 12
//!
//! [[unloaded]]                    # optional: the same trajectories without it, paired by order
//! files = ["../out/sim_payload_unloaded"]
//! harmonics = 12
//! ```

use crate::error::{Error, Result};
use crate::ident::study::design::name_ok;
use crate::ident::study::{ExperimentSpec, WeightSource};
use crate::ident::Method;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// A payload's mass, centre of mass and inertia given in the design (a guess or the truth).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PayloadValues {
    /// Mass (kg).
    pub mass: f64,
    /// Centre of mass in the payload's frame (m).
    #[serde(default)]
    pub com: [f64; 3],
    /// Inertia about the centre of mass, frame axes, [Ixx, Ixy, Ixz, Iyy, Iyz, Izz] (kg·m²).
    #[serde(default)]
    pub inertia: [f64; 6],
}

/// Model files written of the identified payload.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PayloadExport {
    /// `payload.script`: URScript `set_target_payload(m, cog, inertia)` (UR e-Series, PolyScope ≥ 5.10).
    Urscript,
    /// `franka_load.json`: mass, `F_x_Cload`, `load_inertia` (column-major) as `setLoad` takes them.
    Franka,
    /// `kuka_load.txt`: KUKA load data M, X, Y, Z (mm), A, B, C (deg), JX, JY, JZ (principal axes).
    Kuka,
    /// `payload.urdf`: a fixed joint and a link carrying the payload's inertial.
    Urdf,
    /// `payload_mjcf.xml`: a MuJoCo body with the payload's inertial.
    Mjcf,
    /// `payload.toml`: the `[payload]` table of idexp's excite and simulate designs.
    Idexp,
}

impl PayloadExport {
    /// Every format.
    pub const ALL: [PayloadExport; 6] = [
        PayloadExport::Urscript,
        PayloadExport::Franka,
        PayloadExport::Kuka,
        PayloadExport::Urdf,
        PayloadExport::Mjcf,
        PayloadExport::Idexp,
    ];
}

fn all_exports() -> Vec<PayloadExport> {
    PayloadExport::ALL.to_vec()
}
fn irls_iterations() -> usize {
    50
}
fn irls_tol() -> f64 {
    1e-6
}
fn sample_limit() -> usize {
    2_000_000
}
fn regularization() -> f64 {
    1e-6
}
fn kuka_tool() -> u32 {
    1
}

/// A payload identification.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PayloadDesign {
    /// Name (output folder); default: the file stem.
    #[serde(default)]
    pub name: String,
    /// The robot's model (robot file or URDF, relative to the design file), without the payload.
    pub robot: PathBuf,
    /// The frame the payload is fixed to (default: the robot's end effector).
    #[serde(default)]
    pub frame: Option<String>,
    /// A guess of the payload (CAD, datasheet): the consistent fit takes the
    /// directions the motion does not determine from it (default: none — the
    /// smallest such parameters).
    #[serde(default)]
    pub guess: Option<PayloadValues>,
    /// A simulated run (folder) whose design carries the true `[payload]`; the report then gives the errors.
    #[serde(default)]
    pub truth: Option<PathBuf>,
    /// Estimator: `wls` or `ols` (the stacked least squares of the twins).
    #[serde(default)]
    pub method: Method,
    /// Where the weights come from (repetitions, residuals per experiment and joint).
    #[serde(default)]
    pub weights: WeightSource,
    /// Largest number of reweighting iterations.
    #[serde(default = "irls_iterations")]
    pub irls_iterations: usize,
    /// Relative change of the block variances that ends the reweighting.
    #[serde(default = "irls_tol")]
    pub irls_tol: f64,
    /// Largest number of samples per repetition (bounds memory before reading).
    #[serde(default = "sample_limit")]
    pub sample_limit: usize,
    /// Runs with the payload.
    #[serde(default)]
    pub loaded: Vec<ExperimentSpec>,
    /// The same trajectories without the payload, paired with `loaded` by
    /// order: the payload's torques are then the difference, and the robot
    /// model's error cancels. Empty: the robot model's torques are subtracted.
    #[serde(default)]
    pub unloaded: Vec<ExperimentSpec>,
    /// J ⪰ margin · I₄ for the payload's pseudo-inertia (kg·m²).
    #[serde(default)]
    pub margin: f64,
    /// Weight of the closest-to-guess term of the consistent fit, relative to
    /// the fit's smallest curvature (decides only what the data leave open).
    #[serde(default = "regularization")]
    pub regularization: f64,
    /// Files to write.
    #[serde(default = "all_exports")]
    pub export: Vec<PayloadExport>,
    /// The KUKA tool number n of `LOAD_DATA[n]` in `kuka_load.txt` (1 … 16; default 1).
    #[serde(default = "kuka_tool")]
    pub kuka_tool: u32,
    /// `[gains]`: calibrate the drive gains with a known mass instead
    /// ([`super::gains`]); `[[loaded]]` runs carry that mass, `[[unloaded]]`
    /// runs do not (any trajectories, not paired).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gains: Option<super::gains::GainsSpec>,
}

impl PayloadDesign {
    /// The stacked least squares' options of this design (weights, method, reweighting).
    pub fn stack_options(&self) -> crate::ident::study::StackOptions {
        crate::ident::study::StackOptions {
            weights: self.weights,
            repetition_weights: None,
            ols: self.method == Method::Ols,
            max_iterations: self.irls_iterations,
            tol: self.irls_tol,
        }
    }

    /// Reads and validates a design file.
    pub fn read(path: &Path) -> Result<PayloadDesign> {
        let text = crate::io::read_to_string(path)?;
        let mut d: PayloadDesign = toml::from_str(&text).map_err(|e| Error::parse(path, e.to_string()))?;
        if d.name.is_empty() {
            d.name = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "payload".into());
        }
        crate::io::design_path(path, "robot", &d.robot)?;
        d.validate(&path.display().to_string())?;
        Ok(d)
    }

    /// Checks every field; errors name `ctx` (the file), the entry and the field.
    pub fn validate(&self, ctx: &str) -> Result<()> {
        let bad = |field: &str, msg: String| Err(Error::invalid(ctx, field, msg));
        if !name_ok(&self.name) {
            return bad(
                "name",
                format!("`{}`: expected letters, digits, `_`, `-` or `.` (it names the output folder)", self.name),
            );
        }
        if !matches!(self.method, Method::Wls | Method::Ols) {
            return bad(
                "method",
                format!(
                    "expected \"wls\" or \"ols\" (the payload is a least-squares fit over every twin), found \"{}\"",
                    self.method
                ),
            );
        }
        if self.loaded.is_empty() {
            return bad(
                "loaded",
                "expected at least one [[loaded]] entry (files = [...] of runs with the payload)".into(),
            );
        }
        if let Some(g) = &self.gains {
            g.validate(ctx)?;
            if self.unloaded.is_empty() {
                return bad(
                    "unloaded",
                    "a gain calibration needs runs without the known mass too ([[unloaded]], any trajectories): with loaded runs alone the mass is indistinguishable from the robot's own link".into(),
                );
            }
        } else if !self.unloaded.is_empty() && self.unloaded.len() != self.loaded.len() {
            return bad(
                "unloaded",
                format!(
                    "{} [[unloaded]] entries for {} [[loaded]]: give each loaded run its unloaded twin (same trajectory, same order), or none",
                    self.unloaded.len(),
                    self.loaded.len()
                ),
            );
        }
        if self.irls_iterations == 0 {
            return bad("irls_iterations", "expected ≥ 1".into());
        }
        if !(self.irls_tol.is_finite() && self.irls_tol > 0.0) {
            return bad("irls_tol", format!("expected a positive tolerance, found {}", self.irls_tol));
        }
        if self.sample_limit < 3 {
            return bad("sample_limit", format!("expected ≥ 3, found {}", self.sample_limit));
        }
        if !(self.margin.is_finite() && self.margin >= 0.0) {
            return bad("margin", format!("expected a margin ≥ 0 (kg·m²), found {}", self.margin));
        }
        if !(self.regularization.is_finite() && self.regularization > 0.0) {
            return bad("regularization", format!("expected a positive weight, found {}", self.regularization));
        }
        if let Some(g) = &self.guess {
            g.check(ctx, "guess")?;
        }
        let mut names: Vec<String> = Vec::new();
        for (what, list) in [("loaded", &self.loaded), ("unloaded", &self.unloaded)] {
            for (i, e) in list.iter().enumerate() {
                let name = e.resolved_name();
                let entry = format!("{ctx}: {what} {} ({name})", i + 1);
                e.validate(&entry)?;
                if !name_ok(&name) {
                    return Err(Error::invalid(&entry, "name", format!("`{name}`: expected letters, digits, `_`, `-` or `.`")));
                }
                if names.contains(&name) {
                    return Err(Error::invalid(
                        &entry,
                        "name",
                        format!("`{name}` is used by another entry: give each run a name of its own"),
                    ));
                }
                names.push(name);
            }
        }
        if !(1..=16).contains(&self.kuka_tool) {
            return bad(
                "kuka_tool",
                format!("expected a KUKA tool number 1 … 16 (LOAD_DATA[n]), found {}", self.kuka_tool),
            );
        }
        let mut seen = Vec::new();
        for f in &self.export {
            if seen.contains(f) {
                return bad("export", format!("{f:?} listed twice"));
            }
            seen.push(*f);
        }
        Ok(())
    }
}

impl PayloadValues {
    /// The spec of these values on `frame`.
    pub fn spec(&self, frame: Option<&str>) -> crate::robot::payload::PayloadSpec {
        crate::robot::payload::PayloadSpec {
            frame: frame.map(String::from),
            mass: self.mass,
            com: self.com,
            inertia: self.inertia,
        }
    }

    /// Checks the values as a physical payload (positive mass, inertia at the
    /// centre of mass positive semidefinite with the triangle inequalities).
    pub fn check(&self, ctx: &str, field: &str) -> Result<crate::robot::payload::Payload> {
        crate::robot::payload::Payload::from_spec(&self.spec(None), ctx, field)
    }
}
