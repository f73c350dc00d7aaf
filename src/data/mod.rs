//! Run formats shared by the simulators and the estimators, and the signal
//! processing every estimator starts from (layer 2: they use only `error`,
//! `io`, `robot` and `trajectory`'s Fourier series and differences, and are
//! used by `sim`, `elastic`, `ident`, `payload`, `plan` and `frf`).
//!
//! - [`Run`] / [`Repetition`]: a measured (or simulated) rigid-body
//!   identification run, N_r repetitions of one experiment on a common time
//!   grid, one CSV per repetition (`t, q1..qn, tau1..taun[, r.., qd.., qdd..]`),
//!   or with motor currents `cur1..curn` converted by the robot's drives.
//! - [`MotorRecord`]: one recorded FRF experiment, motor torques u and motor
//!   positions y per sample (`t, tau1..taun, qm1..qmn`).
//! - [`Truth`]: the true parameters written next to a simulated run
//!   (`truth.json`).
//! - [`process()`](process::process): a run averaged over its repetitions with
//!   the sample variances, filtered and differentiated ([`process::Processed`]),
//!   what identification, the payload and the drive-gain calibration start from.

pub mod logs;
pub mod motor;
pub mod process;
pub mod resample;
pub mod run;
pub mod truth;

pub use motor::MotorRecord;
pub use resample::Sampling;
pub use run::{expand, Averaged, Coordinates, Repetition, Run, SamplingOptions, TorqueColumns, TorqueFrom, TorqueSource, CURRENT_TOLERANCE};
pub use truth::Truth;
