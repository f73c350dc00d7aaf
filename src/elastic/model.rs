//! The elastic gray-box model: a rigid robot whose actuated joints are driven
//! through elastic gearboxes, plus extra non-actuated torsional spring–damper
//! degrees of freedom inside the chain (paper 001 §3), with a parameter list
//! of which some entries are unknown.
//!
//! # Coordinates
//!
//! * `q_m` (n_a): motor positions referred to the joint side (motor angle
//!   divided by the gear ratio), one per actuated joint;
//! * `q` (n_a + n_e): link coordinates of the *extended* rigid robot, whose
//!   joints are the n_a actuated joints and the n_e elastic joints inserted
//!   after their host joints.
//!
//! # Equations of motion
//!
//! With δ = q_m − C q_a the gearbox deflections (C the coupling matrix of the
//! rigid robot, q_a the actuated link coordinates), K_g, D_g the gearbox
//! springs and dampers, K_e, D_e those of the elastic joints, Ia the reflected
//! rotor inertias and f the drive friction:
//!
//! Ia ⊙ q̈_m + K_g δ + D_g δ̇ + f(q̇_m) = τ_m,
//!
//! M(q) q̈ + c(q, q̇) + g(q) = S_aᵀ Cᵀ (K_g δ + D_g δ̇) − S_eᵀ (K_e q_e + D_e q̇_e),
//!
//! M, c, g the rigid-body terms of the extended robot (no rotor inertia: the
//! rotors are the motor coordinates), S_a / S_e the selections of the actuated
//! and elastic coordinates.

use crate::error::{Error, Result};
use crate::robot::{self, Drive, Frame, Friction, Inertial, Joint, JointKind, JointLimits, Link, ParamKind, Robot, RobotParts};
use nalgebra::{DMatrix, Isometry3, Matrix3, Unit, Vector3};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// `[model]` section of a design file: which rigid robot, its gearboxes,
/// extra elastic joints, an optional payload, and which parameters are unknown.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ElasticSpec {
    /// Rigid robot file (URDF or TOML), relative to the design file.
    pub robot: String,
    /// Optional payload added to a link's inertia (rated load).
    #[serde(default)]
    pub payload: Option<PayloadSpec>,
    /// One gearbox spring–damper per actuated joint.
    #[serde(default)]
    pub gearbox: Vec<GearboxSpec>,
    /// Extra non-actuated torsional spring–damper joints.
    #[serde(default)]
    pub elastic: Vec<ElasticJointSpec>,
    /// Names of the unknown parameters, or the groups `springs`, `dampers`,
    /// `gear_springs`, `gear_dampers`, `arm_springs`, `arm_dampers`.
    #[serde(default)]
    pub unknowns: Vec<String>,
    /// Nominal value overrides (θ_init), by parameter name.
    #[serde(default)]
    pub nominal: std::collections::BTreeMap<String, f64>,
}

/// A payload: point mass with inertia about its centre of mass, in link axes.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct PayloadSpec {
    /// Link the payload is attached to.
    pub link: String,
    /// Mass (kg).
    pub mass: f64,
    /// Centre of mass in link coordinates (m).
    #[serde(default)]
    pub com: [f64; 3],
    /// Inertia about the centre of mass, [Ixx, Ixy, Ixz, Iyy, Iyz, Izz] (kg·m²).
    #[serde(default)]
    pub inertia: [f64; 6],
}

/// Gearbox of one actuated joint (joint-side units).
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct GearboxSpec {
    /// Actuated joint name.
    pub joint: String,
    /// Spring constant k (N·m/rad, joint side).
    pub k: f64,
    /// Damper d (N·m·s/rad, joint side).
    pub d: f64,
    /// Reflected rotor inertia override (kg·m², joint side); default: the robot file's `ia`.
    #[serde(default)]
    pub ia: Option<f64>,
}

