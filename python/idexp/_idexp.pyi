"""Type stubs of the native module idexp._idexp (re-exported by idexp)."""

import os
from typing import Any, Callable, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

ArrayLike = npt.ArrayLike
F64 = npt.NDArray[np.float64]
PathLike = Union[str, "os.PathLike[str]"]
Progress = Optional[Callable[[str, int, Optional[int], str], Any]]
RunLike = Union[PathLike, Sequence[PathLike], "SimRun", dict, Sequence[dict]]
Formats = Union[str, Sequence[str]]  # a list of names or a comma-separated string

__version__: str

class IdexpError(ValueError):
    """Bad input found by idexp: the message names the file, the field or row,
    the value and what is allowed."""

class Robot:
    """A robot model (``.toml`` or ``.urdf``); immutable and thread-safe."""

    @staticmethod
    def load(path: PathLike) -> "Robot":
        """Loads a robot file; IdexpError (or OSError) naming file and field on bad input."""
    @property
    def name(self) -> str: ...
    @property
    def path(self) -> str: ...
    @property
    def dof(self) -> int:
        """Number of actuated joints n."""
    @property
    def joint_names(self) -> list[str]: ...
    @property
    def joint_kinds(self) -> list[str]:
        """"revolute" or "prismatic" per joint."""
    @property
    def limits(self) -> dict[str, F64]:
        """lower, upper, velocity, acceleration, effort (n each; inf when not given)."""
    @property
    def param_names(self) -> list[str]:
        """The p standard parameters: XX, XY, XZ, YY, YZ, ZZ, MX, MY, MZ, M per link, then drives."""
    @property
    def n_params(self) -> int: ...
    @property
    def inertial_mask(self) -> list[bool]:
        """True for the rigid-body inertial parameters."""
    @property
    def nominal_params(self) -> F64:
        """Nominal standard parameters θ (p,)."""
    @property
    def gravity(self) -> F64: ...
    def rnea(self, q: ArrayLike, qd: ArrayLike, qdd: ArrayLike) -> F64:
        """Inverse dynamics (nominal θ), motor side: (n,) for one state, (N, n) for a batch."""
    def inverse_dynamics(self, theta: ArrayLike, q: ArrayLike, qd: ArrayLike, qdd: ArrayLike) -> F64:
        """Y(q, q̇, q̈)·θ for a given θ (p,); shapes as rnea."""
    def mass_matrix(self, q: ArrayLike) -> F64:
        """Mass matrix (n, n), or (N, n, n) for positions (N, n)."""
    def id_derivatives(
        self, q: ArrayLike, qd: ArrayLike, qdd: ArrayLike, theta: Optional[ArrayLike] = None
    ) -> Tuple[F64, F64]:
        """(∂τ/∂q, ∂τ/∂q̇), each (n, n), at one state; θ default nominal."""
    def regressor(self, q: ArrayLike, qd: ArrayLike, qdd: ArrayLike, base: bool = False) -> F64:
        """τ = Y θ: (n, p) for one state, (N·n, p) state-major for a batch; base=True: base columns."""
    def base_parameters(
        self, tol: float = 1e-6, samples: int = 200, seed: int = 1, inertial_only: bool = False
    ) -> "BaseParameters":
        """Base parameters θ_b = K θ (greedy QR over random states)."""
    def to_pinocchio(self, theta: Optional[ArrayLike] = None) -> F64:
        """Inertial part of θ (default nominal) in Pinocchio's order, (10·n,):
        [m, mcx, mcy, mcz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz] per body (inertia about the body frame origin)."""
    def from_pinocchio(self, pi: ArrayLike, theta: Optional[ArrayLike] = None) -> F64:
        """Inverse of to_pinocchio: (10·n,) → θ (p,), drive parameters from theta (default nominal)."""
    def with_params(self, theta: ArrayLike) -> "Robot":
        """A copy with standard parameters θ (p,): inertials and drives replaced; same source file."""
    def export(self, folder: PathLike, formats: Optional[Formats] = None) -> list[str]:
        """robot.urdf (the source URDF with this model's inertials; not for a DH robot) and
        robot.toml (the source robot file with this model's drives, and inertials for a DH
        table), as `idexp identify --export urdf,toml` writes them; default: both (toml for DH)."""
    @property
    def inertial_warnings(self) -> list[str]:
        """Physical-consistency warnings (pseudo-inertia not PSD, inertia without mass); [] if none."""
    def provenance(self) -> dict[str, Any]:
        """What of the URDF is left out of the model (`left_out`) and the file each collision shape was read from (`collision`)."""

