//! Streaming versions of the per-state tables of `idexp robot torques|regressor`
//! ([`super::info::torques_table`], [`super::info::regressor_table`]): the
//! states CSV is read, computed and written block by block, so memory does not
//! grow with the file length; the output is the same text.

use crate::error::{Error, Result};
use crate::io::format_f64;
use crate::io::states::{StateBlock, StatesReader};
use crate::params::BaseParams;
use crate::robot::{regressor_rows, rnea, Robot, Workspace};
use std::io::Write;
use std::path::Path;

/// Which table to stream.
#[derive(Debug, Clone, Copy)]
pub enum TableKind<'a> {
    /// `t` (if present), `tau1..taun`: inverse dynamics with nominal parameters.
    Torques,
    /// `sample, joint, <parameter names>`: the regressor, or the base regressor.
    Regressor(Option<&'a BaseParams>),
}

/// Rows read per block.
const BLOCK: usize = 4096;

/// Streams the table of the states in `states` to `out` (CSV text, the format
/// of [`crate::io::write_csv`]). Returns the number of states.
pub fn stream_table(r: &Robot, states: &Path, kind: TableKind<'_>, out: &mut dyn Write) -> Result<usize> {
    let (n, p) = (r.dof(), r.n_params());
    let mut rdr = StatesReader::open(states, n)?;
    let mut header: Vec<String> = Vec::new();
    match kind {
        TableKind::Torques => {
            if rdr.has_t() {
                header.push("t".into());
            }
            header.extend((1..=n).map(|i| format!("tau{i}")));
        }
        TableKind::Regressor(base) => {
            header.extend(["sample".to_string(), "joint".to_string()]);
            match base {
                Some(b) => header.extend(b.names.iter().cloned()),
                None => header.extend(r.param_names()),
            }
        }
    }
    let werr = |e: std::io::Error| Error::Numerical(format!("writing the table: {e}"));
    let mut text = String::with_capacity(1 << 20);
    text.push_str(&header.join(","));
    text.push('\n');
    let mut ws = Workspace::new(r);
    let mut tau = vec![0.0; n];
    let mut y = vec![0.0; n * p];
    let nb = match kind {
        TableKind::Regressor(Some(b)) => b.n_base(),
        _ => p,
    };
    let mut yb = vec![0.0; n * nb];
    let mut block = StateBlock::default();
    let mut k = 0usize;
    let push_row = |text: &mut String, vals: &mut dyn Iterator<Item = f64>| {
        for (i, v) in vals.enumerate() {
            if i > 0 {
                text.push(',');
            }
            text.push_str(&format_f64(v));
        }
        text.push('\n');
    };
    while rdr.next_block(BLOCK, 1, &mut block)? > 0 {
        for i in 0..block.len(n) {
            let s = i * n..(i + 1) * n;
            let (q, qd, qdd) = (&block.q[s.clone()], &block.qd[s.clone()], &block.qdd[s]);
            match kind {
                TableKind::Torques => {
                    rnea(r, &mut ws, q, qd, qdd, &mut tau);
                    let t = block.t.get(i).copied();
                    push_row(&mut text, &mut t.into_iter().chain(tau.iter().copied()));
                }
                TableKind::Regressor(base) => {
                    regressor_rows(r, &mut ws, q, qd, qdd, &mut y);
                    let src: &[f64] = match base {
                        Some(b) => {
                            b.select_rows(&y, n, &mut yb);
                            &yb
                        }
                        None => &y,
                    };
                    for j in 0..n {
                        let row = [k as f64, (j + 1) as f64];
                        push_row(&mut text, &mut row.into_iter().chain(src[j * nb..(j + 1) * nb].iter().copied()));
                    }
                }
            }
            k += 1;
        }
        out.write_all(text.as_bytes()).map_err(werr)?;
        text.clear();
    }
    if k == 0 {
        return Err(Error::parse(states, "no data rows after the header"));
    }
    out.write_all(text.as_bytes()).map_err(werr)?;
    out.flush().map_err(werr)?;
    Ok(k)
}

/// [`stream_table`] into the file `path`, atomically: written to a temporary
/// file next to it and renamed when complete (never half-written).
pub fn stream_table_to_file(r: &Robot, states: &Path, kind: TableKind<'_>, path: &Path) -> Result<usize> {
    let dir = path.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new("."));
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    let name = path.file_name().map(|s| s.to_string_lossy().to_string()).unwrap_or_else(|| "table.csv".into());
    let tmp = dir.join(format!(".{name}.partial-{}", std::process::id()));
    let res = (|| {
        let f = std::fs::File::create(&tmp).map_err(|e| Error::io(&tmp, e))?;
        let mut w = std::io::BufWriter::with_capacity(1 << 20, f);
        let k = stream_table(r, states, kind, &mut w)?;
        let f = w.into_inner().map_err(|e| Error::io(&tmp, e.into_error()))?;
        f.sync_all().map_err(|e| Error::io(&tmp, e))?;
        std::fs::rename(&tmp, path).map_err(|e| Error::io(path, e))?;
        Ok(k)
    })();
    if res.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    res
}
