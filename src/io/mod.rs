//! File input and output: atomic result writers, numeric CSV tables with
//! validated contents, and SVG plots.
//!
//! Every result file is written to a temporary file in the same folder and then
//! renamed over the target, so an interrupted run never leaves a half-written
//! file behind; [`folder`] keeps a whole output folder from being mixed or
//! half-written (status "running" first, the previous set moved aside).

pub mod folder;
pub mod plot;
pub mod states;
pub mod status;
pub mod table;

use crate::error::{Error, Result};
use std::io::Write;
use std::path::{Path, PathBuf};

pub use states::States;
pub use table::Table;

/// Writes `bytes` to `path` atomically: a uniquely named temporary file in
/// the target folder (`.<name>.<pid>.<random>.tmp`, see [`folder`]), written,
/// synced and then persisted (renamed) over `path`. On an error the temporary
/// file is removed; a process killed in between leaves one whose owner is dead,
/// and the next run writing into that folder removes it
/// ([`folder::sweep_stale_temps`]); a second Ctrl-C removes the live ones before
/// exiting ([`folder::remove_live_temps`]).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    std::fs::create_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
    if path.is_dir() {
        return Err(Error::io(path, std::io::Error::other("is a folder, cannot write a file there")));
    }
    let file_name = path.file_name().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let prefix = folder::temp_prefix(&file_name);
    let mut builder = tempfile::Builder::new();
    builder.prefix(&prefix).suffix(folder::TEMP_SUFFIX);
    // the mode of a file created the ordinary way (0666 less the umask, as
    // `File::create` gives), not the 0600 of a temporary file: results in a
    // shared folder are readable by whom the user's umask lets read them
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt as _;
        builder.permissions(std::fs::Permissions::from_mode(0o666));
    }
    let mut tmp = builder.tempfile_in(&dir).map_err(|e| Error::io(&dir, e))?;
    let tmp_path = tmp.path().to_path_buf();
    folder::register_temp(&tmp_path);
    let result = (|| {
        tmp.write_all(bytes).map_err(|e| Error::io(&tmp_path, e))?;
        tmp.as_file().sync_all().map_err(|e| Error::io(&tmp_path, e))?;
        tmp.persist(path).map_err(|e| Error::io(path, e.error))?;
        Ok(())
    })();
    folder::unregister_temp(&tmp_path);
    result
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
    use std::fmt::Write as _;
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
            let _ = write!(out, "{v}");
        }
        out.push('\n');
    }
    write_atomic(path, out.as_bytes())
}

/// The text of a CSV of `rows` rows after `header` (a line, without its
/// newline): `row(k, s)` appends row k, newline included, to `s`. Rows are
/// formatted in blocks in parallel and joined in order, so the text does
/// not depend on the thread count.
pub fn csv_text(header: &str, rows: usize, row: impl Fn(usize, &mut String) + Sync) -> String {
    use rayon::prelude::*;
    const BLOCK: usize = 4096;
    let blocks: Vec<String> = (0..rows.div_ceil(BLOCK))
        .into_par_iter()
        .map(|b| {
            let mut s = String::new();
            for k in b * BLOCK..((b + 1) * BLOCK).min(rows) {
                row(k, &mut s);
            }
            s
        })
        .collect();
    let mut out = String::with_capacity(header.len() + 1 + blocks.iter().map(String::len).sum::<usize>());
    out.push_str(header);
    out.push('\n');
    blocks.iter().for_each(|b| out.push_str(b));
    out
}

/// Shortest representation of `v` that reads back to the same f64.
pub fn format_f64(v: f64) -> String {
    // Rust's Display for f64 is the shortest round-tripping representation.
    format!("{v}")
}

/// The largest text input read whole ([`read_to_string`]): 512 MiB.
pub const MAX_TEXT_BYTES: u64 = 512 << 20;

/// Reads a whole text file, mapping errors to [`Error::Io`] naming the file.
///
/// Only regular files (after following links) of at most [`MAX_TEXT_BYTES`]
/// are read (a device such as `/dev/zero` or a FIFO is refused before any
/// byte is read; a file that grows while read stops at the bound). A leading
/// UTF-8 byte-order mark is dropped, so JSON, TOML, CSV and URDF written by
/// editors that add one are read alike.
pub fn read_to_string(path: &Path) -> Result<String> {
    read_to_string_bounded(path, MAX_TEXT_BYTES)
}

