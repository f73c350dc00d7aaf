//! Robot logs as the robot or its middleware writes them, read into a
//! [`Repetition`] (layer 2, beside the run formats).
//!
//! Four forms ([`LogFormat`]), each described by a [`LogSpec`] (a TOML "map"
//! file, or built in code):
//!
//! - `csv`: a CSV with named columns and a column map: `q = "actual_q_{j}"`,
//!   `{j}` the joint number from `index_base` (0 or 1), torques `tau = …`
//!   **or** motor currents `current = …` (τ_j = s_j k_t,j N_j i_j with each
//!   drive's [`crate::robot::Drive::torque_per_ampere`], as
//!   [`crate::data::Run::read_drives`] converts `cur*` columns), optional
//!   velocities `qd` and accelerations `qdd`, the time column `t` in
//!   `time_unit` (s, ms, us, ns);
//! - `rtde`: the preset for Universal Robots' RTDE recorder (`record.py` of
//!   the RTDE client library): header `timestamp actual_q_0 … actual_qd_0 …
//!   actual_current_0 … target_moment_0 …`, space separated as the recorder
//!   writes it (commas accepted), `timestamp` the controller's uptime in s;
//!   torques from `actual_current_*` × s·k_t·N (default, `torque =
//!   "current"`) or the controller's `target_moment_*` (`torque =
//!   "target_moment"`: the torque the controller's own model commands);
//! - `headerless`: a numeric CSV without a header and a list giving each
//!   column's meaning (`columns = ["t", "q1", …, "tau1", …, "-"]`, `-` for a
//!   column to skip; names as in idexp's run CSV, `cur*` for currents);
//! - `bag`: a ROS 2 bag (MCAP or sqlite3 storage; a bag folder with its
//!   `metadata.yaml` or one `.mcap`/`.db3` file) of
//!   `sensor_msgs/msg/JointState` on `topic` (default: the only JointState
//!   topic), joints matched by name to the robot's (or to `joints`), extra
//!   joints ignored; position → q, velocity → qd, effort → τ; time from the
//!   header stamps (`stamps = "header"`) or the bag's receive times
//!   (`stamps = "receive"`).
//!
//! **Time.** Stamps are subtracted exactly before they become seconds: bag
//! stamps as integer nanoseconds since the epoch, CSV time cells as exact
//! decimals (the text `8123.456` is 8123456·10⁻³, not the nearest double),
//! so t_k = (stamp_k − stamp_0) loses nothing to the size of the epoch or of
//! the uptime. Irregular sampling is kept as it is (no resampling here; the
//! report gives the min/median/max step); stamps that do not increase are an
//! error naming the file, the row or message and the value.
//!
//! Every error names the file, the row (CSV data row, 1-based) or message
//! (1-based on its topic), the column, joint or topic, the value and what is
//! allowed. Files are read row by row and message by message: the memory
//! used beside the samples returned does not grow with the file.

mod bag;
pub mod cdr;
mod csv_map;
mod time;

pub use bag::{bag_info, BagInfo, TopicInfo};
pub use time::{parse_decimal, Decimal};

use crate::data::Repetition;
use crate::error::{Error, Result};
use crate::robot::Robot;
use std::path::{Path, PathBuf};

/// The form of a robot log.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LogFormat {
    /// CSV with a header and a column map.
    Csv,
    /// Universal Robots' RTDE recorder CSV (a preset of `csv`).
    Rtde,
    /// Numeric CSV without a header and a column list.
    Headerless,
    /// ROS 2 bag of `sensor_msgs/msg/JointState` (MCAP or sqlite3).
    Bag,
}

impl LogFormat {
    /// The name in files and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            LogFormat::Csv => "csv",
            LogFormat::Rtde => "rtde",
            LogFormat::Headerless => "headerless",
            LogFormat::Bag => "bag",
        }
    }
}

