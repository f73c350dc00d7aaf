//! Output folders that are never mixed or half-written.
//!
//! Every command's writer starts with [`begin`]:
//!
//! 1. the path is refused if it exists and is not a folder ([`check_out_dir`],
//!    also called by the commands before their long work starts);
//! 2. temporary files left by killed runs (`.<name>.<pid>.<random>.tmp`, see
//!    [`crate::io::write_atomic`]) whose process is gone are removed;
//! 3. if the folder holds an earlier result of the *same* command (its
//!    `status.json` names it), that whole result set is moved aside into
//!    `<dir>/.previous/` (in steps that survive a kill, see [`begin`]); a
//!    folder whose earlier writer was killed while writing (status
//!    `running`) keeps the complete set already in `.previous/` and its
//!    partial files are dropped;
//! 4. `status.json` is written as `running`.
//!
//! The writer then writes its files and, last, the final `status.json`
//! ([`crate::io::status::StatusFile::write`]), which removes `.previous/`. A
//! run killed at any point therefore leaves either the complete new set
//! (final status written) or a folder marked `running` beside the complete
//! previous set in `.previous/`; readers refuse a folder marked `running`
//! ([`crate::io::status::require_complete`]).
//!
//! A folder holding files of another command, or files without a
//! `status.json`, is written in place (nothing of the user's is moved).

use super::status::{RunState, StatusFile};
use crate::error::{Error, Result};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// Name of the folder inside an output folder that holds the previous result set.
pub const PREVIOUS: &str = ".previous";
/// Suffix of the temporary files of [`crate::io::write_atomic`].
pub const TEMP_SUFFIX: &str = ".tmp";

/// Prefix of a temporary file for `file_name`: `.<file_name>.<pid>.`.
pub fn temp_prefix(file_name: &str) -> String {
    format!(".{file_name}.{}.", std::process::id())
}

static LIVE: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// Records a temporary file being written (removed by [`remove_live_temps`]).
pub(crate) fn register_temp(p: &Path) {
    if let Ok(mut v) = LIVE.lock() {
        v.push(p.to_path_buf());
    }
}

/// Forgets a temporary file (persisted or removed).
pub(crate) fn unregister_temp(p: &Path) {
    if let Ok(mut v) = LIVE.lock() {
        v.retain(|x| x != p);
    }
}

/// Removes the temporary files this process is writing right now: for an
/// exit that skips destructors (the CLI's second Ctrl-C).
pub fn remove_live_temps() {
    // never block in a signal-handler thread: skip if another thread holds the lock
    if let Ok(v) = LIVE.try_lock() {
        for p in v.iter() {
            let _ = std::fs::remove_file(p);
        }
    }
}

/// Refuses `dir` as an output folder if it exists and is not a folder.
pub fn check_out_dir(dir: &Path) -> Result<()> {
    match std::fs::metadata(dir) {
        Ok(m) if !m.is_dir() => Err(Error::invalid(
            dir.display().to_string(),
            "output folder",
            "exists and is not a folder; give a new or an existing output folder",
        )),
        _ => Ok(()),
    }
}

/// True if a process with this id runs on this machine (`/proc`; where there
/// is no `/proc`, every process counts as alive and nothing is swept).
fn pid_alive(pid: u32) -> bool {
    if !Path::new("/proc/self").exists() {
        return true;
    }
    pid == std::process::id() || Path::new("/proc").join(pid.to_string()).exists()
}

/// The writer's process id in a temporary file name, if it is one of ours
/// (`.<name>.<pid>.<random>.tmp`, or the older `.<name>.<pid>.tmp`).
fn temp_owner(name: &str) -> Option<Vec<u32>> {
    let stem = name.strip_prefix('.')?.strip_suffix(TEMP_SUFFIX)?;
    let parts: Vec<&str> = stem.split('.').collect();
    if parts.len() < 2 {
        return None;
    }
    let pids: Vec<u32> = parts.iter().rev().take(2).filter_map(|s| s.parse().ok()).collect();
    (!pids.is_empty()).then_some(pids)
}

/// Removes the temporary files in `dir` (not recursively) whose writing
/// process is gone and that were last modified more than two seconds ago
/// (a file of a live writer on another machine sharing the folder is still
/// being written to). Returns how many were removed.
pub fn sweep_stale_temps(dir: &Path) -> usize {
    let Ok(rd) = std::fs::read_dir(dir) else { return 0 };
    let mut removed = 0;
    for e in rd.flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        let Some(pids) = temp_owner(&name) else { continue };
        if pids.iter().any(|&p| pid_alive(p)) {
            continue;
        }
        let old = e
            .metadata()
            .ok()
            .and_then(|m| m.modified().ok())
            .and_then(|t| t.elapsed().ok())
            .is_some_and(|d| d.as_secs_f64() > 2.0);
        if old && std::fs::remove_file(e.path()).is_ok() {
            removed += 1;
        }
    }
    removed
}