class BaseParameters:
    names: list[str]
    groupings: list[str]
    K: F64
    independent: list[int]
    regrouped: list[int]
    unidentifiable: list[int]
    tol: float
    smallest_kept: float
    largest_dropped: float
    n_base: int
    nominal: F64
    report: dict
    def values(self, theta: ArrayLike) -> F64:
        """K θ."""
    def __len__(self) -> int: ...

class ExciteResult:
    status: str
    feasible: bool
    safety: dict[str, Any]
    """collisions ("imposed", "checked_afterwards", "not_checked"), safe (bool or None),
    closest (pair, distance m, cap m, t s, segment; or None), statement."""
    stopped_by: Optional[str]
    coefficients: dict[str, Any]
    x: F64
    criterion: float
    cond: float
    singular_values: F64
    margins: list[dict]
    violated: list[dict]
    seconds: float
    base_names: list[str]
    column_names: list[str]
    robot: str
    trajectory: dict[str, F64]
    report: dict
    def sample(self, rate: float) -> dict[str, F64]:
        """One period sampled at rate Hz: t (N,), q, qd, qdd (N, n)."""
    @property
    def delivered(self) -> Optional[dict[str, Any]]:
        """The delivered trajectory (trajectory.csv): home at rest → lead-in → periods → lead-out →
        home at rest, at the controller rate: t (N,), q, qd, qdd (N, n), segment (N,) int64
        (0 lead-in, k period k, −1 lead-out), source (N,) int64 (the row whose state a row
        repeats bitwise: its own index, or period 1's row at the same phase for the rows of
        periods 2, 3, … when a period is a whole number of samples), labels {code: label},
        phases [(label, start, end)],
        home, periods, period, lead_in_duration, lead_out_duration, duration, rate.
        None when the design is not playable rest to rest."""
    def delivered_sample(self, rate: float) -> Optional[dict[str, Any]]:
        """The delivered trajectory at rate Hz (keys as delivered)."""
    def export(
        self,
        folder: PathLike,
        formats: Formats,
        rate: Optional[float] = None,
        ur: str = "e-series",
        csv_units: str = "rad",
        csv_derivatives: bool = False,
        approach_speed: float = 0.5,
        approach_acceleration: float = 1.0,
    ) -> list[str]:
        """The delivered trajectory for the controller (`idexp excite --export`): "ur"
        (<design>.script, servoj; ur "e-series" 500 Hz or "cb3" 125 Hz), "ros2"
        (<design>_ros2.yaml, <design>_ros2_goal.yaml), "csv" (<design>_export.csv, csv_units
        "rad" or "deg"); ROS 2 and CSV at rate Hz (default: the controller rate)."""
    def write(self, folder: PathLike) -> str:
        """The command line's output folder (coefficients.json, trajectory.csv, reports, SVGs)."""

def export_trajectory(
    coefficients: PathLike,
    formats: Formats,
    out: Optional[PathLike] = None,
    rate: Optional[float] = None,
    ur: str = "e-series",
    csv_units: str = "rad",
    csv_derivatives: bool = False,
    approach_speed: float = 0.5,
    approach_acceleration: float = 1.0,
) -> list[str]:
    """`idexp export`: a coefficients.json written earlier in controller formats (options as
    ExciteResult.export), into out (default: its folder)."""

def mjcf(robot: Robot) -> str:
    """The robot as MJCF for MuJoCo (`idexp robot mjcf`): bodies with inertials, hinge/slide
    joints with range, armature = Ia, damping = Fv, frictionloss = Fc, a motor per joint,
    gravity; what MJCF cannot express stated in XML comments."""

def write_mjcf(robot: Robot, folder: PathLike) -> str:
    """Writes robot.xml (mjcf(robot)) into folder; returns its path."""

def excite(
    design: Union[PathLike, dict],
    time_limit: Optional[float] = None,
    seed: Optional[int] = None,
    base_dir: Optional[PathLike] = None,
    progress: Progress = None,
) -> ExciteResult:
    """Designs an excitation trajectory (the command line's `idexp excite`)."""

