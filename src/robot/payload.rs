//! A payload (tool, gripper, load) rigidly fixed to a frame of the robot.
//!
//! A payload is a rigid body: mass m, centre of mass c and inertia tensor I_c
//! about the centre of mass, both in the axes of its frame F (a named frame of
//! the robot file such as `tool0`, or a link). Its ten standard parameters
//! φ_F = (XX, XY, XZ, YY, YZ, ZZ, MX, MY, MZ, M) about F's origin in F's axes
//! enter the dynamics linearly through the parameters of the link L that F is
//! fixed to: φ_L = T φ_F with T (10 × 10) the fixed-frame change of
//! [`Inertial::transformed`] (rotation of the tensor, parallel-axis terms; it is
//! linear in φ_F), so the payload's regressor columns are Y_L T, where Y_L are
//! link L's ten columns of the robot's regressor.

use super::model::{Inertial, Robot};
use crate::error::{Error, Result};
use nalgebra::{Isometry3, Matrix3, SMatrix, Vector3};
use serde::{Deserialize, Serialize};

/// 10 × 10 matrices (the payload's frame change).
pub type Matrix10 = SMatrix<f64, 10, 10>;

/// A payload's inertial data (design key `[payload]`, simulation key `payload`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PayloadSpec {
    /// Frame the payload is fixed to (a robot frame or link; default: the end effector).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub frame: Option<String>,
    /// Mass m (kg).
    pub mass: f64,
    /// Centre of mass in the frame (m).
    #[serde(default)]
    pub com: [f64; 3],
    /// Inertia about the centre of mass in the frame's axes,
    /// [Ixx, Ixy, Ixz, Iyy, Iyz, Izz] (kg·m², tensor entries as in URDF).
    #[serde(default)]
    pub inertia: [f64; 6],
}

/// The physical description of a payload in its frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Payload {
    /// Mass (kg).
    pub mass: f64,
    /// Centre of mass in the frame (m).
    pub com: [f64; 3],
    /// Inertia about the centre of mass, [Ixx, Ixy, Ixz, Iyy, Iyz, Izz] (kg·m²).
    pub inertia: [f64; 6],
}

/// The frame a payload is fixed to, resolved on a robot.
#[derive(Debug, Clone)]
pub struct Mount {
    /// Frame name.
    pub frame: String,
    /// Index of the moving link the frame is fixed to.
    pub link: usize,
    /// Link frame → payload frame.
    pub placement: Isometry3<f64>,
    /// T: φ_L = T φ_F (see the module documentation).
    pub t: Matrix10,
}

/// Names of the ten standard parameters of a payload, in layout order.
pub const PARAM_NAMES: [&str; 10] = ["XX", "XY", "XZ", "YY", "YZ", "ZZ", "MX", "MY", "MZ", "M"];

fn sym(i: &[f64; 6]) -> Matrix3<f64> {
    Matrix3::new(i[0], i[1], i[2], i[1], i[3], i[4], i[2], i[4], i[5])
}

impl Payload {
    /// The payload of a spec, checked (mass ≥ 0, finite, inertia at the centre
    /// of mass positive semidefinite and satisfying the triangle inequalities).
    pub fn from_spec(s: &PayloadSpec, ctx: &str, field: &str) -> Result<Payload> {
        if !(s.mass.is_finite() && s.mass > 0.0) {
            return Err(Error::invalid(
                ctx,
                format!("{field}.mass"),
                format!("expected a positive mass (kg), found {}", s.mass),
            ));
        }
        if let Some(v) = s.com.iter().find(|v| !v.is_finite()) {
            return Err(Error::invalid(
                ctx,
                format!("{field}.com"),
                format!("expected finite coordinates (m), found {v}"),
            ));
        }
        super::validate::check_com_inertia(ctx, &format!("{field}.inertia"), s.mass, &sym(&s.inertia))?;
        Ok(Payload {
            mass: s.mass,
            com: s.com,
            inertia: s.inertia,
        })
    }

    /// φ_F: the ten standard parameters about the frame's origin, in its axes.
    pub fn params(&self) -> [f64; 10] {
        let c = Vector3::from(self.com);
        Inertial::from_com(self.mass, c, sym(&self.inertia), Matrix3::identity()).to_params()
    }

    /// The payload of standard parameters φ_F (mass > 0 required; the centre
    /// of mass is h/m and the inertia is moved to it by the parallel-axis theorem).
    pub fn from_params(p: &[f64]) -> Result<Payload> {
        if p.len() != 10 {
            return Err(Error::dim("payload parameters", 10, p.len()));
        }
        let m = p[9];
        if !(m.is_finite() && m > 0.0) {
            return Err(Error::Numerical(format!("the payload's mass is {m} kg: no centre of mass")));
        }
        let c = Vector3::new(p[6], p[7], p[8]) / m;
        let io = Matrix3::new(p[0], p[1], p[2], p[1], p[3], p[4], p[2], p[4], p[5]);
        let ic = io - m * (c.norm_squared() * Matrix3::identity() - c * c.transpose());
        Ok(Payload {
            mass: m,
            com: [c.x, c.y, c.z],
            inertia: [ic[(0, 0)], ic[(0, 1)], ic[(0, 2)], ic[(1, 1)], ic[(1, 2)], ic[(2, 2)]],
        })
    }

