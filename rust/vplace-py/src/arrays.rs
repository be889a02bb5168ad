//! Checked numpy input: dtype, shape and contiguity, with messages that name the argument.

use numpy::{
    Element, PyArrayDescrMethods, PyArrayDyn, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArray,
    PyUntypedArrayMethods,
};
use pyo3::prelude::*;
use vplace_core::evaluator::GBuffer;

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

/// The four arrays every G-buffer call takes, checked against each other: `position`
/// (H, W, 3) float32 fixes H and W; `normal`, `albedo` (H, W, 3) float32; `covered` (H, W) bool.
pub struct GBufferArrays<'py> {
    /// Image height, pixels.
    pub height: usize,
    /// Image width, pixels.
    pub width: usize,
    position: PyReadonlyArrayDyn<'py, f32>,
    normal: PyReadonlyArrayDyn<'py, f32>,
    albedo: PyReadonlyArrayDyn<'py, f32>,
    covered: PyReadonlyArrayDyn<'py, bool>,
}

impl<'py> GBufferArrays<'py> {
    /// Reads and checks the four arrays.
    pub fn read(
        position: &Bound<'py, PyAny>,
        normal: &Bound<'py, PyAny>,
        albedo: &Bound<'py, PyAny>,
        covered: &Bound<'py, PyAny>,
    ) -> PyResult<Self> {
        let pos = array::<f32>(
            position,
            "position",
            &[Dim::Any, Dim::Any, Dim::Is(3)],
            "float32",
        )?;
        let (height, width) = (pos.shape()[0], pos.shape()[1]);
        let img3 = [Dim::Is(height), Dim::Is(width), Dim::Is(3)];
        Ok(Self {
            height,
            width,
            normal: array::<f32>(normal, "normal", &img3, "float32")?,
            albedo: array::<f32>(albedo, "albedo", &img3, "float32")?,
            covered: array::<bool>(
                covered,
                "covered",
                &[Dim::Is(height), Dim::Is(width)],
                "bool",
            )?,
            position: pos,
        })
    }

    /// The expected shape of a further (H, W, 3) image.
    pub fn img3(&self) -> [Dim; 3] {
        [Dim::Is(self.height), Dim::Is(self.width), Dim::Is(3)]
    }

    /// The expected shape of a further (H, W) image.
    pub fn img1(&self) -> [Dim; 2] {
        [Dim::Is(self.height), Dim::Is(self.width)]
    }

    /// The core's view of the arrays.
    pub fn gbuffer(&self) -> PyResult<GBuffer<'_>> {
        Ok(GBuffer {
            width: self.width,
            height: self.height,
            position: slice(&self.position, "position")?,
            normal: slice(&self.normal, "normal")?,
            albedo: slice(&self.albedo, "albedo")?,
            covered: slice(&self.covered, "covered")?,
        })
    }
}