impl std::fmt::Display for LogFormat {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for LogFormat {
    type Err = Error;
    fn from_str(s: &str) -> Result<LogFormat> {
        match s {
            "csv" => Ok(LogFormat::Csv),
            "rtde" => Ok(LogFormat::Rtde),
            "headerless" => Ok(LogFormat::Headerless),
            "bag" => Ok(LogFormat::Bag),
            _ => Err(Error::invalid("log", "format", format!("expected csv, rtde, headerless or bag, found `{s}`"))),
        }
    }
}

/// Unit of a CSV time column.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub enum TimeUnit {
    /// Seconds.
    #[default]
    #[serde(rename = "s")]
    S,
    /// Milliseconds.
    #[serde(rename = "ms")]
    Ms,
    /// Microseconds.
    #[serde(rename = "us")]
    Us,
    /// Nanoseconds.
    #[serde(rename = "ns")]
    Ns,
}

impl TimeUnit {
    /// The power of ten of the unit in seconds (0, −3, −6, −9).
    pub fn exponent(self) -> i32 {
        match self {
            TimeUnit::S => 0,
            TimeUnit::Ms => -3,
            TimeUnit::Us => -6,
            TimeUnit::Ns => -9,
        }
    }

    /// The unit's symbol.
    pub fn name(self) -> &'static str {
        match self {
            TimeUnit::S => "s",
            TimeUnit::Ms => "ms",
            TimeUnit::Us => "us",
            TimeUnit::Ns => "ns",
        }
    }
}

/// The torque source of an RTDE recording.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RtdeTorque {
    /// `actual_current_*` (A) × each drive's s·k_t·N: the measured motor currents.
    #[default]
    Current,
    /// `target_moment_*` (N·m): the torque the controller's own model commands.
    TargetMoment,
}

/// The time of a bag message.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BagStamps {
    /// The message's `header.stamp` (sec, nanosec): when the driver sampled the joints.
    #[default]
    Header,
    /// The time the recorder received the message (the bag's log time).
    Receive,
}

/// How a log maps to idexp's run columns (a map file, `idexp log convert
/// --map`, or an experiment entry of the identification study).
///
/// Which fields apply depends on `format`; a field set for another format is
/// an error naming it. Defaults keep map files short: `format = "rtde"` or
/// `format = "bag"` alone is a complete spec.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LogSpec {
    /// The form of the log.
    pub format: LogFormat,
    /// Field separator of a CSV (`csv`, `rtde`, `headerless`): one ASCII
    /// character, `" "` for any run of spaces or tabs. Default: from the
    /// first line (`,` if it has one, else `;`, else tab, else whitespace).
    #[serde(default)]
    pub delimiter: Option<char>,
    /// `csv`: the time column (default `t`).
    #[serde(default)]
    pub t: Option<String>,
    /// `csv`, `headerless`: unit of the time column (`s`, `ms`, `us`, `ns`; default `s`).
    #[serde(default)]
    pub time_unit: Option<TimeUnit>,
    /// `csv`: the number `{j}` of the first joint in the column patterns, 0 or 1 (default 1).
    #[serde(default)]
    pub index_base: Option<u32>,
    /// `csv`: pattern of the position columns (rad or m), e.g. `"actual_q_{j}"`.
    #[serde(default)]
    pub q: Option<String>,
    /// `csv`: pattern of the velocity columns (optional).
    #[serde(default)]
    pub qd: Option<String>,
    /// `csv`: pattern of the acceleration columns (optional, only with `qd`).
    #[serde(default)]
    pub qdd: Option<String>,
    /// `csv`: pattern of the joint torque columns (N·m or N); or give `current`.
    #[serde(default)]
    pub tau: Option<String>,
    /// `csv`: pattern of the motor current columns (A), converted by the drives.
    #[serde(default)]
    pub current: Option<String>,
    /// `headerless`: each column's meaning: `t`, `q1`…, `qd1`…, `qdd1`…,
    /// `tau1`… or `cur1`…, `-` to skip a column.
    #[serde(default)]
    pub columns: Option<Vec<String>>,
    /// `rtde`: the torque source (`current`, default; `target_moment`).
    #[serde(default)]
    pub torque: Option<RtdeTorque>,
    /// `bag`: the JointState topic (default: the only one in the bag).
    #[serde(default)]
    pub topic: Option<String>,
    /// `bag`: the name in the log of each robot joint, in the robot's order
    /// (default: the robot's joint names).
    #[serde(default)]
    pub joints: Option<Vec<String>>,
    /// `bag`: the time of a message (`header`, default; `receive`).
    #[serde(default)]
    pub stamps: Option<BagStamps>,
}

