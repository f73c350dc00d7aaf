//! `idexp simulate`.
