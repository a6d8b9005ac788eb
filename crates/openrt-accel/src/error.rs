//! Errors of the acceleration layer.

use thiserror::Error;

/// What can go wrong when building or checking an acceleration structure.
#[derive(Debug, Error, Clone, PartialEq, Eq)]
pub enum AccelError {
    /// More primitives than a node's 30-bit fields can address.
    #[error("{count} primitives exceed the kd-tree limit of {limit} per tree")]
    TooManyPrimitives {
        /// Primitives given.
        count: usize,
        /// The limit.
        limit: usize,
    },
    /// More nodes or primitive references than fit in 30 bits.
    #[error("kd-tree exceeds {limit} nodes or leaf references")]
    TooManyNodes {
        /// The limit.
        limit: usize,
    },
    /// `validate()` found a broken invariant.
    #[error("kd-tree invariant violated: {0}")]
    Invalid(String),
}
