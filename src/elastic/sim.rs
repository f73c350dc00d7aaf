//! Time-domain simulation (under construction).
