//! A scene's renders from a camera ring (Annex C.2) or from a capture's cameras, kept to
//! compare other versions of it against (Annex C.5): PSNR of the mean squared error over the
//! views (so views average in MSE, not in dB) and mean SSIM. The encoder's rate fit, the
//! real-scene bench, the R-D bench and `salvq compare` all measure with it.

use std::borrow::Cow;

use super::camera::{Bounds, Camera, Ring};
use super::metrics::{psnr, ssim};
use super::raster::{render, sensitivities, Sensitivities};
use super::{Gaussians, Image};
use crate::error::Result;

/// Reference renders and the cameras they were taken from.
pub struct RingTarget {
    /// The cameras: a ring's ([`RingTarget::around`]) or any ([`RingTarget::from_cameras`]).
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

/// How one view of a scene compares with the reference's view.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ViewScore {
    /// Mean squared error over pixels and channels, peak 1 (0: the images are identical).
    pub mse: f64,
    /// SSIM (1 for identical images).
    pub ssim: f64,
}

impl ViewScore {
    /// PSNR in dB, +∞ for identical images.
    pub fn psnr(&self) -> f64 {
        psnr_of(self.mse)
    }

    /// Over several views: the mean MSE (whose PSNR is the overall PSNR) and the mean SSIM.
    pub fn mean(views: &[ViewScore]) -> ViewScore {
        let n = views.len().max(1) as f64;
        ViewScore {
            mse: views.iter().map(|v| v.mse).sum::<f64>() / n,
            ssim: views.iter().map(|v| v.ssim).sum::<f64>() / n,
        }
    }
}

impl RingTarget {
    /// The reference renders from `cameras`, each of what `scene` gives for it.
    pub fn from_cameras<'a>(
        cameras: Vec<Camera>,
        scene: impl Fn(&Camera) -> Result<Cow<'a, Gaussians>>,
    ) -> Result<RingTarget> {
        let images = cameras
            .iter()
            .map(|c| Ok(render(scene(c)?.as_ref(), c, [0.0; 3])))
            .collect::<Result<Vec<_>>>()?;
        Ok(RingTarget { cameras, images })
    }

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
            .map(|v| ring.camera(bounds, v, width, height).map_err(Into::into))
            .collect::<Result<Vec<_>>>()?;
        RingTarget::from_cameras(cameras, scene)
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

    /// Per camera, how what `scene` gives for it compares with the reference (SSIM 0
    /// unless `with_ssim`).
    pub fn view_scores<'a>(
        &self,
        with_ssim: bool,
        scene: impl Fn(&Camera) -> Result<Cow<'a, Gaussians>>,
    ) -> Result<Vec<ViewScore>> {
        self.cameras
            .iter()
            .zip(&self.images)
            .map(|(c, reference)| {
                let image = render(scene(c)?.as_ref(), c, [0.0; 3]);
                Ok(ViewScore {
                    mse: mse_of(psnr(&image, reference)?),
                    ssim: if with_ssim {
                        ssim(&image, reference)?
                    } else {
                        0.0
                    },
                })
            })
            .collect()
    }

    /// (mean squared error over the views, mean SSIM if `with_ssim`, else 0) of what
    /// `scene` gives for each camera.
    pub fn measure<'a>(
        &self,
        with_ssim: bool,
        scene: impl Fn(&Camera) -> Result<Cow<'a, Gaussians>>,
    ) -> Result<(f64, f64)> {
        let mean = ViewScore::mean(&self.view_scores(with_ssim, scene)?);
        Ok((mean.mse, mean.ssim))
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

    /// [`Sensitivities`] of `g` summed over the cameras and divided by their pixels in all:
    /// so that a change `δ` of Gaussian `i`'s RGB alone moves [`RingTarget::mse`] by about
    /// `colour[i] · |δ|² / 3`.
    pub fn sensitivities(&self, g: &Gaussians) -> Sensitivities {
        let mut sum = Sensitivities::default();
        let mut pixels = 0f64;
        for c in &self.cameras {
            let s = sensitivities(g, c);
            pixels += f64::from(c.width) * f64::from(c.height);
            if sum.colour.is_empty() {
                sum = s;
                continue;
            }
            for (a, b) in [
                (&mut sum.colour, &s.colour),
                (&mut sum.position, &s.position),
                (&mut sum.magnification, &s.magnification),
            ] {
                a.iter_mut().zip(b).for_each(|(x, y)| *x += y);
            }
        }
        let scale = (1.0 / pixels.max(1.0)) as f32;
        for v in [&mut sum.colour, &mut sum.position, &mut sum.magnification] {
            v.iter_mut().for_each(|x| *x *= scale);
        }
        sum
    }
}
