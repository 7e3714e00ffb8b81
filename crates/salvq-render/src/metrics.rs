//! Image metrics (spec Annex C.5) on RGB values clamped to [0, 1], as the 3DGS and HAC
//! evaluation scripts compute them (`utils/image_utils.py` `psnr`, `utils/loss_utils.py`
//! `ssim`).

use super::Image;
use crate::error::{Error, Result};

/// SSIM's Gaussian window: side and standard deviation (Wang et al. 2004).
pub const SSIM_WINDOW: usize = 11;
/// SSIM's Gaussian window: σ in pixels (Wang et al. 2004).
pub const SSIM_SIGMA: f64 = 1.5;
/// SSIM's stabilising constants `C1 = (K1 L)²`, `C2 = (K2 L)²` with L = 1.
pub const SSIM_K1: f64 = 0.01;
/// SSIM's K2 constant.
pub const SSIM_K2: f64 = 0.03;

fn same_size(a: &Image, b: &Image) -> Result<()> {
    let pixels = |i: &Image| i.width as usize * i.height as usize;
    if a.width != b.width || a.height != b.height {
        return Err(Error::RenderSettingInvalid {
            setting: "image size",
            value: pixels(b) as f64,
            rule: "compared images must have the same width and height",
        });
    }
    if a.rgb.len() != 3 * pixels(a) || b.rgb.len() != 3 * pixels(b) || pixels(a) == 0 {
        return Err(Error::RenderSettingInvalid {
            setting: "image size",
            value: pixels(a) as f64,
            rule: "compared images need pixels, 3 values each",
        });
    }
    Ok(())
}

fn unit(v: f32) -> f64 {
    f64::from(v.clamp(0.0, 1.0))
}

/// Peak signal-to-noise ratio in dB over all pixels and channels, peak 1:
/// `10 log10(1 / MSE)`; `+∞` when the images are identical.
pub fn psnr(a: &Image, b: &Image) -> Result<f64> {
    same_size(a, b)?;
    let mse = a
        .rgb
        .iter()
        .zip(&b.rgb)
        .map(|(&x, &y)| (unit(x) - unit(y)).powi(2))
        .sum::<f64>()
        / a.rgb.len() as f64;
    Ok(if mse == 0.0 {
        f64::INFINITY
    } else {
        -10.0 * mse.log10()
    })
}

/// The normalised 1D Gaussian window.
fn window() -> [f64; SSIM_WINDOW] {
    let half = (SSIM_WINDOW / 2) as f64;
    let mut w: [f64; SSIM_WINDOW] = std::array::from_fn(|i| {
        let x = i as f64 - half;
        (-(x * x) / (2.0 * SSIM_SIGMA * SSIM_SIGMA)).exp()
    });
    let sum: f64 = w.iter().sum();
    w.iter_mut().for_each(|v| *v /= sum);
    w
}

/// Separable Gaussian filter with zero padding, output the input's size (PyTorch `conv2d`
/// with `padding = 5`, as 3DGS's `ssim`).
fn blur(plane: &[f64], width: usize, height: usize, w: &[f64; SSIM_WINDOW]) -> Vec<f64> {
    let half = SSIM_WINDOW / 2;
    let mut rows = vec![0.0; plane.len()];
    for y in 0..height {
        for x in 0..width {
            let mut s = 0.0;
            for (k, wk) in w.iter().enumerate() {
                if let Some(xx) = (x + k).checked_sub(half).filter(|&xx| xx < width) {
                    s += wk * plane[y * width + xx];
                }
            }
            rows[y * width + x] = s;
        }
    }
    let mut out = vec![0.0; plane.len()];
    for y in 0..height {
        for x in 0..width {
            let mut s = 0.0;
            for (k, wk) in w.iter().enumerate() {
                if let Some(yy) = (y + k).checked_sub(half).filter(|&yy| yy < height) {
                    s += wk * rows[yy * width + x];
                }
            }
            out[y * width + x] = s;
        }
    }
    out
}

/// Structural similarity (Wang et al. 2004): 11 × 11 Gaussian window with σ = 1.5,
/// `K1 = 0.01`, `K2 = 0.03`, zero-padded so every pixel has a value (as 3DGS's `ssim`),
/// the map averaged over pixels and then over the three channels. 1 for identical images.
pub fn ssim(a: &Image, b: &Image) -> Result<f64> {
    same_size(a, b)?;
    let (width, height) = (a.width as usize, a.height as usize);
    let w = window();
    let c1 = (SSIM_K1 * 1.0).powi(2);
    let c2 = (SSIM_K2 * 1.0).powi(2);
    let mut total = 0.0;
    for c in 0..3 {
        let plane = |img: &Image| -> Vec<f64> {
            img.rgb
                .iter()
                .skip(c)
                .step_by(3)
                .map(|&v| unit(v))
                .collect()
        };
        let (x, y) = (plane(a), plane(b));
        let product =
            |p: &[f64], q: &[f64]| -> Vec<f64> { p.iter().zip(q).map(|(u, v)| u * v).collect() };
        let mu_x = blur(&x, width, height, &w);
        let mu_y = blur(&y, width, height, &w);
        let xx = blur(&product(&x, &x), width, height, &w);
        let yy = blur(&product(&y, &y), width, height, &w);
        let xy = blur(&product(&x, &y), width, height, &w);
        let mut sum = 0.0;
        for i in 0..width * height {
            let (mx, my) = (mu_x[i], mu_y[i]);
            let (mxx, myy, mxy) = (mx * mx, my * my, mx * my);
            let (sxx, syy, sxy) = (xx[i] - mxx, yy[i] - myy, xy[i] - mxy);
            sum += ((2.0 * mxy + c1) * (2.0 * sxy + c2)) / ((mxx + myy + c1) * (sxx + syy + c2));
        }
        total += sum / (width * height) as f64;
    }
    Ok(total / 3.0)
}
