//! CSV logs: named columns with a column map (`csv`), the RTDE recorder's
//! preset (`rtde`) and numeric CSVs with a column list (`headerless`), read
//! line by line.

use super::{torque_per_ampere, ColumnUse, Decimal, LogFormat, LogRead, LogReport, LogSpec, RtdeTorque, Samples, TimeUnit};
use crate::error::{Error, Result};
use crate::robot::Robot;
use std::io::{BufRead, BufReader, Read};
use std::path::Path;

/// The longest line read (bytes): a longer one is an error, not an allocation.
const MAX_LINE: u64 = 1 << 20;

/// A column-name pattern with one `{j}` (the joint number).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Pattern {
    prefix: String,
    suffix: String,
}

impl Pattern {
    /// Parses `text`: exactly one `{j}`, the rest taken literally.
    pub fn parse(text: &str) -> std::result::Result<Pattern, String> {
        let n = text.matches("{j}").count();
        if n != 1 {
            return Err(format!(
                "expected a column name pattern with one {{j}} for the joint number (e.g. \"actual_q_{{j}}\"), found {text:?} with {n}"
            ));
        }
        let i = text.find("{j}").unwrap_or(0);
        Ok(Pattern {
            prefix: text[..i].to_string(),
            suffix: text[i + 3..].to_string(),
        })
    }

    /// The column of joint number `j`.
    pub fn name(&self, j: usize) -> String {
        format!("{}{j}{}", self.prefix, self.suffix)
    }

    /// The pattern's text.
    pub fn text(&self) -> String {
        format!("{}{{j}}{}", self.prefix, self.suffix)
    }
}

/// The quantities of a headerless column list.
const QUANTITIES: [&str; 5] = ["qdd", "qd", "q", "tau", "cur"];

/// Splits `q3` into (`q`, 3); `None` for anything else.
fn numbered(name: &str) -> Option<(&'static str, usize)> {
    for p in QUANTITIES {
        if let Some(rest) = name.strip_prefix(p) {
            if !rest.is_empty() && rest.bytes().all(|b| b.is_ascii_digit()) && !rest.starts_with('0') {
                return rest.parse().ok().map(|i| (p, i));
            }
        }
    }
    None
}

/// Checks a headerless column list (names, duplicates, `t` present).
pub fn check_column_list(cols: &[String]) -> std::result::Result<(), String> {
    if cols.is_empty() {
        return Err("expected at least the columns t, q1.., tau1.. (or cur1..)".into());
    }
    for (i, c) in cols.iter().enumerate() {
        let c = c.trim();
        if c != "t" && c != "-" && numbered(c).is_none() {
            return Err(format!(
                "entry {} {c:?}: expected t, q<j>, qd<j>, qdd<j>, tau<j>, cur<j> (j from 1) or - (a column to skip)",
                i + 1
            ));
        }
        if c != "-" && cols[..i].iter().any(|p| p.trim() == c) {
            return Err(format!("entry {} {c:?}: named twice", i + 1));
        }
    }
    if !cols.iter().any(|c| c.trim() == "t") {
        return Err("no time column: the list needs a \"t\"".into());
    }
    Ok(())
}

/// How fields are separated.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Delim {
    Char(char),
    Whitespace,
}

impl Delim {
    fn of(spec: Option<char>, first_line: &str) -> Delim {
        match spec {
            Some(' ') | Some('\t') => Delim::Whitespace,
            Some(c) => Delim::Char(c),
            None if first_line.contains(',') => Delim::Char(','),
            None if first_line.contains(';') => Delim::Char(';'),
            None => Delim::Whitespace,
        }
    }

    fn text(self) -> String {
        match self {
            Delim::Char(c) => format!("{c:?}-separated"),
            Delim::Whitespace => "whitespace-separated".into(),
        }
    }
}

/// A line reader: one line in memory at a time, comments (`#`) and blank
/// lines skipped, each line at most [`MAX_LINE`] bytes.
struct Lines<R> {
    reader: BufReader<R>,
    buf: String,
    /// 1-based number of the line in `buf`.
    line: usize,
}

