//! The Clarabel bridge: one place that assembles a conic program, sets the
//! solver up, runs it under a [`Control`] and reports its status.
//!
//! A [`Program`] is min ½xᵀPx + qᵀx s.t. b − Ax ∈ K (Clarabel's form), its
//! matrices assembled from (row, column, value) entries by Clarabel's own
//! [`CscMatrix::new_from_triplets`] (duplicates summed in the order they
//! were added; zeros are never stored). [`solve`] builds Clarabel's settings
//! (iteration budget, tolerances, and a time limit: the earlier of the
//! caller's and the control's deadline), installs a termination callback
//! that Clarabel asks at every interior-point iteration (true once the
//! control's stop flag is set: status `CallbackTerminated`, so Ctrl-C ends
//! even a long SDP at once; with [`Settings::progress`] it also reports the
//! iteration to the control's observer), and returns the solution with its
//! [`ConicStatus`].
//!
//! The vocabulary is idexp's own: the cones K are [`Cone`]s and a run ends
//! with a [`SolverStatus`]; both are mapped to and from Clarabel's types here
//! and nowhere else (`tests/module_graph.rs` holds that no file outside
//! `src/optim/` names the `clarabel` crate).

use super::{Control, Termination};
use clarabel::algebra::CscMatrix;
use clarabel::solver::{DefaultSettingsBuilder, DefaultSolver, IPSolver, SupportedConeT};

/// One cone of K, over the next rows of b − Ax (in the order of
/// [`Program::cones`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Cone {
    /// `n` rows equal to zero (equality constraints).
    Zero(usize),
    /// `n` rows ≥ 0.
    Nonnegative(usize),
    /// `n` rows (t, x) with ‖x‖ ≤ t (the second-order cone of dimension n).
    SecondOrder(usize),
    /// 3 rows (x, y, z) with y·exp(x/y) ≤ z, y > 0 (the closure of it).
    Exponential,
    /// n(n+1)/2 rows: an n × n symmetric matrix ⪰ 0, its upper triangle
    /// column by column, off-diagonal entries scaled by √2.
    PsdTriangle(usize),
}

impl Cone {
    fn clarabel(self) -> SupportedConeT<f64> {
        match self {
            Cone::Zero(n) => SupportedConeT::ZeroConeT(n),
            Cone::Nonnegative(n) => SupportedConeT::NonnegativeConeT(n),
            Cone::SecondOrder(n) => SupportedConeT::SecondOrderConeT(n),
            Cone::Exponential => SupportedConeT::ExponentialConeT(),
            Cone::PsdTriangle(n) => SupportedConeT::PSDTriangleConeT(n),
        }
    }
}

/// How an interior-point run ended (Clarabel's statuses, written with
/// Clarabel's words: `Solved`, `CallbackTerminated`, ...).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SolverStatus {
    /// The solver did not run.
    Unsolved,
    /// Solved to the tolerances.
    Solved,
    /// Primal infeasible (the solution is a certificate).
    PrimalInfeasible,
    /// Dual infeasible (the solution is a certificate).
    DualInfeasible,
    /// Solved to reduced accuracy.
    AlmostSolved,
    /// Primal infeasible to reduced accuracy.
    AlmostPrimalInfeasible,
    /// Dual infeasible to reduced accuracy.
    AlmostDualInfeasible,
    /// The iteration budget ran out.
    MaxIterations,
    /// The time limit ran out.
    MaxTime,
    /// A numerical error ended the run.
    NumericalError,
    /// The run made too little progress.
    InsufficientProgress,
    /// The termination callback stopped it (the control's stop flag).
    CallbackTerminated,
}

impl SolverStatus {
    fn of(s: clarabel::solver::SolverStatus) -> SolverStatus {
        use clarabel::solver::SolverStatus as C;
        match s {
            C::Unsolved => SolverStatus::Unsolved,
            C::Solved => SolverStatus::Solved,
            C::PrimalInfeasible => SolverStatus::PrimalInfeasible,
            C::DualInfeasible => SolverStatus::DualInfeasible,
            C::AlmostSolved => SolverStatus::AlmostSolved,
            C::AlmostPrimalInfeasible => SolverStatus::AlmostPrimalInfeasible,
            C::AlmostDualInfeasible => SolverStatus::AlmostDualInfeasible,
            C::MaxIterations => SolverStatus::MaxIterations,
            C::MaxTime => SolverStatus::MaxTime,
            C::NumericalError => SolverStatus::NumericalError,
            C::InsufficientProgress => SolverStatus::InsufficientProgress,
            C::CallbackTerminated => SolverStatus::CallbackTerminated,
        }
    }

