//! Motor records: one recorded experiment of an FRF measurement, the motor
//! torques u (N·m) and motor positions y (rad) at every sample t = k/rate.
//! File format: CSV with columns `t, tau1..taun, qm1..qmn`.

use crate::error::Result;
use std::path::Path;

/// One recorded experiment: samples of motor torques u and motor positions y.
#[derive(Debug, Clone)]
pub struct MotorRecord {
    /// Motor torques `u[t][i]` (N·m).
    pub u: Vec<Vec<f64>>,
    /// Motor positions `y[t][i]` (rad).
    pub y: Vec<Vec<f64>>,
}

impl MotorRecord {
    /// Reads one record CSV (`t, tau1..taun, qm1..qmn`) for n motors.
    pub fn read(path: &Path, n: usize) -> Result<MotorRecord> {
        let t = crate::io::Table::read(path)?;
        let ui = t.numbered("tau", n)?;
        let yi = t.numbered("qm", n)?;
        Ok(MotorRecord {
            u: t.rows.iter().map(|r| ui.iter().map(|&c| r[c]).collect()).collect(),
            y: t.rows.iter().map(|r| yi.iter().map(|&c| r[c]).collect()).collect(),
        })
    }

    /// Writes the record as CSV (atomically), times t = k / `rate` (s, rate in Hz).
    pub fn write(&self, path: &Path, rate: f64) -> Result<()> {
        let n = self.u.first().map(|v| v.len()).unwrap_or(0);
        let mut header = vec!["t".to_string()];
        header.extend((1..=n).map(|i| format!("tau{i}")));
        header.extend((1..=n).map(|i| format!("qm{i}")));
        let rows = self.u.iter().zip(&self.y).enumerate().map(|(t, (u, y))| {
            let mut r = Vec::with_capacity(2 * n + 1);
            r.push(t as f64 / rate);
            r.extend_from_slice(u);
            r.extend_from_slice(y);
            r
        });
        crate::io::write_csv(path, &header, rows)
    }
}