class Identifiability:
    names: list[str]
    rank: int
    cond: float
    singular_values: F64
    std_dev: F64
    rel_std_dev: F64
    sensitivity: F64
    unexcited: list[str]
    report: dict
    def text(self) -> str: ...
    def write(self, folder: PathLike, title: str = "identifiability") -> str: ...

def assess(
    robot: Robot,
    t: Optional[ArrayLike],
    q: ArrayLike,
    qd: ArrayLike,
    qdd: ArrayLike,
    noise: Optional[ArrayLike] = None,
    inertial: bool = False,
) -> Identifiability:
    """Identifiability of sampled states (N, n) (the command line's `idexp assess`)."""

class SimRun:
    repetitions: list[dict[str, F64]]
    truth: dict
    status: dict
    def write(self, folder: PathLike) -> str: ...
    def __len__(self) -> int: ...

def simulate(
    design: Union[PathLike, dict],
    seed: Optional[int] = None,
    base_dir: Optional[PathLike] = None,
    progress: Progress = None,
) -> SimRun:
    """Closed-loop simulation of a design (the command line's `idexp simulate`)."""

class Study:
    """An identification (idexp.study; `idexp identify study.toml`; idexp.identify's Identification)."""
    status: str
    """`ok`, `rank_deficient` (the least-squares estimate), or the solver's status (ML)."""
    state: str
    """What status.json says: complete, failed or interrupted."""
    names: list[str]
    groupings: list[str]
    theta: F64
    std: F64
    rel_std: F64
    covariance: F64
    experiments: list[dict]
    """Per experiment: weights, σ per joint, errors, information share, rank and cond alone."""
    validation: list[dict]
    """Per validation run: e_j, e*_j, RMS of the least-squares and the consistent estimate."""
    truth: Optional[list[dict]]
    """Per base parameter: name, truth, estimate, z (when the truth is known), or None."""
    consistent: Optional[dict]
    """The consistent estimate with its prior: per link beside the prior, flags, prior-decided directions."""
    consistent_theta: Optional[F64]
    """Consistent standard parameters θ (p,), or None."""
    report: dict
    def model(self) -> Robot:
        """The robot with the consistent standard parameters (needs consistent=True / a [consistent] table)."""
    def export(self, folder: PathLike, formats: Optional[Formats] = None) -> list[str]:
        """`idexp identify --export`: "csv" (params.csv), "urdf" (robot.urdf), "toml" (robot.toml);
        urdf and toml need the consistent fit; default all three."""
    def text(self) -> str: ...
    def write(self, folder: PathLike) -> str: ...

class Identification(Study):
    """A one-experiment identification (idexp.identify): a Study with the one-run views."""
    errors: dict
    """Errors on the identification run's rows used: e, e_rel, rms (n,), noise_floor."""
    validation_errors: Optional[dict]
    """Errors on the validation run, or None."""
    torques: dict[str, F64]
    """t (N,), measured and predicted (N, n) torques of the identification data (N·m)."""

def identify(
    robot: Robot,
    run: RunLike,
    method: str = "wls",
    weights: str = "sample",
    filter: str = "auto",
    cutoff: float = 10.0,
    trajectory: Optional[Union[PathLike, ExciteResult]] = None,
    harmonics: Optional[int] = None,
    decimate: int = 1,
    validate: Optional[RunLike] = None,
    truth: Optional[Union[PathLike, SimRun]] = None,
    consistent: bool = False,
    margin: float = 0.0,
    regularization: float = 1e-6,
    standstill: str = "auto",
    torque_from: str = "auto",
    current_tolerance: float = 0.05,
    velocity_from: str = "auto",
    dead_band: float = 0.01,
    time_limit: Optional[float] = None,
    progress: Progress = None,
) -> Identification:
    """Identifies the base parameters (the command line's `idexp identify`).
    method: ols, wls, projection or ml. consistent=True: physically consistent standard
    parameters after the fit (semidefinite program: every pseudo-inertia ⪰ margin·I,
    drive parameters signed; regularization weighs closeness to the nominal values).
    standstill: auto (drop the slow rows of joints with sign friction, keep those of
    tanh/stribeck joints), drop or keep. torque_from: auto, torque or current (a run folder
    or CSV logging cur1..curn: τ = current_sign·k_t·N·i from the robot file's drives);
    current_tolerance: relative RMS by which logged torques and currents may disagree.
    velocity_from: auto (the logged qd1..qdn when the run has them), log or positions.
    dead_band (rad/s): for joints with a sign Coulomb term, |q̇| below it is rest (no
    Coulomb term), in the run and the validation run alike; 0: sign(q̇) everywhere."""