    /// The inertia tensor about the centre of mass (frame axes).
    pub fn inertia_matrix(&self) -> Matrix3<f64> {
        sym(&self.inertia)
    }
}

impl Mount {
    /// Resolves `frame` (default: the robot's end effector) on `robot`; the
    /// frame must be fixed to a moving link.
    pub fn new(robot: &Robot, frame: Option<&str>, ctx: &str, field: &str) -> Result<Mount> {
        let f = match frame {
            Some(name) => robot.find_frame(name).ok_or_else(|| {
                let mut all: Vec<&str> = robot.links.iter().map(|l| l.name.as_str()).collect();
                all.extend(robot.frames.iter().map(|f| f.name.as_str()));
                Error::invalid(
                    ctx,
                    field,
                    format!("no frame or link `{name}` in robot `{}`; known: {}", robot.name, all.join(", ")),
                )
            })?,
            None => robot.end_effector(),
        };
        let link = f.link.ok_or_else(|| {
            Error::invalid(
                ctx,
                field,
                format!(
                    "frame `{}` is fixed to the base of robot `{}`: a payload must be carried by a moving link",
                    f.name, robot.name
                ),
            )
        })?;
        let mut t = Matrix10::zeros();
        for k in 0..10 {
            let mut e = [0.0; 10];
            e[k] = 1.0;
            let col = Inertial::from_params(&e).transformed(&f.placement).to_params();
            for (r, v) in col.iter().enumerate() {
                t[(r, k)] = *v;
            }
        }
        Ok(Mount {
            frame: f.name,
            link,
            placement: f.placement,
            t,
        })
    }

    /// φ_L = T φ_F.
    pub fn to_link(&self, phi: &[f64; 10]) -> [f64; 10] {
        let v = self.t * SMatrix::<f64, 10, 1>::from_column_slice(phi);
        let mut out = [0.0; 10];
        out.copy_from_slice(v.as_slice());
        out
    }

    /// The robot carrying the payload of parameters φ_F: link L's parameters
    /// become φ_L + T φ_F (everything else unchanged).
    pub fn attach(&self, robot: &Robot, phi: &[f64; 10]) -> Result<Robot> {
        let mut theta = robot.nominal_params();
        let o = robot.link_param_offset(self.link);
        let add = self.to_link(phi);
        for k in 0..10 {
            theta[o + k] += add[k];
        }
        let mut r = robot.with_params(theta.as_slice())?;
        r.source = format!("{} + payload on {}", robot.source, self.frame);
        Ok(r)
    }

    /// The payload's columns of a row-major n × p regressor `y` (p = the
    /// robot's parameter count): Y_L T, into row-major n × 10 `out`.
    pub fn columns(&self, robot: &Robot, y: &[f64], out: &mut [f64]) {
        let p = robot.n_params();
        let n = y.len() / p;
        let o = robot.link_param_offset(self.link);
        for r in 0..n {
            let row = &y[r * p + o..r * p + o + 10];
            for k in 0..10 {
                let mut s = 0.0;
                for (i, v) in row.iter().enumerate() {
                    s += v * self.t[(i, k)];
                }
                out[r * 10 + k] = s;
            }
        }
    }
}