impl LogSpec {
    /// The spec of `format` with every default (for `csv` and `headerless`
    /// the column map must still be given).
    pub fn new(format: LogFormat) -> LogSpec {
        LogSpec {
            format,
            delimiter: None,
            t: None,
            time_unit: None,
            index_base: None,
            q: None,
            qd: None,
            qdd: None,
            tau: None,
            current: None,
            columns: None,
            torque: None,
            topic: None,
            joints: None,
            stamps: None,
        }
    }

    /// The spec a front end asks for: a map (`map`, read from a file or
    /// given as data; `map_name` names it in messages), else the spec of
    /// `format`, else — for a folder or an `.mcap`/`.db3` file `log` — a bag;
    /// `format` and `topic` override the map's (a `format` that contradicts
    /// the map is an error). Validated; errors name `map_name`.
    pub fn resolve(map: Option<LogSpec>, map_name: &str, format: Option<LogFormat>, topic: Option<String>, log: Option<&Path>) -> Result<LogSpec> {
        let mut spec = match (map, format) {
            (Some(m), Some(f)) if m.format != f => {
                return Err(Error::invalid(
                    map_name,
                    "format",
                    format!("the map says format = \"{}\", but {f} was asked: give one of them", m.format),
                ))
            }
            (Some(m), _) => m,
            (None, Some(f)) => LogSpec::new(f),
            (None, None) => match log {
                Some(l) if l.is_dir() || l.extension().is_some_and(|e| e == "mcap" || e == "db3") => LogSpec::new(LogFormat::Bag),
                _ => {
                    return Err(Error::invalid(
                        log.map_or_else(|| map_name.to_string(), |l| l.display().to_string()),
                        "format",
                        "give the log's form (rtde, csv, headerless, bag; csv and headerless also need the column map)",
                    ))
                }
            },
        };
        if topic.is_some() {
            spec.topic = topic;
        }
        spec.validate(map_name)?;
        Ok(spec)
    }

    /// Reads and validates a map file (TOML).
    pub fn read(path: &Path) -> Result<LogSpec> {
        let spec: LogSpec = crate::io::read_toml(path)?;
        spec.validate(&path.display().to_string())?;
        Ok(spec)
    }