impl<R: Read> Lines<R> {
    /// The next content line, or None at the end.
    fn next(&mut self, path: &Path) -> Result<Option<&str>> {
        loop {
            self.buf.clear();
            let n = (&mut self.reader)
                .take(MAX_LINE + 1)
                .read_line(&mut self.buf)
                .map_err(|e| Error::parse(path, format!("line {}: {e} (a CSV log must be UTF-8 text)", self.line + 1)))?;
            if n == 0 {
                return Ok(None);
            }
            self.line += 1;
            if n as u64 > MAX_LINE {
                return Err(Error::parse(path, format!("line {} is longer than {MAX_LINE} bytes: not a CSV log", self.line)));
            }
            let s = self.buf.trim_start_matches('\u{feff}').trim();
            if !s.is_empty() && !s.starts_with('#') {
                return Ok(Some(self.buf.trim_start_matches('\u{feff}').trim()));
            }
        }
    }
}

/// Splits a line into fields (trimmed, one pair of surrounding quotes dropped).
fn split<'a>(line: &'a str, d: Delim, out: &mut Vec<&'a str>) {
    out.clear();
    let clean = |f: &'a str| {
        let f = f.trim();
        f.strip_prefix('"').and_then(|x| x.strip_suffix('"')).unwrap_or(f)
    };
    match d {
        Delim::Char(c) => out.extend(line.split(c).map(clean)),
        Delim::Whitespace => out.extend(line.split_ascii_whitespace().map(clean)),
    }
}

/// Column indices of each quantity and how torques are obtained.
struct Plan {
    t: usize,
    q: Vec<usize>,
    qd: Option<Vec<usize>>,
    qdd: Option<Vec<usize>>,
    tau: Vec<usize>,
    /// s·k_t·N per joint when `tau` holds currents.
    scale: Option<Vec<f64>>,
    /// The name of each field (header or column list), for messages.
    names: Vec<String>,
    torque: String,
}

/// The column map of a spec with a header (`csv`, `rtde`).
struct Map {
    t: String,
    base: usize,
    q: Pattern,
    qd: Option<Pattern>,
    qdd: Option<Pattern>,
    tau: Pattern,
    /// The torque pattern holds currents.
    current: bool,
}

impl Map {
    fn of(spec: &LogSpec) -> std::result::Result<Map, String> {
        let p = |s: &Option<String>| s.as_deref().map(Pattern::parse).transpose();
        if spec.format == LogFormat::Rtde {
            let current = spec.torque.unwrap_or_default() == RtdeTorque::Current;
            return Ok(Map {
                t: "timestamp".into(),
                base: 0,
                q: Pattern::parse("actual_q_{j}")?,
                qd: Some(Pattern::parse("actual_qd_{j}")?),
                qdd: None,
                tau: Pattern::parse(if current { "actual_current_{j}" } else { "target_moment_{j}" })?,
                current,
            });
        }
        let (tau, current) = match (&spec.tau, &spec.current) {
            (Some(t), _) => (t, false),
            (None, Some(c)) => (c, true),
            (None, None) => return Err("no torque columns (tau or current)".into()),
        };
        Ok(Map {
            t: spec.t.clone().unwrap_or_else(|| "t".into()),
            base: spec.index_base.unwrap_or(1) as usize,
            q: Pattern::parse(spec.q.as_deref().unwrap_or_default())?,
            qd: p(&spec.qd)?,
            qdd: p(&spec.qdd)?,
            tau: Pattern::parse(tau)?,
            current,
        })
    }
}

/// s·k_t·N per joint for the current columns `cols` (named `what` in the
/// report) and the report's line.
fn currents(robot: &Robot, path: &Path, cols: &[String], what: &str) -> Result<(Vec<f64>, String)> {
    let s = torque_per_ampere(robot, path, cols)?;
    let text = format!(
        "motor currents {what} (A) × s·k_t·N = [{}] N·m/A of the robot's drives",
        s.iter().map(|v| format!("{v}")).collect::<Vec<_>>().join(", ")
    );
    Ok((s, text))
}