def study(
    design: Union[PathLike, dict],
    base_dir: Optional[PathLike] = None,
    time_limit: Optional[float] = None,
    progress: Progress = None,
) -> Union[Study, JointFits]:
    """Runs an identification study from a study file or a dict with the file's keys
    (experiments and validation runs relative to the file's folder, or to base_dir for a dict);
    a design whose every experiment names its `joint` gives its dedicated one-joint fits (JointFits)."""

class JointFits:
    """The dedicated one-joint fits of paper 002 §3.2 (idexp.study of a design whose
    every [[experiment]] names its `joint`)."""
    fits: dict[str, dict[str, Any]]
    report: str
    def write(self, folder: PathLike) -> PathLike: ...

class GainsFit:
    """A drive-gain calibration with a known mass (idexp.calibrate_gains)."""
    joints: list[str]
    gains: F64
    """The gains written (N·m/A, joint side, signed): identified where determined, else the file's."""
    std: F64
    """σ of each gain (inf where not determined)."""
    file_gains: F64
    """The robot file's gains s·k_t·N (N·m/A)."""
    determined: list[bool]
    report: dict
    """gains.json: per joint ratio, σ, reason, sign, offset; runs and delays; compared sets; notes."""
    def text(self) -> str: ...
    def write(self, folder: PathLike) -> str: ...

def calibrate_gains(
    design: Union[PathLike, dict],
    base_dir: Optional[PathLike] = None,
    time_limit: Optional[float] = None,
    progress: Progress = None,
) -> GainsFit:
    """Calibrates each joint's drive gain with a known mass: a payload design with a [gains]
    table (`idexp payload identify` of such a design); runs relative to the file's folder or base_dir."""

def rtde_gains(robot: Robot, path: PathLike) -> F64:
    """Per joint the controller's target torque / target current ratio (N·m/A) in an RTDE
    recording (least squares through the origin), as [[gains.compare]] rtde = "..." compares it."""

class Plan:
    """An accuracy plan (idexp.plan; `idexp plan plan.toml`)."""
    status: str
    """planned, unreachable, over_budget, interrupted or failed."""
    candidates: list[str]
    repetitions: list[int]
    cost: float
    """The plan's robot time (s)."""
    relaxed_cost: float
    """The relaxation's lower bound on every plan's cost (s)."""
    values: list[float]
    """Every target's predicted value for the plan."""
    refused: list[dict]
    report: dict
    rehearsal: Optional[dict]
    sigma: list[Tuple[list[float], str]]
    """σ per joint of one repetition of each candidate (N·m), and where it comes from."""
    budget: Optional[float]
    """The total robot time available (s), or None."""
    within_budget: Optional[dict]
    """over_budget: the best plan within the budget (repetitions, cost, values, worst_ratio,
    lower_bound, missed targets), else None."""
    def text(self) -> str: ...
    def write(self, folder: PathLike) -> str: ...

def plan(
    design: Union[PathLike, dict],
    base_dir: Optional[PathLike] = None,
    rehearse: int = 0,
    time_limit: Optional[float] = None,
    progress: Progress = None,
) -> Plan:
    """Plans the cheapest repetitions of the design's candidate experiments that meet every target
    (`idexp plan`); rehearse=N simulates and identifies the plan with N noise seeds."""

class PayloadFit:
    """A payload identification (idexp.payload; `idexp payload identify payload.toml`)."""
    state: str
    """What status.json says: complete, failed or interrupted."""
    mass: Optional[float]
    """Mass (kg)."""
    com: Optional[F64]
    """Centre of mass in the payload's frame (m)."""
    inertia: Optional[F64]
    """Inertia about the centre of mass, (3, 3), frame axes (kg·m²)."""
    params: Optional[F64]
    """The ten standard parameters XX, XY, XZ, YY, YZ, ZZ, MX, MY, MZ, M about the frame's origin."""
    std: Optional[dict]
    """σ of mass, com and inertia (when every parameter is identifiable)."""
    report: dict
    def kuka(self) -> Optional[dict]:
        """KUKA load data: M, X, Y, Z (mm), A, B, C (deg), JX, JY, JZ."""
    def text(self) -> str: ...
    def write(self, folder: PathLike) -> str: ...

