//! One `status.json` schema for every command's output folder.
//!
//! ```json
//! {
//!   "command": "excite",
//!   "status": "complete",
//!   "detail": "feasible, cond 12.3",
//!   "started": "2026-01-01T12:00:00Z",
//!   "finished": "2026-01-01T12:00:41Z",
//!   "idexp_version": "0.1.0",
//!   "design_fingerprint": "9c2f0d1e3b4a5c6d",
//!   "summary": { "...": "command-specific fields" }
//! }
//! ```
//!
//! * `status` is one word of [`RunState`]; `detail` is one human sentence.
//! * `started`/`finished` are RFC 3339 UTC times with whole seconds;
//!   `started` is `null` where the writer does not know when the run began.
//! * `design_fingerprint` is the 64-bit FNV-1a hash ([`fingerprint`], 16 hex
//!   digits) of the resolved design (or inputs) serialised as JSON: two
//!   folders with the same fingerprint were computed from the same inputs.
//! * `summary` holds whatever the command adds (JSON object).

use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};
use std::path::Path;
use std::time::{SystemTime, UNIX_EPOCH};

/// How a run ended, as written in `status.json`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RunState {
    /// Still running (written at the start of long, resumable runs).
    Running,
    /// Finished; the result is usable.
    Complete,
    /// One shard of a sharded run finished; merge the shards for the result.
    ShardComplete,
    /// Finished, but the design violates its constraints.
    Infeasible,
    /// Finished, but the solver or estimator failed (the result is not usable).
    Failed,
    /// Stopped early (Ctrl-C or a time limit); the files written are valid and partial.
    Interrupted,
}

impl RunState {
    /// The word written in `status.json`.
    pub fn as_str(self) -> &'static str {
        match self {
            RunState::Running => "running",
            RunState::Complete => "complete",
            RunState::ShardComplete => "shard_complete",
            RunState::Infeasible => "infeasible",
            RunState::Failed => "failed",
            RunState::Interrupted => "interrupted",
        }
    }
}

impl std::fmt::Display for RunState {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// The contents of `status.json` (see the module documentation).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StatusFile {
    /// The command that wrote the folder (`excite`, `fit`, ...).
    pub command: String,
    /// How the run ended.
    pub status: RunState,
    /// One human sentence about the outcome.
    pub detail: String,
    /// Start time, RFC 3339 UTC (`null`: unknown to the writer).
    pub started: Option<String>,
    /// End time, RFC 3339 UTC.
    pub finished: String,
    /// idexp version (the crate's).
    pub idexp_version: String,
    /// 16 hex digits of FNV-1a over the resolved design's JSON ([`fingerprint`]).
    pub design_fingerprint: String,
    /// Command-specific fields (a JSON object, `{}` when there are none).
    pub summary: serde_json::Value,
}

impl StatusFile {
    /// A status finished now. `started`: when the run began, if known.
    pub fn now(
        command: &str,
        status: RunState,
        detail: impl Into<String>,
        started: Option<SystemTime>,
        design_fingerprint: String,
        summary: serde_json::Value,
    ) -> StatusFile {
        StatusFile {
            command: command.to_string(),
            status,
            detail: detail.into(),
            started: started.map(rfc3339),
            finished: rfc3339(SystemTime::now()),
            idexp_version: env!("CARGO_PKG_VERSION").to_string(),
            design_fingerprint,
            summary,
        }
    }

    /// Writes `dir/status.json` atomically. A final status (anything but
    /// `running`) also removes the previous result set that
    /// [`super::folder::begin`] moved aside.
    pub fn write(&self, dir: &Path) -> Result<()> {
        super::write_json(&dir.join("status.json"), self)?;
        if self.status != RunState::Running {
            super::folder::discard_previous(dir);
        }
        Ok(())
    }

    /// Reads a `status.json` (an error names the file and the field).
    pub fn read(path: &Path) -> Result<StatusFile> {
        let text = super::read_to_string(path)?;
        serde_json::from_str(&text).map_err(|e| Error::parse(path, e.to_string()))
    }
}

/// Refuses `dir` as an input folder unless its `status.json` says
/// `complete` (or there is no `status.json`: a folder recorded outside idexp).
/// `allow_incomplete` accepts a folder marked `interrupted`, `failed`,
/// `infeasible` or `shard_complete` (never one marked `running`: its writer
/// was killed while writing, so its files are partial).
pub fn require_complete(dir: &Path, allow_incomplete: bool) -> Result<()> {
    let dir = if dir.is_file() { dir.parent().unwrap_or(Path::new(".")) } else { dir };
    let path = dir.join("status.json");
    if !path.exists() {
        return Ok(());
    }
    let s = StatusFile::read(&path)?;
    match s.status {
        RunState::Complete => Ok(()),
        RunState::Running => Err(Error::invalid(
            path.display().to_string(),
            "status",
            format!(
                "`running`: the `{}` run that writes this folder has not finished (or was killed while writing), so its files are partial; run it again",
                s.command
            ),
        )),
        other if allow_incomplete => {
            let _ = other;
            Ok(())
        }
        other => Err(Error::invalid(
            path.display().to_string(),
            "status",
            format!(
                "`{other}` ({}): the folder is not a complete result; accept it with allow_incomplete (the command line's flag of that name)",
                s.detail
            ),
        )),
    }
}

