//! The one error type of the core. Every variant says what to fix and carries context.

/// Errors returned by the checked entry points of `vplace-core`.
///
/// Bad user data is always an `Err`, never a panic. The Python binding maps every variant
/// to a `vplace.VplaceError` subclass with an exhaustive `match`, so adding a variant here
/// forces the binding to decide how to present it.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum VplaceError {
    /// An array or list has the wrong length or shape.
    #[error("{what}: expected {expected}, got {got}")]
    Shape {
        /// What was checked, e.g. `"normals"`.
        what: String,
        /// The expected shape, in words, e.g. `"(120, 160, 3)"`.
        expected: String,
        /// The shape that was passed.
        got: String,
    },
    /// A value is NaN or infinite where only finite values are allowed.
    #[error("{what} holds a non-finite value (NaN or inf) at index {index}")]
    NonFinite {
        /// What was checked.
        what: String,
        /// Flat index of the first non-finite value.
        index: usize,
    },
    /// Something that must not be empty is empty.
    #[error("{what} is empty: {hint}")]
    Empty {
        /// What was empty, e.g. `"scene triangles"`.
        what: String,
        /// What to do about it.
        hint: String,
    },
    /// A value is outside its valid range.
    #[error("{what} = {value} is out of range: {expected}")]
    OutOfRange {
        /// The parameter.
        what: String,
        /// The value that was passed, formatted.
        value: String,
        /// The valid range, in words.
        expected: String,
    },
    /// An index refers to an element that does not exist.
    #[error("{what}: index {index} is out of bounds for length {len}")]
    IndexOutOfBounds {
        /// What was indexed.
        what: String,
        /// The offending index.
        index: usize,
        /// The length of the indexed collection.
        len: usize,
    },
    /// Input that is well-formed but cannot be handled (e.g. a degenerate geometric configuration).
    #[error("{what}: {reason}")]
    Invalid {
        /// What was wrong.
        what: String,
        /// Why, and what to do.
        reason: String,
    },
    /// The caller raised the cancel flag; the computation stopped without a result.
    #[error("cancelled")]
    Cancelled,
}

/// Result alias of the core.
pub type Result<T> = std::result::Result<T, VplaceError>;

/// Returns `Err(NonFinite)` naming the first non-finite value of `values`.
pub fn check_finite(what: &str, values: &[f32]) -> Result<()> {
    match values.iter().position(|v| !v.is_finite()) {
        Some(index) => Err(VplaceError::NonFinite {
            what: what.to_owned(),
            index,
        }),
        None => Ok(()),
    }
}
