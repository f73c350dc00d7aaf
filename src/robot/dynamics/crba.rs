//! The composite-rigid-body algorithm (CRBA): the joint-space mass matrix,
//! with the link inertials kept in their ten parameters.

use super::rnea::Inertials;
use super::Workspace;
use crate::robot::kinematics::{joint_transform, joint_transforms, Real};
use crate::robot::model::{Inertial, Robot};
use nalgebra::{DMatrix, Matrix3, Vector3};

/// A symmetric 3×3 matrix as its upper triangle [xx, xy, xz, yy, yz, zz].
pub(super) type Sym3 = [f64; 6];

/// s·x for a [`Sym3`] s.
#[inline(always)]
pub(super) fn sym_mul(s: &Sym3, x: &Vector3<f64>) -> Vector3<f64> {
    Vector3::new(
        s[0] * x.x + s[1] * x.y + s[2] * x.z,
        s[1] * x.x + s[3] * x.y + s[4] * x.z,
        s[2] * x.x + s[4] * x.y + s[5] * x.z,
    )
}

/// The ten inertial parameters of a body about a frame's origin, in that
/// frame's coordinates: mass m, first moment h = m·c, rotational inertia I
/// about the origin.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Ten {
    pub(super) m: f64,
    pub(super) h: Vector3<f64>,
    pub(super) i: Sym3,
}

impl Ten {
    #[inline(always)]
    pub(super) fn of(ine: &Inertial) -> Self {
        let i = &ine.inertia;
        Ten {
            m: ine.mass,
            h: ine.first_moment,
            i: [i[(0, 0)], i[(0, 1)], i[(0, 2)], i[(1, 1)], i[(1, 2)], i[(2, 2)]],
        }
    }

    #[inline(always)]
    pub(super) fn add(&mut self, o: &Ten) {
        self.m += o.m;
        self.h += o.h;
        for k in 0..6 {
            self.i[k] += o.i[k];
        }
    }

    /// The same body's parameters about the origin of a frame A, in A's
    /// coordinates, given the orientation `r` and position `p` of this
    /// frame in A: h' = R h + m p and, with u = R h and g = u + (m/2) p,
    /// I' = R I Rᵀ − [p]×[u]× − [u]×[p]× − m [p]×² = R I Rᵀ + 2 (p·g) 1 − g pᵀ − p gᵀ
    /// (parallel axes).
    #[inline(always)]
    pub(super) fn in_frame(&self, r: &Matrix3<f64>, p: &Vector3<f64>) -> Ten {
        // rows r_x of R; row x of A = R I is (I r_x)ᵀ (I symmetric); then
        // (R I Rᵀ)_xy = (I r_x) · r_y, upper triangle only
        let rows = [
            Vector3::new(r[(0, 0)], r[(0, 1)], r[(0, 2)]),
            Vector3::new(r[(1, 0)], r[(1, 1)], r[(1, 2)]),
            Vector3::new(r[(2, 0)], r[(2, 1)], r[(2, 2)]),
        ];
        let a = [sym_mul(&self.i, &rows[0]), sym_mul(&self.i, &rows[1]), sym_mul(&self.i, &rows[2])];
        let rir = |x: usize, y: usize| a[x].dot(&rows[y]);
        let ri = [rir(0, 0), rir(0, 1), rir(0, 2), rir(1, 1), rir(1, 2), rir(2, 2)];
        self.shifted(&ri, &(r * self.h), p)
    }

