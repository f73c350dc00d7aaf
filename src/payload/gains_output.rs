//! The output of a drive-gain calibration ([`super::gains`]): the report,
//! `gains.json`, `gains.csv` (the gains beside the file's and any other set)
//! and `robot.toml` (the robot file with the identified gains and signs).
//!
//! | file | content |
//! |---|---|
//! | `report.txt` | the gains, which joints the motion determines and why not, delays, offsets, signs, the known mass's centre |
//! | `gains.json` | [`GainsEstimate`] |
//! | `gains.csv` | joint, file gain, identified gain, σ, determined, then one column per compared set (N·m/A) |
//! | `robot.toml` | the design's robot file with `torque_constant` (and `current_sign`) of the determined joints replaced |
//! | `design.json`, `status.json` | the resolved design, how it ended |

use super::gains::GainsEstimate;
use super::PayloadDesign;
use crate::error::{Error, Result};
use crate::io::status::RunState;
use std::fmt::Write;
use std::path::{Path, PathBuf};

impl GainsEstimate {
    /// The text report.
    pub fn text(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(
            s,
            "Drive gains of {} calibrated with a known mass of {} kg on frame `{}`",
            self.robot.display(),
            self.mass,
            self.frame
        );
        let _ = writeln!(s, "\nRuns:");
        for r in &self.runs {
            let _ = write!(
                s,
                "  {} ({}): {} samples, {} rows",
                r.name,
                if r.loaded { "with the mass" } else { "without" },
                r.samples,
                r.rows
            );
            if let Some((d, sd)) = r.delay {
                let _ = write!(s, ", currents' delay behind the positions {:.3} ± {:.3} ms", 1e3 * d, 1e3 * sd);
            }
            let _ = writeln!(s);
            let _ = writeln!(
                s,
                "    weight σ (N·m): {}",
                r.sigma.iter().map(|x| format!("{x:.3}")).collect::<Vec<_>>().join(" ")
            );
        }
        let _ = writeln!(s, "\nGains (joint side, N·m/A = s·k_t·N; ratio = identified / file):");
        let mut head = format!(
            "  {:<22} {:>12} {:>12} {:>10} {:>9} {:>12}",
            "joint", "file", "identified", "σ", "ratio", "mass τ RMS"
        );
        // each compared set's column as wide as its name (at least 12)
        let width = |name: &str| name.chars().count().max(12);
        for (name, _) in &self.compare {
            let _ = write!(head, " {name:>w$}", w = width(name));
        }
        let _ = writeln!(s, "{head}");
        for (j, g) in self.joints.iter().enumerate() {
            let (id, sd, ratio) = if g.determined {
                (format!("{:.5}", g.gain), format!("{:.5}", g.std), format!("{:.4}", g.ratio))
            } else {
                ("kept".into(), "—".into(), "—".into())
            };
            let mut line = format!(
                "  {:<22} {:>12.5} {:>12} {:>10} {:>9} {:>12.3}",
                trunc(&g.joint, 22),
                g.file,
                id,
                sd,
                ratio,
                g.mass_torque_rms
            );
            for (name, v) in &self.compare {
                let _ = write!(line, " {:>w$.5}", v[j], w = width(name));
            }
            let _ = writeln!(s, "{line}");
        }
        let undetermined: Vec<&super::gains::JointGain> = self.joints.iter().filter(|g| !g.determined).collect();
        if undetermined.is_empty() {
            let _ = writeln!(s, "\nEvery joint's gain is determined by the motion.");
        } else {
            let _ = writeln!(s, "\nNot determined (the file's gain is kept):");
            for g in undetermined {
                let _ = writeln!(s, "  {}: {}", g.joint, g.reason.clone().unwrap_or_default());
            }
        }
        if self.joints.iter().any(|g| g.offset.is_some()) {
            let _ = writeln!(s, "\nCurrent offsets (logged − true, A):");
            for g in &self.joints {
                if let Some((o, so)) = g.offset {
                    let _ = writeln!(s, "  {:<22} {:+.5} ± {:.5}", g.joint, o, so);
                }
            }
        }
        let _ = writeln!(s, "\nCurrent signs:");
        for g in self.joints.iter().filter(|g| g.determined) {
            let _ = writeln!(
                s,
                "  {:<22} {}",
                g.joint,
                if g.sign_flipped {
                    "WRONG in the file (flipped in robot.toml)"
                } else {
                    "as in the file"
                }
            );
        }
        let _ = writeln!(s, "\nThe known mass's other parameters (about the frame's origin, in its axes):");
        for (name, v, sd) in &self.payload {
            let _ = writeln!(s, "  {name:<8} {v:+.6} ± {sd:.6}");
        }
        if let Some(m) = self
            .payload
            .iter()
            .find(|p| p.0 == "MX")
            .zip(self.payload.iter().find(|p| p.0 == "MY"))
            .zip(self.payload.iter().find(|p| p.0 == "MZ"))
        {
            let ((x, y), z) = m;
            let _ = writeln!(
                s,
                "  centre of mass: [{:.2}, {:.2}, {:.2}] ± [{:.2}, {:.2}, {:.2}] mm",
                1e3 * x.1 / self.mass,
                1e3 * y.1 / self.mass,
                1e3 * z.1 / self.mass,
                1e3 * x.2 / self.mass,
                1e3 * y.2 / self.mass,
                1e3 * z.2 / self.mass
            );
        }
        let _ = writeln!(s, "\nFit: {} unknowns, rank {}, χ²/dof {:.3}", self.unknowns, self.rank, self.chi2_dof);
        if !self.notes.is_empty() {
            let _ = writeln!(s, "\nNotes:");
            for n in &self.notes {
                let _ = writeln!(s, "  - {n}");
            }
        }
        s
    }