/// Resolves and checks a payload spec on a robot: the mount and the payload.
pub fn resolve(robot: &Robot, spec: &PayloadSpec, ctx: &str, field: &str) -> Result<(Mount, Payload)> {
    let p = Payload::from_spec(spec, ctx, field)?;
    let m = Mount::new(robot, spec.frame.as_deref(), ctx, &format!("{field}.frame"))?;
    Ok((m, p))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix6, Translation3, UnitQuaternion};
    use rand::{RngExt, SeedableRng};

    /// The 6 × 6 spatial inertia (angular first) about a frame's origin in its
    /// axes: [[I_O, S(h)], [S(h)ᵀ, m 1]] (Featherstone, RBDA eq. 2.63).
    fn spatial(p: &[f64; 10]) -> Matrix6<f64> {
        let i = Inertial::from_params(p);
        let sh = i.first_moment.cross_matrix();
        let mut s = Matrix6::zeros();
        s.fixed_view_mut::<3, 3>(0, 0).copy_from(&i.inertia);
        s.fixed_view_mut::<3, 3>(0, 3).copy_from(&sh);
        s.fixed_view_mut::<3, 3>(3, 0).copy_from(&sh.transpose());
        s.fixed_view_mut::<3, 3>(3, 3).copy_from(&(i.mass * Matrix3::identity()));
        s
    }

    /// The same inertia in frame A: I_A = X_{B←A}ᵀ I_B X_{B←A}, with the
    /// motion transform X_{B←A} = [[Rᵀ, 0], [−Rᵀ S(p), Rᵀ]] of a_t_b = (R, p):
    /// kinetic energy is frame-independent. Built from the 6 × 6 blocks, not
    /// from `Inertial::transformed`'s parallel-axis formula.
    fn spatial_in_a(p: &[f64; 10], a_t_b: &Isometry3<f64>) -> [f64; 10] {
        let r = a_t_b.rotation.to_rotation_matrix().into_inner();
        let t = a_t_b.translation.vector;
        let mut x = Matrix6::zeros();
        x.fixed_view_mut::<3, 3>(0, 0).copy_from(&r.transpose());
        x.fixed_view_mut::<3, 3>(3, 0).copy_from(&(-r.transpose() * t.cross_matrix()));
        x.fixed_view_mut::<3, 3>(3, 3).copy_from(&r.transpose());
        let s = x.transpose() * spatial(p) * x;
        let h = Vector3::new(s[(2, 4)], s[(0, 5)], s[(1, 3)]);
        [s[(0, 0)], s[(0, 1)], s[(0, 2)], s[(1, 1)], s[(1, 2)], s[(2, 2)], h.x, h.y, h.z, s[(3, 3)]]
    }

    fn random_iso(g: &mut rand_chacha::ChaCha8Rng) -> Isometry3<f64> {
        let q = nalgebra::Quaternion::new(
            g.random::<f64>() - 0.5,
            g.random::<f64>() - 0.5,
            g.random::<f64>() - 0.5,
            g.random::<f64>() - 0.5,
        );
        let t = Translation3::new(g.random::<f64>() - 0.5, g.random::<f64>() - 0.5, g.random::<f64>() - 0.5);
        Isometry3::from_parts(t, UnitQuaternion::from_quaternion(q))
    }

    #[test]
    fn transformed_is_the_spatial_inertia_transform_also_for_unit_vectors() {
        let mut g = rand_chacha::ChaCha8Rng::seed_from_u64(43);
        // UR tool0 against wrist_3_link (rpy −π/2 0 0, 82.3 mm along y), then random frames
        let mut isos = vec![Isometry3::from_parts(
            Translation3::new(0.0, 0.0823, 0.0),
            UnitQuaternion::from_euler_angles(-std::f64::consts::FRAC_PI_2, 0.0, 0.0),
        )];
        isos.extend((0..20).map(|_| random_iso(&mut g)));
        let body = Payload {
            mass: 2.0,
            com: [0.03, 0.02, 0.1],
            inertia: [0.012, 0.001, -0.0005, 0.010, 0.0007, 0.006],
        }
        .params();
        for iso in &isos {
            let mut inputs: Vec<[f64; 10]> = (0..10)
                .map(|k| {
                    let mut e = [0.0; 10];
                    e[k] = 1.0;
                    e
                })
                .collect();
            inputs.push(body);
            // zero mass, zero inertia, a first moment only (the shortcut's case)
            inputs.push([0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.3, -0.2, 0.5, 0.0]);
            for e in &inputs {
                let got = Inertial::from_params(e).transformed(iso).to_params();
                let want = spatial_in_a(e, iso);
                for k in 0..10 {
                    assert!(
                        (got[k] - want[k]).abs() < 1e-12,
                        "input {e:?}, parameter {}: {} vs {}",
                        PARAM_NAMES[k],
                        got[k],
                        want[k]
                    );
                }
            }
        }
    }

    #[test]
    fn mount_matrix_is_linear_map_of_transformed() {
        // T φ = transformed(φ) for a full rigid body, on a rotated and offset frame
        let mut g = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let iso = random_iso(&mut g);
        let mut t = Matrix10::zeros();
        for k in 0..10 {
            let mut e = [0.0; 10];
            e[k] = 1.0;
            let col = spatial_in_a(&e, &iso);
            for (r, v) in col.iter().enumerate() {
                t[(r, k)] = *v;
            }
        }
        let phi = Payload {
            mass: 1.3,
            com: [-0.01, 0.04, 0.07],
            inertia: [0.01, 0.0, 0.001, 0.012, -0.002, 0.008],
        }
        .params();
        let lin = t * SMatrix::<f64, 10, 1>::from_column_slice(&phi);
        let direct = Inertial::from_params(&phi).transformed(&iso).to_params();
        for k in 0..10 {
            assert!((lin[k] - direct[k]).abs() < 1e-12);
        }
    }

    #[test]
    fn params_round_trip() {
        let p = Payload {
            mass: 2.5,
            com: [0.01, -0.02, 0.08],
            inertia: [0.012, 0.001, -0.0005, 0.010, 0.0007, 0.006],
        };
        let q = Payload::from_params(&p.params()).unwrap();
        assert!((q.mass - p.mass).abs() < 1e-15);
        for k in 0..3 {
            assert!((q.com[k] - p.com[k]).abs() < 1e-15);
        }
        for k in 0..6 {
            assert!((q.inertia[k] - p.inertia[k]).abs() < 1e-15);
        }
    }
}