    /// Checks the fields that `format` uses and refuses those it does not;
    /// errors name `context` and the field.
    pub fn validate(&self, context: &str) -> Result<()> {
        use LogFormat::*;
        let set: [(&str, bool, &[LogFormat]); 14] = [
            ("delimiter", self.delimiter.is_some(), &[Csv, Rtde, Headerless]),
            ("t", self.t.is_some(), &[Csv]),
            ("time_unit", self.time_unit.is_some(), &[Csv, Headerless]),
            ("index_base", self.index_base.is_some(), &[Csv]),
            ("q", self.q.is_some(), &[Csv]),
            ("qd", self.qd.is_some(), &[Csv]),
            ("qdd", self.qdd.is_some(), &[Csv]),
            ("tau", self.tau.is_some(), &[Csv]),
            ("current", self.current.is_some(), &[Csv]),
            ("columns", self.columns.is_some(), &[Headerless]),
            ("torque", self.torque.is_some(), &[Rtde]),
            ("topic", self.topic.is_some(), &[Bag]),
            ("joints", self.joints.is_some(), &[Bag]),
            ("stamps", self.stamps.is_some(), &[Bag]),
        ];
        for (field, present, formats) in set {
            if present && !formats.contains(&self.format) {
                let names: Vec<&str> = formats.iter().map(|f| f.name()).collect();
                return Err(Error::invalid(
                    context,
                    field,
                    format!("applies to format {} only; this spec has format = \"{}\"", names.join(", "), self.format),
                ));
            }
        }
        if let Some(d) = self.delimiter {
            if !d.is_ascii() || matches!(d, '"' | '\n' | '\r' | '#') || d.is_ascii_alphanumeric() || d == '.' || d == '-' || d == '+' {
                return Err(Error::invalid(
                    context,
                    "delimiter",
                    format!("expected one ASCII separator such as \",\", \";\", \"\\t\" or \" \" (not a letter, digit, sign, point, quote or #), found {d:?}"),
                ));
            }
        }
        match self.format {
            Csv => {
                let q = self
                    .q
                    .as_deref()
                    .ok_or_else(|| Error::invalid(context, "q", "format csv needs the position column pattern, e.g. q = \"actual_q_{j}\""))?;
                for (field, v) in [
                    ("q", Some(q)),
                    ("qd", self.qd.as_deref()),
                    ("qdd", self.qdd.as_deref()),
                    ("tau", self.tau.as_deref()),
                    ("current", self.current.as_deref()),
                ] {
                    if let Some(p) = v {
                        csv_map::Pattern::parse(p).map_err(|m| Error::invalid(context, field, m))?;
                    }
                }
                match (&self.tau, &self.current) {
                    (None, None) => {
                        return Err(Error::invalid(
                            context,
                            "tau",
                            "format csv needs the torque columns: tau = \"…{j}…\" (joint torques) or current = \"…{j}…\" (motor currents, converted with the robot's drives)",
                        ))
                    }
                    (Some(_), Some(_)) => {
                        return Err(Error::invalid(
                            context,
                            "current",
                            "give either tau (joint torques) or current (motor currents), not both",
                        ))
                    }
                    _ => {}
                }
                if self.qdd.is_some() && self.qd.is_none() {
                    return Err(Error::invalid(context, "qdd", "logged accelerations need logged velocities: give qd too"));
                }
                if let Some(b) = self.index_base {
                    if b > 1 {
                        return Err(Error::invalid(context, "index_base", format!("expected 0 or 1, found {b}")));
                    }
                }
                if self.t.as_deref().is_some_and(|t| t.trim().is_empty()) {
                    return Err(Error::invalid(context, "t", "expected the name of the time column, found an empty string"));
                }
            }
            Headerless => {
                let cols = self.columns.as_ref().ok_or_else(|| {
                    Error::invalid(
                        context,
                        "columns",
                        "format headerless needs the column list, e.g. columns = [\"t\", \"q1\", \"q2\", \"tau1\", \"tau2\"]",
                    )
                })?;
                csv_map::check_column_list(cols).map_err(|m| Error::invalid(context, "columns", m))?;
            }
            Rtde => {}
            Bag => {
                if self.topic.as_deref().is_some_and(|t| t.trim().is_empty()) {
                    return Err(Error::invalid(
                        context,
                        "topic",
                        "expected a topic name such as /joint_states, found an empty string",
                    ));
                }
                if let Some(j) = &self.joints {
                    for (i, n) in j.iter().enumerate() {
                        if n.trim().is_empty() {
                            return Err(Error::invalid(context, "joints", format!("entry {}: empty joint name", i + 1)));
                        }
                        if j[..i].contains(n) {
                            return Err(Error::invalid(context, "joints", format!("joint `{n}` named twice")));
                        }
                    }
                }
            }
        }
        Ok(())
    }
}

/// Steps between consecutive samples (s).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct StepStats {
    /// Smallest step.
    pub min: f64,
    /// Median step.
    pub median: f64,
    /// Largest step.
    pub max: f64,
    /// Mean step (span / (samples − 1)).
    pub mean: f64,
    /// True when every step is within 0.1 % of the mean (what idexp's run CSV requires).
    pub uniform: bool,
}

impl StepStats {
    /// The statistics of the steps of increasing times `t` (none for fewer than 2).
    pub fn of(t: &[f64]) -> Option<StepStats> {
        StepStats::from_steps(t.windows(2).map(|w| w[1] - w[0]).collect())
    }

    /// The statistics of the steps `d` (none when empty).
    pub fn from_steps(mut d: Vec<f64>) -> Option<StepStats> {
        if d.is_empty() {
            return None;
        }
        let mean = d.iter().sum::<f64>() / d.len() as f64;
        let uniform = d.iter().all(|s| (s - mean).abs() <= 1e-3 * mean);
        let min = d.iter().copied().fold(f64::INFINITY, f64::min);
        let max = d.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let mid = d.len() / 2;
        let (_, m, _) = d.select_nth_unstable_by(mid, f64::total_cmp);
        let median = *m;
        Some(StepStats {
            min,
            median,
            max,
            mean,
            uniform,
        })
    }