fn header_plan(path: &Path, robot: &Robot, spec: &LogSpec, header: &[&str]) -> Result<Plan> {
    let n = robot.dof();
    let map = Map::of(spec).map_err(|m| Error::invalid(path.display().to_string(), "log spec", m))?;
    let names: Vec<String> = header.iter().map(|s| s.to_string()).collect();
    for (i, c) in names.iter().enumerate() {
        if names[..i].contains(c) {
            return Err(Error::Data {
                path: path.into(),
                row: 0,
                column: c.clone(),
                msg: "duplicate column name in the header".into(),
            });
        }
    }
    let shown = || {
        let mut s: Vec<&str> = names.iter().take(12).map(String::as_str).collect();
        if names.len() > 12 {
            s.push("…");
        }
        format!("{} ({} columns)", s.join(", "), names.len())
    };
    let find = |c: &str, what: String| -> Result<usize> {
        names.iter().position(|h| h == c).ok_or_else(|| Error::Data {
            path: path.into(),
            row: 0,
            column: c.into(),
            msg: format!("missing column ({what}); the header has: {}", shown()),
        })
    };
    let family = |p: &Pattern, field: &str| -> Result<Vec<usize>> {
        let idx = (0..n)
            .map(|j| {
                find(
                    &p.name(j + map.base),
                    format!("{field} = \"{}\", joint {} `{}`", p.text(), j + 1, robot.joints[j].name),
                )
            })
            .collect::<Result<Vec<_>>>()?;
        let extra = p.name(n + map.base);
        if names.contains(&extra) {
            return Err(Error::Data {
                path: path.into(),
                row: 0,
                column: extra,
                msg: format!(
                    "the robot has {n} joints but the log has more `{}` columns (index_base = {}): use a robot with all the logged joints",
                    p.text(),
                    map.base
                ),
            });
        }
        Ok(idx)
    };
    let t = find(
        &map.t,
        if spec.format == LogFormat::Rtde {
            "the RTDE recorder's timestamp".into()
        } else {
            "the time column t".into()
        },
    )?;
    let q = family(&map.q, "q")?;
    let qd = map.qd.as_ref().map(|p| family(p, "qd")).transpose()?;
    let qdd = map.qdd.as_ref().map(|p| family(p, "qdd")).transpose()?;
    let tau_field = if map.current { "current" } else { "tau" };
    let tau = family(&map.tau, tau_field)?;
    let cols: Vec<String> = tau.iter().map(|&i| names[i].clone()).collect();
    let (scale, torque) = if map.current {
        let (s, text) = currents(robot, path, &cols, &map.tau.text())?;
        (Some(s), text)
    } else if spec.format == LogFormat::Rtde {
        (
            None,
            "the controller's target_moment_{j} (N·m): the torque its own model commands, not a measurement".into(),
        )
    } else {
        (None, format!("joint torques {}", map.tau.text()))
    };
    Ok(Plan {
        t,
        q,
        qd,
        qdd,
        tau,
        scale,
        names,
        torque,
    })
}

fn list_plan(path: &Path, robot: &Robot, cols: &[String]) -> Result<Plan> {
    let n = robot.dof();
    let err = |column: &str, msg: String| Error::Data {
        path: path.into(),
        row: 0,
        column: column.into(),
        msg,
    };
    let names: Vec<String> = cols.iter().map(|c| c.trim().to_string()).collect();
    let mut fam: std::collections::BTreeMap<&str, Vec<Option<usize>>> = QUANTITIES.iter().map(|&p| (p, vec![None; n])).collect();
    for (i, c) in names.iter().enumerate() {
        if let Some((p, j)) = numbered(c) {
            if j > n {
                return Err(err(c, format!("the column list names joint {j}, but the robot has {n} joints")));
            }
            if let Some(v) = fam.get_mut(p) {
                v[j - 1] = Some(i);
            }
        }
    }
    let t = names
        .iter()
        .position(|c| c == "t")
        .ok_or_else(|| err("t", "the column list has no time column t".into()))?;
    let get = |p: &str, required: bool| -> Result<Option<Vec<usize>>> {
        let v = &fam[p];
        let present = v.iter().filter(|x| x.is_some()).count();
        if present == 0 && !required {
            return Ok(None);
        }
        if let Some(j) = v.iter().position(|x| x.is_none()) {
            return Err(err(
                &format!("{p}{}", j + 1),
                format!(
                    "the column list has no {p}{} for joint `{}`: {p}* columns are given for every joint ({p}1..{p}{n})",
                    j + 1,
                    robot.joints[j].name
                ) + if present == 0 { "" } else { " or for none" },
            ));
        }
        Ok(Some(v.iter().map(|x| x.unwrap_or(0)).collect()))
    };
    let q = get("q", true)?.unwrap_or_default();
    let has_tau = fam["tau"].iter().any(Option::is_some);
    let has_cur = fam["cur"].iter().any(Option::is_some);
    if has_tau && has_cur {
        return Err(err("cur1", "the column list has both tau* and cur* columns: give one torque source".into()));
    }
    let qd = get("qd", false)?;
    let qdd = get("qdd", false)?;
    if qdd.is_some() && qd.is_none() {
        return Err(err("qd1", "logged accelerations qdd* need logged velocities qd*".into()));
    }
    let (tau, scale, torque) = if has_cur {
        let tau = get("cur", true)?.unwrap_or_default();
        let cols: Vec<String> = (1..=n).map(|j| format!("cur{j}")).collect();
        let (s, text) = currents(robot, path, &cols, "cur*")?;
        (tau, Some(s), text)
    } else {
        (get("tau", true)?.unwrap_or_default(), None, "joint torques tau*".to_string())
    };
    let names = names.iter().enumerate().map(|(i, c)| format!("{c} (field {})", i + 1)).collect();
    Ok(Plan {
        t,
        q,
        qd,
        qdd,
        tau,
        scale,
        names,
        torque,
    })
}

