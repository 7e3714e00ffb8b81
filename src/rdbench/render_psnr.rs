//! Render-domain accuracy for the R-D bench (issue 11, Annex C.5): a decoded scene is
//! rendered from the same ring cameras as the uncompressed model, and compared by PSNR (of
//! the mean squared error over all views) and SSIM (mean over views). This is what a 3DGS
//! user sees; feature SNR is what the codec controls.

use crate::error::Result;
use crate::model::SceneModel;
use crate::render::camera::{Bounds, Camera, Ring};
use crate::render::metrics::{psnr, ssim};
use crate::render::neural::{anchor_positions, neural_gaussians};
use crate::render::raster::render;
use crate::render::Image;

/// Views of the ring and image size the bench renders (small: the bench codes many points).
pub const VIEWS: u32 = 4;
pub const WIDTH: u32 = 160;
pub const HEIGHT: u32 = 120;

/// The uncompressed model's renders, kept to compare every decoded point against.
pub struct RenderReference {
    cameras: Vec<Camera>,
    images: Vec<Image>,
}

impl RenderReference {
    /// Renders `original` from views 0 … `views − 1` of the default ring around its anchors.
    pub fn new(original: &SceneModel, views: u32, width: u32, height: u32) -> Result<Self> {
        let bounds = Bounds::of_points(&anchor_positions(original));
        let ring = Ring {
            views,
            ..Ring::default()
        };
        let cameras = (0..views)
            .map(|v| ring.camera(&bounds, v, width, height))
            .collect::<Result<Vec<_>>>()?;
        let images = cameras
            .iter()
            .map(|c| {
                Ok(render(
                    &neural_gaussians(original, c.position)?,
                    c,
                    [0.0; 3],
                ))
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(RenderReference { cameras, images })
    }

    /// (PSNR dB, SSIM) of `decoded`'s renders against the reference's; PSNR is `+∞` when
    /// every view is identical.
    pub fn compare(&self, decoded: &SceneModel) -> Result<(f64, f64)> {
        let mut mse = 0.0;
        let mut ssim_sum = 0.0;
        for (camera, reference) in self.cameras.iter().zip(&self.images) {
            let image = render(
                &neural_gaussians(decoded, camera.position)?,
                camera,
                [0.0; 3],
            );
            // PSNR of one view back to its MSE (peak 1), so views average in MSE.
            let p = psnr(&image, reference)?;
            mse += if p.is_infinite() {
                0.0
            } else {
                10f64.powf(-p / 10.0)
            };
            ssim_sum += ssim(&image, reference)?;
        }
        let n = self.images.len().max(1) as f64;
        let mse = mse / n;
        let psnr = if mse == 0.0 {
            f64::INFINITY
        } else {
            -10.0 * mse.log10()
        };
        Ok((psnr, ssim_sum / n))
    }
}