/// An extra elastic (non-actuated) torsional joint inserted after `after`.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ElasticJointSpec {
    /// Name (parameters are `k_<name>`, `d_<name>`).
    pub name: String,
    /// Host: an actuated joint name (the spring sits in that joint's link,
    /// between the joint and the link body) or `base` (elastic foundation).
    pub after: String,
    /// Rotation axis in the host link frame (normalised).
    pub axis: [f64; 3],
    /// Spring location in the host link frame (m).
    #[serde(default)]
    pub xyz: [f64; 3],
    /// Orientation of the spring frame (roll, pitch, yaw; rad).
    #[serde(default)]
    pub rpy: [f64; 3],
    /// Spring constant k (N·m/rad).
    pub k: f64,
    /// Damper d (N·m·s/rad).
    pub d: f64,
}

/// What a model parameter is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(tag = "kind", content = "index", rename_all = "snake_case")]
pub enum ParamRole {
    /// Gearbox spring of actuated joint j.
    GearSpring(usize),
    /// Gearbox damper of actuated joint j.
    GearDamper(usize),
    /// Spring of elastic joint e.
    ArmSpring(usize),
    /// Damper of elastic joint e.
    ArmDamper(usize),
    /// Reflected rotor inertia of motor j.
    RotorInertia(usize),
    /// Viscous friction of motor j.
    MotorViscous(usize),
    /// Standard inertial parameter at this index of the extended robot's layout.
    Link(usize),
}

/// One physical parameter of the elastic model.
#[derive(Debug, Clone, Serialize)]
pub struct ModelParam {
    /// Name: `k_<joint>`, `d_<joint>`, `k_<elastic>`, `d_<elastic>`, `Ia<j>`, `Fv<j>`, or a rigid name such as `M6`.
    pub name: String,
    /// Role in the equations.
    pub role: ParamRole,
    /// Nominal value (θ_init for unknowns).
    pub nominal: f64,
    /// Positive by nature (fitted in log space when unknown).
    pub positive: bool,
}

/// The elastic gray-box model (immutable).
#[derive(Debug, Clone)]
pub struct ElasticModel {
    /// The rigid robot (payload included).
    pub rigid: Robot,
    /// The extended rigid robot: actuated + elastic joints, no drives.
    pub ext: Robot,
    /// Extended index of each actuated joint.
    pub act_index: Vec<usize>,
    /// Extended index of each elastic joint.
    pub elastic_index: Vec<usize>,
    /// Elastic joint names.
    pub elastic_names: Vec<String>,
    /// Coupling matrix C (n_a × n_a; identity without coupling).
    pub coupling: DMatrix<f64>,
    /// Every physical parameter (known and unknown).
    pub params: Vec<ModelParam>,
    /// Indices into `params` of the unknowns, in the order of θ.
    pub unknowns: Vec<usize>,
    /// Where the model came from.
    pub source: String,
}

fn finite_pos(ctx: &str, field: &str, v: f64, allow_zero: bool) -> Result<f64> {
    if !v.is_finite() || v < 0.0 || (!allow_zero && v == 0.0) {
        let what = if allow_zero { "non-negative" } else { "positive" };
        return Err(Error::invalid(ctx, field, format!("expected a {what} finite number, found {v}")));
    }
    Ok(v)
}

fn rpy_iso(xyz: [f64; 3], rpy: [f64; 3]) -> Isometry3<f64> {
    let r = nalgebra::UnitQuaternion::from_euler_angles(rpy[0], rpy[1], rpy[2]);
    Isometry3::from_parts(nalgebra::Translation3::new(xyz[0], xyz[1], xyz[2]), r)
}

