//! `idexp.Robot` and `idexp.BaseParameters`.

use crate::arrays::{self, out1, out2, out_matrix, Arg};
use crate::err::{value, IntoPy};
use idexp::params::{BaseOptions, BaseParams};
use idexp::robot::{self as rb, Workspace};
use numpy::{PyArray1, PyArray2};
use pyo3::prelude::*;
use std::path::PathBuf;
use std::sync::{Arc, OnceLock};

/// A pair of (n, n) float64 arrays (∂τ/∂q, ∂τ/∂q̇).
type MatrixPair<'py> = (Bound<'py, PyArray2<f64>>, Bound<'py, PyArray2<f64>>);

/// Pinocchio's order of a body's 10 dynamic parameters
/// `[m, mcx, mcy, mcz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz]` as indices into idexp's
/// `[XX, XY, XZ, YY, YZ, ZZ, MX, MY, MZ, M]` (both about the body frame origin).
pub const PINOCCHIO_FROM_IDEXP: [usize; 10] = [9, 6, 7, 8, 0, 1, 3, 2, 4, 5];

/// A robot model loaded from a `.toml` (DH or URDF-like description) or
/// `.urdf` file. Immutable; every method is thread-safe.
#[pyclass(module = "idexp", frozen)]
pub struct Robot {
    pub(crate) inner: Arc<rb::Robot>,
    pub(crate) path: PathBuf,
    base: OnceLock<Arc<BaseParams>>,
}

impl Robot {
    pub(crate) fn new(r: rb::Robot, path: PathBuf) -> Robot {
        Robot {
            inner: Arc::new(r),
            path,
            base: OnceLock::new(),
        }
    }

    /// The default base parameters (all columns), computed once.
    pub(crate) fn default_base(&self) -> PyResult<Arc<BaseParams>> {
        if let Some(b) = self.base.get() {
            return Ok(b.clone());
        }
        let b = Arc::new(BaseParams::compute(&self.inner, &BaseOptions::default()).py()?);
        Ok(self.base.get_or_init(|| b).clone())
    }

    fn theta_arg(&self, theta: Option<&Arg>) -> PyResult<Vec<f64>> {
        let p = self.inner.n_params();
        match theta {
            Some(t) => arrays::vector("theta", t, p, "one value per standard parameter, see robot.param_names"),
            None => Ok(self.inner.nominal_params().iter().copied().collect()),
        }
    }
}

/// One state → 1-D, a batch → 2-D, from row-major `rows × cols` values.
fn shaped<'py>(py: Python<'py>, batch: bool, rows: usize, cols: usize, v: Vec<f64>) -> Bound<'py, PyAny> {
    if batch {
        out2(py, rows, cols, v).into_any()
    } else {
        out1(py, v).into_any()
    }
}

#[pymethods]
impl Robot {
    /// Robot.load(path) -> Robot
    ///
    /// Loads a robot file (`.toml` or `.urdf`). Errors name the file, the
    /// field and what is allowed (`idexp.IdexpError`; `OSError` if the file
    /// cannot be read).
    #[staticmethod]
    fn load(py: Python<'_>, path: PathBuf) -> PyResult<Robot> {
        let r = py.detach(|| rb::load(&path)).py()?;
        Ok(Robot::new(r, path))
    }

    /// Robot name.
    #[getter]
    fn name(&self) -> String {
        self.inner.name.clone()
    }

    /// The file it was loaded from.
    #[getter]
    fn path(&self) -> PathBuf {
        self.path.clone()
    }

    /// Number of actuated joints n.
    #[getter]
    fn dof(&self) -> usize {
        self.inner.dof()
    }

    /// Joint names (n).
    #[getter]
    fn joint_names(&self) -> Vec<String> {
        self.inner.joints.iter().map(|j| j.name.clone()).collect()
    }

