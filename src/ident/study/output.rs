//! The output folder of a study:
//!
//! | file | content |
//! |---|---|
//! | `study.json` | the resolved study design |
//! | `estimate.json` | [`super::Estimate`]: estimate, covariance, experiments, validation, consistent fit |
//! | `report.txt` | the text report |
//! | `params.csv` | every base and standard parameter (as `identify --export csv`) |
//! | `experiments.csv` | per experiment and joint: weights, σ, rows, e_j, e*_j, RMS, information share |
//! | `validation.csv` | per validation run and joint: e_j, e*_j, RMS of the least-squares and the consistent estimate |
//! | `validation/<run>.csv` | per sample: t, q, q̇, q̈ (processed), measured torque, the predictions |
//! | `prior.csv` | per standard parameter: prior, scale, consistent estimate |
//! | `experiments/<name>.svg`, `validation/<run>.svg` | measured vs predicted torques |
//! | `validation.svg` | e*_j of every validation run |
//! | `params.svg` | the estimates with ±3σ, σ*, and z against the truth when known |
//! | `reduction.csv`, `reduction.svg` | the model reduction's steps (`[reduce]`) |
//! | `robot.urdf`, `robot.toml`, `robot.xml` | the consistent model (`export`: urdf, toml, mjcf) |
//! | `status.json` | how the study ended |
//!
//! The validation CSVs carry the processed states, so an independent program
//! recomputes the predictions from the written standard parameters (inverse
//! dynamics plus the drive terms) and e_j, e*_j from the columns.

use super::{Estimate, StudyResult};
use crate::error::{Error, Result};
use crate::io::plot::{write_svg, Panel, Series};
use crate::io::status::RunState;
use nalgebra::DVector;
use std::fmt::Write;
use std::path::{Path, PathBuf};

impl Estimate {
    /// What status.json says: with a consistent fit, its outcome (a
    /// rank-deficient least-squares estimate is then usable: the prior
    /// decides the directions the data do not see); without, the estimate's;
    /// interrupted when `interrupted`.
    pub fn state(&self, interrupted: bool) -> RunState {
        match &self.consistent {
            _ if interrupted => RunState::Interrupted,
            Some(c) if c.status.is_ok() => RunState::Complete,
            Some(_) => RunState::Failed,
            None => self.status.state(),
        }
    }

    /// Why the result is not usable (None when it is).
    pub fn unusable_reason(&self) -> Option<String> {
        match (&self.status, self.consistent.as_ref().map(|c| &c.status)) {
            (_, Some(s)) if !s.is_ok() => Some(format!("the consistent fit ended with status `{s}`")),
            (_, Some(_)) => None,
            (st, None) if st.state() == RunState::Failed && !self.is_stacked() => {
                Some(format!("the {} estimate ended with status `{st}`", self.method.words()))
            }
            (st, None) if st.state() == RunState::Failed => Some(format!(
                "the stacked estimate ended with status `{st}`: the experiments together do not excite every base parameter (see each experiment's rank alone in the report; a [consistent] table with a prior decides the directions they do not see)"
            )),
            _ => None,
        }
    }
}

fn joint_header(prefix: &str, n: usize) -> Vec<String> {
    (1..=n).map(|j| format!("{prefix}{j}")).collect()
}

impl StudyResult {
    /// The identified model (the robot with the consistent standard parameters), if any.
    pub fn model(&self) -> Result<Option<crate::robot::Robot>> {
        match &self.estimate.consistent {
            Some(c) if c.status.is_ok() => Ok(Some(self.robot.with_params(&c.standard)?)),
            _ => Ok(None),
        }
    }