    /// `gains.csv`: joint, file, identified, σ, determined, then the compared sets.
    pub fn csv(&self) -> String {
        let mut s = String::from("joint,file,identified,std,determined");
        for (n, _) in &self.compare {
            let _ = write!(s, ",{}", n.replace(',', " "));
        }
        s.push('\n');
        for (j, g) in self.joints.iter().enumerate() {
            let _ = write!(
                s,
                "{},{},{},{},{}",
                g.joint,
                g.file,
                g.gain,
                if g.std.is_finite() { g.std.to_string() } else { "nan".into() },
                g.determined
            );
            for (_, v) in &self.compare {
                let _ = write!(s, ",{}", v[j]);
            }
            s.push('\n');
        }
        s
    }

    /// The design's robot file with the determined joints' gains: each
    /// `[[drive]]`'s `torque_constant` = |g|/N and `current_sign` = sign(g)
    /// (gear ratio kept); paths rewritten relative to `dir`.
    pub fn robot_toml(&self, dir: &Path) -> Result<String> {
        let robot = crate::robot::load(&self.robot)?;
        let src = crate::robot::export::source_of(&self.robot)?;
        let urdf = match &src {
            crate::robot::export::Source::Urdf { urdf, toml: Some(_) } => {
                Some(std::path::absolute(urdf).unwrap_or_else(|_| urdf.clone()).display().to_string())
            }
            crate::robot::export::Source::Urdf { toml: None, .. } => {
                return Err(Error::invalid(
                    "payload",
                    "robot",
                    format!(
                        "{}: a URDF has no drive gains; give a robot TOML with [[drive]] torque_constant entries",
                        self.robot.display()
                    ),
                ))
            }
            crate::robot::export::Source::Dh { .. } => None,
        };
        let text = crate::robot::export::robot_toml(&src, &robot, urdf.as_deref(), dir)?;
        let body: String = text.lines().skip_while(|l| l.starts_with('#')).collect::<Vec<_>>().join("\n");
        let mut t: toml::Table = body.parse().map_err(|e: toml::de::Error| Error::parse(&self.robot, e.to_string()))?;
        t.insert(
            "source".into(),
            format!(
                "drive gains calibrated by idexp payload identify ([gains], known mass {} kg) from {}",
                self.mass,
                robot.source.replace('\n', " ")
            )
            .into(),
        );
        if let Some(toml::Value::Array(drives)) = t.get_mut("drive") {
            for d in drives.iter_mut().filter_map(|v| v.as_table_mut()) {
                let Some(jn) = d.get("joint").and_then(|v| v.as_str()).map(String::from) else {
                    continue;
                };
                let Some(j) = robot.joints.iter().position(|x| x.name == jn) else { continue };
                let g = &self.joints[j];
                if g.determined {
                    let n = robot.drives[j].gear_ratio;
                    d.insert("torque_constant".into(), (g.gain.abs() / n.abs()).into());
                    // τ = s·k_t·N·i: the sign of g/N
                    d.insert("current_sign".into(), (if g.gain * n >= 0.0 { 1.0 } else { -1.0 }).into());
                }
            }
        }
        let body = toml::to_string(&t).map_err(|e| Error::invalid("payload", "robot.toml", e.to_string()))?;
        Ok(format!(
            "# robot file written by idexp payload identify [gains]: the drive gains calibrated with a known mass\n{body}"
        ))
    }

    /// Writes the output folder; returns the files written and the state.
    pub fn write(&self, design: &PayloadDesign, dir: &Path, started: Option<std::time::SystemTime>) -> Result<(Vec<PathBuf>, RunState)> {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        let mut files = Vec::new();
        let mut put = |name: &str, bytes: &[u8]| -> Result<()> {
            let p = dir.join(name);
            crate::io::write_atomic(&p, bytes)?;
            files.push(p);
            Ok(())
        };
        let json = |v: &dyn super::erased::Json| v.to_json();
        put("design.json", json(design)?.as_bytes())?;
        put("gains.json", json(self)?.as_bytes())?;
        put("report.txt", self.text().as_bytes())?;
        put("gains.csv", self.csv().as_bytes())?;
        put("robot.toml", self.robot_toml(dir)?.as_bytes())?;
        let determined = self.joints.iter().filter(|g| g.determined).count();
        let state = if determined > 0 { RunState::Complete } else { RunState::Failed };
        let detail = format!("{determined} of {} joints' gains determined", self.joints.len());
        let summary = crate::io::status::summary_of(&serde_json::json!({
            "gains": self.joints.iter().map(|g| g.gain).collect::<Vec<_>>(),
            "determined": self.joints.iter().map(|g| g.determined).collect::<Vec<_>>(),
            "delays": self.runs.iter().map(|r| r.delay.map(|d| d.0)).collect::<Vec<_>>(),
        }))?;
        crate::io::status::write_status(
            dir,
            "payload identify",
            state,
            detail,
            started,
            crate::io::status::fingerprint_of(design)?,
            summary,
        )?;
        files.push(dir.join("status.json"));
        Ok((files, state))
    }

    /// Why there is no usable result (None when at least one gain is determined).
    pub fn unusable_reason(&self) -> Option<String> {
        (!self.joints.iter().any(|g| g.determined)).then(|| "no joint's gain is determined by these runs (the known mass loads none of them)".into())
    }
}

fn trunc(s: &str, n: usize) -> String {
    s.chars().take(n).collect()
}