/// Reads a `csv`, `rtde` or `headerless` log.
pub(super) fn read(path: &Path, robot: &Robot, spec: &LogSpec) -> Result<LogRead> {
    let meta = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    if !meta.is_file() {
        return Err(Error::io(
            path,
            std::io::Error::other(format!("is not a regular file; a {} log is one CSV file", spec.format)),
        ));
    }
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let mut lines = Lines {
        reader: BufReader::with_capacity(1 << 16, file),
        buf: String::new(),
        line: 0,
    };
    let unit = if spec.format == LogFormat::Rtde {
        TimeUnit::S
    } else {
        spec.time_unit.unwrap_or_default()
    };
    let first = lines
        .next(path)?
        .ok_or_else(|| Error::parse(path, "empty file: no header or data line"))?
        .to_string();
    let delim = Delim::of(spec.delimiter, &first);
    let (plan, pending) = if spec.format == LogFormat::Headerless {
        let cols = spec.columns.as_deref().unwrap_or_default();
        (list_plan(path, robot, cols)?, Some(first))
    } else {
        let mut header = Vec::new();
        split(&first, delim, &mut header);
        (header_plan(path, robot, spec, &header)?, None)
    };
    let width = plan.names.len();
    let mut s = Samples::new(path, plan.qd.is_some(), plan.qdd.is_some());
    let mut row = 0usize;
    let mut handle = |line: &str, row: usize| -> Result<()> {
        let mut f: Vec<&str> = Vec::with_capacity(width);
        split(line, delim, &mut f);
        if f.len() != width {
            return Err(Error::Data {
                path: path.into(),
                row,
                column: plan.names.get(f.len().min(width.saturating_sub(1))).cloned().unwrap_or_default(),
                msg: format!(
                    "expected {width} values ({}), found {}",
                    if spec.format == LogFormat::Headerless {
                        "one per entry of the column list"
                    } else {
                        "as in the header"
                    },
                    f.len()
                ),
            });
        }
        let cell = f[plan.t];
        let ts = super::parse_decimal(cell).map_err(|m| Error::Data {
            path: path.into(),
            row,
            column: plan.names[plan.t].clone(),
            msg: format!("time: {m}"),
        })?;
        let ts = Decimal {
            mantissa: ts.mantissa,
            exponent: ts.exponent.saturating_add(unit.exponent()),
        };
        s.time(ts, || format!("{cell} {}", unit.name())).map_err(|msg| Error::Data {
            path: path.into(),
            row,
            column: plan.names[plan.t].clone(),
            msg,
        })?;
        let value = |i: usize| -> Result<f64> {
            let c = f[i];
            match c.parse::<f64>() {
                Ok(v) if v.is_finite() => Ok(v),
                Ok(_) => Err(Error::Data {
                    path: path.into(),
                    row,
                    column: plan.names[i].clone(),
                    msg: format!("expected a finite number, found {c}"),
                }),
                Err(_) => Err(Error::Data {
                    path: path.into(),
                    row,
                    column: plan.names[i].clone(),
                    msg: format!("expected a number, found {c:?}"),
                }),
            }
        };
        let pick = |idx: &[usize]| idx.iter().map(|&i| value(i)).collect::<Result<Vec<f64>>>();
        s.rep.q.push(pick(&plan.q)?);
        let mut tau = pick(&plan.tau)?;
        if let Some(sc) = &plan.scale {
            tau.iter_mut().zip(sc).for_each(|(t, k)| *t *= k);
        }
        s.rep.tau.push(tau);
        if let (Some(idx), Some(v)) = (&plan.qd, s.rep.qd.as_mut()) {
            v.push(pick(idx)?);
        }
        if let (Some(idx), Some(v)) = (&plan.qdd, s.rep.qdd.as_mut()) {
            v.push(pick(idx)?);
        }
        Ok(())
    };
    if let Some(line) = pending {
        row += 1;
        handle(&line, row)?;
    }
    while let Some(line) = lines.next(path)? {
        row += 1;
        handle(line, row)?;
    }
    let (rep, start, span, steps) = s.finish("data rows")?;
    let src = |idx: &[usize]| idx.iter().map(|&i| plan.names[i].clone()).collect::<Vec<_>>();
    let mut columns = vec![ColumnUse {
        column: "t".into(),
        source: format!("{} ({})", plan.names[plan.t], unit.name()),
    }];
    let mut used = vec![plan.t];
    for (p, idx) in [
        ("q", Some(&plan.q)),
        ("qd", plan.qd.as_ref()),
        ("qdd", plan.qdd.as_ref()),
        ("tau", Some(&plan.tau)),
    ] {
        if let Some(idx) = idx {
            used.extend(idx);
            columns.extend(src(idx).into_iter().enumerate().map(|(j, c)| ColumnUse {
                column: format!("{p}{}", j + 1),
                source: match (&plan.scale, p) {
                    (Some(k), "tau") => format!("{c} × {} N·m/A", k[j]),
                    _ => c,
                },
            }));
        }
    }
    let unused: Vec<&str> = (0..width).filter(|i| !used.contains(i)).map(|i| plan.names[i].as_str()).collect();
    let mut ignored = Vec::new();
    if !unused.is_empty() {
        let mut list: Vec<&str> = unused.iter().take(8).copied().collect();
        if unused.len() > 8 {
            list.push("…");
        }
        ignored.push(format!("{} column(s): {}", unused.len(), list.join(", ")));
    }
    let source = match spec.format {
        LogFormat::Rtde => format!("RTDE recorder CSV, {}", delim.text()),
        LogFormat::Headerless => format!("headerless CSV, {}, {} columns", delim.text(), width),
        _ => format!("CSV with a column map, {}", delim.text()),
    };
    Ok(LogRead {
        report: LogReport {
            file: path.to_path_buf(),
            format: spec.format,
            source,
            samples: rep.len(),
            start: format!(
                "{} = {start}{}",
                plan.names[plan.t],
                if spec.format == LogFormat::Rtde { " (controller uptime)" } else { "" }
            ),
            span,
            steps,
            columns,
            torque: plan.torque.clone(),
            torque_per_ampere: plan.scale.clone(),
            ignored,
        },
        rep,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn patterns_and_column_lists() {
        let p = Pattern::parse("actual_q_{j}").unwrap();
        assert_eq!(p.name(0), "actual_q_0");
        assert_eq!(p.text(), "actual_q_{j}");
        assert!(Pattern::parse("q").is_err());
        assert!(Pattern::parse("q{j}_{j}").is_err());
        assert_eq!(Pattern::parse("{j}").unwrap().name(3), "3");
        let l = |v: &[&str]| v.iter().map(|s| s.to_string()).collect::<Vec<_>>();
        assert!(check_column_list(&l(&["t", "q1", "tau1", "-", "-"])).is_ok());
        assert!(check_column_list(&l(&["q1", "tau1"])).unwrap_err().contains("time"));
        assert!(check_column_list(&l(&["t", "q1", "q1"])).unwrap_err().contains("twice"));
        assert!(check_column_list(&l(&["t", "q0"])).is_err());
        assert!(check_column_list(&l(&["t", "x1"])).is_err());
        assert_eq!(numbered("qdd12"), Some(("qdd", 12)));
        assert_eq!(numbered("cur1"), Some(("cur", 1)));
        assert_eq!(numbered("q01"), None);
    }
}
