//! The exception hierarchy and the one helper every long call goes through.

use pyo3::create_exception;
use pyo3::exceptions::PyException;
use pyo3::prelude::*;
use std::panic::{catch_unwind, AssertUnwindSafe};
use vplace_core::VplaceError as CoreError;

create_exception!(
    vplace._native,
    VplaceError,
    PyException,
    "Base class of every error raised by vplace."
);
create_exception!(
    vplace._native,
    InputError,
    VplaceError,
    "Bad input: wrong shape or dtype, non-finite values, empty data, out-of-range parameters."
);
create_exception!(
    vplace._native,
    CancelledError,
    VplaceError,
    "The computation was cancelled through its Progress object."
);
create_exception!(
    vplace._native,
    InternalError,
    VplaceError,
    "A bug in vplace (a Rust panic, caught at the boundary). Please report it."
);

/// Maps every core error to a Python exception. Exhaustive on purpose: no catch-all arm.
pub fn to_py(err: CoreError) -> PyErr {
    let msg = err.to_string();
    match err {
        CoreError::Shape { .. }
        | CoreError::NonFinite { .. }
        | CoreError::Empty { .. }
        | CoreError::OutOfRange { .. }
        | CoreError::IndexOutOfBounds { .. }
        | CoreError::Invalid { .. } => InputError::new_err(msg),
        CoreError::Cancelled => CancelledError::new_err(msg),
    }
}

/// Runs `f` with the GIL released and any panic caught and turned into [`InternalError`].
/// Never call Python from inside `f`.
pub fn run<T: Send, F: FnOnce() -> Result<T, CoreError> + Send>(
    py: Python<'_>,
    f: F,
) -> PyResult<T> {
    py.detach(|| match catch_unwind(AssertUnwindSafe(f)) {
        Ok(Ok(v)) => Ok(v),
        Ok(Err(e)) => Err(to_py(e)),
        Err(payload) => {
            let what = payload
                .downcast_ref::<&str>()
                .map(|s| (*s).to_owned())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown panic".to_owned());
            Err(InternalError::new_err(format!(
                "internal error (a bug in vplace): {what}"
            )))
        }
    })
}

/// An [`InputError`] with `msg`.
pub fn input_error(msg: impl Into<String>) -> PyErr {
    InputError::new_err(msg.into())
}

/// Registers the exception classes on the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("VplaceError", py.get_type::<VplaceError>())?;
    m.add("InputError", py.get_type::<InputError>())?;
    m.add("CancelledError", py.get_type::<CancelledError>())?;
    m.add("InternalError", py.get_type::<InternalError>())?;
    Ok(())
}
