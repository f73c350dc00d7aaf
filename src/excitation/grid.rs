//! The Fourier series' fixed time grids ([`crate::trajectory::TrigGrid`],
//! behind the trajectory-shape seam since the B-splines), re-exported here.

pub use crate::trajectory::TrigGrid;
