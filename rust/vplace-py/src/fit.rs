//! Placeholder: filled by its issue.

use pyo3::prelude::*;

/// Registers this file's classes and functions.
pub fn register(_m: &Bound<'_, PyModule>) -> PyResult<()> {
    Ok(())
}
