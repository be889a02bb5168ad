//! Error metrics: RMSE and relative MSE on linear HDR images, and SSIM (Wang et al. 2004) on
//! the luminance of the display image.

use crate::color::luminance_f64;
use crate::error::{check_finite, Result, VplaceError};

/// The `epsilon` of [`relative_mse`]: keeps dark reference pixels from dominating.
pub const RELATIVE_MSE_EPSILON: f64 = 1e-2;

fn check_pair(image: &[f32], reference: &[f32]) -> Result<()> {
    check_named("image", image, "reference", reference)
}

/// [`check_pair`] with the two images' names, as the caller calls them.
fn check_named(what: &str, image: &[f32], like: &str, reference: &[f32]) -> Result<()> {
    if image.len() != reference.len() {
        return Err(VplaceError::Shape {
            what: what.into(),
            expected: format!("{} values, like the {like}", reference.len()),
            got: format!("{} values", image.len()),
        });
    }
    if image.is_empty() {
        return Err(VplaceError::Empty {
            what: what.into(),
            hint: "compare at least one pixel".into(),
        });
    }
    check_finite(what, image)?;
    check_finite(like, reference)
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

/// RMSE against the noise-free image of which `truth` and `other` are two independent renders
/// (two seeds), without that image: the square root of `mean((image - truth) (image_other -
/// other))`, clamped at 0. The truths' noises are independent of each other, so their cross
/// term averages out and the mean is the squared error against the noise-free image.
/// `image_other` is `image` where the image is independent of both renders (EEVEE, Cycles
/// with its own seed); where it is built on a render's passes (the evaluator's image holds the
/// truth's direct light), `image_other` is the same image built on `other`'s passes.
pub fn rmse_noise_free(
    image: &[f32],
    truth: &[f32],
    image_other: &[f32],
    other: &[f32],
) -> Result<f64> {
    check_named("image", image, "truth", truth)?;
    check_named("image_other", image_other, "truth", truth)?;
    check_named("other", other, "truth", truth)?;
    let sum: f64 = image
        .iter()
        .zip(truth)
        .zip(image_other.iter().zip(other))
        .map(|((&x, &a), (&y, &b))| (f64::from(x) - f64::from(a)) * (f64::from(y) - f64::from(b)))
        .sum();
    Ok((sum / image.len() as f64).max(0.0).sqrt())
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

/// The Gaussian window of `params` for a `width x height` image: its normalized 1D kernel and
/// half width, once the settings and the size are checked.
fn window(params: &SsimParams, width: usize, height: usize) -> Result<(Vec<f64>, usize)> {
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
    let mut kernel: Vec<f64> = (0..win)
        .map(|i| {
            let d = i as f64 - r as f64;
            (-0.5 * d * d / (params.sigma * params.sigma)).exp()
        })
        .collect();
    let ks: f64 = kernel.iter().sum();
    kernel.iter_mut().for_each(|k| *k /= ks);
    Ok((kernel, r))
}

/// Checks that every one of `images` holds `width * height` finite values.
fn check_gray(images: &[&[f64]], width: usize, height: usize) -> Result<()> {
    let n = width * height;
    if let Some(bad) = images.iter().find(|x| x.len() != n) {
        return Err(VplaceError::Shape {
            what: "ssim images".into(),
            expected: format!("{n} values each ({height} x {width})"),
            got: format!("{} values", bad.len()),
        });
    }
    for x in images {
        if let Some(index) = x.iter().position(|v| !v.is_finite()) {
            return Err(VplaceError::NonFinite {
                what: "ssim images".into(),
                index,
            });
        }
    }
    Ok(())
}

/// The SSIM windows over checked gray images: Gaussian window means, and SSIM's formula averaged
/// over the pixels at least the window's half width from the border (scikit-image's crop).
struct Windows {
    kernel: Vec<f64>,
    r: usize,
    width: usize,
    height: usize,
    c1: f64,
    c2: f64,
}

impl Windows {
    /// Checks `images` (each `width * height` finite values) and the settings.
    fn new(images: &[&[f64]], width: usize, height: usize, params: &SsimParams) -> Result<Self> {
        check_gray(images, width, height)?;
        let (kernel, r) = window(params, width, height)?;
        let (c1, c2) = (params.k1 * params.k1, params.k2 * params.k2);
        Ok(Self {
            kernel,
            r,
            width,
            height,
            c1,
            c2,
        })
    }

    /// Every window's weighted mean of `img`.
    fn mean(&self, img: &[f64]) -> Vec<f64> {
        gaussian(img, self.width, self.height, &self.kernel)
    }

    /// Mean SSIM from each window's `[mean x, mean y, var x, var y, cov xy]`.
    fn ssim(&self, stats: impl Fn(usize) -> [f64; 5]) -> f64 {
        let (w, h, r) = (self.width, self.height, self.r);
        let mut sum = 0.0;
        for yy in r..h - r {
            for xx in r..w - r {
                let [mx, my, vx, vy, vxy] = stats(yy * w + xx);
                sum += (2.0 * mx * my + self.c1) * (2.0 * vxy + self.c2)
                    / ((mx * mx + my * my + self.c1) * (vx + vy + self.c2));
            }
        }
        sum / ((w - 2 * r) * (h - 2 * r)) as f64
    }
}

fn product(a: &[f64], b: &[f64]) -> Vec<f64> {
    a.iter().zip(b).map(|(p, q)| p * q).collect()
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
    let w = Windows::new(&[x, y], width, height, params)?;
    let (ux, uy) = (w.mean(x), w.mean(y));
    let (uxx, uyy, uxy) = (
        w.mean(&product(x, x)),
        w.mean(&product(y, y)),
        w.mean(&product(x, y)),
    );
    Ok(w.ssim(|i| {
        let (mx, my) = (ux[i], uy[i]);
        [mx, my, uxx[i] - mx * mx, uyy[i] - my * my, uxy[i] - mx * my]
    }))
}

/// Mean SSIM of `x` against the noise-free image of which `a` and `b` are two independent noisy
/// renders (two seeds of one path tracer), estimated without that image: each window's
/// statistics of the noise-free image come from products *across* the two renders, whose noise
/// averages out. Its mean is `sqrt(mean(a) mean(b))`, its covariance with `x` that of `x` with
/// `(a + b) / 2`, and its variance `cov(a, b)` (clamped at 0). With `a == b` it is [`ssim_gray`]
/// of `x` against `a`. Noise that `x` shares with one render (an image built on its passes)
/// counts half as signal.
///
/// It reads low where the renders are noisy on flat surfaces: there the noise-free image's
/// variance is about 0, SSIM's contrast-structure term divides by it plus `C2`, and the
/// clamped estimate of it is noise, at least 0, so every image loses alike. Measured with a
/// known clean image and a real truth's noise (`docs/noise_free/simulate.py`, a sky-lit room at
/// 192x108): a noise-free image reads .997-.998 where the two renders agree at SSIM .84-.86
/// (the noise of 2048 spp), .977-.980 at .62-.64 and .943 on a view lit by bounce light alone
/// at .47 (512 spp), and .84-.91 at .30-.40; an image with an error reads low by about as much.
/// Less noisy renders are the remedy (a clamp-free or thresholded variance trades the error for
/// a larger one of either sign).
pub fn ssim_gray_noise_free(
    x: &[f64],
    a: &[f64],
    b: &[f64],
    width: usize,
    height: usize,
    params: &SsimParams,
) -> Result<f64> {
    let w = Windows::new(&[x, a, b], width, height, params)?;
    let (ux, ua, ub) = (w.mean(x), w.mean(a), w.mean(b));
    let mean_ab: Vec<f64> = a.iter().zip(b).map(|(p, q)| 0.5 * (p + q)).collect();
    let (uxx, uab) = (w.mean(&product(x, x)), w.mean(&product(a, b)));
    let uxt = w.mean(&product(x, &mean_ab));
    Ok(w.ssim(|i| {
        let mx = ux[i];
        let vxt = uxt[i] - mx * 0.5 * (ua[i] + ub[i]);
        let vt = (uab[i] - ua[i] * ub[i]).max(0.0);
        let mt = (ua[i] * ub[i]).max(0.0).sqrt();
        [mx, mt, uxx[i] - mx * mx, vt, vxt]
    }))
}

/// Mean SSIM that the noise-free image would score against the noisy render `a`, estimated
/// from `b`, an independent render of the same image: the ceiling that `a`'s noise puts on
/// any image scored against it. The noise-free image's mean is estimated by
/// `sqrt(mean(a) mean(b))`, its variance and its covariance with `a` by `cov(a, b)`, clamped to
/// `[0, var(a)]` (Cauchy-Schwarz). 1 when `a == b`.
pub fn ssim_gray_ceiling(
    a: &[f64],
    b: &[f64],
    width: usize,
    height: usize,
    params: &SsimParams,
) -> Result<f64> {
    let w = Windows::new(&[a, b], width, height, params)?;
    let (ua, ub) = (w.mean(a), w.mean(b));
    let (uaa, uab) = (w.mean(&product(a, a)), w.mean(&product(a, b)));
    Ok(w.ssim(|i| {
        let ma = ua[i];
        let va = uaa[i] - ma * ma;
        // Cauchy-Schwarz: cov(s, a)^2 <= var(s) var(a) with cov(s, a) = var(s).
        let vs = (uab[i] - ua[i] * ub[i]).clamp(0.0, va.max(0.0));
        let ms = (ua[i] * ub[i]).max(0.0).sqrt();
        [ms, ma, vs, va, vs]
    }))
}

/// SSIM of two linear HDR images (`height x width x 3`) on their display luminance
/// ([`display_luminance`]) with [`SsimParams::WANG_2004`] (DESIGN, Metrics).
pub fn ssim(image: &[f32], reference: &[f32], width: usize, height: usize) -> Result<f64> {
    check_pair(image, reference)?;
    check_rgb("image", image, width, height)?;
    ssim_gray(
        &display_luminance(image),
        &display_luminance(reference),
        width,
        height,
        &SsimParams::WANG_2004,
    )
}

/// Checks an `H x W x 3` image of `width * height` pixels.
fn check_rgb(what: &str, image: &[f32], width: usize, height: usize) -> Result<()> {
    if image.len() != 3 * width * height {
        return Err(VplaceError::Shape {
            what: what.into(),
            expected: format!("({height}, {width}, 3)"),
            got: format!("{} values", image.len()),
        });
    }
    Ok(())
}

/// [`ssim_gray_noise_free`] of the linear HDR `image` against the noise-free image of which
/// `truth` and `other` are two independent renders (`height x width x 3` each), on their
/// display luminance with [`SsimParams::WANG_2004`].
pub fn ssim_noise_free(
    image: &[f32],
    truth: &[f32],
    other: &[f32],
    width: usize,
    height: usize,
) -> Result<f64> {
    check_named("image", image, "truth", truth)?;
    check_named("other", other, "truth", truth)?;
    check_rgb("image", image, width, height)?;
    ssim_gray_noise_free(
        &display_luminance(image),
        &display_luminance(truth),
        &display_luminance(other),
        width,
        height,
        &SsimParams::WANG_2004,
    )
}

/// [`ssim_gray_ceiling`] of the linear HDR render `truth` (`other`: an independent render of
/// the same image), on their display luminance with [`SsimParams::WANG_2004`].
pub fn ssim_ceiling(truth: &[f32], other: &[f32], width: usize, height: usize) -> Result<f64> {
    check_named("other", other, "truth", truth)?;
    check_rgb("truth", truth, width, height)?;
    ssim_gray_ceiling(
        &display_luminance(truth),
        &display_luminance(other),
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
    fn noise_free_rmse_takes_the_truths_noise_out() {
        let (w, h) = (64, 48);
        let (clean, a, b) = noisy_pair(w, h, 0.05);
        let f = |v: &[f64]| v.iter().map(|&x| x as f32).collect::<Vec<f32>>();
        let (clean, a, b) = (f(&clean), f(&a), f(&b));
        let x: Vec<f32> = clean.iter().map(|v| v * 1.1).collect();
        let exact = rmse(&x, &clean).unwrap();
        let plain = rmse(&x, &a).unwrap();
        let free = rmse_noise_free(&x, &a, &x, &b).unwrap();
        assert!(plain > 1.2 * exact, "{plain} {exact}");
        assert!((free - exact).abs() < 0.1 * exact, "{free} {exact}");
        // The truth itself scores about 0 against the noise-free image; never NaN.
        assert!(rmse_noise_free(&a, &a, &b, &b).unwrap() < 0.2 * exact);
        assert!(rmse_noise_free(&x, &a, &x, &b[1..]).is_err());
        let mut nan = b.clone();
        nan[3] = f32::NAN;
        assert!(rmse_noise_free(&x, &a, &x, &nan).is_err());
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

    /// A textured gray image in `[0.1, 0.9]`, and two independent noisy renders of it
    /// (uniform noise of standard deviation `sigma`, from a fixed LCG).
    fn noisy_pair(w: usize, h: usize, sigma: f64) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        let clean: Vec<f64> = (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f64, (i / w) as f64);
                0.5 + 0.25 * (x / 5.0).sin() * (y / 7.0).cos() + 0.15 * ((i % w) / 16 % 2) as f64
            })
            .collect();
        let mut state = 12_345u64;
        let mut noise = || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1);
            ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * sigma * 12f64.sqrt()
        };
        let a = clean.iter().map(|v| v + noise()).collect();
        let b = clean.iter().map(|v| v + noise()).collect();
        (clean, a, b)
    }

    #[test]
    fn noise_free_ssim_sees_through_the_truths_noise() {
        let (w, h) = (96, 64);
        let p = SsimParams::WANG_2004;
        let (clean, a, b) = noisy_pair(w, h, 0.04);
        // An image a little off the clean one: what a good estimate looks like.
        let x: Vec<f64> = clean.iter().map(|v| 0.95 * v + 0.02).collect();
        let exact = ssim_gray(&x, &clean, w, h, &p).unwrap();
        let plain = ssim_gray(&x, &a, w, h, &p).unwrap();
        let free = ssim_gray_noise_free(&x, &a, &b, w, h, &p).unwrap();
        assert!(
            exact - plain > 0.2,
            "the noise costs plain SSIM: {exact} {plain}"
        );
        assert!((free - exact).abs() < 0.01, "{free} {exact}");
        // A blurred, darker image: the estimate follows the exact score down.
        let mut blur = vec![0.0; w * h];
        for (i, v) in blur.iter_mut().enumerate() {
            let (cx, cy) = (i % w, i / w);
            let mut acc = (0.0, 0.0);
            for y in cy.saturating_sub(1)..(cy + 2).min(h) {
                for x in cx.saturating_sub(1)..(cx + 2).min(w) {
                    acc = (acc.0 + clean[y * w + x], acc.1 + 1.0);
                }
            }
            *v = 0.9 * acc.0 / acc.1 + 0.03;
        }
        let exact_blur = ssim_gray(&blur, &clean, w, h, &p).unwrap();
        let free_blur = ssim_gray_noise_free(&blur, &a, &b, w, h, &p).unwrap();
        assert!(exact - exact_blur > 0.03, "{exact} {exact_blur}");
        assert!(
            (free_blur - exact_blur).abs() < 0.01,
            "{free_blur} {exact_blur}"
        );
        // The ceiling: what the clean image itself scores against the noisy render.
        let ceiling = ssim_gray_ceiling(&a, &b, w, h, &p).unwrap();
        let truly = ssim_gray(&clean, &a, w, h, &p).unwrap();
        assert!((ceiling - truly).abs() < 0.02, "{ceiling} {truly}");
        assert!(ceiling < 0.9, "{ceiling}");
        assert!(
            ssim_gray(&a, &b, w, h, &p).unwrap() > 0.6,
            "moderate noise, as documented"
        );
        // One render twice: plain SSIM, and a ceiling of 1.
        let same = ssim_gray_noise_free(&x, &a, &a, w, h, &p).unwrap();
        assert!((same - plain).abs() < 1e-12, "{same} {plain}");
        assert!((ssim_gray_ceiling(&a, &a, w, h, &p).unwrap() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn noise_free_ssim_checks_its_input() {
        let (w, h) = (20, 14);
        let img: Vec<f32> = (0..w * h * 3).map(|i| (i % 7) as f32 / 7.0).collect();
        let mut nan = img.clone();
        nan[5] = f32::NAN;
        assert!(ssim_noise_free(&img, &img, &img, w, h).is_ok());
        assert!(ssim_noise_free(&img, &img, &img[3..], w, h).is_err());
        assert!(ssim_noise_free(&img, &img, &nan, w, h).is_err());
        assert!(ssim_noise_free(&img, &img, &img, w + 1, h).is_err());
        assert!(ssim_ceiling(&img, &nan, w, h).is_err());
        assert!(ssim_ceiling(&img[..30], &img[..30], 10, 1).is_err());
        let gray = vec![0.5; w * h];
        assert!(
            ssim_gray_noise_free(&gray, &gray, &gray[1..], w, h, &SsimParams::WANG_2004).is_err()
        );
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