    /// [`Ten::in_frame`] for a joint rotation R = Rx(α) Rz(θ) of
    /// [`Placed::RxZ`]: I and h turned about z (c = cos θ, s = sin θ), then
    /// the exact quarter or half turn about x, a permutation with signs.
    #[inline(always)]
    pub(super) fn in_frame_rxz(&self, alpha: i8, (c, s): (f64, f64), p: &Vector3<f64>) -> Ten {
        let [xx, xy, xz, yy, yz, zz] = self.i;
        // Rz I Rzᵀ
        let (cc, ss, cs) = (c * c, s * s, c * s);
        let cs2 = 2.0 * cs * xy;
        let z = [
            cc * xx - cs2 + ss * yy,
            cs * (xx - yy) + (cc - ss) * xy,
            c * xz - s * yz,
            ss * xx + cs2 + cc * yy,
            s * xz + c * yz,
            zz,
        ];
        let u = Vector3::new(c * self.h.x - s * self.h.y, s * self.h.x + c * self.h.y, self.h.z);
        let (ri, u) = match alpha {
            0 => (z, u),
            // (x, y, z) → (x, −z, y)
            1 => ([z[0], -z[2], z[1], z[5], -z[4], z[3]], Vector3::new(u.x, -u.z, u.y)),
            // (x, y, z) → (x, z, −y)
            -1 => ([z[0], z[2], -z[1], z[5], -z[4], z[3]], Vector3::new(u.x, u.z, -u.y)),
            // (x, y, z) → (x, −y, −z)
            _ => ([z[0], -z[1], -z[2], z[3], z[4], z[5]], Vector3::new(u.x, -u.y, -u.z)),
        };
        self.shifted(&ri, &u, p)
    }

    /// The parallel-axis part of [`Ten::in_frame`], given the turned
    /// inertia `ri` = R I Rᵀ and first moment `u` = R h: h' = u + m p and,
    /// with g = u + (m/2) p, I' = R I Rᵀ + 2 (p·g) 1 − g pᵀ − p gᵀ.
    #[inline(always)]
    pub(super) fn shifted(&self, ri: &Sym3, u: &Vector3<f64>, p: &Vector3<f64>) -> Ten {
        let g = u + p * (0.5 * self.m);
        let d = 2.0 * p.dot(&g);
        Ten {
            m: self.m,
            h: u + p * self.m,
            i: [
                ri[0] + d - 2.0 * g.x * p.x,
                ri[1] - (g.x * p.y + p.x * g.y),
                ri[2] - (g.x * p.z + p.x * g.z),
                ri[3] + d - 2.0 * g.y * p.y,
                ri[4] - (g.y * p.z + p.y * g.z),
                ri[5] + d - 2.0 * g.z * p.z,
            ],
        }
    }

    /// The spatial force (moment about the origin n, force f) of the motion
    /// (angular a, linear l at the origin) on this body: n = I a + h × l,
    /// f = m l + a × h.
    #[inline(always)]
    pub(super) fn times(&self, a: &Vector3<f64>, l: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
        (sym_mul(&self.i, a) + self.h.cross(l), l * self.m + a.cross(&self.h))
    }
}

/// A joint's rotation R(q) in its parent, for the CRBA's transforms. A
/// revolute joint about +e_z, without post-rotation, whose placement
/// rotation is Rx(α) with α ∈ {0, π/2, −π/2, π} to 1e-15 (the modified-DH
/// placements of most arms) has R = Rx(α) Rz(θ): a turn about z, then a
/// permutation with signs (`RxZ`, α coded 0, 1, −1, 2; cos θ and sin θ
/// read back from the joint transform). Any other joint is `General`.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Placed {
    RxZ(i8),
    General,
}

impl Placed {
    pub(super) fn of(robot: &Robot, i: usize) -> Self {
        let g = &robot.geo[i];
        if robot.joints[i].kind != crate::robot::model::JointKind::Revolute || g.coord != Some((2, 1.0)) || !g.post_identity {
            return Placed::General;
        }
        let rx = |c: f64, s: f64| Matrix3::new(1.0, 0.0, 0.0, 0.0, c, -s, 0.0, s, c);
        [(0, rx(1.0, 0.0)), (1, rx(0.0, 1.0)), (-1, rx(0.0, -1.0)), (2, rx(-1.0, 0.0))]
            .into_iter()
            .find(|(_, m)| (m - g.pl_r).amax() <= 1e-15)
            .map_or(Placed::General, |(a, _)| Placed::RxZ(a))
    }