    /// One line for reports.
    pub fn text(&self) -> String {
        format!(
            "steps min/median/max {:.6}/{:.6}/{:.6} s (mean {:.6} s, {:.2} Hz){}",
            self.min,
            self.median,
            self.max,
            self.mean,
            1.0 / self.mean,
            if self.uniform { ", uniform" } else { ", irregular" }
        )
    }
}

/// Where each run column came from.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ColumnUse {
    /// The run column (`t`, `q1`, `tau3`, …).
    pub column: String,
    /// Its source in the log (a CSV column, a joint's field in a bag).
    pub source: String,
}

/// What [`read_log`] did: the source, the columns used, the time span and
/// the irregularity of the steps, for reports.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct LogReport {
    /// The log file or bag folder.
    pub file: PathBuf,
    /// The format it was read as.
    pub format: LogFormat,
    /// A description of the source (storage, topic, delimiter, …).
    pub source: String,
    /// Samples read.
    pub samples: usize,
    /// The first stamp as recorded (text), e.g. `1733400000.123456789 s since the epoch`.
    pub start: String,
    /// Time span (s) from the first to the last sample.
    pub span: f64,
    /// The steps between samples (none for a single sample).
    pub steps: Option<StepStats>,
    /// Where each run column came from.
    pub columns: Vec<ColumnUse>,
    /// How the joint torques were obtained.
    pub torque: String,
    /// Per joint s·k_t·N (N·m/A, joint side) when torques came from currents.
    pub torque_per_ampere: Option<Vec<f64>>,
    /// Log content not used (extra joints, other topics, columns).
    pub ignored: Vec<String>,
}

impl LogReport {
    /// A few lines for reports.
    pub fn text(&self) -> String {
        let mut s = format!(
            "{} ({}): {} samples from {}, span {:.6} s",
            self.file.display(),
            self.source,
            self.samples,
            self.start,
            self.span
        );
        if let Some(st) = &self.steps {
            s += &format!("; {}", st.text());
        }
        s += &format!("\n  torques: {}", self.torque);
        let cols: Vec<String> = self.columns.iter().map(|c| format!("{} ← {}", c.column, c.source)).collect();
        s += &format!("\n  columns: {}", cols.join(", "));
        if !self.ignored.is_empty() {
            s += &format!("\n  not used: {}", self.ignored.join("; "));
        }
        s
    }
}

/// A log read: the samples as one repetition (t from 0 at the first sample,
/// possibly irregular) and what was done.
#[derive(Debug, Clone)]
pub struct LogRead {
    /// The samples.
    pub rep: Repetition,
    /// What was read from where.
    pub report: LogReport,
}

/// Reads the log at `path` (a file, or a bag folder) for `robot` as `spec`
/// says. The spec is validated first (context: the path).
pub fn read_log(path: &Path, robot: &Robot, spec: &LogSpec) -> Result<LogRead> {
    spec.validate(&format!("log spec for {}", path.display()))?;
    if !path.exists() {
        return Err(Error::io(path, std::io::Error::new(std::io::ErrorKind::NotFound, "no such file or folder")));
    }
    match spec.format {
        LogFormat::Bag => bag::read(path, robot, spec),
        _ => csv_map::read(path, robot, spec),
    }
}

/// Per joint s·k_t·N (N·m/A, joint side) of the robot's drives, for current
/// columns named `columns` (one per joint) of `file`; an error names the
/// first joint whose drive has no torque constant. The same conversion as
/// [`crate::data::Run::read_drives`] applies to `cur*` columns.
pub fn torque_per_ampere(robot: &Robot, file: &Path, columns: &[String]) -> Result<Vec<f64>> {
    robot
        .drives
        .iter()
        .enumerate()
        .map(|(j, d)| {
            d.torque_per_ampere().ok_or_else(|| Error::Data {
                path: file.to_path_buf(),
                row: 0,
                column: columns.get(j).cloned().unwrap_or_default(),
                msg: format!(
                    "a current column for joint `{}`, but its drive has no torque_constant in the robot file {}: add torque_constant = k_t (N·m/A, motor side) and gear_ratio to its [[drive]] entry (τ = current_sign·k_t·N·i), or take torques from another column",
                    robot.joints[j].name, robot.source
                ),
            })
        })
        .collect()
}