/// [`read_to_string`] with an explicit size bound (bytes).
pub fn read_to_string_bounded(path: &Path, max_bytes: u64) -> Result<String> {
    use std::io::Read;
    let meta = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    if meta.is_dir() {
        return Err(Error::io(path, std::io::Error::other("is a folder, expected a file")));
    }
    if !meta.is_file() {
        return Err(Error::io(
            path,
            std::io::Error::other("is not a regular file (a device, FIFO or socket); only regular files are read"),
        ));
    }
    if meta.len() > max_bytes {
        return Err(Error::io(
            path,
            std::io::Error::other(format!("is {} bytes; at most {max_bytes} bytes are read", meta.len())),
        ));
    }
    let f = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let mut bytes = Vec::with_capacity(meta.len() as usize);
    f.take(max_bytes + 1).read_to_end(&mut bytes).map_err(|e| Error::io(path, e))?;
    if bytes.len() as u64 > max_bytes {
        return Err(Error::io(
            path,
            std::io::Error::other(format!("grew beyond {max_bytes} bytes while being read")),
        ));
    }
    let mut text = String::from_utf8(bytes).map_err(|e| {
        Error::io(
            path,
            std::io::Error::new(
                std::io::ErrorKind::InvalidData,
                format!("is not UTF-8 text (invalid byte at offset {})", e.utf8_error().valid_up_to()),
            ),
        )
    })?;
    if text.starts_with('\u{feff}') {
        text.drain(..'\u{feff}'.len_utf8());
    }
    Ok(text)
}

/// A path written in a design (or robot) file, resolved as every design
/// resolves its paths: relative to the folder of `file` (absolute paths
/// kept), and checked to exist. A path that does not exist is an error
/// naming `file`, `field`, the path as written, the path it resolved to and
/// the folder it is relative to (and when the folder above it does not
/// exist either, that too).
pub fn design_path(file: &Path, field: &str, written: &Path) -> Result<std::path::PathBuf> {
    let dir = file.parent().unwrap_or(Path::new(""));
    path_in(&file.display().to_string(), dir, field, written)
}

/// [`design_path`] for a design whose paths are relative to a folder given
/// apart from the file (a design read from a dict, or placed elsewhere):
/// `ctx` names the design in the error, `dir` is the folder.
pub fn path_in(ctx: &str, dir: &Path, field: &str, written: &Path) -> Result<std::path::PathBuf> {
    let resolved = if written.is_absolute() { written.to_path_buf() } else { dir.join(written) };
    if resolved.exists() {
        return Ok(resolved);
    }
    let shown = if dir.as_os_str().is_empty() { Path::new(".") } else { dir };
    let why = if written.is_absolute() {
        format!("`{}` does not exist", written.display())
    } else {
        format!(
            "`{}` does not exist: a relative path is relative to the folder of the file that writes it ({}), so it names {}",
            written.display(),
            shown.display(),
            resolved.display()
        )
    };
    let missing_dir = resolved
        .parent()
        .filter(|p| !p.as_os_str().is_empty() && !p.exists())
        .map(|p| format!(" (no folder {})", p.display()))
        .unwrap_or_default();
    Err(Error::invalid(ctx, field, format!("{why}{missing_dir}")))
}

/// Reads a TOML file into `T`, reporting syntax and field errors with the file
/// name, line and column.
pub fn read_toml<T: serde::de::DeserializeOwned>(path: &Path) -> Result<T> {
    let text = read_to_string(path)?;
    parse_toml(path, &text)
}