    /// (cos θ, sin θ) of R = Rx(α) Rz(θ) from its first column `r0`:
    /// c = R₀₀, and s = R₁₀, R₂₀, −R₂₀, −R₁₀ for α = 0, π/2, −π/2, π.
    #[inline(always)]
    pub(super) fn cs(alpha: i8, r0: &Vector3<f64>) -> (f64, f64) {
        let s = match alpha {
            0 => r0.y,
            1 => r0.z,
            -1 => -r0.z,
            _ => -r0.y,
        };
        (r0.x, s)
    }

    /// R v, from `r` (General) or from (c, s) = (cos θ, sin θ) (RxZ).
    #[inline(always)]
    pub(super) fn apply(self, r: &Matrix3<f64>, (c, s): (f64, f64), v: &Vector3<f64>) -> Vector3<f64> {
        match self {
            Placed::General => r * v,
            Placed::RxZ(alpha) => {
                let (x, y, z) = (c * v.x - s * v.y, s * v.x + c * v.y, v.z);
                match alpha {
                    0 => Vector3::new(x, y, z),
                    1 => Vector3::new(x, -z, y),
                    -1 => Vector3::new(x, z, -y),
                    _ => Vector3::new(x, -y, -z),
                }
            }
        }
    }
}

/// What the CRBA with the [`Placed::RxZ`] shortcut reads of joint i's
/// transform: nothing for a root (its column ends at itself); the whole
/// rotation for a child of a root (the root's entry reads rows of it) and
/// for a [`Placed::General`] joint; otherwise only cos θ and sin θ (the turn
/// about z; the position is the constant placement of a revolute joint).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Need {
    Nothing,
    Full,
    Turn,
}

impl Need {
    pub(super) fn of(robot: &Robot, placed: &[Placed], i: usize) -> Self {
        match (robot.joints[i].parent, placed[i]) {
            (None, _) => Need::Nothing,
            (Some(par), Placed::RxZ(_)) if robot.joints[par].parent.is_some() => Need::Turn,
            _ => Need::Full,
        }
    }
}

/// A joint's motion subspace S = (angular a, linear l), in link
/// coordinates, for the kernels that specialise to it: a revolute joint
/// about a coordinate axis (a = e_k exactly, l = 0), or any other.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Axis {
    /// Revolute about e_k (k = 0, 1, 2) through the link origin.
    Coord(usize),
    /// Any other (a, l).
    General(Vector3<f64>, Vector3<f64>),
}

impl Axis {
    pub(super) fn of(robot: &Robot, i: usize) -> Self {
        let (a, l) = (robot.s_ang[i], robot.s_lin[i]);
        if l == Vector3::zeros() {
            for k in 0..3 {
                if (0..3).all(|c| a[c] == if c == k { 1.0 } else { 0.0 }) {
                    return Axis::Coord(k);
                }
            }
        }
        Axis::General(a, l)
    }

    /// Sᵀ (n, f).
    #[inline(always)]
    pub(super) fn dot(&self, n: &Vector3<f64>, f: &Vector3<f64>) -> f64 {
        // literal components: a runtime index would send the vector
        // through memory (a store-forwarding stall on every call)
        match self {
            Axis::Coord(0) => n.x,
            Axis::Coord(1) => n.y,
            Axis::Coord(_) => n.z,
            Axis::General(a, l) => a.dot(n) + l.dot(f),
        }
    }

    /// The force (n, f) = I S of the motion S on the body `t`.
    #[inline(always)]
    pub(super) fn force(&self, t: &Ten) -> (Vector3<f64>, Vector3<f64>) {
        match self {
            // the k-th column of I and e_k × h, written out per k
            Axis::Coord(0) => (Vector3::new(t.i[0], t.i[1], t.i[2]), Vector3::new(0.0, -t.h.z, t.h.y)),
            Axis::Coord(1) => (Vector3::new(t.i[1], t.i[3], t.i[4]), Vector3::new(t.h.z, 0.0, -t.h.x)),
            Axis::Coord(_) => (Vector3::new(t.i[2], t.i[4], t.i[5]), Vector3::new(-t.h.y, t.h.x, 0.0)),
            Axis::General(a, l) => t.times(a, l),
        }
    }
}

