//! Payloads: identify a tool's mass, centre of mass and inertia after the
//! robot's own model is known, and write it where controllers read it.
//!
//! * Excitation: an [`crate::excitation::design::ExciteDesign`] with a `[payload]`
//!   (its nominal values and, in `[[collision.attached]]`, its geometry) and
//!   `objective.columns = "payload"` optimises the criterion on the payload
//!   link's ten columns only (`idexp payload excite`, the same engine as
//!   `idexp excite`).
//! * Identification ([`identify::identify`], `idexp payload identify`): from
//!   runs with the payload and, optionally, the same runs without it (the
//!   robot model's error then cancels), the ten parameters by weighted least
//!   squares, physically consistent, with uncertainties and a statement of
//!   what the motion does and does not determine ([`design::PayloadDesign`]).
//! * Exports ([`export`]): URScript, Franka, KUKA, URDF and MJCF.
//!
//! The output folder of an identification:
//!
//! | file | content |
//! |---|---|
//! | `payload.json` | [`identify::PayloadEstimate`]: the payload, its σ, base estimate, covariance, runs, consistent fit |
//! | `report.txt` | the text report |
//! | `design.json` | the resolved design |
//! | `residuals.svg` | per joint: the payload's torque b and its prediction A φ̂ (first run) |
//! | `payload.script`, `franka_load.json`, `kuka_load.txt`, `payload.urdf`, `payload_mjcf.xml`, `payload.toml` | the exports |
//! | `status.json` | how it ended |

pub mod align;
pub mod chain;
pub mod design;
pub mod export;
pub mod gains;
pub mod gains_output;
pub mod identify;

pub use design::{PayloadDesign, PayloadExport, PayloadValues};
pub use identify::{identify, PayloadEstimate, PayloadRun, PayloadStd, Structural};

use crate::error::{Error, Result};
use crate::io::plot::{write_svg, Panel, Series};
use crate::io::status::RunState;
use std::fmt::Write;
use std::path::{Path, PathBuf};

/// A payload identification and the design it ran.
#[derive(Debug, Clone)]
pub struct PayloadResult {
    /// The design.
    pub design: PayloadDesign,
    /// What was found.
    pub estimate: PayloadEstimate,
}

/// Runs [`identify::identify`] and keeps the design (a design with `[gains]` is refused: [`gains::calibrate`] runs it).
pub fn run(design: &PayloadDesign, dir: &Path, ctl: &crate::optim::Control) -> Result<PayloadResult> {
    if design.gains.is_some() {
        return Err(Error::invalid(
            format!("payload design `{}`", design.name),
            "gains",
            "a [gains] table calibrates the drive gains with the known mass (gains::calibrate) instead of identifying a payload",
        ));
    }
    Ok(PayloadResult {
        design: design.clone(),
        estimate: identify(design, dir, ctl)?,
    })
}

fn vec3(v: &[f64; 3], scale: f64, digits: usize) -> String {
    format!("[{:.d$}, {:.d$}, {:.d$}]", v[0] * scale, v[1] * scale, v[2] * scale, d = digits)
}

impl PayloadEstimate {
    /// The state status.json records.
    pub fn state(&self) -> RunState {
        match (&self.payload, self.interrupted) {
            (_, true) => RunState::Interrupted,
            (Some(_), false) => RunState::Complete,
            (None, false) => RunState::Failed,
        }
    }

    /// Why there is no usable payload (None when there is).
    pub fn unusable_reason(&self) -> Option<String> {
        match (&self.payload, &self.consistent) {
            (Some(_), _) => None,
            (None, Some(c)) if !c.status.is_ok() => Some(format!("the consistent fit ended with status `{}`", c.status)),
            (None, Some(_)) => Some("the identified mass is zero: no payload is seen in the torques".into()),
            (None, None) => Some("interrupted before the consistent fit".into()),
        }
    }

