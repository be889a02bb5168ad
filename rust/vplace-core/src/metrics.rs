//! Error metrics on linear HDR images: RMSE and relative MSE.
//!
//! SSIM (on the display luminance) belongs to the layout issue and lives beside these when added.

use crate::error::{check_finite, Result, VplaceError};

/// The `epsilon` of [`relative_mse`]: keeps dark reference pixels from dominating.
pub const RELATIVE_MSE_EPSILON: f64 = 1e-2;

fn check_pair(image: &[f32], reference: &[f32]) -> Result<()> {
    if image.len() != reference.len() {
        return Err(VplaceError::Shape {
            what: "image".into(),
            expected: format!("{} values, like the reference", reference.len()),
            got: format!("{} values", image.len()),
        });
    }
    if image.is_empty() {
        return Err(VplaceError::Empty {
            what: "image".into(),
            hint: "compare at least one pixel".into(),
        });
    }
    check_finite("image", image)?;
    check_finite("reference", reference)
}

/// Root mean squared error over every value, in the images' own units.
pub fn rmse(image: &[f32], reference: &[f32]) -> Result<f64> {
    check_pair(image, reference)?;
    let sum: f64 = image
        .iter()
        .zip(reference)
        .map(|(&a, &b)| (a as f64 - b as f64).powi(2))
        .sum();
    Ok((sum / image.len() as f64).sqrt())
}

/// Relative MSE: `mean((a - b)^2 / (b^2 + epsilon))` with [`RELATIVE_MSE_EPSILON`].
pub fn relative_mse(image: &[f32], reference: &[f32]) -> Result<f64> {
    check_pair(image, reference)?;
    let sum: f64 = image
        .iter()
        .zip(reference)
        .map(|(&a, &b)| {
            let (a, b) = (a as f64, b as f64);
            (a - b).powi(2) / (b * b + RELATIVE_MSE_EPSILON)
        })
        .sum();
    Ok(sum / image.len() as f64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values_and_errors() {
        assert_eq!(rmse(&[1.0, 2.0], &[1.0, 2.0]).unwrap(), 0.0);
        assert!((rmse(&[0.0, 0.0], &[3.0, 4.0]).unwrap() - 12.5f64.sqrt()).abs() < 1e-12);
        let r = relative_mse(&[2.0], &[1.0]).unwrap();
        assert!((r - 1.0 / 1.01).abs() < 1e-12);
        assert!(rmse(&[1.0], &[1.0, 2.0]).is_err());
        assert!(rmse(&[], &[]).is_err());
        assert!(rmse(&[f32::NAN], &[1.0]).is_err());
    }
}
