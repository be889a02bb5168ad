//! `vplace._native`: the pyo3 binding of `vplace-core`.
//!
//! Thin on purpose: numpy <-> core conversion with exact messages, the GIL released around
//! long calls, panics caught and turned into `vplace.InternalError`, core errors mapped
//! exhaustively (see `errors.rs`). No algorithms live here.

use pyo3::prelude::*;

mod arrays;
mod direct;
mod errors;
mod fit;
mod layout;
mod materials;
mod par2d;
mod params;
mod refit;
mod scene;
mod view;
mod vpls;

#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    errors::register(m)?;
    params::register(m)?;
    scene::register(m)?;
    materials::register(m)?;
    view::register(m)?;
    vpls::register(m)?;
    fit::register(m)?;
    layout::register(m)?;
    par2d::register(m)?;
    direct::register(m)?;
    refit::register(m)?;
    Ok(())
}
