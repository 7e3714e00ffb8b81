//! A scene's renders from a camera ring (Annex C.2), kept to compare other versions of it
//! against (Annex C.5): PSNR of the mean squared error over the views (so views average in
//! MSE, not in dB) and mean SSIM. The encoder's rate fit, the real-scene bench and the R-D
//! bench all measure with it.

use std::borrow::Cow;

use super::camera::{Bounds, Camera, Ring};
use super::metrics::{psnr, ssim};
use super::raster::render;
use super::{Gaussians, Image};
use crate::error::Result;

/// Reference renders and the cameras they were taken from.
pub struct RingTarget {
    /// The ring's cameras.
    pub cameras: Vec<Camera>,
    /// The reference's image from each.
    pub images: Vec<Image>,
}

/// MSE (peak 1) from a PSNR, 0 for an identical image.
fn mse_of(p: f64) -> f64 {
    if p.is_infinite() {
        0.0
    } else {
        10f64.powf(-p / 10.0)
    }
}

/// PSNR from an MSE, +∞ for 0.
pub fn psnr_of(mse: f64) -> f64 {
    if mse == 0.0 {
        f64::INFINITY
    } else {
        -10.0 * mse.log10()
    }
}

impl RingTarget {
    /// `views` cameras of the default ring around `bounds`, each rendering what `scene`
    /// gives for it (a scene's Gaussians may depend on the camera, Annex C.1).
    pub fn around<'a>(
        bounds: &Bounds,
        views: u32,
        width: u32,
        height: u32,
        scene: impl Fn(&Camera) -> Result<Cow<'a, Gaussians>>,
    ) -> Result<RingTarget> {
        let ring = Ring {
            views,
            ..Ring::default()
        };
        let cameras = (0..views)
            .map(|v| ring.camera(bounds, v, width, height))
            .collect::<Result<Vec<_>>>()?;
        let images = cameras
            .iter()
            .map(|c| Ok(render(scene(c)?.as_ref(), c, [0.0; 3])))
            .collect::<Result<Vec<_>>>()?;
        Ok(RingTarget { cameras, images })
    }

    /// The ring around `g`'s means, rendering `g`.
    pub fn new(g: &Gaussians, views: u32, width: u32, height: u32) -> Result<RingTarget> {
        RingTarget::around(
            &Bounds::of_points(&g.positions),
            views,
            width,
            height,
            |_| Ok(Cow::Borrowed(g)),
        )
    }

    /// (mean squared error over the views, mean SSIM if `with_ssim`, else 0) of what
    /// `scene` gives for each camera.
    pub fn measure<'a>(
        &self,
        with_ssim: bool,
        scene: impl Fn(&Camera) -> Result<Cow<'a, Gaussians>>,
    ) -> Result<(f64, f64)> {
        let (mut mse, mut s) = (0.0, 0.0);
        for (c, reference) in self.cameras.iter().zip(&self.images) {
            let image = render(scene(c)?.as_ref(), c, [0.0; 3]);
            mse += mse_of(psnr(&image, reference)?);
            if with_ssim {
                s += ssim(&image, reference)?;
            }
        }
        let n = self.images.len().max(1) as f64;
        Ok((mse / n, s / n))
    }

    /// Mean squared error of `g` over the views (peak 1).
    pub fn mse(&self, g: &Gaussians) -> Result<f64> {
        Ok(self.measure(false, |_| Ok(Cow::Borrowed(g)))?.0)
    }

    /// PSNR (dB) of `g` against the target.
    pub fn psnr(&self, g: &Gaussians) -> Result<f64> {
        Ok(psnr_of(self.mse(g)?))
    }

    /// (PSNR dB, mean SSIM) of `g` against the target.
    pub fn psnr_ssim(&self, g: &Gaussians) -> Result<(f64, f64)> {
        let (mse, s) = self.measure(true, |_| Ok(Cow::Borrowed(g)))?;
        Ok((psnr_of(mse), s))
    }
}
