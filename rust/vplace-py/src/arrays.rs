//! Checked numpy input: dtype, shape and contiguity, with messages that name the argument.

use numpy::{
    Element, PyArrayDescrMethods, PyArrayDyn, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArray,
    PyUntypedArrayMethods,
};
use pyo3::prelude::*;

use crate::errors::input_error;

/// A dimension of an expected shape: a fixed size, or any size.
#[derive(Clone, Copy)]
pub enum Dim {
    /// Exactly this many.
    Is(usize),
    /// Any number (at least zero).
    Any,
}

fn shape_text(dims: &[Dim]) -> String {
    let parts: Vec<String> = dims
        .iter()
        .map(|d| match d {
            Dim::Is(n) => n.to_string(),
            Dim::Any => "N".to_owned(),
        })
        .collect();
    if parts.len() == 1 {
        format!("({},)", parts[0])
    } else {
        format!("({})", parts.join(", "))
    }
}

/// Extracts a C-contiguous numpy array of `T` named `name` with the given shape.
pub fn array<'py, T: Element>(
    obj: &Bound<'py, PyAny>,
    name: &str,
    dims: &[Dim],
    dtype_name: &str,
) -> PyResult<PyReadonlyArrayDyn<'py, T>> {
    let untyped = obj.cast::<PyUntypedArray>().map_err(|_| {
        input_error(format!(
            "{name} must be a numpy array of {dtype_name} with shape {}, got {}",
            shape_text(dims),
            obj.get_type()
                .name()
                .map(|n| n.to_string())
                .unwrap_or_default()
        ))
    })?;
    let want = numpy::dtype::<T>(obj.py());
    if !untyped.dtype().is_equiv_to(&want) {
        return Err(input_error(format!(
            "{name} must have dtype {dtype_name}, got {} (convert with .astype(numpy.{dtype_name}))",
            untyped.dtype()
        )));
    }
    let shape = untyped.shape();
    let ok = shape.len() == dims.len()
        && shape.iter().zip(dims).all(|(&s, d)| match d {
            Dim::Is(n) => s == *n,
            Dim::Any => true,
        });
    if !ok {
        return Err(input_error(format!(
            "{name} must have shape {}, got {:?}",
            shape_text(dims),
            shape
        )));
    }
    if !untyped.is_c_contiguous() {
        return Err(input_error(format!(
            "{name} must be C-contiguous (use numpy.ascontiguousarray)"
        )));
    }
    let typed = obj
        .cast::<PyArrayDyn<T>>()
        .map_err(|_| input_error(format!("{name}: unexpected array type")))?;
    Ok(typed.readonly())
}

/// The contiguous data of a checked array as a slice.
pub fn slice<'a, T: Element>(a: &'a PyReadonlyArrayDyn<'_, T>, name: &str) -> PyResult<&'a [T]> {
    a.as_slice()
        .map_err(|_| input_error(format!("{name} must be C-contiguous")))
}
