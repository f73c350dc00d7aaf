//! # idexp — identification experiments for industrial robots
//!
//! (crate documentation is completed in the README-backed section below)
#![warn(missing_docs)]

pub mod elastic;
pub mod error;
pub mod excitation;
pub mod frf;
pub mod ident;
pub mod io;
pub mod linalg;
pub mod params;
pub mod positions;
pub mod robot;
pub mod sim;
pub mod trajectory;

pub use error::{Error, Result};
