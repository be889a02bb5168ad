//! Colour conventions shared by the whole core: the luminance of linear RGB.
//!
//! The weights are Rec. 709's (those of sRGB and of Blender's linear scene colours), written
//! once here: the layout's flux, the feature label, the refinement's residuals, the light-path
//! Russian roulette and SSIM's display luma all use them.

use glam::Vec3;

/// Rec. 709 luminance weights in `f64`, the one place their digits are written. They sum to 1.
pub const LUMINANCE_F64: [f64; 3] = [0.2126, 0.7152, 0.0722];

/// Rec. 709 luminance weights (`f32`): [`LUMINANCE_F64`] rounded to the nearest `f32`, the
/// same values as the literals `0.2126`, `0.7152`, `0.0722` read as `f32`.
pub const LUMINANCE: Vec3 = Vec3::new(
    LUMINANCE_F64[0] as f32,
    LUMINANCE_F64[1] as f32,
    LUMINANCE_F64[2] as f32,
);

/// The luminance of a linear RGB value: `LUMINANCE . v`, summed in the order R, G, B.
#[inline]
#[must_use]
pub fn luminance(v: Vec3) -> f32 {
    v.dot(LUMINANCE)
}

/// [`luminance`] in `f64` with the [`LUMINANCE_F64`] weights.
#[inline]
#[must_use]
pub fn luminance_f64(v: [f64; 3]) -> f64 {
    LUMINANCE_F64[0] * v[0] + LUMINANCE_F64[1] * v[1] + LUMINANCE_F64[2] * v[2]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn weights_sum_to_one_and_agree() {
        assert!((LUMINANCE_F64.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        for (w, w64) in LUMINANCE.to_array().into_iter().zip(LUMINANCE_F64) {
            assert!((f64::from(w) - w64).abs() < 1e-8);
        }
        assert_eq!(
            luminance(Vec3::ONE),
            LUMINANCE.x + LUMINANCE.y + LUMINANCE.z
        );
        let v = Vec3::new(0.3, 0.9, -2.0);
        assert_eq!(
            luminance(v),
            LUMINANCE.x * v.x + LUMINANCE.y * v.y + LUMINANCE.z * v.z
        );
        assert_eq!(luminance_f64([0.0, 1.0, 0.0]), LUMINANCE_F64[1]);
    }
}
