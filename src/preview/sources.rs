//! Where a page's trajectory and scene come from: an `idexp excite` result
//! in memory ([`write_for_result`]) or its output folder
//! ([`write_for_folder`]), or a trajectory CSV with a robot file
//! ([`write_for_trajectory`], [`read_rows`]); the report's worst instants
//! ([`report_instants`]).

use super::{write, Motion, PreviewOptions, ReportInstant, Setup, Written};
use crate::error::{Error, Result};
use crate::excitation::design::ExciteDesign;
use crate::trajectory::lead::Delivered;
use std::path::Path;

/// The worst distances of `report.json`'s margins (`result.margins`: self
/// and world), as instants of the delivered trajectory (period 1 starts at
/// `lead_in`). Each margin is its JSON object (`name`, `kind`, `worst`, `at`).
pub fn report_instants(margins: &[serde_json::Value], lead_in: f64) -> Vec<ReportInstant> {
    let mut out = Vec::new();
    for (kind, class) in [("self_collision", "self"), ("world_collision", "world")] {
        let least = margins
            .iter()
            .filter(|m| m["kind"] == kind)
            .filter_map(|m| Some((m["name"].as_str()?, m["worst"].as_f64()?, m["at"].as_f64()?)))
            .min_by(|a, b| a.1.total_cmp(&b.1));
        if let Some((name, worst, at)) = least {
            let pair = name.strip_prefix("distance ").unwrap_or(name);
            let pair = pair.split(" ≥ ").next().unwrap_or(pair);
            out.push(ReportInstant {
                class: class.into(),
                pair: pair.to_string(),
                distance: worst,
                t: lead_in + at,
            });
        }
    }
    out
}

/// The page of an `idexp excite` run, from its problem and result (the
/// hook of the excite command: written beside `trajectory.csv`).
pub fn write_for_result(p: &crate::excitation::Problem, r: &crate::excitation::ExciteResult, dir: &Path, opts: &PreviewOptions) -> Result<Written> {
    let d = &p.design;
    let mut setup = Setup::from_design(d, (*p.robot).clone(), &d.name)?;
    let delivered = delivered_or_periodic(r.execution.delivered.as_ref(), &r.trajectory);
    let margins: Vec<serde_json::Value> = r
        .margins
        .iter()
        .map(serde_json::to_value)
        .collect::<std::result::Result<_, _>>()
        .map_err(|e| Error::invalid(&d.name, "margins", e.to_string()))?;
    setup.report = report_instants(&margins, delivered.lead_in_duration());
    let motion = Motion::Delivered {
        delivered,
        rate: d.trajectory.controller_rate,
    };
    write(&setup, &motion, opts, &dir.join("preview.html"))
}

/// The delivered trajectory, or one period when none is playable (as
/// `trajectory.csv` then holds).
fn delivered_or_periodic(d: Option<&Delivered>, tr: &crate::trajectory::ShapeMotion) -> Delivered {
    match d {
        Some(d) => d.clone(),
        None => Delivered {
            home: crate::trajectory::Motion::rest_pose(tr),
            lead_in: None,
            periodic: tr.clone(),
            periods: 1,
            lead_out: None,
        },
    }
}

/// Largest JSON file of an output folder read (bytes).
const MAX_JSON: u64 = 256 << 20;

fn read_json(path: &Path) -> Result<serde_json::Value> {
    let text = crate::io::read_to_string_bounded(path, MAX_JSON)?;
    serde_json::from_str(&text).map_err(|e| Error::parse(path, e.to_string()))
}

