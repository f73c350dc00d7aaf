//! The fit's FRF kernel: G(jω_k, θ) and ∂G/∂θ at every line of one position,
//! allocation-free per line, with the solves W = A(jω)⁻¹B kept for reuse.
//!
//! The arithmetic is that of [`crate::elastic::FrfKernel`] (motor block
//! eliminated first, Schur complement on the link side, pivoted full solve
//! as fallback; rank-one derivatives −s^r c v vᵀ with v = bᵀW), operation
//! for operation, so both give bit-identical values (tested). What differs
//! is the bookkeeping of a fit, which evaluates the same 370 lines hundreds
//! of times per start:
//!
//! * [`PosSystem`] extracts once per position and parameter vector what
//!   every line needs (the diagonal motor block, the sparse motor–link
//!   coupling, the link blocks as contiguous rows), so a line allocates
//!   nothing;
//! * the line solve writes W into caller-owned storage: Levenberg–Marquardt
//!   evaluates the cost at a trial point and, when the step is accepted, the
//!   normal equations at the same point, which then reuse the W of every
//!   line instead of solving again ([`SolveCache`]);
//! * the derivatives are not stored as p matrices n×n: a rank-one parameter
//!   i keeps the two factors (f_i v_i and v_i, f_i = −s^r c_i) and
//!   ∂G_ab/∂θ_i = (f_i `v_i[a]`) `v_i[b]` is formed where the estimator needs it;
//!   parameters sharing a direction b (a spring and its damper) share v.

use crate::elastic::linear::solve_in_place;
use crate::elastic::{ElasticModel, LinearModel, OperatingPoint, Output, ParamRole, C64};
use crate::error::{Error, Result};

const ZERO: C64 = C64 { re: 0.0, im: 0.0 };
const ONE: C64 = C64 { re: 1.0, im: 0.0 };

/// How ∂A/∂θ_i looks for one unknown.
#[derive(Debug, Clone, Copy)]
enum Deriv {
    /// c(s) b bᵀ with b = direction `dir`; c = 1, s or s² (`power`).
    Rank1 { dir: usize, power: u8 },
    /// s² ∂M + ∂K_g of a rigid inertial parameter: index into the operating point's `dlink`.
    Link { unknown: usize },
}

/// Structure of the model's derivatives, built once per model.
#[derive(Debug, Clone)]
pub struct FitKernel {
    n_motors: usize,
    output: Output,
    derivs: Vec<Deriv>,
    /// Distinct derivative directions: gearbox j (`b_j`, from the linear
    /// model) or a unit vector e_x.
    dirs: Vec<Dir>,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Dir {
    Gear(usize),
    Unit(usize),
}

impl FitKernel {
    /// The kernel for `model` and FRF `output`.
    pub fn new(model: &ElasticModel, output: Output) -> FitKernel {
        let na = model.n_motors();
        let mut dirs: Vec<Dir> = Vec::new();
        let mut dir_of = |d: Dir| match dirs.iter().position(|x| *x == d) {
            Some(i) => i,
            None => {
                dirs.push(d);
                dirs.len() - 1
            }
        };
        let derivs = model
            .unknowns
            .iter()
            .map(|&u| match model.params[u].role {
                ParamRole::GearSpring(j) => Deriv::Rank1 {
                    dir: dir_of(Dir::Gear(j)),
                    power: 0,
                },
                ParamRole::GearDamper(j) => Deriv::Rank1 {
                    dir: dir_of(Dir::Gear(j)),
                    power: 1,
                },
                ParamRole::ArmSpring(e) => Deriv::Rank1 {
                    dir: dir_of(Dir::Unit(na + model.elastic_index[e])),
                    power: 0,
                },
                ParamRole::ArmDamper(e) => Deriv::Rank1 {
                    dir: dir_of(Dir::Unit(na + model.elastic_index[e])),
                    power: 1,
                },
                ParamRole::RotorInertia(j) => Deriv::Rank1 {
                    dir: dir_of(Dir::Unit(j)),
                    power: 2,
                },
                ParamRole::MotorViscous(j) => Deriv::Rank1 {
                    dir: dir_of(Dir::Unit(j)),
                    power: 1,
                },
                ParamRole::Link(_) => Deriv::Link { unknown: u },
            })
            .collect();
        FitKernel {
            n_motors: na,
            output,
            derivs,
            dirs,
        }
    }