/// Writes `dir/status.json` for `command` (see [`StatusFile::now`]).
pub fn write_status(
    dir: &Path,
    command: &str,
    status: RunState,
    detail: impl Into<String>,
    started: Option<SystemTime>,
    design_fingerprint: String,
    summary: serde_json::Value,
) -> Result<()> {
    StatusFile::now(command, status, detail, started, design_fingerprint, summary).write(dir)
}

/// 64-bit FNV-1a over the bytes of `parts`, each followed by a zero byte, as
/// 16 lowercase hex digits (the multistart logs use the same hash).
pub fn fingerprint(parts: &[&str]) -> String {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for p in parts {
        for b in p.bytes().chain(std::iter::once(0u8)) {
            h ^= b as u64;
            h = h.wrapping_mul(0x0100_0000_01b3);
        }
    }
    format!("{h:016x}")
}

/// [`fingerprint`] of `value` serialised as compact JSON.
pub fn fingerprint_of<T: Serialize + ?Sized>(value: &T) -> Result<String> {
    let s = serde_json::to_string(value).map_err(|e| Error::Numerical(format!("cannot serialise the design for its fingerprint: {e}")))?;
    Ok(fingerprint(&[&s]))
}

/// `value` as a JSON value, for [`StatusFile::summary`].
pub fn summary_of<T: Serialize + ?Sized>(value: &T) -> Result<serde_json::Value> {
    serde_json::to_value(value).map_err(|e| Error::Numerical(format!("cannot serialise the status summary: {e}")))
}

/// `t` as an RFC 3339 UTC time with whole seconds, `YYYY-MM-DDThh:mm:ssZ`
/// (times before 1970 are written as 1970-01-01T00:00:00Z).
pub fn rfc3339(t: SystemTime) -> String {
    let secs = t.duration_since(UNIX_EPOCH).map(|d| d.as_secs()).unwrap_or(0);
    let (days, rem) = (secs / 86_400, secs % 86_400);
    let (y, m, d) = civil_from_days(days as i64);
    format!("{y:04}-{m:02}-{d:02}T{:02}:{:02}:{:02}Z", rem / 3600, (rem / 60) % 60, rem % 60)
}

/// Proleptic Gregorian (year, month 1–12, day 1–31) of `z` days after 1970-01-01:
/// counts 400-year eras of 146 097 days from 0000-03-01, so the leap day is
/// the last day of the shifted year.
fn civil_from_days(z: i64) -> (i64, u32, u32) {
    let z = z + 719_468; // days from 0000-03-01 to 1970-01-01
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097); // day of era, 0..=146096
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365; // year of era, 0..=399
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100); // day of the March-based year, 0..=365
    let mp = (5 * doy + 2) / 153; // March = 0
    let d = (doy - (153 * mp + 2) / 5 + 1) as u32;
    let m = if mp < 10 { mp + 3 } else { mp - 9 } as u32;
    let y = yoe + era * 400 + i64::from(m <= 2);
    (y, m, d)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    #[test]
    fn rfc3339_known_dates() {
        let at = |s: u64| rfc3339(UNIX_EPOCH + Duration::from_secs(s));
        assert_eq!(at(0), "1970-01-01T00:00:00Z");
        // 2000-02-29 12:34:56 (a leap day of a year divisible by 400)
        assert_eq!(at(951_827_696), "2000-02-29T12:34:56Z");
        // 2024-12-31 23:59:59 and the next second
        assert_eq!(at(1_735_689_599), "2024-12-31T23:59:59Z");
        assert_eq!(at(1_735_689_600), "2025-01-01T00:00:00Z");
        // 2100-03-01 (2100 is not a leap year)
        assert_eq!(at(4_107_542_400), "2100-03-01T00:00:00Z");
    }

    #[test]
    fn fingerprint_is_fnv1a_and_order_sensitive() {
        // FNV-1a 64 of the single byte 0 (an empty part with its separator)
        assert_eq!(fingerprint(&[""]), "af63bd4c8601b7df");
        assert_ne!(fingerprint(&["a", "b"]), fingerprint(&["b", "a"]));
        assert_ne!(fingerprint(&["ab"]), fingerprint(&["a", "b"]));
    }

    #[test]
    fn status_round_trips_and_uses_snake_case_words() {
        let dir = tempfile::tempdir().unwrap();
        let s = StatusFile::now(
            "fit",
            RunState::ShardComplete,
            "3 of 10 starts",
            Some(UNIX_EPOCH),
            fingerprint(&["x"]),
            serde_json::json!({ "starts": 3 }),
        );
        s.write(dir.path()).unwrap();
        let text = std::fs::read_to_string(dir.path().join("status.json")).unwrap();
        assert!(text.contains("\"status\": \"shard_complete\""), "{text}");
        assert!(text.contains("\"started\": \"1970-01-01T00:00:00Z\""), "{text}");
        assert_eq!(StatusFile::read(&dir.path().join("status.json")).unwrap(), s);
    }
}
