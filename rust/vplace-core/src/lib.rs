//! # vplace-core
//!
//! Pure-Rust core of vplace: regression-guided virtual point light (VPL) layout, a VPL
//! evaluator with BVH shadow rays, and analytic 2D direct lighting (PAR).
//!
//! Knows nothing of Python, numpy or Blender. Arrays are flat `f32` slices in row-major
//! `H x W x C` order with row 0 at the top, in Blender world space (Z up, metres).
//! Every entry point checks its input once and returns [`Result`]; a panic is a bug.
//!
//! The pipeline, one module per stage (see `ARCHITECTURE.md` in the repository). A stage imports
//! only the foundations ([`error`], [`color`], [`rng`], [`progress`]) and the stages before it,
//! never one after it:
//! 1. [`scene`]: [`scene::Scene`], triangles, materials ([`scene::texture`]) and the scene's
//!    lights, with an obvhs BVH; [`scene::emitters`] samples every light source (lights, the
//!    world, emissive triangles) by power.
//! 2. [`view`]: one captured [`view::View`] (G-buffer, lighting passes, camera), checked once, and
//!    [`view::GBuffer`], the borrowed per-pixel contract the later stages read.
//! 3. [`vpl`]: [`vpl::Vpl`], [`vpl::Profile`] and Keller's instant radiosity
//!    ([`vpl::uniform_vpls`]): light paths from every emitter, a VPL at each surface hit.
//! 4. [`shade`]: the one VPL-to-pixel term ([`shade::shading`]); [`shade::evaluator::evaluate`],
//!    the indirect image of a VPL set over a G-buffer with shadow rays (also used by the refit
//!    and the layout's view efficiency); [`shade::direct`], the direct light of the scene's own
//!    emitters.
//! 5. [`fit`]: per-cell features and label of views ([`fit::features`]) and the least-squares
//!    model with feature selection ([`fit::regression`]).
//! 6. [`layout`]: candidate emitters (lit pixels and off-screen light-ray hits), strata (image
//!    cells plus off-screen strata), the budget split `N * lerp(u_k, m_k, alpha)` by largest
//!    remainder, flux-proportional draws that keep the total flux; [`layout::iterate`]: the
//!    iteration that evaluates the layout, compares it per cell with the indirect image and
//!    moves budget toward high residuals, returning the best layout; [`layout::refit`]: the
//!    optional non-negative least-squares refit of the VPL powers; [`layout::rsm`]: the
//!    reflective-shadow-map baseline.
//!
//! Beside the pipeline: [`metrics`] (RMSE and relative MSE against a reference, SSIM on the
//! display luminance) and [`par2d`] (analytic 2D direct lighting).
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

// Foundations: no stage imported.
pub mod color;
pub mod error;
pub mod progress;
pub mod rng;

// The stages, each importing only those above it.
pub mod fit;
pub mod layout;
pub mod scene;
pub mod shade;
pub mod view;
pub mod vpl;

// Beside the pipeline.
pub mod metrics;
pub mod par2d;
#[cfg(any(test, feature = "test-util"))]
pub mod test_util;

pub use color::{luminance, LUMINANCE};
pub use error::{Result, VplaceError};
pub use progress::Progress;
