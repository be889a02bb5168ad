//! # vplace-core
//!
//! Pure-Rust core of vplace: regression-guided virtual point light (VPL) layout, a VPL
//! evaluator with BVH shadow rays, and analytic 2D direct lighting (PAR).
//!
//! Knows nothing of Python, numpy or Blender. Arrays are flat `f32` slices in row-major
//! `H x W x C` order with row 0 at the top, in Blender world space (Z up, metres).
//! Every entry point checks its input once and returns [`Result`]; a panic is a bug.
//!
//! The pipeline (see `ARCHITECTURE.md` in the repository):
//! 1. [`scene::Scene`]: triangles, per-triangle albedo and the scene's lights, with an obvhs BVH.
//! 2. [`vpl::uniform_vpls`]: Keller's instant radiosity: rays from the lights, first hits become
//!    VPLs carrying `P / n * albedo`.
//! 3. [`evaluator::evaluate`]: the indirect image of a VPL set over a captured G-buffer, every
//!    pixel shaded by the one VPL-to-pixel term of [`shading`] (also used by the refit and the
//!    layout's view efficiency).
//! 4. [`metrics`]: RMSE and relative MSE against a reference, SSIM on the display luminance.
//! 5. [`layout`]: candidate emitters (lit pixels and off-screen light-ray hits), strata (image
//!    cells plus an off-screen stratum), the budget split `N * lerp(u_k, m_k, alpha)` by largest
//!    remainder, flux-proportional draws that keep the total flux; [`refine`]: the iteration that
//!    evaluates the layout, compares it per cell with the indirect image and moves budget toward
//!    high residuals, returning the best layout; [`rsm`]: the reflective-shadow-map baseline.
//! 6. [`refit`]: the optional non-negative least-squares refit of the VPL powers against the
//!    indirect image.
//!
//! Luminance is Rec. 709's everywhere ([`luminance`]). The `test-util` feature exposes
//! `test_util`: the procedural scenes and views of the tests, for benches and examples.
//!
//! ```
//! use vplace_core::{scene::{Scene, Light}, vpl::{uniform_vpls, Profile}};
//! use glam::Vec3;
//! // A unit floor quad lit by a point light 1 m above it.
//! let vertices = [Vec3::new(-1., -1., 0.), Vec3::new(1., -1., 0.), Vec3::new(1., 1., 0.), Vec3::new(-1., 1., 0.)];
//! let triangles = [[0u32, 1, 2], [0, 2, 3]];
//! let scene = Scene::build(&vertices, &triangles, &[0, 0], &[Vec3::splat(0.5)],
//!     vec![Light::point(Vec3::new(0., 0., 1.), Vec3::splat(100.0))]).unwrap();
//! let vpls = uniform_vpls(&scene, 32, 7).unwrap();
//! assert_eq!(vpls.len(), 32);
//! assert!(vpls.iter().all(|v| v.position.z > 0.0 && v.position.z < 1e-2));
//! # let _ = Profile::Cosine;
//! ```

pub mod color;
pub mod direct;
pub mod emitters;
pub mod error;
pub mod evaluator;
pub mod features;
pub mod layout;
pub mod metrics;
pub mod par2d;
pub mod refine;
pub mod refit;
pub mod regression;
pub mod rng;
pub mod rsm;
pub mod scene;
pub mod shading;
mod shadow_cache;
#[cfg(any(test, feature = "test-util"))]
pub mod test_util;
pub mod texture;
pub mod view;
pub mod vpl;

pub use color::{luminance, LUMINANCE};
pub use error::{Result, VplaceError};