/// Composite rigid-body algorithm into `m` (n×n, overwritten): M_rb(q) for
/// the inertials `inert` plus Cᵀ diag(Ia) C for the rotor inertias `ia(j)`.
/// Allocation-free (buffers in `ws`).
///
/// The composite inertias are kept in their ten parameters ([`Ten`]: mass,
/// first moment, rotational inertia about the link origin, link
/// coordinates), carried from each link to its parent with the rotation and
/// parallel-axis transform of [`Ten::in_frame`] (leaves first). Column i:
/// the force F = I^c_i S_i ([`Axis::force`]; for a revolute joint about e_k
/// the k-th column of I and e_k × h), M_ii = S_iᵀ F, then F carried up the
/// path to the root (n ← R n + p × R f, f ← R f) and projected on each
/// ancestor's S_j (the k-th moment component for a joint about e_k; at the
/// root only that component is computed). A root joint about e_k reads only
/// the (k, k) entry of its composite, so only that entry is accumulated.
/// Column i holds the upper triangle M_ji (j ≤ i), mirrored at the end.
/// Rotations R = Rx(α) Rz(θ) ([`Placed::RxZ`], most arms' modified-DH
/// placements) are applied as a turn about z and a signed permutation when
/// most joints have one; on a serial chain the path is walked by index.
pub(super) fn crba_into(robot: &Robot, ws: &mut Workspace, inert: Inertials<'_>, ia: impl Fn(usize) -> Option<f64>, q: &[f64], m: &mut DMatrix<f64>) {
    // the per-joint dispatch on [`Placed`] pays only when most joints take
    // the Rx(α) Rz(θ) shortcut; otherwise every transform is general
    match (robot.topology.rxz_crba, robot.topology.chain) {
        (true, true) => crba_placed::<true, true>(robot, ws, inert, ia, q, m),
        (true, false) => crba_placed::<true, false>(robot, ws, inert, ia, q, m),
        (false, true) => crba_placed::<false, true>(robot, ws, inert, ia, q, m),
        (false, false) => crba_placed::<false, false>(robot, ws, inert, ia, q, m),
    }
}

