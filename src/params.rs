//! Standard ⇄ base parameters.