/// Adds the payload's inertial (if any) to its link of the rigid robot.
fn add_payload(rigid: &mut Robot, payload: Option<&PayloadSpec>, rpath: &Path, ctxm: &str) -> Result<()> {
    if let Some(p) = payload {
        let i = rigid
            .links
            .iter()
            .position(|l| l.name == p.link)
            .ok_or_else(|| Error::invalid(ctxm, "payload.link", format!("no link `{}` in {}", p.link, rpath.display())))?;
        finite_pos(ctxm, "payload.mass", p.mass, true)?;
        let c = p.com;
        let ii = p.inertia;
        if c.iter().chain(ii.iter()).any(|v| !v.is_finite()) {
            return Err(Error::invalid(ctxm, "payload", "com and inertia must be finite"));
        }
        let ic = Matrix3::new(ii[0], ii[1], ii[2], ii[1], ii[3], ii[4], ii[2], ii[4], ii[5]);
        crate::robot::validate::check_com_inertia(ctxm, "payload.inertia", p.mass, &ic)?;
        let add = Inertial::from_com(p.mass, Vector3::new(c[0], c[1], c[2]), ic, Matrix3::identity());
        let sum = rigid.links[i].inertial.add(&add);
        if !(sum.mass.is_finite() && sum.first_moment.iter().chain(sum.inertia.iter()).all(|v| v.is_finite())) {
            return Err(Error::invalid(
                ctxm,
                "payload.com",
                format!("{c:?} m: the link's inertia about its origin with this payload overflows (expected a centre of mass within the robot's size)"),
            ));
        }
        rigid.links[i].inertial = sum;
    }
    Ok(())
}

/// The gearbox entry of every actuated joint (exactly one each), checked.
fn gearbox_per_joint<'a>(rigid: &Robot, spec: &'a ElasticSpec, names: &[String], ctxm: &str) -> Result<Vec<&'a GearboxSpec>> {
    let na = rigid.dof();
    let mut gear: Vec<Option<&GearboxSpec>> = vec![None; na];
    for (gi, g) in spec.gearbox.iter().enumerate() {
        let j = rigid
            .joints
            .iter()
            .position(|jj| jj.name == g.joint)
            .ok_or_else(|| Error::invalid(ctxm, format!("gearbox[{gi}].joint"), format!("no actuated joint `{}` in the robot", g.joint)))?;
        if gear[j].is_some() {
            return Err(Error::invalid(
                ctxm,
                format!("gearbox[{gi}].joint"),
                format!("joint `{}` has two gearbox entries", g.joint),
            ));
        }
        finite_pos(ctxm, &format!("gearbox[{gi}].k"), g.k, false)?;
        finite_pos(ctxm, &format!("gearbox[{gi}].d"), g.d, true)?;
        if let Some(ia) = g.ia {
            finite_pos(ctxm, &format!("gearbox[{gi}].ia"), ia, false)?;
        }
        gear[j] = Some(g);
    }
    gear.into_iter()
        .enumerate()
        .map(|(j, g)| g.ok_or_else(|| Error::invalid(ctxm, "gearbox", format!("missing a [[model.gearbox]] entry for joint `{}`", names[j]))))
        .collect::<Result<_>>()
}

/// Host of every elastic joint (None = the base, else the actuated joint it
/// follows), with the elastic joints' fields checked.
fn elastic_hosts(spec: &ElasticSpec, names: &[String], ctxm: &str) -> Result<Vec<Option<usize>>> {
    let mut hosts: Vec<Option<usize>> = Vec::new();
    for (ei, e) in spec.elastic.iter().enumerate() {
        let f = |s: &str| format!("elastic[{ei}].{s}");
        if e.name.is_empty() || spec.elastic[..ei].iter().any(|o| o.name == e.name) || names.contains(&e.name) {
            return Err(Error::invalid(
                ctxm,
                f("name"),
                format!("`{}` must be a non-empty name unique among joints", e.name),
            ));
        }
        let host = if e.after == "base" {
            None
        } else {
            Some(
                names
                    .iter()
                    .position(|n| *n == e.after)
                    .ok_or_else(|| Error::invalid(ctxm, f("after"), format!("expected `base` or an actuated joint name, found `{}`", e.after)))?,
            )
        };
        let a = Vector3::from(e.axis);
        if !a.iter().all(|v| v.is_finite()) || a.norm() < 1e-9 {
            return Err(Error::invalid(ctxm, f("axis"), "expected a finite non-zero vector"));
        }
        if e.xyz.iter().chain(e.rpy.iter()).any(|v| !v.is_finite()) {
            return Err(Error::invalid(ctxm, f("xyz"), "expected finite numbers"));
        }
        finite_pos(ctxm, &f("k"), e.k, false)?;
        finite_pos(ctxm, &f("d"), e.d, true)?;
        hosts.push(host);
    }
    Ok(hosts)
}