    /// Number of unknowns p.
    pub fn n_params(&self) -> usize {
        self.derivs.len()
    }

    /// Length of one line's W (N × n_a).
    pub fn w_len(&self, sys: &PosSystem) -> usize {
        sys.n * self.n_motors
    }

    /// The per-position data of `lin` (at operating point `op`) for every line.
    pub fn system<'a>(&self, lin: &'a LinearModel, op: &'a OperatingPoint) -> Result<PosSystem<'a>> {
        let n = lin.m.nrows();
        let na = lin.n_motors;
        let nx = n - na;
        let nz = |r: usize, c: usize| lin.m[(r, c)] != 0.0 || lin.d[(r, c)] != 0.0 || lin.k[(r, c)] != 0.0;
        let mut diag_motor = na > 0 && nx > 0;
        'check: for i in 0..na {
            for j in 0..na {
                if i != j && nz(i, j) {
                    diag_motor = false;
                    break 'check;
                }
            }
        }
        let mut aml = Vec::new();
        let mut aml_start = vec![0usize; na + 1];
        let mut alm = Vec::new();
        let mut alm_start = vec![0usize; nx + 1];
        if diag_motor {
            for j in 0..na {
                for c in 0..nx {
                    if nz(j, na + c) {
                        aml.push((c, [lin.m[(j, na + c)], lin.d[(j, na + c)], lin.k[(j, na + c)]]));
                    }
                }
                aml_start[j + 1] = aml.len();
            }
            for r in 0..nx {
                for j in 0..na {
                    if nz(na + r, j) {
                        alm.push((j, [lin.m[(na + r, j)], lin.d[(na + r, j)], lin.k[(na + r, j)]]));
                    }
                }
                alm_start[r + 1] = alm.len();
            }
        }
        let block = |m: &nalgebra::DMatrix<f64>| {
            let mut v = vec![0.0; nx * nx];
            for r in 0..nx {
                for c in 0..nx {
                    v[r * nx + c] = m[(na + r, na + c)];
                }
            }
            v
        };
        let mut links = Vec::new();
        for d in &self.derivs {
            if let Deriv::Link { unknown } = *d {
                let (_, dm, dk) = op
                    .dlink
                    .iter()
                    .find(|(uu, _, _)| *uu == unknown)
                    .ok_or_else(|| Error::Numerical("operating point was built for other unknowns".into()))?;
                links.push((dm, dk));
            }
        }
        Ok(PosSystem {
            lin,
            n,
            na,
            nx,
            diag_motor,
            mm: (0..na).map(|i| [lin.m[(i, i)], lin.d[(i, i)], lin.k[(i, i)]]).collect(),
            aml,
            aml_start,
            alm,
            alm_start,
            ml: block(&lin.m),
            dl: block(&lin.d),
            kl: block(&lin.k),
            links,
        })
    }

    /// G(jω) into `g` (n_a × n_a, row-major) from a line's W, and, if `jac`
    /// is given, the factors of ∂G/∂θ at that line.
    pub fn frf(&self, sys: &PosSystem, omega: f64, w: &[C64], g: &mut [C64], jac: Option<&mut LineJac>) {
        let na = self.n_motors;
        let s = C64::new(0.0, omega);
        let sr = s.powi(self.output.power());
        for i in 0..na {
            for j in 0..na {
                g[i * na + j] = sr * w[i * na + j];
            }
        }
        let Some(jac) = jac else { return };
        let p = self.derivs.len();
        jac.na = na;
        jac.fa.resize(p * na, ZERO);
        jac.vb.resize(self.dirs.len() * na, ZERO);
        jac.dir.resize(p, usize::MAX);
        let nlink = self.derivs.iter().filter(|d| matches!(d, Deriv::Link { .. })).count();
        jac.dense.resize(nlink * na * na, ZERO);
        // v = bᵀW per direction, over the non-zero entries of b
        for (k, d) in self.dirs.iter().enumerate() {
            let v = &mut jac.vb[k * na..(k + 1) * na];
            v.iter_mut().for_each(|x| *x = ZERO);
            let mut add = |r: usize, br: f64| {
                for j in 0..na {
                    v[j] += w[r * na + j] * br;
                }
            };
            match *d {
                Dir::Gear(j) => sys.lin.b_nz[j].iter().for_each(|&(r, br)| add(r, br)),
                Dir::Unit(x) => add(x, 1.0),
            }
        }
        let cs = [ONE, s, s * s];
        let mut li = 0;
        for (i, d) in self.derivs.iter().enumerate() {
            match *d {
                Deriv::Rank1 { dir, power } => {
                    let f = -sr * cs[power as usize];
                    jac.dir[i] = dir;
                    for a in 0..na {
                        jac.fa[i * na + a] = f * jac.vb[dir * na + a];
                    }
                }
                Deriv::Link { .. } => {
                    jac.dir[i] = usize::MAX;
                    let (dm, dk) = sys.links[li];
                    let out = &mut jac.dense[li * na * na..(li + 1) * na * na];
                    link_derivative(dm, dk, s * s, sr, w, na, out);
                    li += 1;
                }
            }
        }
        jac.link_of.clear();
        let mut li = 0;
        for d in &self.derivs {
            jac.link_of.push(if matches!(d, Deriv::Link { .. }) {
                li += 1;
                li - 1
            } else {
                usize::MAX
            });
        }
    }
}