    /// The word written in reports (Clarabel's name of the status).
    pub fn as_str(self) -> &'static str {
        match self {
            SolverStatus::Unsolved => "Unsolved",
            SolverStatus::Solved => "Solved",
            SolverStatus::PrimalInfeasible => "PrimalInfeasible",
            SolverStatus::DualInfeasible => "DualInfeasible",
            SolverStatus::AlmostSolved => "AlmostSolved",
            SolverStatus::AlmostPrimalInfeasible => "AlmostPrimalInfeasible",
            SolverStatus::AlmostDualInfeasible => "AlmostDualInfeasible",
            SolverStatus::MaxIterations => "MaxIterations",
            SolverStatus::MaxTime => "MaxTime",
            SolverStatus::NumericalError => "NumericalError",
            SolverStatus::InsufficientProgress => "InsufficientProgress",
            SolverStatus::CallbackTerminated => "CallbackTerminated",
        }
    }
}

impl std::fmt::Display for SolverStatus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// How a conic solve ended: the solver's status, or why the solver could
/// not be set up. Serialised as the status word (`Solved`,
/// `CallbackTerminated`, ...), `SettingsError: ...`, `SetupError: ...`.
#[derive(Debug, Clone, PartialEq)]
pub enum ConicStatus {
    /// Clarabel ran; its status (`CallbackTerminated` when the run control stopped it).
    Solver(SolverStatus),
    /// The settings were rejected.
    Settings(String),
    /// The problem data were rejected.
    Setup(String),
}

impl ConicStatus {
    /// True for `Solved` and `AlmostSolved`.
    pub fn is_solved(&self) -> bool {
        matches!(self, ConicStatus::Solver(SolverStatus::Solved | SolverStatus::AlmostSolved))
    }
    /// The run-control word: solved → converged, a callback stop →
    /// interrupted, Clarabel's own limits → iterations/time, else failed.
    pub fn termination(&self) -> Termination {
        use SolverStatus as S;
        match self {
            ConicStatus::Solver(S::Solved | S::AlmostSolved) => Termination::Converged,
            ConicStatus::Solver(S::CallbackTerminated) => Termination::Interrupted,
            ConicStatus::Solver(S::MaxIterations) => Termination::MaxIterations,
            ConicStatus::Solver(S::MaxTime) => Termination::TimeLimit,
            s => Termination::Failed(s.to_string()),
        }
    }
}

impl std::fmt::Display for ConicStatus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ConicStatus::Solver(s) => f.write_str(s.as_str()),
            ConicStatus::Settings(e) => write!(f, "SettingsError: {e}"),
            ConicStatus::Setup(e) => write!(f, "SetupError: {e}"),
        }
    }
}

