//! Error metrics: RMSE and relative MSE on linear HDR images, and SSIM (Wang et al. 2004) on
//! the luminance of the display image.

use crate::color::luminance_f64;
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

/// SSIM settings (Wang et al. 2004, as scikit-image's `structural_similarity` with
/// `gaussian_weights=True, use_sample_covariance=False, data_range=1`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SsimParams {
    /// Standard deviation of the Gaussian window, pixels (`> 0`).
    pub sigma: f64,
    /// The window reaches `round(truncate * sigma)` pixels each side (scipy's `truncate`).
    pub truncate: f64,
    /// `K1` of the luminance term.
    pub k1: f64,
    /// `K2` of the contrast-structure term.
    pub k2: f64,
}

impl SsimParams {
    /// Wang 2004: window 11 (sigma 1.5, truncate 3.5), K1 0.01, K2 0.03.
    pub const WANG_2004: Self = Self {
        sigma: 1.5,
        truncate: 3.5,
        k1: 0.01,
        k2: 0.03,
    };

    /// Half width of the window, pixels.
    #[must_use]
    pub fn radius(&self) -> usize {
        (self.truncate * self.sigma + 0.5) as usize
    }
}

impl Default for SsimParams {
    fn default() -> Self {
        Self::WANG_2004
    }
}

