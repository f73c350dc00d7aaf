//! File input and output: atomic result writers, numeric CSV tables with
//! validated contents, and SVG plots.
//!
//! Every result file is written to a temporary file in the same folder and then
//! renamed over the target, so an interrupted run never leaves a half-written
//! output behind.

pub mod plot;
pub mod states;
pub mod status;
pub mod table;

use crate::error::{Error, Result};
use std::io::Write;
use std::path::{Path, PathBuf};

pub use states::States;
pub use table::Table;

/// Writes `bytes` to `path` atomically (temp file in the same folder, fsync, rename).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    std::fs::create_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
    let file_name = path.file_name().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let tmp = dir.join(format!(".{}.{}.tmp", file_name, std::process::id()));
    {
        let mut f = std::fs::File::create(&tmp).map_err(|e| Error::io(&tmp, e))?;
        f.write_all(bytes).map_err(|e| Error::io(&tmp, e))?;
        f.sync_all().map_err(|e| Error::io(&tmp, e))?;
    }
    std::fs::rename(&tmp, path).map_err(|e| Error::io(path, e))
}

/// Serialises `value` as pretty JSON and writes it atomically.
pub fn write_json<T: serde::Serialize + ?Sized>(path: &Path, value: &T) -> Result<()> {
    let mut s = serde_json::to_string_pretty(value).map_err(|e| Error::Numerical(format!("cannot serialise {}: {e}", path.display())))?;
    s.push('\n');
    write_atomic(path, s.as_bytes())
}

/// Writes a numeric CSV (header + rows) atomically. Values are written with
/// full precision (`{:e}` round-trips f64 exactly).
pub fn write_csv<R: AsRef<[f64]>>(path: &Path, header: &[String], rows: impl IntoIterator<Item = R>) -> Result<()> {
    let mut out = String::with_capacity(1024);
    out.push_str(&header.join(","));
    out.push('\n');
    for row in rows {
        let row = row.as_ref();
        if row.len() != header.len() {
            return Err(Error::dim(format!("row of {}", path.display()), header.len(), row.len()));
        }
        for (i, v) in row.iter().enumerate() {
            if i > 0 {
                out.push(',');
            }
            out.push_str(&format_f64(*v));
        }
        out.push('\n');
    }
    write_atomic(path, out.as_bytes())
}

/// Shortest representation of `v` that reads back to the same f64.
pub fn format_f64(v: f64) -> String {
    // Rust's Display for f64 is the shortest round-tripping representation.
    format!("{v}")
}

/// Reads a whole text file, mapping errors to [`Error::Io`] naming the file.
pub fn read_to_string(path: &Path) -> Result<String> {
    std::fs::read_to_string(path).map_err(|e| Error::io(path, e))
}

/// Reads a TOML file into `T`, reporting syntax and field errors with the file
/// name, line and column.
pub fn read_toml<T: serde::de::DeserializeOwned>(path: &Path) -> Result<T> {
    let text = read_to_string(path)?;
    parse_toml(path, &text)
}

/// Parses TOML text (from `path`, for messages) into `T`.
pub fn parse_toml<T: serde::de::DeserializeOwned>(path: &Path, text: &str) -> Result<T> {
    toml::from_str::<T>(text).map_err(|e| {
        let loc = e
            .span()
            .map(|s| {
                let line = text[..s.start.min(text.len())].matches('\n').count() + 1;
                format!("line {line}: ")
            })
            .unwrap_or_default();
        Error::parse(path, format!("{loc}{}", e.message()))
    })
}