def payload(
    design: Union[PathLike, dict],
    base_dir: Optional[PathLike] = None,
    time_limit: Optional[float] = None,
    progress: Progress = None,
) -> PayloadFit:
    """Identifies a payload from a payload design file or a dict with the file's keys
    ([[loaded]] runs, optional [[unloaded]] twins, [guess], export; paths relative to the
    file's folder, or to base_dir for a dict)."""

def with_payload(
    robot: Robot,
    mass: float,
    com: Sequence[float] = (0.0, 0.0, 0.0),
    inertia: Sequence[float] = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
    frame: Optional[str] = None,
) -> Robot:
    """The robot carrying a payload fixed to `frame` (default: the end effector): mass (kg),
    centre of mass (m) and inertia about it [Ixx, Ixy, Ixz, Iyy, Iyz, Izz] (kg·m²) in the
    frame's axes, placed by the frame's pose in its link (the URDF meaning, Pinocchio's
    frame.placement.act(Y))."""

class PositionsResult:
    param_names: list[str]
    n_candidates: int
    ranks: list[int]
    costs: F64
    q: F64
    weights: F64
    plan: list[int]
    rounded: dict
    certificate: dict
    relaxed: dict
    status: Any
    plan_poses: dict[str, Any]
    """The rounded plan's poses: joint_names, q (k, n), m (k,) measurements per pose."""
    def export(
        self, folder: PathLike, formats: Formats, dwell: float = 2.0, move_speed: float = 0.5,
        move_acceleration: float = 1.0,
    ) -> list[str]:
        """`idexp positions --export`: "ur" (<design>_poses.script, movej + m_i·dwell s),
        "ros2" (<design>_poses_ros2.yaml waypoints), "csv" (<design>_poses.csv)."""
    def text(self) -> str: ...
    def write(self, folder: PathLike) -> str: ...

def positions(
    design: Union[PathLike, dict],
    seed: Optional[int] = None,
    base_dir: Optional[PathLike] = None,
    time_limit: Optional[float] = None,
    progress: Progress = None,
) -> PositionsResult:
    """Optimal measurement positions (the command line's `idexp positions`)."""

class FitResult:
    folder: str
    log: str
    records: list[dict]
    report: Optional[dict]
    best_index: Optional[int]
    def text(self) -> Optional[str]: ...

def fit(
    design: PathLike,
    starts: Optional[int] = None,
    shard: Optional[str] = None,
    data: Optional[PathLike] = None,
    method: Optional[str] = None,
    weights: Optional[str] = None,
    seed: Optional[int] = None,
    out: Optional[PathLike] = None,
    time_limit: Optional[float] = None,
    progress: Progress = None,
) -> FitResult:
    """Multistart gray-box FRF fit (the command line's `idexp fit`); shard "i/N"."""

def multisine(design: PathLike, out: Optional[PathLike] = None) -> dict:
    """Multisine references of an elastic design (`idexp multisine`); "folder" holds the output folder."""

def frf(input: PathLike, out: Optional[PathLike] = None, progress: Progress = None) -> str:
    """FRF estimates (`idexp frf`) from an elastic design or a runs.json; returns the frf.json path."""

def read_log(
    log: PathLike,
    robot: Robot,
    format: Optional[str] = None,
    spec: Optional[Union[PathLike, dict]] = None,
    topic: Optional[str] = None,
) -> dict:
    """A robot log (RTDE recorder CSV, CSV with a column map, headerless CSV, ROS 2 bag) as arrays.

    Keys: ``t`` (N,) s from the first sample, ``q``, ``tau`` (N, n), ``qd``,
    ``qdd`` (N, n) or None, ``report`` (source, columns, span, steps).
    """

def log_info(bag: PathLike) -> dict:
    """Topics, message counts, joint names, span and rates of a ROS 2 bag (`idexp log info`)."""

def write_preview(
    source: PathLike,
    robot: Optional[PathLike] = None,
    design: Optional[PathLike] = None,
    out: Optional[PathLike] = None,
    fps: float = 30.0,
) -> str:
    """`idexp view`: writes preview.html, the self-contained 3D preview of an excite output folder
    or (with robot) of a trajectory CSV, into out (default: that folder); returns its path."""