    /// Writes every file of the module documentation into `dir`, status.json
    /// last (`started`: when the run began). Returns the files written and the state.
    pub fn write(&self, dir: &Path, started: Option<std::time::SystemTime>) -> Result<(Vec<PathBuf>, RunState)> {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        let e = &self.estimate;
        let n = self.robot.dof();
        let mut files = Vec::new();
        let put = |files: &mut Vec<PathBuf>, name: &str, bytes: &[u8]| -> Result<()> {
            let p = dir.join(name);
            crate::io::write_atomic(&p, bytes)?;
            files.push(p);
            Ok(())
        };
        put(
            &mut files,
            "study.json",
            serde_json::to_string_pretty(&self.design)
                .map_err(|x| Error::Numerical(x.to_string()))?
                .as_bytes(),
        )?;
        put(
            &mut files,
            "estimate.json",
            serde_json::to_string_pretty(e).map_err(|x| Error::Numerical(x.to_string()))?.as_bytes(),
        )?;
        put(&mut files, "report.txt", e.text().as_bytes())?;
        put(&mut files, "params.csv", crate::ident::output::params_csv(e).as_bytes())?;
        let mut csv = String::from("experiment,kind,joint,weights,sigma,rows,e,e_rel,rms,information_share\n");
        for x in &e.experiments {
            for j in 0..n {
                let _ = writeln!(
                    csv,
                    "{},{},{},{},{},{},{},{},{},{}",
                    x.name,
                    x.kind.name(),
                    j + 1,
                    serde_json::to_value(x.weights[j])
                        .ok()
                        .and_then(|v| v.as_str().map(String::from))
                        .unwrap_or_default(),
                    x.sigma[j],
                    x.rows_used[j].used,
                    x.errors_all.e[j],
                    x.errors_all.e_rel[j],
                    x.errors_all.rms[j],
                    x.information_share
                );
            }
        }
        put(&mut files, "experiments.csv", csv.as_bytes())?;
        if !e.validation.is_empty() {
            let mut csv = String::from("run,kind,joint,e,e_rel,rms,consistent_e,consistent_e_rel,consistent_rms\n");
            for v in &e.validation {
                for j in 0..n {
                    let c = v.consistent_all.as_ref();
                    let f = |x: Option<f64>| x.map(|v| v.to_string()).unwrap_or_default();
                    let _ = writeln!(
                        csv,
                        "{},{},{},{},{},{},{},{},{}",
                        v.name,
                        v.kind.name(),
                        j + 1,
                        v.errors_all.e[j],
                        v.errors_all.e_rel[j],
                        v.errors_all.rms[j],
                        f(c.map(|c| c.e[j])),
                        f(c.map(|c| c.e_rel[j])),
                        f(c.map(|c| c.rms[j]))
                    );
                }
            }
            put(&mut files, "validation.csv", csv.as_bytes())?;
        }
        let theta = DVector::from_column_slice(&e.theta);
        let cbase = e.consistent.as_ref().filter(|c| c.status.is_ok()).map(|c| DVector::from_column_slice(&c.base));
        for v in &self.validations {
            let ds = &v.prep.every;
            let pr = &v.prep.pr;
            let m = ds.n_samples;
            let ls = &ds.c * &theta;
            let cs = cbase.as_ref().map(|b| &ds.c * b);
            let mut header = vec!["t".to_string()];
            for p in ["q", "qd", "qdd", "tau", "tau_ls"] {
                header.extend(joint_header(p, n));
            }
            if cs.is_some() {
                header.extend(joint_header("tau_consistent", n));
            }
            let rows = (0..m).map(|k| {
                let mut row = vec![pr.t[k]];
                row.extend_from_slice(&pr.q[k]);
                row.extend_from_slice(&pr.qd[k]);
                row.extend_from_slice(&pr.qdd[k]);
                row.extend((0..n).map(|j| ds.y[j * m + k]));
                row.extend((0..n).map(|j| ls[j * m + k]));
                if let Some(c) = &cs {
                    row.extend((0..n).map(|j| c[j * m + k]));
                }
                row
            });
            let p = dir.join("validation").join(format!("{}.csv", v.name));
            std::fs::create_dir_all(dir.join("validation")).map_err(|err| Error::io(dir, err))?;
            crate::io::write_csv(&p, &header, rows)?;
            files.push(p);
        }
        if let Some(c) = &e.consistent {
            let mut csv = String::from("name,prior,scale,consistent\n");
            for j in 0..c.standard.len() {
                let _ = writeln!(csv, "{},{},{},{}", c.standard_names[j], c.prior_standard[j], c.prior_scale[j], c.standard[j]);
            }
            put(&mut files, "prior.csv", csv.as_bytes())?;
        }
        self.write_plots(dir, &mut files)?;
        let p = dir.join("params.svg");
        write_svg(&p, "identified base parameters", &crate::ident::output::params_panels(e), 1)?;
        files.push(p);
        if let Some(r) = &e.reduction {
            let mut csv = format!(
                "k,parameter,sensitivity,decision,growth,cond,n_params,{}\n",
                (1..=n).map(|j| format!("e_rel{j}")).collect::<Vec<_>>().join(",")
            );
            for st in &r.steps {
                let _ = writeln!(
                    csv,
                    "{},{},{},{},{},{},{},{}",
                    st.k,
                    st.parameter,
                    st.sensitivity,
                    st.decision,
                    st.growth,
                    st.cond,
                    st.n_params,
                    st.e_rel.iter().map(|v| v.to_string()).collect::<Vec<_>>().join(",")
                );
            }
            put(&mut files, "reduction.csv", csv.as_bytes())?;
            let p = dir.join("reduction.svg");
            write_svg(&p, "model reduction (Algorithm 1)", &crate::ident::output::reduction_panels(r), 2)?;
            files.push(p);
        }
        if let Some(m) = self.model()? {
            use super::design::ExportFormat;
            let src = crate::robot::export::source_of(&self.robot_path)?;
            // robot.toml must carry the identified inertials: from a URDF robot it
            // points at a URDF, so that URDF is the identified one, written beside it
            let urdf_too = self.design.export.contains(&ExportFormat::Toml) && matches!(src, crate::robot::export::Source::Urdf { .. });
            if self.design.export.contains(&ExportFormat::Urdf) || urdf_too {
                if let crate::robot::export::Source::Dh { toml } = &src {
                    return Err(Error::invalid(
                        toml.display().to_string(),
                        "export",
                        "\"urdf\": this robot is a DH table, not a URDF: there is no URDF to copy the kinematics from; use export = [\"toml\"]",
                    ));
                }
                files.push(crate::robot::export::write_urdf(&src, &m, dir)?);
            }
            if self.design.export.contains(&ExportFormat::Mjcf) {
                files.push(crate::robot::export::write_mjcf(&m, dir)?);
            }
            if self.design.export.contains(&ExportFormat::Toml) {
                let urdf_ref = match &src {
                    crate::robot::export::Source::Urdf { .. } => Some("robot.urdf".to_string()),
                    _ => None,
                };
                files.push(crate::robot::export::write_robot_toml(&src, &m, dir, urdf_ref.as_deref())?);
            }
        }
        let state = e.state(self.interrupted);
        let detail = format!(
            "{} experiment(s), {} validation run(s): {}{}",
            e.experiments.len(),
            e.validation.len(),
            e.status,
            e.consistent.as_ref().map(|c| format!(", consistent {}", c.status)).unwrap_or_default()
        );
        let summary = serde_json::json!({
            "study": e.name,
            "estimate_status": e.status,
            "consistent_status": e.consistent.as_ref().map(|c| c.status.to_string()),
            "validation_mean_relative_rms": e.validation_total.as_ref().map(|t| t.mean_relative_rms),
        });
        let fp = crate::io::status::fingerprint_of(&self.design)?;
        crate::io::status::write_status(dir, "identify", state, detail, started, fp, summary)?;
        files.push(dir.join("status.json"));
        Ok((files, state))
    }

