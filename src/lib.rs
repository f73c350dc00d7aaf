//! # idexp — identification experiments for industrial robots
//!
//! (crate documentation is completed in the README-backed section below)
#![warn(missing_docs)]

pub mod error;
pub mod io;
pub mod robot;

pub use error::{Error, Result};