/// The page of an `idexp excite` output folder (`design.json`,
/// `coefficients.json`, `report.json`), written into `out_dir` (default:
/// that folder) as `preview.html`.
pub fn write_for_folder(dir: &Path, out_dir: Option<&Path>, opts: &PreviewOptions) -> Result<Written> {
    crate::io::status::require_complete(dir, true)?;
    let design_path = dir.join("design.json");
    if !design_path.is_file() {
        return Err(Error::invalid(
            dir.display().to_string(),
            "design.json",
            "missing: expected the output folder of `idexp excite` (design.json, coefficients.json, report.json)",
        ));
    }
    let design: ExciteDesign = serde_json::from_value(read_json(&design_path)?).map_err(|e| Error::parse(&design_path, e.to_string()))?;
    let ctx = design_path.display().to_string();
    let robot = crate::robot::load(&design.robot)?;
    let coeff_path = dir.join("coefficients.json");
    let coeff = read_json(&coeff_path)?;
    let tr: crate::trajectory::ShapeMotion =
        serde_json::from_value(coeff["trajectory"].clone()).map_err(|e| Error::invalid(coeff_path.display().to_string(), "trajectory", e.to_string()))?;
    let delivered: Option<Delivered> =
        serde_json::from_value(coeff["delivered"].clone()).map_err(|e| Error::invalid(coeff_path.display().to_string(), "delivered", e.to_string()))?;
    let delivered = delivered_or_periodic(delivered.as_ref(), &tr);
    if delivered.home.len() != robot.dof() {
        return Err(Error::invalid(
            coeff_path.display().to_string(),
            "delivered.home",
            format!("{} joints, but robot `{}` has {}", delivered.home.len(), robot.name, robot.dof()),
        ));
    }
    let mut setup = Setup::from_design(&design, robot, &ctx)?;
    let report_path = dir.join("report.json");
    if report_path.is_file() {
        let report = read_json(&report_path)?;
        let margins = report["result"]["margins"].as_array().cloned().unwrap_or_default();
        setup.report = report_instants(&margins, delivered.lead_in_duration());
    }
    let motion = Motion::Delivered {
        delivered,
        rate: design.trajectory.controller_rate,
    };
    let out = out_dir.unwrap_or(dir);
    crate::io::folder::check_out_dir(out)?;
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    write(&setup, &motion, opts, &out.join("preview.html"))
}

/// The page of a trajectory CSV ([`read_rows`]) played by the robot of
/// `robot_path`; with `design`, that excitation design's obstacles,
/// workspace and limits. Written into `out_dir` (default: the CSV's folder)
/// as `preview.html`.
pub fn write_for_trajectory(robot_path: &Path, csv: &Path, design: Option<&Path>, out_dir: Option<&Path>, opts: &PreviewOptions) -> Result<Written> {
    let robot = crate::robot::load(robot_path)?;
    let title = csv.display().to_string();
    let setup = match design {
        Some(dp) => {
            let d = ExciteDesign::load(dp)?;
            let mut s = Setup::from_design(&d, robot, &dp.display().to_string())?;
            s.title = format!("{} ({title})", d.name);
            s
        }
        None => Setup::from_robot(robot, &title)?,
    };
    let motion = read_rows(csv, setup.robot.dof())?;
    let dir = match out_dir {
        Some(d) => d.to_path_buf(),
        None => csv.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new(".")).to_path_buf(),
    };
    crate::io::folder::check_out_dir(&dir)?;
    std::fs::create_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
    write(&setup, &motion, opts, &dir.join("preview.html"))
}

/// Reads a trajectory CSV for a robot with `n` joints: columns `t`,
/// `q1..qn`, `qd1..qdn` (others ignored; `segment` used when present).
pub fn read_rows(path: &Path, n: usize) -> Result<Motion> {
    let table = crate::io::Table::read(path)?;
    let it = table.index("t").ok_or_else(|| Error::Data {
        path: path.into(),
        row: 0,
        column: "t".into(),
        msg: "missing: the preview needs the time of every row".into(),
    })?;
    let iq = table.numbered("q", n)?;
    let iqd = table.numbered("qd", n)?;
    let t = table.column(it);
    for k in 1..t.len() {
        if t[k] <= t[k - 1] {
            return Err(Error::Data {
                path: path.into(),
                row: k + 1,
                column: "t".into(),
                msg: format!("{} after {}: the times must increase", t[k], t[k - 1]),
            });
        }
    }
    let pick = |idx: &[usize]| table.rows.iter().flat_map(|r| idx.iter().map(|&i| r[i])).collect::<Vec<f64>>();
    let segment = table.index("segment").map(|i| table.column(i).iter().map(|&v| v as i64).collect());
    Ok(Motion::Rows {
        q: pick(&iq),
        qd: pick(&iqd),
        t,
        segment,
    })
}