    fn write_plots(&self, dir: &Path, files: &mut Vec<PathBuf>) -> Result<()> {
        let e = &self.estimate;
        let cons = e.consistent.as_ref().filter(|c| c.status.is_ok()).map(|c| c.base.as_slice());
        let mut fits: Vec<(&str, &[f64])> = vec![("least squares", e.theta.as_slice())];
        if let Some(c) = cons {
            fits.push(("consistent", c));
        }
        for (sub, list, title) in [
            ("experiments", &self.experiments, "experiment"),
            ("validation", &self.validations, "validation run"),
        ] {
            for l in list {
                let p = dir.join(sub).join(format!("{}.svg", l.name));
                std::fs::create_dir_all(dir.join(sub)).map_err(|err| Error::io(dir, err))?;
                let panels = crate::ident::output::torque_panels(&l.prep.every, &l.prep.pr.t, &fits, false);
                write_svg(&p, &format!("{title} `{}`: measured vs predicted torque", l.name), &panels, 2)?;
                files.push(p);
            }
        }
        if !e.validation.is_empty() {
            let n = self.robot.dof();
            let x: Vec<f64> = (1..=e.validation.len()).map(|i| i as f64).collect();
            let panels: Vec<Panel> = (0..n)
                .map(|j| {
                    // side by side at each run, so that equal values stay visible
                    let mut series = vec![Series::points(
                        "least squares",
                        x.iter().map(|v| v - 0.1).collect(),
                        e.validation.iter().map(|v| 100.0 * v.errors_all.e_rel[j]).collect(),
                    )];
                    if e.validation.iter().all(|v| v.consistent_all.is_some()) {
                        series.push(Series::points(
                            "consistent",
                            x.iter().map(|v| v + 0.1).collect(),
                            e.validation
                                .iter()
                                .map(|v| v.consistent_all.as_ref().map_or(f64::NAN, |c| 100.0 * c.e_rel[j]))
                                .collect(),
                        ));
                    }
                    Panel {
                        title: format!("joint {}", j + 1),
                        x_label: "validation run".into(),
                        y_label: "e*_j (%)".into(),
                        series,
                        x_names: e.validation.iter().map(|v| v.name.clone()).collect(),
                        ..Default::default()
                    }
                })
                .collect();
            let p = dir.join("validation.svg");
            write_svg(&p, "relative prediction error e*_j of every validation run", &panels, 2)?;
            files.push(p);
        }
        Ok(())
    }
}