/// Parses TOML text (from `path`, for messages) into `T`.
///
/// An array longer than a fixed-size field takes (`xyz = [1, 2, 3, 4]`,
/// `band = [2, 40, 60]`) is refused naming the key: the toml crate's text
/// reader drops the extra elements silently (its value reader does not), so
/// the text is also read through [`toml::Value`] and, when only that read
/// fails, the array whose trimming makes it succeed is named.
pub fn parse_toml<T: serde::de::DeserializeOwned>(path: &Path, text: &str) -> Result<T> {
    let line_of = |pos: usize| text[..pos.min(text.len())].matches('\n').count() + 1;
    let v = toml::from_str::<T>(text).map_err(|e| {
        let loc = e.span().map(|s| format!("line {}: ", line_of(s.start))).unwrap_or_default();
        Error::parse(path, format!("{loc}{}", e.message()))
    })?;
    if let Ok(table) = toml::from_str::<toml::Table>(text) {
        let value = toml::Value::Table(table);
        if value.clone().try_into::<T>().is_err() {
            if let Some((key, len)) = overlong_array::<T>(&value) {
                let last = key
                    .rsplit('.')
                    .next()
                    .unwrap_or(&key)
                    .trim_end_matches(|c: char| c == ']' || c.is_ascii_digit())
                    .trim_end_matches('[');
                // the line, when only one line sets a key of that name
                let lines: Vec<usize> = text
                    .lines()
                    .enumerate()
                    .filter(|(_, l)| {
                        let l = l.trim_start();
                        l.strip_prefix(last).is_some_and(|r| r.trim_start().starts_with('='))
                    })
                    .map(|(i, _)| i + 1)
                    .collect();
                let loc = if lines.len() == 1 { format!("line {}: ", lines[0]) } else { String::new() };
                return Err(Error::parse(
                    path,
                    format!("{loc}`{key}`: the array has {len} elements, more than the field takes (extra elements are not ignored)"),
                ));
            }
        }
    }
    Ok(v)
}

/// The key path and length of the first array (of numbers, strings, … — not
/// of tables) whose trimming (last elements removed) lets `value`
/// deserialize into `T`.
fn overlong_array<T: serde::de::DeserializeOwned>(value: &toml::Value) -> Option<(String, usize)> {
    // every array's path, as indices into tables and arrays
    #[derive(Clone)]
    enum Step {
        Key(String),
        Index(usize),
    }
    fn walk(v: &toml::Value, at: &mut Vec<Step>, out: &mut Vec<Vec<Step>>) {
        match v {
            toml::Value::Table(t) => {
                for (k, x) in t {
                    at.push(Step::Key(k.clone()));
                    walk(x, at, out);
                    at.pop();
                }
            }
            toml::Value::Array(a) => {
                if !a.is_empty() && !a.iter().all(|x| x.is_table()) {
                    out.push(at.clone());
                }
                for (i, x) in a.iter().enumerate() {
                    at.push(Step::Index(i));
                    walk(x, at, out);
                    at.pop();
                }
            }
            _ => {}
        }
    }
    fn get_mut<'a>(v: &'a mut toml::Value, path: &[Step]) -> Option<&'a mut toml::Value> {
        let mut cur = v;
        for s in path {
            cur = match (s, cur) {
                (Step::Key(k), toml::Value::Table(t)) => t.get_mut(k)?,
                (Step::Index(i), toml::Value::Array(a)) => a.get_mut(*i)?,
                _ => return None,
            };
        }
        Some(cur)
    }
    let mut paths = Vec::new();
    walk(value, &mut Vec::new(), &mut paths);
    let mut tries = 0usize;
    for p in &paths {
        let mut trial = value.clone();
        let len = match get_mut(&mut trial, p) {
            Some(toml::Value::Array(a)) => a.len(),
            _ => continue,
        };
        let mut fits = false;
        for _ in 0..len {
            tries += 1;
            if tries > 5000 {
                return None;
            }
            if let Some(toml::Value::Array(a)) = get_mut(&mut trial, p) {
                a.pop();
            }
            if trial.clone().try_into::<T>().is_ok() {
                fits = true;
                break;
            }
        }
        if fits {
            let mut key = String::new();
            for s in p {
                match s {
                    Step::Key(k) => {
                        if !key.is_empty() {
                            key.push('.');
                        }
                        key.push_str(k);
                    }
                    Step::Index(i) => key.push_str(&format!("[{i}]")),
                }
            }
            return Some((key, len));
        }
    }
    None
}
