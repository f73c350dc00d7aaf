"""idexp: design and evaluation of identification experiments for industrial robots.

Python bindings of the idexp Rust library (numpy float64 arrays in and out;
C or Fortran order accepted; shapes checked with ``ValueError`` naming the
argument and the expected shape). Units are SI, angles in rad.

>>> import idexp, numpy as np
>>> robot = idexp.Robot.load("designs/robots/ur5.urdf")
>>> q = np.zeros((100, robot.dof))
>>> robot.regressor(q, q, q).shape          # (N·n, p)
(600, 60)

The problems:

- :func:`excite` designs an excitation trajectory (Fourier series), :func:`assess`
  rates a given one;
- :func:`simulate` runs the closed-loop simulation of a design (a rehearsal);
- :func:`study` runs an identification study (many experiments, validation runs, a
  prior) from a study file or dict, as ``idexp identify study.toml``;
- :func:`identify` identifies the base parameters from a run (folder, arrays or
  a :class:`SimRun`);
- :func:`payload` identifies a tool's or payload's mass, centre of mass and
  inertia from loaded (and unloaded) runs, as ``idexp payload identify``;
  :func:`calibrate_gains` calibrates each joint's drive gain (current to
  torque) with a known mass (a payload design with ``[gains]``);
- :func:`plan` finds the cheapest repetitions of candidate experiments that
  meet accuracy targets, as ``idexp plan`` (optionally rehearsed);
- :func:`positions` selects optimal measurement positions (with a
  Kiefer-Wolfowitz certificate); :func:`fit` fits the elastic gray-box model
  to FRF data from many starts.

Long calls release the GIL, report progress to an optional
``progress(phase, done, total, message)`` callback and stop on Ctrl-C within a
second, raising ``KeyboardInterrupt`` (nothing half-done is returned).
Library errors raise :class:`IdexpError` (a ``ValueError``) or ``OSError``
with idexp's message (file, field, value, what is allowed).

MuJoCo: :func:`mjcf` / :func:`write_mjcf` give a robot model (nominal, or
identified: ``Identification.model()``) as MJCF (inertials, joints, armature =
Ia, damping = Fv, frictionloss = Fc).

Pinocchio: :meth:`Robot.to_pinocchio` / :meth:`Robot.from_pinocchio` convert
standard parameters to and from Pinocchio's ``[m, mcx, mcy, mcz, Ixx, Ixy,
Iyy, Ixz, Iyz, Izz]`` order per body.
"""

from ._idexp import (
    BaseParameters,
    ExciteResult,
    FitResult,
    GainsFit,
    JointFits,
    IdexpError,
    Identifiability,
    Identification,
    PayloadFit,
    Plan,
    PositionsResult,
    Robot,
    SimRun,
    Study,
    __version__,
    assess,
    calibrate_gains,
    excite,
    export_trajectory,
    fit,
    frf,
    identify,
    log_info,
    mjcf,
    multisine,
    payload,
    plan,
    positions,
    read_log,
    rtde_gains,
    simulate,
    study,
    with_payload,
    write_mjcf,
    write_preview,
)

__all__ = [
    "BaseParameters",
    "ExciteResult",
    "FitResult",
    "GainsFit",
    "JointFits",
    "IdexpError",
    "Identifiability",
    "Identification",
    "PayloadFit",
    "Plan",
    "PositionsResult",
    "Robot",
    "SimRun",
    "Study",
    "__version__",
    "assess",
    "calibrate_gains",
    "excite",
    "export_trajectory",
    "fit",
    "frf",
    "identify",
    "log_info",
    "mjcf",
    "multisine",
    "payload",
    "plan",
    "positions",
    "read_log",
    "rtde_gains",
    "simulate",
    "study",
    "with_payload",
    "write_mjcf",
    "write_preview",
]