/// The extended chain: the rigid robot with the elastic joints inserted
/// (massless links), and where every actuated and elastic joint landed.
struct ExtendedChain {
    /// The extended robot (no drives, no coupling).
    ext: Robot,
    /// Index in `ext` of actuated joint j.
    act_index: Vec<usize>,
    /// Index in `ext` of elastic joint e.
    elastic_index: Vec<usize>,
    /// Index in `ext` of the last joint of actuated joint j's segment (its body sits there).
    tail: Vec<usize>,
}

/// Builds the extended chain: base elastic joints first, then every actuated
/// joint followed by the elastic joints it hosts; each rigid body moves to the
/// tail of its segment.
fn extended_chain(rigid: &Robot, spec: &ElasticSpec, hosts: &[Option<usize>]) -> Result<ExtendedChain> {
    let na = rigid.dof();
    let mut joints: Vec<Joint> = Vec::new();
    let mut links: Vec<Link> = Vec::new();
    let mut act_index = vec![0usize; na];
    let mut elastic_index = vec![0usize; spec.elastic.len()];
    let mut tail: Vec<usize> = vec![0; na];
    let push_elastic = |ei: usize, parent: Option<usize>, host_name: &str, joints: &mut Vec<Joint>, links: &mut Vec<Link>| {
        let e = &spec.elastic[ei];
        let pl = rpy_iso(e.xyz, e.rpy);
        joints.push(Joint {
            name: e.name.clone(),
            kind: JointKind::Revolute,
            parent,
            placement: pl,
            axis: Unit::new_normalize(Vector3::from(e.axis)),
            post: pl.inverse(),
            offset: 0.0,
            limits: JointLimits::default(),
        });
        links.push(Link {
            name: format!("{host_name}_{}", e.name),
            inertial: Inertial::zero(),
        });
        joints.len() - 1
    };
    let mut base_tail: Option<usize> = None;
    for ei in 0..spec.elastic.len() {
        if hosts[ei].is_none() {
            let k = push_elastic(ei, base_tail, "base", &mut joints, &mut links);
            elastic_index[ei] = k;
            base_tail = Some(k);
        }
    }
    for j in 0..na {
        let rj = &rigid.joints[j];
        let parent = match rj.parent {
            None => base_tail,
            Some(p) => Some(tail[p]),
        };
        let mut jj = rj.clone();
        jj.parent = parent;
        joints.push(jj);
        links.push(Link {
            name: rigid.links[j].name.clone(),
            inertial: Inertial::zero(),
        });
        act_index[j] = joints.len() - 1;
        let mut t = act_index[j];
        for ei in 0..spec.elastic.len() {
            if hosts[ei] == Some(j) {
                let k = push_elastic(ei, Some(t), &rigid.links[j].name, &mut joints, &mut links);
                elastic_index[ei] = k;
                t = k;
            }
        }
        tail[j] = t;
        // the body (and its name, for frames) sits at the tail
        if t != act_index[j] {
            let nm = links[act_index[j]].name.clone();
            links[act_index[j]].name = format!("{nm}_gear");
            links[t].name = nm;
        }
        links[t].inertial = rigid.links[j].inertial;
    }
    let frames: Vec<Frame> = rigid
        .frames
        .iter()
        .map(|f| Frame {
            name: f.name.clone(),
            link: f.link.map(|l| tail[l]),
            placement: f.placement,
        })
        .collect();
    let nx = joints.len();
    let drives = vec![
        Drive {
            rotor_inertia: None,
            gear_ratio: 1.0,
            friction: Friction::None,
            ..Drive::default()
        };
        nx
    ];
    let ext = Robot::new(RobotParts {
        name: format!("{} (elastic)", rigid.name),
        joints,
        links,
        drives,
        coupling: None,
        frames,
        gravity: rigid.gravity,
        source: format!("extended from {}", rigid.source),
    })?;
    Ok(ExtendedChain {
        ext,
        act_index,
        elastic_index,
        tail,
    })
}