impl serde::Serialize for ConicStatus {
    fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

/// Index of (i, j) (either order) in svec of an n×n symmetric matrix (upper triangle by columns, [`Cone::PsdTriangle`]).
pub fn svec_index(i: usize, j: usize) -> usize {
    let (i, j) = if i <= j { (i, j) } else { (j, i) };
    j * (j + 1) / 2 + i
}

/// svec scaling of entry (i, j): 1 on the diagonal, √2 off it.
pub fn svec_scale(i: usize, j: usize) -> f64 {
    if i == j {
        1.0
    } else {
        std::f64::consts::SQRT_2
    }
}

/// A sparse matrix being assembled: (row, column, value) entries, rows
/// reserved in blocks.
#[derive(Debug, Clone, Default)]
pub struct Entries {
    /// Number of rows so far.
    pub rows: usize,
    i: Vec<usize>,
    j: Vec<usize>,
    v: Vec<f64>,
}

impl Entries {
    /// No entries, no rows.
    pub fn new() -> Self {
        Self::default()
    }
    /// Adds `v` at (r, c) (zeros are skipped; repeated entries are summed).
    pub fn push(&mut self, r: usize, c: usize, v: f64) {
        if v != 0.0 {
            self.i.push(r);
            self.j.push(c);
            self.v.push(v);
        }
    }
    /// Reserves `k` new rows and returns the first.
    pub fn rows(&mut self, k: usize) -> usize {
        let r = self.rows;
        self.rows += k;
        r
    }
    /// The CSC matrix (`rows` × `ncols`) by Clarabel's constructor.
    pub fn csc(self, ncols: usize) -> CscMatrix<f64> {
        CscMatrix::new_from_triplets(self.rows, ncols, self.i, self.j, self.v)
    }
}

/// min ½xᵀPx + qᵀx s.t. b − Ax ∈ `cones` (P upper triangular; none: P = 0).
#[derive(Debug, Clone)]
pub struct Program {
    /// Number of variables.
    pub n_var: usize,
    /// P's upper triangle (n_var × n_var), if the objective is quadratic.
    pub p: Option<Entries>,
    /// q.
    pub q: Vec<f64>,
    /// A (its `rows` are the constraint rows).
    pub a: Entries,
    /// b.
    pub b: Vec<f64>,
    /// The cones, in row order.
    pub cones: Vec<Cone>,
}

/// Clarabel's settings that idexp chooses (the rest are Clarabel's defaults).
#[derive(Debug, Clone, Default)]
pub struct Settings {
    /// Clarabel prints its iterations.
    pub verbose: bool,
    /// Interior-point iteration budget (None: Clarabel's default).
    pub max_iter: Option<u32>,
    /// Time limit (s) before the control's deadline, whichever comes first.
    pub time_limit: Option<f64>,
    /// Absolute and relative gap tolerance (None: Clarabel's defaults); the
    /// feasibility tolerance is then max(tol, 1e-12) and the KKT ratio 1e-8.
    pub tol: Option<f64>,
    /// Report each iteration to the control's observer (`progress`).
    pub progress: bool,
}

/// What [`solve`] returns.
#[derive(Debug, Clone)]
pub struct Solved {
    /// How it ended.
    pub status: ConicStatus,
    /// Primal solution (empty when the solver could not be set up).
    pub x: Vec<f64>,
    /// Dual solution of the cone rows (empty when not set up).
    pub z: Vec<f64>,
    /// Interior-point iterations.
    pub iterations: u32,
    /// Clarabel's solve time (s).
    pub solve_time: f64,
    /// Number of variables and constraint rows.
    pub size: (usize, usize),
}

/// Solves `prog` with Clarabel under `ctl` (see the module docs).
pub fn solve(prog: Program, set: &Settings, ctl: &Control) -> Solved {
    let Program { n_var, p, q, a, b, cones } = prog;
    let m = a.rows;
    let a = a.csc(n_var);
    let p = match p {
        Some(p) => p.csc(n_var),
        None => CscMatrix::<f64>::zeros((n_var, n_var)),
    };
    let failed = |status: ConicStatus| Solved {
        status,
        x: Vec::new(),
        z: Vec::new(),
        iterations: 0,
        solve_time: 0.0,
        size: (n_var, m),
    };
    let limit = set.time_limit.unwrap_or(f64::INFINITY);
    let mut builder = DefaultSettingsBuilder::default();
    builder.verbose(set.verbose);
    if let Some(n) = set.max_iter {
        builder.max_iter(n);
    }
    // the earlier of the caller's limit and the control's deadline
    builder.time_limit(ctl.remaining().map_or(limit, |r| limit.min(r.as_secs_f64())));
    if let Some(tol) = set.tol {
        builder.tol_gap_abs(tol).tol_gap_rel(tol).tol_feas(tol.max(1e-12)).tol_ktratio(1e-8);
    }
    let settings = match builder.build() {
        Ok(s) => s,
        Err(e) => return failed(ConicStatus::Settings(e.to_string())),
    };
    let cones: Vec<SupportedConeT<f64>> = cones.into_iter().map(Cone::clarabel).collect();
    let mut solver = match DefaultSolver::new(&p, &q, &a, &b, &cones, settings) {
        Ok(s) => s,
        Err(e) => return failed(ConicStatus::Setup(e.to_string())),
    };
    let cb = ctl.clone();
    let progress = set.progress;
    solver.set_termination_callback(move |info: &clarabel::solver::DefaultInfo<f64>| {
        if progress {
            cb.observer().progress(info.iterations as u64, &format!("gap {:.1e}", info.gap_rel));
        }
        cb.interrupted()
    });
    solver.solve();
    let sol = &solver.solution;
    Solved {
        status: ConicStatus::Solver(SolverStatus::of(sol.status)),
        x: sol.x.clone(),
        z: sol.z.clone(),
        iterations: sol.iterations,
        solve_time: sol.solve_time,
        size: (n_var, m),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn duplicates_are_summed_and_zeros_skipped() {
        let mut t = Entries::new();
        assert_eq!(t.rows(2), 0);
        t.push(1, 0, 2.0);
        t.push(0, 1, 3.0);
        t.push(1, 0, 0.5);
        t.push(0, 0, 0.0);
        let m = t.csc(2);
        assert_eq!(m.colptr, vec![0, 1, 2]);
        assert_eq!(m.rowval, vec![1, 0]);
        assert_eq!(m.nzval, vec![2.5, 3.0]);
    }

    /// min x s.t. x ≥ 1 (s = x − 1 ≥ 0 ⇔ b − Ax with A = −1, b = −1).
    fn tiny() -> Program {
        let mut a = Entries::new();
        let r = a.rows(1);
        a.push(r, 0, -1.0);
        Program {
            n_var: 1,
            p: None,
            q: vec![1.0],
            a,
            b: vec![-1.0],
            cones: vec![Cone::Nonnegative(1)],
        }
    }

    #[test]
    fn solves_and_stops_on_the_control() {
        let s = solve(tiny(), &Settings::default(), &Control::new());
        assert!(s.status.is_solved(), "{}", s.status);
        approx::assert_abs_diff_eq!(s.x[0], 1.0, epsilon = 1e-7);
        let ctl = Control::new();
        ctl.stop_flag().request();
        let s = solve(tiny(), &Settings::default(), &ctl);
        assert_eq!(s.status, ConicStatus::Solver(SolverStatus::CallbackTerminated));
        assert_eq!(s.status.termination(), Termination::Interrupted);
    }

    /// Each status is written with Clarabel's own word for it.
    #[test]
    fn status_words_are_clarabels() {
        use clarabel::solver::SolverStatus as C;
        for c in [
            C::Unsolved,
            C::Solved,
            C::PrimalInfeasible,
            C::DualInfeasible,
            C::AlmostSolved,
            C::AlmostPrimalInfeasible,
            C::AlmostDualInfeasible,
            C::MaxIterations,
            C::MaxTime,
            C::NumericalError,
            C::InsufficientProgress,
            C::CallbackTerminated,
        ] {
            let ours = ConicStatus::Solver(SolverStatus::of(c));
            assert_eq!(ours.to_string(), c.to_string());
            assert_eq!(serde_json::to_string(&ours).unwrap(), format!("\"{c}\""));
        }
    }

    /// min t over one cone whose rows are s = b + c·t (A = −c); the
    /// optimum is known in closed form for each cone.
    fn one_cone(cone: Cone, b: &[f64], c: &[(usize, f64)]) -> f64 {
        let mut a = Entries::new();
        a.rows(b.len());
        for &(r, v) in c {
            a.push(r, 0, -v);
        }
        let prog = Program {
            n_var: 1,
            p: None,
            q: vec![1.0],
            a,
            b: b.to_vec(),
            cones: vec![cone],
        };
        let s = solve(prog, &Settings::default(), &Control::new());
        assert!(s.status.is_solved(), "{cone:?}: {}", s.status);
        s.x[0]
    }

    #[test]
    fn each_cone_is_the_one_it_names() {
        use approx::assert_abs_diff_eq as close;
        use std::f64::consts::{E, FRAC_1_SQRT_2, SQRT_2};
        // zero: t − 2 = 0
        close!(one_cone(Cone::Zero(1), &[-2.0], &[(0, 1.0)]), 2.0, epsilon = 1e-7);
        // nonnegative: t − 1 ≥ 0 and t − 3 ≥ 0 → t = 3
        close!(one_cone(Cone::Nonnegative(2), &[-1.0, -3.0], &[(0, 1.0), (1, 1.0)]), 3.0, epsilon = 1e-6);
        // second order: ‖(3, 4)‖ ≤ t → t = 5
        close!(one_cone(Cone::SecondOrder(3), &[0.0, 3.0, 4.0], &[(0, 1.0)]), 5.0, epsilon = 1e-6);
        // exponential: (1, 1, t) with 1·exp(1/1) ≤ t → t = e
        close!(one_cone(Cone::Exponential, &[1.0, 1.0, 0.0], &[(2, 1.0)]), E, epsilon = 1e-6);
        // PSD triangle: [[t, 1], [1, 2t]] ⪰ 0 as (t, √2·1, 2t) → 2t² ≥ 1
        close!(
            one_cone(Cone::PsdTriangle(2), &[0.0, SQRT_2, 0.0], &[(0, 1.0), (2, 2.0)]),
            FRAC_1_SQRT_2,
            epsilon = 1e-6
        );
    }
}