    /// The text report.
    pub fn text(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(
            s,
            "Payload identification on frame `{}` (link {}) of {}",
            self.frame,
            self.link,
            self.robot.display()
        );
        let _ = writeln!(
            s,
            "Robot model's torques: {}",
            if self.differencing {
                "cancelled by the unloaded runs (the model only corrects the two runs' tracking difference)"
            } else {
                "subtracted (no unloaded runs: the model's error stays in the payload's torques)"
            }
        );
        let _ = writeln!(s, "\nRuns:");
        for r in &self.runs {
            let _ = write!(s, "  {}: {} repetition(s), {} samples, {} rows", r.name, r.repetitions, r.samples, r.rows);
            if let Some(u) = &r.unloaded {
                let _ = write!(s, ", minus `{u}`");
            }
            let _ = writeln!(s, ", information {:.0} %", 100.0 * r.information_share);
            let f = |v: &[f64]| v.iter().map(|x| format!("{x:.3}")).collect::<Vec<_>>().join(" ");
            let _ = writeln!(s, "    payload torque RMS (N·m):   {}", f(&r.rms_payload));
            let _ = writeln!(s, "    residual RMS (N·m):         {}", f(&r.rms_residual));
            let _ = writeln!(s, "    weight σ (N·m):             {}", f(&r.sigma));
            if let Some(a) = &r.alignment {
                let mrad = |t: &[f64]| t.iter().map(|x| format!("{:.2}", 1e3 * x)).collect::<Vec<_>>().join(" ");
                let _ = writeln!(
                    s,
                    "    twin aligned: unloaded time = loaded time {:+.5} s ({:+.3} samples); {} and {} samples, {} paired (loaded samples {}..{})",
                    a.shift_s,
                    a.shift_samples,
                    a.samples[0],
                    a.samples[1],
                    a.overlap[1] - a.overlap[0],
                    a.overlap[0],
                    a.overlap[1]
                );
                let _ = writeln!(s, "    RMS |q_loaded − q_unloaded| (mrad): {}", mrad(&a.rms_difference));
                let _ = writeln!(s, "    max |q_loaded − q_unloaded| (mrad): {}", mrad(&a.max_difference));
            }
        }
        let st = &self.structural;
        let _ = writeln!(s, "\nIdentifiable from the joint torques: {} of 10 parameters", st.names.len());
        for (n, g) in st.names.iter().zip(&st.groupings) {
            if n.ends_with('R') {
                let _ = writeln!(s, "  {n} = {g}");
            }
        }
        if !st.unidentifiable.is_empty() {
            let _ = writeln!(s, "  no effect on the torques: {}", st.unidentifiable.join(", "));
        }
        let _ = writeln!(
            s,
            "This motion: rank {} of {}, cond {:.3e} (unit columns), χ²/dof {:.3}, least squares {}",
            self.rank,
            st.names.len(),
            self.cond,
            self.chi2_dof,
            self.status.as_str()
        );
        let _ = writeln!(s, "  {:<6} {:>14} {:>12} {:>8}", "param", "estimate", "σ", "σ rel");
        for i in 0..self.theta.len() {
            let _ = writeln!(
                s,
                "  {:<6} {:>14.6e} {:>12.3e} {:>7.2}%",
                st.names[i],
                self.theta[i],
                self.std[i],
                100.0 * self.rel_std[i]
            );
        }
        if self.poorly_determined.is_empty() {
            let _ = writeln!(s, "  every identifiable parameter is determined by this motion (σ ≤ 25 % of its scale)");
        } else {
            let _ = writeln!(
                s,
                "  poorly determined by this motion (σ > 25 % of its scale): {} — excite more (idexp payload excite) or give a [guess]",
                self.poorly_determined.join(", ")
            );
        }
        if let Some(c) = &self.consistent {
            let _ = writeln!(
                s,
                "\nConsistent fit: {}, smallest pseudo-inertia eigenvalue {:.3e} kg·m², extra weighted SSR {:.3e}",
                c.status, c.min_eig, c.extra_cost
            );
            if c.on_boundary {
                let _ = writeln!(
                    s,
                    "  on the consistency boundary (a flat body): what the data allow, not a physical tool (see the note below)"
                );
            }
        }
        match &self.payload {
            Some(p) => {
                let _ = writeln!(s, "\nPayload (frame {}):", self.frame);
                let sd = self.payload_std.as_ref();
                let _ = write!(s, "  mass          {:.4} kg", p.mass);
                if let Some(d) = sd {
                    let _ = write!(s, " ± {:.4}", d.mass);
                }
                let _ = write!(s, "\n  centre (mm)   {}", vec3(&p.com, 1e3, 2));
                if let Some(d) = sd {
                    let _ = write!(s, " ± {}", vec3(&d.com, 1e3, 2));
                }
                let _ = write!(
                    s,
                    "\n  inertia about the centre [Ixx Ixy Ixz Iyy Iyz Izz] (kg·m²):\n    {}",
                    p.inertia.iter().map(|v| format!("{v:.4e}")).collect::<Vec<_>>().join(" ")
                );
                if let Some(d) = sd {
                    let _ = write!(s, "\n  ± {}", d.inertia.iter().map(|v| format!("{v:.1e}")).collect::<Vec<_>>().join(" "));
                }
                let pr = export::principal(p);
                let _ = writeln!(
                    s,
                    "\n  principal moments {} kg·m², axes A B C = {} deg",
                    pr.moments.iter().map(|v| format!("{v:.4e}")).collect::<Vec<_>>().join(" "),
                    vec3(&pr.abc_deg, 1.0, 2)
                );
                if let Some(t) = &self.truth {
                    let dc: Vec<f64> = (0..3).map(|k| p.com[k] - t.com[k]).collect();
                    let _ = writeln!(
                        s,
                        "  truth: mass {:.4} kg (error {:+.3} %), centre {} mm (error {:.2} mm)",
                        t.mass,
                        100.0 * (p.mass / t.mass - 1.0),
                        vec3(&t.com, 1e3, 2),
                        1e3 * dc.iter().map(|v| v * v).sum::<f64>().sqrt()
                    );
                }
                if let Some(g) = &self.guess {
                    let _ = writeln!(s, "  guess: mass {:.4} kg, centre {} mm", g.mass, vec3(&g.com, 1e3, 2));
                }
            }
            None => {
                let _ = writeln!(s, "\nNo usable payload: {}", self.unusable_reason().unwrap_or_default());
            }
        }
        for n in &self.notes {
            let _ = writeln!(s, "Note: {n}");
        }
        s
    }
}