/// Every parameter of the model in its canonical order: gear spring and
/// damper per actuated joint, arm spring and damper per elastic joint, rotor
/// inertia and viscous friction per motor, the ten inertial parameters per link.
fn model_params(rigid: &Robot, chain: &ExtendedChain, spec: &ElasticSpec, gear: &[&GearboxSpec], names: &[String], ctxm: &str) -> Result<Vec<ModelParam>> {
    let na = rigid.dof();
    let (ext, tail) = (&chain.ext, &chain.tail);
    let mut params = Vec::new();
    for j in 0..na {
        let g = gear[j];
        params.push(ModelParam {
            name: format!("k_{}", names[j]),
            role: ParamRole::GearSpring(j),
            nominal: g.k,
            positive: true,
        });
        params.push(ModelParam {
            name: format!("d_{}", names[j]),
            role: ParamRole::GearDamper(j),
            nominal: g.d,
            positive: true,
        });
    }
    for (ei, e) in spec.elastic.iter().enumerate() {
        params.push(ModelParam {
            name: format!("k_{}", e.name),
            role: ParamRole::ArmSpring(ei),
            nominal: e.k,
            positive: true,
        });
        params.push(ModelParam {
            name: format!("d_{}", e.name),
            role: ParamRole::ArmDamper(ei),
            nominal: e.d,
            positive: true,
        });
    }
    for j in 0..na {
        let ia = match (gear[j].ia, rigid.drives[j].rotor_inertia) {
            (Some(v), _) => v,
            (None, Some(v)) if v > 0.0 => v,
            _ => {
                return Err(Error::invalid(
                    ctxm,
                    format!("gearbox[{}].ia", names[j]),
                    "the motor side needs a positive rotor inertia: give `ia` in the robot file's [[drive]] or in the gearbox entry",
                ))
            }
        };
        params.push(ModelParam {
            name: format!("Ia{}", j + 1),
            role: ParamRole::RotorInertia(j),
            nominal: ia,
            positive: true,
        });
        let fv = match rigid.drives[j].friction {
            Friction::None => 0.0,
            Friction::Symmetric { fv, .. } => fv,
            Friction::Asymmetric { fv_pos, fv_neg, .. } => 0.5 * (fv_pos + fv_neg),
        };
        params.push(ModelParam {
            name: format!("Fv{}", j + 1),
            role: ParamRole::MotorViscous(j),
            nominal: fv,
            positive: fv > 0.0,
        });
    }
    let nominal_ext = ext.nominal_params();
    for j in 0..na {
        let off = ext.link_param_offset(tail[j]);
        for (k, kind) in ParamKind::INERTIAL.iter().enumerate() {
            let v = nominal_ext[off + k];
            let positive = matches!(kind, ParamKind::M | ParamKind::XX | ParamKind::YY | ParamKind::ZZ) && v > 0.0;
            params.push(ModelParam {
                name: format!("{}{}", kind.label(), j + 1),
                role: ParamRole::Link(off + k),
                nominal: v,
                positive,
            });
        }
    }
    Ok(params)
}

/// Applies `[model.nominal]`: name → value, positive where the parameter must be.
fn apply_nominal_overrides(params: &mut [ModelParam], spec: &ElasticSpec, ctxm: &str) -> Result<()> {
    for (name, v) in &spec.nominal {
        let p = params.iter_mut().find(|p| &p.name == name).ok_or_else(|| {
            Error::invalid(
                ctxm,
                format!("nominal.{name}"),
                "no parameter of that name (k_<joint>, d_<joint>, Ia<j>, Fv<j>, XX<j>..M<j>)",
            )
        })?;
        if !v.is_finite() || (p.positive && *v <= 0.0) {
            return Err(Error::invalid(
                ctxm,
                format!("nominal.{name}"),
                format!("expected a finite{} value, found {v}", if p.positive { " positive" } else { "" }),
            ));
        }
        p.nominal = *v;
    }
    Ok(())
}