/// [`crba_into`], with ([`Placed`]) or without (`RXZ` false) the joint
/// rotations' shortcut, for a serial chain (`CHAIN`: joint i's parent is
/// i − 1) or any tree.
fn crba_placed<const RXZ: bool, const CHAIN: bool>(
    robot: &Robot,
    ws: &mut Workspace,
    inert: Inertials<'_>,
    ia: impl Fn(usize) -> Option<f64>,
    q: &[f64],
    m: &mut DMatrix<f64>,
) {
    let n = robot.dof();
    assert!(m.nrows() == n && m.ncols() == n, "mass matrix output must be n×n");
    assert!(q.len() == n && robot.topology.need.len() == n, "workspace made for another robot");
    if RXZ {
        // only what the passes below read ([`Need`]): a turn's (cos θ, sin θ)
        // are the bits `joint_transform` would have put in R₀₀ and R₁₀/R₂₀
        for i in 0..n {
            match (robot.topology.need[i], robot.topology.placed[i]) {
                (Need::Nothing, _) => {}
                (Need::Turn, Placed::RxZ(alpha)) => {
                    let (s, c) = (q[i] + robot.joints[i].offset).sincos();
                    // R's first column is P e_x c + P e_y s (`joint_transform`
                    // about +e_z): the same products, signed zeros included
                    let pl = &robot.geo[i].pl_r;
                    let r0 = |x: usize| pl[(x, 0)] * c + pl[(x, 1)] * s;
                    ws.cs[i] = Placed::cs(alpha, &Vector3::new(r0(0), r0(1), r0(2)));
                    ws.kin.pos[i] = robot.geo[i].pl_p;
                }
                (_, placed) => {
                    let (r, p) = joint_transform(robot, i, q[i]);
                    if let Placed::RxZ(alpha) = placed {
                        ws.cs[i] = Placed::cs(alpha, &r.column(0).into_owned());
                    }
                    ws.kin.rot[i] = r;
                    ws.kin.pos[i] = p;
                }
            }
        }
    } else {
        joint_transforms(robot, q, &mut ws.kin);
    }
    for i in 0..n {
        let ine = match inert {
            Inertials::Nominal => &robot.links[i].inertial,
            Inertials::Of(v) => &v[i],
        };
        ws.crb[i] = Ten::of(ine);
    }
    let kin = &ws.kin;
    let axes = &robot.topology.axes;
    assert_eq!(axes.len(), n, "workspace made for another robot");
    // The composite of link i's chain child (parent i) is handed over in
    // `carry`, not through ws.crb: reading back a Ten just written field by
    // field stalls on store forwarding. Other children (branches) add into
    // ws.crb[par] as before.
    let mut carry: Option<Ten> = None;
    for i in (0..n).rev() {
        let mut t = ws.crb[i];
        if let Some(c) = carry.take() {
            t.add(&c);
            ws.crb[i] = t;
        }
        if let Some(par) = robot.joints[i].parent {
            let (r, p) = (&kin.rot[i], &kin.pos[i]);
            match (robot.joints[par].parent, axes[par]) {
                // a root joint about e_k reads only I^c_kk of its composite
                // (M_par,par; its column's force n = I^c e_k is read only at k):
                // (R I Rᵀ)_kk + 2 p·g − 2 g_k p_k, g = R h + (m/2) p
                (None, Axis::Coord(k)) => {
                    let rk = Vector3::new(r[(k, 0)], r[(k, 1)], r[(k, 2)]);
                    let g = r * t.h + p * (0.5 * t.m);
                    let v = rk.dot(&sym_mul(&t.i, &rk)) + 2.0 * p.dot(&g) - 2.0 * g[k] * p[k];
                    ws.crb[par].i[[0, 3, 5][k]] += v;
                }
                _ => {
                    let c = match if RXZ { robot.topology.placed[i] } else { Placed::General } {
                        Placed::RxZ(alpha) => t.in_frame_rxz(alpha, ws.cs[i], p),
                        Placed::General => t.in_frame(r, p),
                    };
                    if par + 1 == i {
                        carry = Some(c);
                    } else {
                        ws.crb[par].add(&c);
                    }
                }
            }
        }
    }
    let ms = m.as_mut_slice(); // column-major: ms[col * n + row]
    ms.fill(0.0);
    let (crb, rot, pos, placed, cs) = (&ws.crb[..n], &kin.rot[..n], &kin.pos[..n], &robot.topology.placed[..n], &ws.cs[..n]);
    // column i's force carried up its path; the upper triangle M[j, i]
    // (j ≤ i) goes into column i, mirrored below at the end. On a chain the
    // path is i, i − 1, …, 0 (indices the compiler can bound).
    for i in 0..n {
        let col = &mut ms[i * n..(i + 1) * n];
        let (mut nn, mut ff) = axes[i].force(&crb[i]);
        col[i] = axes[i].dot(&nn, &ff);
        let mut j = i;
        loop {
            let par = if CHAIN {
                if j == 0 {
                    break;
                }
                j - 1
            } else {
                match robot.joints[j].parent {
                    Some(p) => p,
                    None => break,
                }
            };
            let root = if CHAIN { par == 0 } else { robot.joints[par].parent.is_none() };
            let (r, p) = (&rot[j], &pos[j]);
            let (turn, cj) = if RXZ { (placed[j], cs[j]) } else { (Placed::General, (1.0, 0.0)) };
            let rf = turn.apply(r, cj, &ff);
            if let (true, Axis::Coord(k)) = (root, axes[par]) {
                // only the k-th moment component: (R n)_k + (p × R f)_k
                let (k1, k2) = ((k + 1) % 3, (k + 2) % 3);
                let rn = r[(k, 0)] * nn.x + r[(k, 1)] * nn.y + r[(k, 2)] * nn.z;
                col[par] = rn + (p[k1] * rf[k2] - p[k2] * rf[k1]);
                break;
            }
            nn = turn.apply(r, cj, &nn) + p.cross(&rf);
            ff = rf;
            col[par] = axes[par].dot(&nn, &ff);
            j = par;
        }
    }
    for i in 0..n {
        for j in 0..i {
            ms[j * n + i] = ms[i * n + j];
        }
    }
    // rotor inertias: Cᵀ diag(Ia) C
    if robot.coupling.is_none() {
        for j in 0..n {
            if let Some(v) = ia(j) {
                m[(j, j)] += v;
            }
        }
    } else {
        for &(j, a, ca) in &robot.c_sparse {
            if let Some(v) = ia(j) {
                for &(jj, b, cb) in &robot.c_sparse {
                    if jj == j {
                        m[(a, b)] += ca * v * cb;
                    }
                }
            }
        }
    }
}