/// Visible entries of `dir` (names not starting with `.`).
fn visible_entries(dir: &Path) -> Result<Vec<PathBuf>> {
    let rd = std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))?;
    let mut v = Vec::new();
    for e in rd {
        let e = e.map_err(|e| Error::io(dir, e))?;
        if !e.file_name().to_string_lossy().starts_with('.') {
            v.push(e.path());
        }
    }
    v.sort();
    Ok(v)
}

fn remove_any(p: &Path) -> Result<()> {
    let r = if p.is_dir() && !p.is_symlink() {
        std::fs::remove_dir_all(p)
    } else {
        std::fs::remove_file(p)
    };
    match r {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(()),
        Err(e) => Err(Error::io(p, e)),
    }
}

fn running_status(command: &str, design_fingerprint: &str, moving: bool) -> StatusFile {
    StatusFile::now(
        command,
        RunState::Running,
        "running: the files of this folder are being written",
        Some(std::time::SystemTime::now()),
        design_fingerprint.to_string(),
        if moving {
            serde_json::json!({ "previous_set": "moving" })
        } else {
            serde_json::json!({})
        },
    )
}

/// Moves every visible entry of `dir` into `to` (created if missing).
fn move_visible(dir: &Path, to: &Path) -> Result<()> {
    std::fs::create_dir_all(to).map_err(|e| Error::io(to, e))?;
    for p in visible_entries(dir)? {
        if p.file_name().is_some_and(|n| n == "status.json") {
            continue;
        }
        let dest = to.join(p.file_name().unwrap_or_default());
        remove_any(&dest)?;
        std::fs::rename(&p, &dest).map_err(|e| Error::io(&p, e))?;
    }
    Ok(())
}

/// Prepares `dir` for a new result set of `command` (see the module
/// documentation) and writes `status.json` as `running`.
///
/// The move aside survives a kill at any step: the earlier `status.json` is
/// first copied into `.previous.new/`, then the folder is marked `running`
/// (with `"previous_set": "moving"`), then the files move, `.previous.new`
/// becomes `.previous`, and the mark is cleared; a later `begin` finishes a
/// move it finds half done.
pub fn begin(dir: &Path, command: &str, design_fingerprint: &str) -> Result<()> {
    check_out_dir(dir)?;
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    sweep_stale_temps(dir);
    let status_path = dir.join("status.json");
    let prev = dir.join(PREVIOUS);
    let staging = dir.join(".previous.new");
    if status_path.exists() {
        // an unreadable status.json is treated as a killed writer's
        let earlier = StatusFile::read(&status_path).ok();
        let same = earlier.as_ref().is_none_or(|s| s.command == command);
        if same {
            let killed = earlier.as_ref().is_none_or(|s| s.status == RunState::Running);
            let moving = earlier
                .as_ref()
                .is_some_and(|s| s.status == RunState::Running && s.summary.get("previous_set").is_some());
            if moving {
                // a move aside was killed half way: finish it
                if staging.is_dir() {
                    move_visible(dir, &staging)?;
                    remove_any(&prev)?;
                    std::fs::rename(&staging, &prev).map_err(|e| Error::io(&staging, e))?;
                }
            } else if killed {
                // a writer killed while writing: its files are partial; the
                // complete set before it, if any, is already in .previous
                remove_any(&staging)?;
                for p in visible_entries(dir)? {
                    if p.file_name().is_some_and(|n| n != "status.json") {
                        remove_any(&p)?;
                    }
                }
            } else {
                remove_any(&staging)?;
                std::fs::create_dir(&staging).map_err(|e| Error::io(&staging, e))?;
                let old = std::fs::read(&status_path).map_err(|e| Error::io(&status_path, e))?;
                super::write_atomic(&staging.join("status.json"), &old)?;
                running_status(command, design_fingerprint, true).write(dir)?;
                move_visible(dir, &staging)?;
                remove_any(&prev)?;
                std::fs::rename(&staging, &prev).map_err(|e| Error::io(&staging, e))?;
            }
            sweep_stale_temps(&prev);
        }
    }
    running_status(command, design_fingerprint, false).write(dir)
}

/// For folders that also hold inputs or resumable logs (a runs manifest's
/// folder, a multistart fit's shard logs): removes stale temporary files and
/// marks the folder `running`, moving nothing aside.
pub fn begin_in_place(dir: &Path, command: &str, design_fingerprint: &str) -> Result<()> {
    check_out_dir(dir)?;
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    sweep_stale_temps(dir);
    running_status(command, design_fingerprint, false).write(dir)
}