impl PayloadResult {
    /// The comment lines of the exports.
    fn header(&self) -> Vec<String> {
        vec![format!(
            "payload `{}` identified by idexp on frame {} of robot {}",
            self.design.name,
            self.estimate.frame,
            self.estimate.robot.display()
        )]
    }

    /// Writes every file of the module documentation into `dir`, status.json
    /// last (`started`: when the run began). Returns the files written and the state.
    pub fn write(&self, dir: &Path, started: Option<std::time::SystemTime>) -> Result<(Vec<PathBuf>, RunState)> {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        let e = &self.estimate;
        let mut files = Vec::new();
        let mut put = |name: &str, bytes: &[u8]| -> Result<()> {
            let p = dir.join(name);
            crate::io::write_atomic(&p, bytes)?;
            files.push(p);
            Ok(())
        };
        let json = |v: &dyn erased::Json| v.to_json();
        put("design.json", json(&self.design)?.as_bytes())?;
        put("payload.json", json(e)?.as_bytes())?;
        put("report.txt", e.text().as_bytes())?;
        if let Some(p) = &e.payload {
            let h = self.header();
            for f in &self.design.export {
                match f {
                    PayloadExport::Urscript => put("payload.script", export::urscript(p, &e.frame, &h).as_bytes())?,
                    PayloadExport::Franka => put("franka_load.json", json(&export::franka(p, &e.frame))?.as_bytes())?,
                    PayloadExport::Kuka => put("kuka_load.txt", export::kuka(p, self.design.kuka_tool, &e.frame, &h).as_bytes())?,
                    PayloadExport::Urdf => put("payload.urdf", export::urdf(p, &e.frame, &h).as_bytes())?,
                    PayloadExport::Mjcf => put("payload_mjcf.xml", export::mjcf(p, &e.frame, &h).as_bytes())?,
                    PayloadExport::Idexp => put("payload.toml", export::idexp_table(p, &e.frame, &h)?.as_bytes())?,
                }
            }
        }
        if !e.plot.is_empty() {
            let names: Vec<String> = match crate::robot::load(&e.robot) {
                Ok(r) => r.joints.iter().map(|j| j.name.clone()).collect(),
                Err(_) => (1..=e.plot.len()).map(|j| format!("joint {j}")).collect(),
            };
            let measured_label = if e.differencing {
                "loaded − unloaded run"
            } else {
                "measured − robot model"
            };
            let panels: Vec<Panel> = e
                .plot
                .iter()
                .enumerate()
                .map(|(j, p)| Panel {
                    title: names.get(j).cloned().unwrap_or_else(|| format!("joint {}", j + 1)),
                    x_label: "t (s)".into(),
                    y_label: "payload torque (N·m)".into(),
                    series: vec![
                        Series::points(measured_label, p.t.clone(), p.measured.clone()),
                        Series::line("identified payload", p.t.clone(), p.predicted.clone()),
                    ],
                    ..Default::default()
                })
                .collect();
            let run = e.runs.first().map(|r| r.name.as_str()).unwrap_or("");
            let title = format!(
                "payload torques of run `{run}`{}: measured and identified",
                if e.differencing { " (minus its unloaded twin)" } else { "" }
            );
            let p = dir.join("residuals.svg");
            write_svg(&p, &title, &panels, 2)?;
            files.push(p);
        }
        let state = e.state();
        let detail = match &e.payload {
            Some(p) => format!("mass {:.4} kg, centre {} mm", p.mass, vec3(&p.com, 1e3, 2)),
            None => e.unusable_reason().unwrap_or_default(),
        };
        let summary = crate::io::status::summary_of(&serde_json::json!({
            "mass": e.payload.map(|p| p.mass),
            "com": e.payload.map(|p| p.com),
            "rank": e.rank,
            "cond": e.cond,
        }))?;
        crate::io::status::write_status(
            dir,
            "payload identify",
            state,
            detail,
            started,
            crate::io::status::fingerprint_of(&self.design)?,
            summary,
        )?;
        files.push(dir.join("status.json"));
        Ok((files, state))
    }
}

/// Pretty JSON of serialisable values (one helper for the folder's files).
pub(crate) mod erased {
    use crate::error::{Error, Result};

    pub trait Json {
        fn to_json(&self) -> Result<String>;
    }

    impl<T: serde::Serialize> Json for T {
        fn to_json(&self) -> Result<String> {
            serde_json::to_string_pretty(self).map_err(|x| Error::Numerical(x.to_string()))
        }
    }
}