/// Samples gathered row by row (or message by message): strictly increasing
/// exact stamps, converted to seconds from the first.
struct Samples {
    file: PathBuf,
    /// The first stamp (exact) and its text.
    first: Option<(Decimal, String)>,
    /// The previous stamp, for the order check.
    prev: Option<Decimal>,
    rep: Repetition,
}

impl Samples {
    fn new(file: &Path, with_qd: bool, with_qdd: bool) -> Samples {
        Samples {
            file: file.to_path_buf(),
            first: None,
            prev: None,
            rep: Repetition {
                t: Vec::new(),
                q: Vec::new(),
                tau: Vec::new(),
                r: None,
                qd: with_qd.then(Vec::new),
                qdd: with_qdd.then(Vec::new),
            },
        }
    }

    /// Appends the stamp `ts` (text `raw` for messages); `at` names the row
    /// or message for an error. Returns an error message when the stamp does
    /// not increase.
    fn time(&mut self, ts: Decimal, raw: impl FnOnce() -> String) -> std::result::Result<(), String> {
        if let Some(p) = self.prev {
            if ts.cmp_exact(&p) != std::cmp::Ordering::Greater {
                let what = if ts.cmp_exact(&p) == std::cmp::Ordering::Equal {
                    "a duplicate of"
                } else {
                    "before"
                };
                return Err(format!(
                    "time stamp {} is {what} the previous one ({}): stamps must increase strictly",
                    raw(),
                    p.text()
                ));
            }
        }
        let t = match &self.first {
            None => {
                self.first = Some((ts, raw()));
                0.0
            }
            Some((t0, _)) => ts.seconds_since(t0),
        };
        self.prev = Some(ts);
        self.rep.t.push(t);
        Ok(())
    }

    /// The repetition and the time part of the report; `what` names a sample
    /// for the "no samples" error.
    fn finish(self, what: &str) -> Result<(Repetition, String, f64, Option<StepStats>)> {
        let Some((_, start)) = self.first else {
            return Err(Error::parse(&self.file, format!("no {what} to read: the log holds no samples")));
        };
        let span = self.rep.t.last().copied().unwrap_or(0.0);
        let steps = StepStats::of(&self.rep.t);
        Ok((self.rep, start, span, steps))
    }
}

/// A run from robot logs: each path one repetition read by [`read_log`],
/// irregular stamps resampled to a common uniform grid
/// ([`crate::data::resample::resample_run`]: `rate` Hz, default the inverse
/// median step; at most `limit` samples). Returns the run, how its torques
/// were obtained, what was done with the time stamps, and each log's report.
pub fn read_run(
    paths: &[PathBuf],
    robot: &Robot,
    spec: &LogSpec,
    rate: Option<f64>,
    limit: usize,
) -> Result<(crate::data::Run, crate::data::TorqueSource, crate::data::Sampling, Vec<LogReport>)> {
    if paths.is_empty() {
        return Err(Error::invalid("log", "files", "expected at least one log file or bag folder"));
    }
    let mut reps = Vec::with_capacity(paths.len());
    let mut reports = Vec::with_capacity(paths.len());
    for p in paths {
        let r = read_log(p, robot, spec)?;
        reps.push(r.rep);
        reports.push(r.report);
    }
    let sampling = crate::data::resample::resample_run(&mut reps, paths, rate, limit)?;
    let run = crate::data::Run::new(paths.to_vec(), reps)?;
    let tpa = reports[0].torque_per_ampere.clone();
    let source = crate::data::TorqueSource {
        from: if tpa.is_some() {
            crate::data::TorqueColumns::Current
        } else {
            crate::data::TorqueColumns::Torque
        },
        torque_per_ampere: tpa,
        agreement: None,
        tolerance: crate::data::CURRENT_TOLERANCE,
        note: format!("{} log: {}", spec.format.name(), reports[0].torque),
    };
    Ok((run, source, sampling, reports))
}