/// Indices of the unknowns (names or groups), in the canonical order of `params`.
fn select_unknowns(params: &[ModelParam], spec: &ElasticSpec, ctxm: &str) -> Result<Vec<usize>> {
    let mut unknowns: Vec<usize> = Vec::new();
    for (ui, u) in spec.unknowns.iter().enumerate() {
        // a group name selects every parameter whose role it covers
        let group: Option<fn(&ParamRole) -> bool> = match u.as_str() {
            "springs" => Some(|r| matches!(r, ParamRole::GearSpring(_) | ParamRole::ArmSpring(_))),
            "dampers" => Some(|r| matches!(r, ParamRole::GearDamper(_) | ParamRole::ArmDamper(_))),
            "gear_springs" => Some(|r| matches!(r, ParamRole::GearSpring(_))),
            "gear_dampers" => Some(|r| matches!(r, ParamRole::GearDamper(_))),
            "arm_springs" => Some(|r| matches!(r, ParamRole::ArmSpring(_))),
            "arm_dampers" => Some(|r| matches!(r, ParamRole::ArmDamper(_))),
            _ => None,
        };
        let sel: Vec<usize> = match (group, u.as_str()) {
            (Some(in_group), _) => params.iter().enumerate().filter(|(_, p)| in_group(&p.role)).map(|(i, _)| i).collect(),
            (None, name) => {
                let i = params.iter().position(|p| p.name == name).ok_or_else(|| {
                    Error::invalid(
                        ctxm,
                        format!("unknowns[{ui}]"),
                        format!("`{name}` is neither a parameter name nor a group (springs, dampers, gear_springs, gear_dampers, arm_springs, arm_dampers)"),
                    )
                })?;
                vec![i]
            }
        };
        for i in sel {
            if !unknowns.contains(&i) {
                unknowns.push(i);
            }
        }
    }
    // keep the model's canonical order (as in `params`)
    unknowns.sort_unstable();
    // a positive unknown is fitted in log space from multiplicatively perturbed
    // starts: a nominal 0 would stay exactly 0 in every start
    for &i in &unknowns {
        let p = &params[i];
        if p.positive && (p.nominal.is_nan() || p.nominal <= 0.0) {
            return Err(Error::invalid(
                ctxm,
                format!("unknown `{}`", p.name),
                format!(
                    "its nominal value is {}: an unknown spring, damper or inertia must start from a positive value (it is fitted in log space, so a start at 0 stays at 0); give it a positive nominal value (gearbox `d`, elastic `d`, or [model.nominal]) or remove it from `unknowns`",
                    p.nominal
                ),
            ));
        }
    }
    Ok(unknowns)
}

impl ElasticModel {
    /// Loads the `[model]` table of a design file (other tables are ignored
    /// here), resolving the robot path relative to the file.
    pub fn load(path: &Path) -> Result<ElasticModel> {
        let text = crate::io::read_to_string(path)?;
        let v: toml::Table = crate::io::parse_toml(path, &text)?;
        let m = v.get("model").ok_or_else(|| {
            Error::invalid(
                path.display().to_string(),
                "model",
                "expected a [model] table (robot, gearbox, elastic, unknowns)",
            )
        })?;
        let spec: ElasticSpec = m
            .clone()
            .try_into()
            .map_err(|e: toml::de::Error| Error::parse(path, format!("[model]: {}", e.message())))?;
        crate::io::design_path(path, "model.robot", Path::new(&spec.robot))?;
        let base = path.parent().unwrap_or(Path::new("."));
        Self::from_spec(&spec, base, &path.display().to_string())
    }

