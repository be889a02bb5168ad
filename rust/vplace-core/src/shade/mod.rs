//! Shading: the one VPL-to-pixel term ([`shading`]), the evaluator that sums it over a view
//! with shadow rays ([`evaluator`]), the short-range light gathered from the view's pixels
//! ([`near_field`]), the shadow-ray cache of the layout iterations
//! (`shadow_cache`) and the direct-light estimator of the scene's own lights ([`direct`]).

pub mod direct;
pub mod evaluator;
pub mod near_field;
pub mod shading;
pub(crate) mod shadow_cache;