    /// Joint kinds (n): "revolute" or "prismatic".
    #[getter]
    fn joint_kinds(&self) -> Vec<&'static str> {
        self.inner
            .joints
            .iter()
            .map(|j| match j.kind {
                rb::JointKind::Revolute => "revolute",
                rb::JointKind::Prismatic => "prismatic",
            })
            .collect()
    }

    /// Joint limits as a dict of arrays (n each): lower, upper (rad or m),
    /// velocity, acceleration, effort (symmetric; inf when not given).
    #[getter]
    fn limits<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, pyo3::types::PyDict>> {
        let d = pyo3::types::PyDict::new(py);
        let j = &self.inner.joints;
        let col = |f: fn(&rb::JointLimits) -> f64| j.iter().map(|j| f(&j.limits)).collect::<Vec<f64>>();
        d.set_item("lower", out1(py, col(|l| l.lower)))?;
        d.set_item("upper", out1(py, col(|l| l.upper)))?;
        d.set_item("velocity", out1(py, col(|l| l.velocity)))?;
        d.set_item("acceleration", out1(py, col(|l| l.acceleration)))?;
        d.set_item("effort", out1(py, col(|l| l.effort)))?;
        Ok(d)
    }

    /// Names of the p standard parameters (XX1 … M1, …, then Ia1, Fc1, Fv1, …).
    #[getter]
    fn param_names(&self) -> Vec<String> {
        self.inner.param_names()
    }

    /// Number of standard parameters p.
    #[getter]
    fn n_params(&self) -> usize {
        self.inner.n_params()
    }

    /// Boolean mask (p,) of the rigid-body inertial parameters.
    #[getter]
    fn inertial_mask(&self) -> Vec<bool> {
        self.inner.inertial_mask()
    }

    /// Nominal standard parameter values θ (p,).
    #[getter]
    fn nominal_params<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        out1(py, self.inner.nominal_params().iter().copied().collect())
    }

    /// Gravity vector in base coordinates (3,), m/s².
    #[getter]
    fn gravity<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        out1(py, self.inner.gravity.iter().copied().collect())
    }

    /// robot.rnea(q, qd, qdd) -> tau
    ///
    /// Inverse dynamics with the nominal parameters, motor side (N·m or N):
    /// shape (n,) for one state, (N, n) for a batch of N states.
    fn rnea<'py>(&self, py: Python<'py>, q: Arg, qd: Arg, qdd: Arg) -> PyResult<Bound<'py, PyAny>> {
        let r = &self.inner;
        let n = r.dof();
        let (q, qd, qdd) = arrays::state_triple(&q, &qd, &qdd, n)?;
        let out = py.detach(|| {
            let mut ws = Workspace::new(r);
            let mut tau = vec![0.0; q.rows * n];
            for (k, t) in tau.chunks_mut(n).enumerate() {
                rb::rnea(r, &mut ws, q.row(k, n), qd.row(k, n), qdd.row(k, n), t);
            }
            tau
        });
        Ok(shaped(py, q.batch, q.rows, n, out))
    }

    /// robot.inverse_dynamics(theta, q, qd, qdd) -> tau
    ///
    /// Inverse dynamics Y(q, q̇, q̈)·θ for a given standard parameter vector
    /// θ (p,); shapes as for `rnea`.
    fn inverse_dynamics<'py>(&self, py: Python<'py>, theta: Arg, q: Arg, qd: Arg, qdd: Arg) -> PyResult<Bound<'py, PyAny>> {
        let r = &self.inner;
        let n = r.dof();
        let theta = self.theta_arg(Some(&theta))?;
        let (q, qd, qdd) = arrays::state_triple(&q, &qd, &qdd, n)?;
        let out = py.detach(|| {
            let mut ws = Workspace::new(r);
            let mut tau = vec![0.0; q.rows * n];
            for (k, t) in tau.chunks_mut(n).enumerate() {
                rb::inverse_dynamics(r, &mut ws, &theta, q.row(k, n), qd.row(k, n), qdd.row(k, n), t);
            }
            tau
        });
        Ok(shaped(py, q.batch, q.rows, n, out))
    }

    /// robot.mass_matrix(q) -> M
    ///
    /// Joint-space mass matrix (n, n) with the nominal parameters, or
    /// (N, n, n) for a batch of positions (N, n).
    fn mass_matrix<'py>(&self, py: Python<'py>, q: Arg) -> PyResult<Bound<'py, PyAny>> {
        let r = &self.inner;
        let n = r.dof();
        let q = arrays::states("q", &q, n)?;
        let data = py.detach(|| {
            let mut ws = Workspace::new(r);
            let mut out = Vec::with_capacity(q.rows * n * n);
            for k in 0..q.rows {
                let m = rb::mass_matrix(r, &mut ws, q.row(k, n));
                out.extend((0..n * n).map(|i| m[(i / n, i % n)]));
            }
            out
        });
        if q.batch {
            let a = numpy::ndarray::Array3::from_shape_vec((q.rows, n, n), data).expect("N·n·n values");
            Ok(numpy::IntoPyArray::into_pyarray(a, py).into_any())
        } else {
            Ok(out2(py, n, n, data).into_any())
        }
    }

    /// robot.id_derivatives(q, qd, qdd, theta=None) -> (dtau_dq, dtau_dqd)
    ///
    /// Derivatives of inverse dynamics (motor side) at one state, with the
    /// standard parameters θ (p,; default the nominal ones): ∂τ/∂q and
    /// ∂τ/∂q̇, each (n, n), entry [j, i] = ∂τ_j/∂x_i (the recursive RNEA
    /// derivatives, friction slopes included in ∂τ/∂q̇).
    #[pyo3(signature = (q, qd, qdd, theta = None))]
    fn id_derivatives<'py>(&self, py: Python<'py>, q: Arg, qd: Arg, qdd: Arg, theta: Option<Arg>) -> PyResult<MatrixPair<'py>> {
        let r = &self.inner;
        let n = r.dof();
        let theta = self.theta_arg(theta.as_ref())?;
        let (q, qd, qdd) = arrays::state_triple(&q, &qd, &qdd, n)?;
        if q.batch || qd.batch || qdd.batch {
            return Err(value(format!("id_derivatives: one state, q, qd, qdd of shape ({n},)")));
        }
        let (a, b) = py.detach(|| {
            let mut ws = Workspace::new(r);
            let (a, b) = rb::id_derivatives(r, &mut ws, &theta, q.row(0, n), qd.row(0, n), qdd.row(0, n));
            let rm = |m: &nalgebra::DMatrix<f64>| (0..n * n).map(|i| m[(i / n, i % n)]).collect::<Vec<f64>>();
            (rm(&a), rm(&b))
        });
        Ok((out2(py, n, n, a), out2(py, n, n, b)))
    }

    /// robot.regressor(q, qd, qdd, base=False) -> Y
    ///
    /// The regressor Y with τ = Y θ (motor side): (n, p) for one state, or
    /// the stack (N·n, p) for a batch (N, n), state-major (rows k·n … k·n+n−1
    /// are state k). `base=True`: the base regressor, the columns
    /// `robot.base_parameters().independent` (p → n_base).
    #[pyo3(signature = (q, qd, qdd, base = false))]
    fn regressor<'py>(&self, py: Python<'py>, q: Arg, qd: Arg, qdd: Arg, base: bool) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let r = &self.inner;
        let (n, p) = (r.dof(), r.n_params());
        let (q, qd, qdd) = arrays::state_triple(&q, &qd, &qdd, n)?;
        let bp = if base { Some(self.default_base()?) } else { None };
        let cols = bp.as_ref().map_or(p, |b| b.n_base());
        let rows = q.rows * n;
        let data = py.detach(|| {
            let mut ws = Workspace::new(r);
            let mut out = vec![0.0; rows * cols];
            match &bp {
                None => {
                    for (k, y) in out.chunks_mut(n * p).enumerate() {
                        rb::regressor_rows(r, &mut ws, q.row(k, n), qd.row(k, n), qdd.row(k, n), y);
                    }
                }
                Some(b) => {
                    let mut y = vec![0.0; n * p];
                    for (k, yb) in out.chunks_mut(n * cols).enumerate() {
                        rb::regressor_rows(r, &mut ws, q.row(k, n), qd.row(k, n), qdd.row(k, n), &mut y);
                        b.select_rows(&y, n, yb);
                    }
                }
            }
            out
        });
        Ok(out2(py, rows, cols, data))
    }

    /// robot.base_parameters(tol=1e-6, samples=200, seed=1, inertial_only=False) -> BaseParameters
    ///
    /// The base parameters θ_b = K θ (numerically, greedy QR over random
    /// states, Gautier 1991): names, K, groupings, tolerance.
    #[pyo3(signature = (tol = 1e-6, samples = 200, seed = 1, inertial_only = false))]
    fn base_parameters(&self, py: Python<'_>, tol: f64, samples: usize, seed: u64, inertial_only: bool) -> PyResult<BaseParameters> {
        if !(tol.is_finite() && tol > 0.0 && tol < 1.0) {
            return Err(value(format!("tol: expected a relative tolerance in (0, 1), got {tol}")));
        }
        if samples == 0 || samples > 1_000_000 {
            return Err(value(format!("samples: expected 1 … 1000000 random states, got {samples}")));
        }
        let opts = BaseOptions {
            samples,
            seed,
            tol,
            inertial_only,
        };
        let r = &self.inner;
        let b = py.detach(|| BaseParams::compute(r, &opts)).py()?;
        Ok(BaseParameters {
            inner: Arc::new(b),
            nominal: r.nominal_params().iter().copied().collect(),
        })
    }

    /// robot.to_pinocchio(theta=None) -> pi
    ///
    /// The inertial part of a standard parameter vector θ (p,; default the
    /// nominal one) in Pinocchio's order, `[m, mcx, mcy, mcz, Ixx, Ixy, Iyy,
    /// Ixz, Iyz, Izz]` per moving body (the layout of
    /// `model.inertias[i].toDynamicParameters()`, inertia about the body
    /// frame origin as in idexp), concatenated over the n bodies: shape (10·n,).
    /// Drive parameters (Ia, friction) have no Pinocchio counterpart and are
    /// left out. `robot.from_pinocchio` is the inverse.
    #[pyo3(signature = (theta = None))]
    fn to_pinocchio<'py>(&self, py: Python<'py>, theta: Option<Arg>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let th = self.theta_arg(theta.as_ref())?;
        let r = &self.inner;
        let mut out = Vec::with_capacity(10 * r.links.len());
        for i in 0..r.links.len() {
            let o = r.link_param_offset(i);
            out.extend(PINOCCHIO_FROM_IDEXP.iter().map(|&k| th[o + k]));
        }
        Ok(out1(py, out))
    }

    /// robot.from_pinocchio(pi, theta=None) -> theta
    ///
    /// The inverse of `to_pinocchio`: Pinocchio dynamic parameters (10·n,)
    /// into a standard parameter vector (p,); the drive parameters are taken
    /// from `theta` (default: the nominal ones).
    #[pyo3(signature = (pi, theta = None))]
    #[allow(clippy::wrong_self_convention)] // the Python method's name, the inverse of `to_pinocchio`
    fn from_pinocchio<'py>(&self, py: Python<'py>, pi: Arg, theta: Option<Arg>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let r = &self.inner;
        let nb = r.links.len();
        let pi = arrays::vector("pi", &pi, 10 * nb, "10 Pinocchio dynamic parameters per body")?;
        let mut th = self.theta_arg(theta.as_ref())?;
        for i in 0..nb {
            let o = r.link_param_offset(i);
            for (j, &k) in PINOCCHIO_FROM_IDEXP.iter().enumerate() {
                th[o + k] = pi[10 * i + j];
            }
        }
        Ok(out1(py, th))
    }

    /// robot.with_params(theta) -> Robot
    ///
    /// A copy of the model with the standard parameters θ (p,): the link
    /// inertials and the drive parameters (Ia, friction) replaced; the file it
    /// came from (`path`) stays, as the source of the kinematics for `export`.
    fn with_params(&self, py: Python<'_>, theta: Arg) -> PyResult<Robot> {
        let th = self.theta_arg(Some(&theta))?;
        let r = py.detach(|| self.inner.with_params(&th)).py()?;
        Ok(Robot::new(r, self.path.clone()))
    }

    /// robot.export(folder, formats=("urdf", "toml")) -> list of paths
    ///
    /// Writes the model with its current parameters the way `idexp identify
    /// --export urdf,toml` writes the identified one: `robot.urdf` (the
    /// source URDF with this model's inertials, everything else copied byte
    /// for byte; a DH robot has none: ValueError) and `robot.toml` (the
    /// source robot file with this model's drive parameters and, for a DH
    /// table, inertials; it points at the exported URDF, else at the source
    /// URDF). `formats`: a list or a comma-separated string. Both files load
    /// back with `Robot.load`.
    #[pyo3(signature = (folder, formats = None))]
    fn export(&self, py: Python<'_>, folder: PathBuf, formats: Option<Bound<'_, PyAny>>) -> PyResult<Vec<PathBuf>> {
        let kinds = match &formats {
            Some(f) => crate::exports::model_kinds(f, &["urdf", "toml"])?,
            None => match idexp::robot::export::source_of(&self.path).py()? {
                idexp::robot::export::Source::Dh { .. } => vec!["toml".to_string()],
                _ => vec!["urdf".to_string(), "toml".to_string()],
            },
        };
        py.detach(|| crate::exports::write_model(&self.path, &self.inner, &folder, &kinds))
    }

    /// Physical-consistency warnings about the model's inertials (a
    /// pseudo-inertia that is not positive semidefinite, inertia without
    /// mass); empty when every link is consistent.
    #[getter]
    fn inertial_warnings(&self) -> Vec<String> {
        idexp::robot::export::inertial_warnings(&self.inner)
    }

    /// Robot.provenance() -> dict
    ///
    /// Where the model came from, as `idexp robot info` prints it:
    /// `left_out` (what of the URDF is not part of the model and why: joints
    /// off the chain to `tip_link`, `<mimic>` groups such as a gripper's
    /// fingers, locked and merged) and `collision` (every collision shape:
    /// `body`, `link`, `written_in`, `shape`, and for a mesh its `uri` as
    /// written and the `file` read).
    fn provenance<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let p = py.detach(|| idexp::robot::provenance::provenance(&self.path)).py()?;
        crate::dicts::to_dict(py, &p)
    }

    fn __repr__(&self) -> String {
        format!(
            "Robot({:?}, dof={}, params={}, path={:?})",
            self.inner.name,
            self.inner.dof(),
            self.inner.n_params(),
            self.path.display().to_string()
        )
    }
}