/// −s^r W_lᵀ (s² dM + dK) W_l into `out` (n_a × n_a, row-major).
fn link_derivative(dm: &nalgebra::DMatrix<f64>, dk: &nalgebra::DMatrix<f64>, s2: C64, sr: C64, w: &[C64], na: usize, out: &mut [C64]) {
    let nx = dm.nrows();
    let wv = |r: usize, j: usize| w[r * na + j];
    let mut t = vec![ZERO; nx * na];
    for r in 0..nx {
        for c in 0..nx {
            let coef = s2 * dm[(r, c)] + C64::new(dk[(r, c)], 0.0);
            if coef.re == 0.0 && coef.im == 0.0 {
                continue;
            }
            for j in 0..na {
                t[r * na + j] += coef * wv(na + c, j);
            }
        }
    }
    for i in 0..na {
        for j in 0..na {
            let mut acc = ZERO;
            for r in 0..nx {
                acc += wv(na + r, i) * t[r * na + j];
            }
            out[i * na + j] = -sr * acc;
        }
    }
}

/// The factors of ∂G/∂θ at one line ([`FitKernel::frf`]).
#[derive(Debug, Clone, Default)]
pub struct LineJac {
    na: usize,
    /// f_i v_i (p × n_a) for rank-one parameters.
    fa: Vec<C64>,
    /// v per direction (directions × n_a).
    vb: Vec<C64>,
    /// Direction of parameter i (usize::MAX for a rigid parameter).
    dir: Vec<usize>,
    /// Index into `dense` per parameter.
    link_of: Vec<usize>,
    /// Dense ∂G of the rigid parameters (n_a × n_a each).
    dense: Vec<C64>,
}

impl LineJac {
    /// ∂G_ab/∂θ_i.
    #[inline]
    pub fn dg(&self, i: usize, a: usize, b: usize) -> C64 {
        let na = self.na;
        let d = self.dir[i];
        if d != usize::MAX {
            self.fa[i * na + a] * self.vb[d * na + b]
        } else {
            self.dense[self.link_of[i] * na * na + a * na + b]
        }
    }
}

/// One position's linear model arranged for line solves.
#[derive(Debug)]
pub struct PosSystem<'a> {
    lin: &'a LinearModel,
    n: usize,
    na: usize,
    nx: usize,
    /// The motor block is diagonal (Schur elimination possible).
    diag_motor: bool,
    /// Motor diagonal (m, d, k).
    mm: Vec<[f64; 3]>,
    /// A_ml rows: (link column, (m, d, k)), motor j's entries in aml[aml_start[j]..aml_start[j+1]].
    aml: Vec<(usize, [f64; 3])>,
    aml_start: Vec<usize>,
    /// A_lm rows: (motor column, (m, d, k)).
    alm: Vec<(usize, [f64; 3])>,
    alm_start: Vec<usize>,
    /// Link blocks (row-major n_x × n_x).
    ml: Vec<f64>,
    dl: Vec<f64>,
    kl: Vec<f64>,
    /// (∂M, ∂K_g) of the rigid unknowns, in the order of the kernel's unknowns.
    links: Vec<(&'a nalgebra::DMatrix<f64>, &'a nalgebra::DMatrix<f64>)>,
}

