//! Identification from measured runs (paper 000 §II-B, §III-C, §III-D, §IV;
//! paper 002 §2.2, §3.2–3.5).
pub mod estimate;
pub mod process;
pub mod run;

pub use process::{process, Filter, Processed};