/// Link-side mass matrix for parameters `theta` into `out` (n×n):
/// M_rb(q) + Cᵀ diag(Ia) C. Allocation-free.
pub fn mass_matrix_with_into(robot: &Robot, ws: &mut Workspace, theta: &[f64], q: &[f64], out: &mut DMatrix<f64>) {
    let n = robot.dof();
    assert_eq!(theta.len(), robot.n_params(), "parameter vector length");
    assert_eq!(q.len(), n, "q length");
    let mut inert = std::mem::take(&mut ws.theta_inertials);
    for (i, slot) in inert.iter_mut().enumerate().take(n) {
        let o = robot.link_param_offset(i);
        *slot = Inertial::from_params(&theta[o..o + 10]);
    }
    let ia = |j: usize| robot.drives[j].rotor_inertia.map(|_| theta[robot.drive_param_offset(j)]);
    crba_into(robot, ws, Inertials::Of(&inert), ia, q, out);
    ws.theta_inertials = inert;
}

/// Link-side mass matrix with the nominal parameters into `out` (n×n).
/// Allocation-free.
pub fn mass_matrix_into(robot: &Robot, ws: &mut Workspace, q: &[f64], out: &mut DMatrix<f64>) {
    assert_eq!(q.len(), robot.dof(), "q length");
    crba_into(robot, ws, Inertials::Nominal, |j| robot.drives[j].rotor_inertia, q, out);
}

/// Link-side mass matrix for parameters `theta`: M_rb(q) + Cᵀ diag(Ia) C
/// (n×n, symmetric, positive definite for physical parameters). Composite
/// rigid-body algorithm ([`mass_matrix_with_into`] without the output buffer).
pub fn mass_matrix_with(robot: &Robot, ws: &mut Workspace, theta: &[f64], q: &[f64]) -> DMatrix<f64> {
    let n = robot.dof();
    let mut m = DMatrix::zeros(n, n);
    mass_matrix_with_into(robot, ws, theta, q, &mut m);
    m
}

/// Link-side mass matrix with the nominal parameters.
pub fn mass_matrix(robot: &Robot, ws: &mut Workspace, q: &[f64]) -> DMatrix<f64> {
    let n = robot.dof();
    let mut m = DMatrix::zeros(n, n);
    mass_matrix_into(robot, ws, q, &mut m);
    m
}

/// ∂τ/∂q̈ of the motor-side torque: C⁻ᵀ M_rb + diag(Ia) C (n×n; equals the
/// mass matrix when there is no coupling).
pub fn motor_inertia(robot: &Robot, ws: &mut Workspace, theta: &[f64], q: &[f64]) -> DMatrix<f64> {
    match &robot.coupling_inv_t {
        None => mass_matrix_with(robot, ws, theta, q),
        // M_total = M_rb + Cᵀ D C  ⇒  C⁻ᵀ M_total = C⁻ᵀ M_rb + D C
        Some(ct) => ct * mass_matrix_with(robot, ws, theta, q),
    }
}