    /// Builds the model from a spec; `base` resolves the robot path, `ctx` names the file in errors.
    ///
    /// Steps: load the rigid robot and add the payload; match one gearbox to
    /// every actuated joint; place the elastic joints on their hosts; build
    /// the extended chain; list the parameters and apply the nominal
    /// overrides; select the unknowns.
    pub fn from_spec(spec: &ElasticSpec, base: &Path, ctx: &str) -> Result<ElasticModel> {
        let rpath = base.join(&spec.robot);
        let mut rigid = robot::load(&rpath)?;
        let ctxm = format!("{ctx} [model]");
        add_payload(&mut rigid, spec.payload.as_ref(), &rpath, &ctxm)?;
        let names: Vec<String> = rigid.joints.iter().map(|j| j.name.clone()).collect();
        let gear = gearbox_per_joint(&rigid, spec, &names, &ctxm)?;
        let hosts = elastic_hosts(spec, &names, &ctxm)?;
        let chain = extended_chain(&rigid, spec, &hosts)?;
        let mut params = model_params(&rigid, &chain, spec, &gear, &names, &ctxm)?;
        apply_nominal_overrides(&mut params, spec, &ctxm)?;
        let unknowns = select_unknowns(&params, spec, &ctxm)?;
        let coupling = rigid.coupling_matrix();
        Ok(ElasticModel {
            rigid,
            ext: chain.ext,
            act_index: chain.act_index,
            elastic_index: chain.elastic_index,
            elastic_names: spec.elastic.iter().map(|e| e.name.clone()).collect(),
            coupling,
            params,
            unknowns,
            source: format!("{ctx}: robot {}", rpath.display()),
        })
    }

    /// Number of motors (actuated joints) n_a.
    pub fn n_motors(&self) -> usize {
        self.rigid.dof()
    }

    /// Number of extra elastic joints n_e.
    pub fn n_elastic(&self) -> usize {
        self.elastic_index.len()
    }

    /// Number of coordinates of the linear model N = 2 n_a + n_e.
    pub fn n_coords(&self) -> usize {
        self.n_motors() + self.ext.dof()
    }

    /// Number of unknown parameters p.
    pub fn n_unknowns(&self) -> usize {
        self.unknowns.len()
    }

    /// Names of the unknown parameters, in the order of θ.
    pub fn unknown_names(&self) -> Vec<String> {
        self.unknowns.iter().map(|&i| self.params[i].name.clone()).collect()
    }

    /// Nominal values θ_init of the unknowns.
    pub fn nominal_unknowns(&self) -> Vec<f64> {
        self.unknowns.iter().map(|&i| self.params[i].nominal).collect()
    }

    /// Which unknowns are positive (fitted in log space).
    pub fn unknown_positive(&self) -> Vec<bool> {
        self.unknowns.iter().map(|&i| self.params[i].positive).collect()
    }

    /// Index of a parameter by name in `params`.
    pub fn param_index(&self, name: &str) -> Option<usize> {
        self.params.iter().position(|p| p.name == name)
    }

    /// All parameter values with the unknowns set to `theta` (length p).
    pub fn full_values(&self, theta: &[f64]) -> Result<Vec<f64>> {
        if theta.len() != self.n_unknowns() {
            return Err(Error::dim("unknown parameter vector θ", self.n_unknowns(), theta.len()));
        }
        let mut v: Vec<f64> = self.params.iter().map(|p| p.nominal).collect();
        for (k, &i) in self.unknowns.iter().enumerate() {
            v[i] = theta[k];
        }
        Ok(v)
    }

    /// The extended robot's standard parameter vector for full values `vals`.
    pub fn ext_params(&self, vals: &[f64]) -> Vec<f64> {
        let mut pi: Vec<f64> = self.ext.nominal_params().as_slice().to_vec();
        for (p, v) in self.params.iter().zip(vals) {
            if let ParamRole::Link(i) = p.role {
                pi[i] = *v;
            }
        }
        pi
    }
}
