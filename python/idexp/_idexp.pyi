"""Type stubs of the native module idexp._idexp (re-exported by idexp)."""

import os
from typing import Any, Callable, Optional, Sequence, Union

import numpy as np
import numpy.typing as npt

ArrayLike = npt.ArrayLike
F64 = npt.NDArray[np.float64]
PathLike = Union[str, "os.PathLike[str]"]
Progress = Optional[Callable[[str, int, Optional[int], str], Any]]
RunLike = Union[PathLike, Sequence[PathLike], "SimRun", dict, Sequence[dict]]

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
    robot: str
    trajectory: dict[str, F64]
    report: dict
    def sample(self, rate: float) -> dict[str, F64]:
        """One period sampled at rate Hz: t (N,), q, qd, qdd (N, n)."""
    def write(self, folder: PathLike) -> str:
        """The command line's output folder (coefficients.json, trajectory.csv, reports, SVGs)."""

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

class Identification:
    status: str
    names: list[str]
    groupings: list[str]
    theta: F64
    std: F64
    rel_std: F64
    covariance: F64
    errors: dict
    validation_errors: Optional[dict]
    truth: Optional[list[dict]]
    report: dict
    torques: dict[str, F64]
    def text(self) -> str: ...
    def write(self, folder: PathLike) -> str: ...

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
    time_limit: Optional[float] = None,
    progress: Progress = None,
) -> Identification:
    """Identifies the base parameters (the command line's `idexp identify`).
    method: ols, wls, projection or ml."""

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
