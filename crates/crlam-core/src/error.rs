//! The error type of the core.

use thiserror::Error;

/// Everything the core can refuse. The Python glue maps each variant to a `crlam` exception.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum CrlamError {
    /// A configuration value is out of range or inconsistent.
    #[error("invalid configuration: {field}: {reason}")]
    Config { field: &'static str, reason: String },
    /// Array arguments whose lengths or shapes do not match.
    #[error("shape mismatch: {0}")]
    Shape(String),
    /// A pose or point lies outside a map with a fixed extent.
    #[error("out of map bounds: {0}")]
    OutOfBounds(String),
    /// A non-finite value where a finite one is required.
    #[error("non-finite value in {field}: {value}")]
    NonFinite { field: &'static str, value: f64 },
    /// An input asks for more than a resource limit allows (see [`crate::limits`]).
    #[error(
        "{what} needs {needed:.0} {unit}, more than the limit of {limit} (raise it with --max-{flag} N \
         or the environment variable CRLAM_MAX_{env}=N)",
        flag = setting.replace('_', "-"),
        env = setting.to_uppercase()
    )]
    Limit {
        what: String,
        needed: f64,
        limit: u64,
        unit: &'static str,
        setting: &'static str,
    },
    /// A buffer sized by the data could not be allocated.
    #[error("out of memory: {0}")]
    Alloc(String),
}

/// Result alias used throughout the core.
pub type Result<T> = std::result::Result<T, CrlamError>;

/// Builds a [`CrlamError::Config`].
pub fn config_err(field: &'static str, reason: impl Into<String>) -> CrlamError {
    CrlamError::Config {
        field,
        reason: reason.into(),
    }
}
