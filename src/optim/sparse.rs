//! Sparse matrix assembly for Clarabel's conic programs: (row, column, value)
//! triplets, duplicates summed, into a compressed-sparse-column matrix. Shared
//! by the measurement-position design (`positions::conic`) and the physically
//! consistent identification (`ident::consistent`).

use clarabel::algebra::CscMatrix;

/// Sparse matrix assembly from (row, col, value) triplets; duplicates summed.
#[derive(Debug, Clone, Default)]
pub struct Triplets {
    /// Number of rows so far.
    pub rows: usize,
    t: Vec<(usize, usize, f64)>,
}

impl Triplets {
    /// An empty matrix with no rows.
    pub fn new() -> Self {
        Triplets { rows: 0, t: Vec::new() }
    }

    /// Adds `v` at (r, c) (zeros are skipped).
    pub fn push(&mut self, r: usize, c: usize, v: f64) {
        if v != 0.0 {
            self.t.push((r, c, v));
        }
    }

    /// Reserves `k` new rows and returns the first.
    pub fn rows(&mut self, k: usize) -> usize {
        let r = self.rows;
        self.rows += k;
        r
    }

    /// The CSC matrix (`rows` × `ncols`), duplicates summed.
    pub fn csc(mut self, ncols: usize) -> CscMatrix<f64> {
        self.t.sort_by_key(|a| (a.1, a.0));
        let mut colptr = vec![0usize; ncols + 1];
        let mut rowval = Vec::with_capacity(self.t.len());
        let mut nzval: Vec<f64> = Vec::with_capacity(self.t.len());
        let mut last: Option<(usize, usize)> = None;
        for &(r, c, v) in &self.t {
            if last == Some((r, c)) {
                if let Some(x) = nzval.last_mut() {
                    *x += v;
                }
                continue;
            }
            rowval.push(r);
            nzval.push(v);
            colptr[c + 1] += 1;
            last = Some((r, c));
        }
        for c in 0..ncols {
            colptr[c + 1] += colptr[c];
        }
        CscMatrix::new(self.rows, ncols, colptr, rowval, nzval)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn duplicates_are_summed_and_columns_compressed() {
        let mut t = Triplets::new();
        let r0 = t.rows(2);
        assert_eq!(r0, 0);
        t.push(1, 0, 2.0);
        t.push(0, 1, 3.0);
        t.push(1, 0, 0.5);
        t.push(0, 0, 0.0);
        let m = t.csc(2);
        assert_eq!(m.colptr, vec![0, 1, 2]);
        assert_eq!(m.rowval, vec![1, 0]);
        assert_eq!(m.nzval, vec![2.5, 3.0]);
    }
}