/// Scratch of the line solve (reused across lines and calls).
#[derive(Debug, Clone, Default)]
pub struct Scratch {
    am: Vec<C64>,
    inv_am: Vec<C64>,
    aml: Vec<C64>,
    alm: Vec<C64>,
    sm: Vec<C64>,
    rhs: Vec<C64>,
    full: Vec<C64>,
}

#[inline]
fn at3(s: C64, s2: C64, e: &[f64; 3]) -> C64 {
    s2 * e[0] + s * e[1] + C64::new(e[2], 0.0)
}

impl PosSystem<'_> {
    /// W = A(jω)⁻¹B (N × n_a, row-major) into `w`; an error if A is singular.
    pub fn solve(&self, omega: f64, sc: &mut Scratch, w: &mut [C64]) -> Result<()> {
        let s = C64::new(0.0, omega);
        if self.solve_w(s, sc, w) {
            Ok(())
        } else {
            Err(Error::Numerical(format!(
                "the linear model is singular at ω = {omega} rad/s (an undamped pole on the grid)"
            )))
        }
    }

    fn solve_w(&self, s: C64, sc: &mut Scratch, w: &mut [C64]) -> bool {
        let (n, na, nx) = (self.n, self.na, self.nx);
        let s2 = s * s;
        w.iter_mut().for_each(|x| *x = ZERO);
        let mut schur = self.diag_motor;
        sc.am.clear();
        if schur {
            for e in &self.mm {
                let a = at3(s, s2, e);
                let scale = (s2 * e[0]).norm() + (s * e[1]).norm() + e[2].abs();
                sc.am.push(a);
                let ok = a.norm() > 1e-6 * scale; // false for NaN too
                if !ok {
                    schur = false;
                    break;
                }
            }
        }
        if !schur {
            let lin = self.lin;
            sc.full.clear();
            for i in 0..n {
                for j in 0..n {
                    sc.full.push(s2 * lin.m[(i, j)] + s * lin.d[(i, j)] + C64::new(lin.k[(i, j)], 0.0));
                }
            }
            for j in 0..na {
                w[j * na + j] = ONE;
            }
            return solve_in_place(&mut sc.full, n, w, na);
        }
        sc.inv_am.clear();
        sc.inv_am.extend(sc.am.iter().map(|a| ONE / a));
        sc.aml.clear();
        sc.aml.extend(self.aml.iter().map(|(_, e)| at3(s, s2, e)));
        sc.alm.clear();
        sc.alm.extend(self.alm.iter().map(|(_, e)| at3(s, s2, e)));
        sc.sm.clear();
        for r in 0..nx * nx {
            sc.sm.push(s2 * self.ml[r] + s * self.dl[r] + C64::new(self.kl[r], 0.0));
        }
        sc.rhs.clear();
        sc.rhs.resize(nx * na, ZERO);
        for r in 0..nx {
            for q in self.alm_start[r]..self.alm_start[r + 1] {
                let j = self.alm[q].0;
                let f = sc.alm[q] * sc.inv_am[j];
                sc.rhs[r * na + j] -= f;
                for t in self.aml_start[j]..self.aml_start[j + 1] {
                    let c = self.aml[t].0;
                    sc.sm[r * nx + c] -= f * sc.aml[t];
                }
            }
        }
        if !solve_in_place(&mut sc.sm, nx, &mut sc.rhs, na) {
            return false;
        }
        for j in 0..na {
            for i in 0..na {
                let mut acc = if i == j { ONE } else { ZERO };
                for t in self.aml_start[j]..self.aml_start[j + 1] {
                    acc -= sc.aml[t] * sc.rhs[self.aml[t].0 * na + i];
                }
                w[j * na + i] = acc * sc.inv_am[j];
            }
        }
        w[na * na..].copy_from_slice(&sc.rhs);
        true
    }
}

/// The W of every line of every position at the last parameter vector
/// evaluated, for reuse by the next evaluation at the same θ (bit for bit).
#[derive(Debug, Clone, Default)]
pub struct SolveCache {
    /// θ of the stored solves (empty: nothing stored).
    pub(crate) theta: Vec<f64>,
    /// W per (position, line), `w_len` each; lines without weight are left unsolved.
    pub(crate) w: Vec<C64>,
    pub(crate) scratch: Scratch,
}