/// The base parameters of a robot (`robot.base_parameters()`).
#[pyclass(module = "idexp", frozen)]
pub struct BaseParameters {
    pub(crate) inner: Arc<BaseParams>,
    nominal: Vec<f64>,
}

#[pymethods]
impl BaseParameters {
    /// Base parameter names (n_base).
    #[getter]
    fn names(&self) -> Vec<String> {
        self.inner.names.clone()
    }
    /// Each base parameter as a readable combination of standard ones.
    #[getter]
    fn groupings(&self) -> Vec<String> {
        self.inner.groupings.clone()
    }
    /// K (n_base, p): θ_base = K θ.
    #[getter]
    #[allow(non_snake_case)]
    fn K<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        out_matrix(py, &self.inner.k)
    }
    /// Standard-parameter indices of the base parameters (the kept columns).
    #[getter]
    fn independent(&self) -> Vec<usize> {
        self.inner.independent.clone()
    }
    /// Standard parameters regrouped into others.
    #[getter]
    fn regrouped(&self) -> Vec<usize> {
        self.inner.regrouped.clone()
    }
    /// Standard parameters with no effect on the torques.
    #[getter]
    fn unidentifiable(&self) -> Vec<usize> {
        self.inner.unidentifiable.clone()
    }
    /// Rank tolerance used.
    #[getter]
    fn tol(&self) -> f64 {
        self.inner.tol
    }
    /// Smallest relative residual among the kept columns (margin above tol).
    #[getter]
    fn smallest_kept(&self) -> f64 {
        self.inner.smallest_kept
    }
    /// Largest relative residual among the dropped columns (margin below tol).
    #[getter]
    fn largest_dropped(&self) -> f64 {
        self.inner.largest_dropped
    }
    /// Number of base parameters.
    #[getter]
    fn n_base(&self) -> usize {
        self.inner.n_base()
    }
    /// Nominal base values K θ_nominal (n_base,).
    #[getter]
    fn nominal<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        out1(py, self.inner.base_values(&self.nominal).iter().copied().collect())
    }
    /// base.values(theta) -> K θ for a standard vector θ (p,).
    fn values<'py>(&self, py: Python<'py>, theta: Arg) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let th = arrays::vector("theta", &theta, self.inner.n_std, "one value per standard parameter")?;
        Ok(out1(py, self.inner.base_values(&th).iter().copied().collect()))
    }
    /// The library's serialisation as a dict (everything but K).
    #[getter]
    fn report<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        crate::dicts::to_dict(py, &*self.inner)
    }
    fn __len__(&self) -> usize {
        self.inner.n_base()
    }
    fn __repr__(&self) -> String {
        format!(
            "BaseParameters(n_base={}, p={}, tol={:e})",
            self.inner.n_base(),
            self.inner.n_std,
            self.inner.tol
        )
    }
}
