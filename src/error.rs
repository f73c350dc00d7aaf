//! The crate's error type: every way user input can be wrong, with enough
//! context (file, line or field, what was expected) for the user to act on it.

use std::path::PathBuf;

/// Errors raised by idexp for bad input or unusable problems.
///
/// Solver outcomes (did not converge, infeasible after search) are *not* errors:
/// they are reported as a status inside the result types.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// An I/O failure on a named file. The OS message is part of the
    /// message (and not repeated as a `source`, so a printed error chain
    /// says it once).
    #[error("{path}: {err}")]
    Io {
        /// The file concerned.
        path: PathBuf,
        /// The underlying error.
        err: std::io::Error,
    },
    /// A file could not be parsed (syntax), with location if known.
    #[error("{path}: {msg}")]
    Parse {
        /// The file concerned.
        path: PathBuf,
        /// What was wrong, including line/column when known.
        msg: String,
    },
    /// A value in a file or argument is out of range or inconsistent.
    #[error("{context}: field `{field}`: {msg}")]
    Invalid {
        /// Where the field lives (file name, design section, ...).
        context: String,
        /// The field name.
        field: String,
        /// What was expected.
        msg: String,
    },
    /// Data in a CSV file is bad (NaN, missing column, wrong count...).
    #[error("{path}: row {row}, column `{column}`: {msg}")]
    Data {
        /// The file concerned.
        path: PathBuf,
        /// 1-based data row (0 for the header).
        row: usize,
        /// Column name.
        column: String,
        /// What was expected.
        msg: String,
    },
    /// Dimensions of arrays passed to a function do not agree.
    #[error("dimension mismatch in {what}: expected {expected}, got {got}")]
    Dimension {
        /// What was being checked.
        what: String,
        /// Expected size.
        expected: usize,
        /// Actual size.
        got: usize,
    },
    /// A numerical problem that cannot be solved as posed (singular, rank deficient...).
    #[error("{0}")]
    Numerical(String),
    /// The run was stopped by the user (Ctrl-C) before any result existed.
    #[error("interrupted by the user")]
    Interrupted,
}

/// Result alias used throughout the crate.
pub type Result<T> = std::result::Result<T, Error>;

impl Error {
    /// Shorthand for [`Error::Invalid`].
    pub fn invalid(context: impl Into<String>, field: impl Into<String>, msg: impl Into<String>) -> Self {
        Error::Invalid {
            context: context.into(),
            field: field.into(),
            msg: msg.into(),
        }
    }
    /// An [`Error::Invalid`] with its context rewritten by `f` (e.g. the
    /// entry or file it came from put in front); any other error as it is.
    pub fn map_context(self, f: impl FnOnce(String) -> String) -> Self {
        match self {
            Error::Invalid { context, field, msg } => Error::Invalid {
                context: f(context),
                field,
                msg,
            },
            e => e,
        }
    }
    /// Shorthand for [`Error::Parse`].
    pub fn parse(path: impl Into<PathBuf>, msg: impl Into<String>) -> Self {
        Error::Parse {
            path: path.into(),
            msg: msg.into(),
        }
    }
    /// Shorthand for [`Error::Io`].
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            err: source,
        }
    }
    /// Shorthand for [`Error::Dimension`].
    pub fn dim(what: impl Into<String>, expected: usize, got: usize) -> Self {
        Error::Dimension {
            what: what.into(),
            expected,
            got,
        }
    }
}