/// The sRGB transfer function of a linear value in `[0, 1]`.
#[inline]
#[must_use]
pub fn srgb_encode(v: f64) -> f64 {
    if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

/// The display luminance of a linear RGB image (`H x W x 3`): exposure 1, each channel clamped to
/// `[0, 1]` and sRGB-encoded, then weighted by the Rec. 709 luminance weights
/// ([`luminance_f64`]).
#[must_use]
pub fn display_luminance(image: &[f32]) -> Vec<f64> {
    image
        .chunks_exact(3)
        .map(|c| {
            let e = |v: f32| srgb_encode(f64::from(v).clamp(0.0, 1.0));
            luminance_f64([e(c[0]), e(c[1]), e(c[2])])
        })
        .collect()
}

/// Separable Gaussian filter with scipy's `mode="reflect"` border (`d c b a | a b c d`).
fn gaussian(img: &[f64], w: usize, h: usize, kernel: &[f64]) -> Vec<f64> {
    let r = kernel.len() / 2;
    let reflect = |i: isize, n: usize| -> usize {
        let n = n as isize;
        let period = 2 * n;
        let mut i = i.rem_euclid(period);
        if i >= n {
            i = period - 1 - i;
        }
        i as usize
    };
    let mut tmp = vec![0.0; w * h];
    for y in 0..h {
        for x in 0..w {
            tmp[y * w + x] = kernel
                .iter()
                .enumerate()
                .map(|(k, c)| c * img[y * w + reflect(x as isize + k as isize - r as isize, w)])
                .sum();
        }
    }
    let mut out = vec![0.0; w * h];
    for y in 0..h {
        for x in 0..w {
            out[y * w + x] = kernel
                .iter()
                .enumerate()
                .map(|(k, c)| c * tmp[reflect(y as isize + k as isize - r as isize, h) * w + x])
                .sum();
        }
    }
    out
}

/// Mean SSIM of two single-channel images `x`, `y` (`height x width`, values in `[0, 1]`,
/// `data_range` 1). The SSIM map is averaged over the pixels at least `radius` from the border,
/// as scikit-image does. Both sides must be at least `2 * radius + 1` pixels.
pub fn ssim_gray(
    x: &[f64],
    y: &[f64],
    width: usize,
    height: usize,
    params: &SsimParams,
) -> Result<f64> {
    let n = width * height;
    if x.len() != n || y.len() != n {
        return Err(VplaceError::Shape {
            what: "ssim images".into(),
            expected: format!("{n} values each ({height} x {width})"),
            got: format!("{} and {}", x.len(), y.len()),
        });
    }
    if !(params.sigma > 0.0 && params.sigma.is_finite() && params.truncate >= 0.0) {
        return Err(VplaceError::OutOfRange {
            what: "sigma".into(),
            value: params.sigma.to_string(),
            expected: "> 0 and finite".into(),
        });
    }
    let r = params.radius();
    let win = 2 * r + 1;
    if width < win || height < win {
        return Err(VplaceError::OutOfRange {
            what: "image size".into(),
            value: format!("{height} x {width}"),
            expected: format!("at least {win} x {win} (the SSIM window)"),
        });
    }
    if let Some(index) = x.iter().chain(y).position(|v| !v.is_finite()) {
        return Err(VplaceError::NonFinite {
            what: "ssim images".into(),
            index,
        });
    }
    let mut kernel: Vec<f64> = (0..win)
        .map(|i| {
            let d = i as f64 - r as f64;
            (-0.5 * d * d / (params.sigma * params.sigma)).exp()
        })
        .collect();
    let ks: f64 = kernel.iter().sum();
    kernel.iter_mut().for_each(|k| *k /= ks);
    let prod = |a: &[f64], b: &[f64]| -> Vec<f64> { a.iter().zip(b).map(|(p, q)| p * q).collect() };
    let ux = gaussian(x, width, height, &kernel);
    let uy = gaussian(y, width, height, &kernel);
    let uxx = gaussian(&prod(x, x), width, height, &kernel);
    let uyy = gaussian(&prod(y, y), width, height, &kernel);
    let uxy = gaussian(&prod(x, y), width, height, &kernel);
    let (c1, c2) = (params.k1 * params.k1, params.k2 * params.k2);
    let mut sum = 0.0;
    for yy in r..height - r {
        for xx in r..width - r {
            let i = yy * width + xx;
            let (mx, my) = (ux[i], uy[i]);
            let vx = uxx[i] - mx * mx;
            let vy = uyy[i] - my * my;
            let vxy = uxy[i] - mx * my;
            sum += (2.0 * mx * my + c1) * (2.0 * vxy + c2)
                / ((mx * mx + my * my + c1) * (vx + vy + c2));
        }
    }
    Ok(sum / ((width - 2 * r) * (height - 2 * r)) as f64)
}

/// SSIM of two linear HDR images (`height x width x 3`) on their display luminance
/// ([`display_luminance`]) with [`SsimParams::WANG_2004`] (DESIGN, Metrics).
pub fn ssim(image: &[f32], reference: &[f32], width: usize, height: usize) -> Result<f64> {
    check_pair(image, reference)?;
    if image.len() != 3 * width * height {
        return Err(VplaceError::Shape {
            what: "image".into(),
            expected: format!("({height}, {width}, 3)"),
            got: format!("{} values", image.len()),
        });
    }
    ssim_gray(
        &display_luminance(image),
        &display_luminance(reference),
        width,
        height,
        &SsimParams::WANG_2004,
    )
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

    #[test]
    fn ssim_identity_and_bounds() {
        let (w, h) = (20, 14);
        let a: Vec<f32> = (0..w * h * 3)
            .map(|i| ((i * 37) % 101) as f32 / 100.0)
            .collect();
        assert!((ssim(&a, &a, w, h).unwrap() - 1.0).abs() < 1e-12);
        let b: Vec<f32> = a.iter().map(|v| 1.0 - v).collect();
        let s = ssim(&a, &b, w, h).unwrap();
        assert!((-1.0..0.5).contains(&s), "{s}");
        // Values above 1 clamp: an over-exposed copy of a white image is identical.
        let white = vec![1.0f32; w * h * 3];
        let hot = vec![5.0f32; w * h * 3];
        assert!((ssim(&white, &hot, w, h).unwrap() - 1.0).abs() < 1e-12);
        assert!(ssim(&a[..30], &a[..30], 10, 1).is_err());
        assert!(ssim(&a, &b, w + 1, h).is_err());
        assert!((srgb_encode(1.0) - 1.0).abs() < 1e-12);
        assert!((srgb_encode(0.001) - 0.01292).abs() < 1e-12);
    }

    #[test]
    fn ssim_matches_a_direct_window_sum() {
        // Away from the border the separable filter equals the 2D Gaussian window sum.
        let (w, h) = (13, 11);
        let x: Vec<f64> = (0..w * h).map(|i| ((i * 13) % 17) as f64 / 17.0).collect();
        let y: Vec<f64> = (0..w * h).map(|i| ((i * 7) % 19) as f64 / 19.0).collect();
        let p = SsimParams::WANG_2004;
        let s = ssim_gray(&x, &y, w, h, &p).unwrap();
        let r = 5i32;
        let g = |d: i32| (-0.5 * f64::from(d * d) / 2.25).exp();
        let norm: f64 = (-r..=r).map(g).sum::<f64>().powi(2);
        let mut total = 0.0;
        for cy in 5..h - 5 {
            for cx in 5..w - 5 {
                let mut m = [0.0f64; 5];
                for dy in -r..=r {
                    for dx in -r..=r {
                        let i = (cy as i32 + dy) as usize * w + (cx as i32 + dx) as usize;
                        let wt = g(dx) * g(dy) / norm;
                        let (a, b) = (x[i], y[i]);
                        for (acc, v) in m.iter_mut().zip([a, b, a * a, b * b, a * b]) {
                            *acc += wt * v;
                        }
                    }
                }
                let (c1, c2) = (1e-4, 9e-4);
                let (vx, vy, vxy) = (m[2] - m[0] * m[0], m[3] - m[1] * m[1], m[4] - m[0] * m[1]);
                total += (2.0 * m[0] * m[1] + c1) * (2.0 * vxy + c2)
                    / ((m[0] * m[0] + m[1] * m[1] + c1) * (vx + vy + c2));
            }
        }
        let expect = total / ((w - 10) * (h - 10)) as f64;
        assert!((s - expect).abs() < 1e-12, "{s} {expect}");
    }
}
