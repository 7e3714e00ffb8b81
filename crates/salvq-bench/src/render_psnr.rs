//! Render-domain accuracy for the R-D bench (Annex C.5): a decoded scene is
//! rendered from the same ring cameras as the uncompressed model, and compared by PSNR (of
//! the mean squared error over all views) and SSIM (mean over views). This is what a 3DGS
//! user sees; feature SNR is what the codec controls.

use std::borrow::Cow;

use salvq_bitstream::model::SceneModel;
use salvq_encoder::Result;
use salvq_render::camera::Bounds;
use salvq_render::compare::{psnr_of, RingTarget};
use salvq_render::neural::{anchor_positions, neural_gaussians};

/// Views of the ring and image size the bench renders (small: the bench codes many points).
pub const VIEWS: u32 = 4;
pub const WIDTH: u32 = 160;
pub const HEIGHT: u32 = 120;

/// The uncompressed model's renders, kept to compare every decoded point against.
pub struct RenderReference {
    target: RingTarget,
}

impl RenderReference {
    /// Renders `original` from views 0 … `views − 1` of the default ring around its anchors.
    pub fn new(original: &SceneModel, views: u32, width: u32, height: u32) -> Result<Self> {
        let bounds = Bounds::of_points(&anchor_positions(original));
        let target = RingTarget::around(&bounds, views, width, height, |c| {
            Ok(Cow::Owned(neural_gaussians(original, c.position)?))
        })?;
        Ok(RenderReference { target })
    }

    /// (PSNR dB, SSIM) of `decoded`'s renders against the reference's; PSNR is `+∞` when
    /// every view is identical.
    pub fn compare(&self, decoded: &SceneModel) -> Result<(f64, f64)> {
        let (mse, s) = self.target.measure(true, |c| {
            Ok(Cow::Owned(neural_gaussians(decoded, c.position)?))
        })?;
        Ok((psnr_of(mse), s))
    }
}