/// Removes `dir/.previous` (after the final status of a new set was written).
pub(crate) fn discard_previous(dir: &Path) {
    let prev = dir.join(PREVIOUS);
    if prev.is_dir() {
        let _ = std::fs::remove_dir_all(prev);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn temp_owner_reads_both_name_forms() {
        assert_eq!(temp_owner(".run.json.4242.tmp"), Some(vec![4242]));
        assert_eq!(temp_owner(".run.json.4242.aB3xYz.tmp"), Some(vec![4242]));
        assert_eq!(temp_owner("run.json"), None);
        assert_eq!(temp_owner(".x.tmp"), None);
    }

    #[test]
    fn begin_moves_a_same_command_set_aside_and_the_final_status_drops_it() {
        let d = tempfile::tempdir().unwrap();
        let dir = d.path().join("o");
        begin(&dir, "excite", "f").unwrap();
        std::fs::write(dir.join("a.json"), "old").unwrap();
        super::super::status::write_status(&dir, "excite", RunState::Complete, "ok", None, "f".into(), serde_json::json!({})).unwrap();
        begin(&dir, "excite", "f").unwrap();
        assert!(!dir.join("a.json").exists());
        assert_eq!(std::fs::read_to_string(dir.join(".previous/a.json")).unwrap(), "old");
        let st = StatusFile::read(&dir.join("status.json")).unwrap();
        assert_eq!(st.status, RunState::Running);
        // a killed writer: the next begin keeps the complete set aside
        std::fs::write(dir.join("b.json"), "partial").unwrap();
        begin(&dir, "excite", "f").unwrap();
        assert!(!dir.join("b.json").exists());
        assert!(dir.join(".previous/a.json").exists());
        super::super::status::write_status(&dir, "excite", RunState::Complete, "ok", None, "f".into(), serde_json::json!({})).unwrap();
        assert!(!dir.join(".previous").exists());
    }

    #[test]
    fn a_move_aside_killed_half_way_is_finished_by_the_next_begin() {
        let d = tempfile::tempdir().unwrap();
        let dir = d.path();
        // the state a kill leaves in the middle of the move: status running
        // (moving), the old status and one file aside, one file still in place
        std::fs::create_dir(dir.join(".previous.new")).unwrap();
        let old = StatusFile::now("fit", RunState::Complete, "ok", None, "f".into(), serde_json::json!({}));
        old.write(&dir.join(".previous.new")).unwrap();
        std::fs::write(dir.join(".previous.new/a.csv"), "a").unwrap();
        std::fs::write(dir.join("b.csv"), "b").unwrap();
        running_status("fit", "f", true).write(dir).unwrap();
        begin(dir, "fit", "f").unwrap();
        assert_eq!(std::fs::read_to_string(dir.join(".previous/a.csv")).unwrap(), "a");
        assert_eq!(std::fs::read_to_string(dir.join(".previous/b.csv")).unwrap(), "b");
        assert_eq!(StatusFile::read(&dir.join(".previous/status.json")).unwrap().status, RunState::Complete);
        assert!(!dir.join("b.csv").exists() && !dir.join(".previous.new").exists());
        let now = StatusFile::read(&dir.join("status.json")).unwrap();
        assert!(now.status == RunState::Running && now.summary.get("previous_set").is_none());
    }

    #[test]
    fn begin_keeps_other_files_and_refuses_a_file() {
        let d = tempfile::tempdir().unwrap();
        std::fs::write(d.path().join("mine.txt"), "x").unwrap();
        begin(d.path(), "simulate", "f").unwrap();
        assert!(d.path().join("mine.txt").exists());
        let f = d.path().join("mine.txt");
        let e = begin(&f, "excite", "f").unwrap_err().to_string();
        assert!(e.contains("not a folder"), "{e}");
    }

    #[test]
    fn stale_temps_of_dead_processes_are_swept() {
        let d = tempfile::tempdir().unwrap();
        // pid 0x7fff_fff0 does not exist
        let stale = d.path().join(".run.json.2147483632.abc123.tmp");
        std::fs::write(&stale, "x").unwrap();
        let old = std::time::SystemTime::now() - std::time::Duration::from_secs(10);
        std::fs::File::options().write(true).open(&stale).unwrap().set_modified(old).unwrap();
        let live = d.path().join(format!(".run.json.{}.abc123.tmp", std::process::id()));
        std::fs::write(&live, "x").unwrap();
        assert_eq!(sweep_stale_temps(d.path()), 1);
        assert!(!stale.exists());
        assert!(live.exists());
    }
}
