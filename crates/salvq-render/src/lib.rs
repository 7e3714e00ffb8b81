//! Renderable output (spec Annex C, informative): standard 3DGS Gaussians, their PLY file,
//! Scaffold-GS neural Gaussians from a decoded scene model, and a CPU preview renderer.
//!
//! | step | Annex C | module |
//! |---|---|---|
//! | scene model → standard Gaussians (Scaffold-GS `generate_neural_gaussians`) | §C.1 | [`neural`] |
//! | the camera ring: reproducible views around a scene's bounds | §C.2 | [`camera`] |
//! | real cameras: the Inria 3DGS `cameras.json`, COLMAP text models | §C.2 | [`camera_file`] |
//! | the Inria 3DGS PLY layout: read and write | §C.3 | [`ply`] |
//! | rasterization as 3DGS's forward pass (Kerbl et al. 2023) | §C.4 | [`raster`], [`sh`] |
//! | PSNR and SSIM | §C.5 | [`metrics`] |
//! | input: a stream, a model file or a PLY file | — | [`scene`] |
//!
//! ```
//! use salvq_gen::{generate, GenParams};
//! use salvq_render::{camera::{Bounds, Ring}, neural, raster};
//! let model = generate(&GenParams { feat_basis: false, ..GenParams::small(200, 1) });
//! let bounds = Bounds::of_points(&neural::anchor_positions(&model));
//! let camera = Ring::default().camera(&bounds, 0, 64, 48)?;
//! let gaussians = neural::neural_gaussians(&model, camera.position)?;
//! let image = raster::render(&gaussians, &camera, [0.0; 3]);
//! assert_eq!(image.rgb.len(), 64 * 48 * 3);
//! # Ok::<(), salvq_render::Error>(())
//! ```

#![warn(missing_docs)]

pub mod camera_file;
pub mod compare;
pub mod error;
pub mod interchange;
pub mod io;
pub mod metrics;
pub mod ply;
pub mod raster;
pub mod scene;
pub mod sh;

pub use error::{Error, Result};
/// Pinhole cameras and the camera ring (Annex C.2): the decoder crate's, which viewers use
/// to place the camera an anchors scene is drawn from.
pub use salvq::camera;
/// Scaffold-GS neural Gaussians (Annex C.1): the decoder crate's, which viewers use too.
pub use salvq::neural;
pub use salvq_bitstream::explicit::{rest_per_channel, Gaussians};

/// An RGB image of binary32 values, row-major from the top-left pixel, 3 values a pixel.
/// Values are what the renderer composited: ≥ 0, and usually but not necessarily ≤ 1.
#[derive(Debug, Clone, PartialEq)]
pub struct Image {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// The pixels, `3·width·height` values.
    pub rgb: Vec<f32>,
}

impl Image {
    /// An image filled with one colour.
    pub fn filled(width: u32, height: u32, colour: [f32; 3]) -> Image {
        let pixels = width as usize * height as usize;
        Image {
            width,
            height,
            rgb: colour.iter().copied().cycle().take(3 * pixels).collect(),
        }
    }

    /// The colour of pixel (x, y).
    pub fn pixel(&self, x: u32, y: u32) -> [f32; 3] {
        let i = 3 * (y as usize * self.width as usize + x as usize);
        [self.rgb[i], self.rgb[i + 1], self.rgb[i + 2]]
    }

    /// 8-bit sRGB-free quantization as 3DGS saves its renders: `round(clamp(v, 0, 1) · 255)`.
    pub fn to_rgb8(&self) -> Vec<u8> {
        self.rgb
            .iter()
            .map(|&v| (v.clamp(0.0, 1.0) * 255.0).round() as u8)
            .collect()
    }

    /// The image as an 8-bit RGB PNG file. Fails on an empty image or one whose buffer does
    /// not hold `width · height` pixels.
    pub fn to_png(&self) -> Result<Vec<u8>> {
        let pixels = self.width as usize * self.height as usize;
        let invalid = |rule| Error::RenderSettingInvalid {
            setting: "image size",
            value: pixels as f64,
            rule,
        };
        if pixels == 0 {
            return Err(invalid("an image needs at least one pixel"));
        }
        if self.rgb.len() != 3 * pixels {
            return Err(invalid("the image buffer must hold 3 values per pixel"));
        }
        let mut out = Vec::new();
        let mut encoder = png::Encoder::new(&mut out, self.width, self.height);
        encoder.set_color(png::ColorType::Rgb);
        encoder.set_depth(png::BitDepth::Eight);
        encoder
            .write_header()
            .and_then(|mut w| w.write_image_data(&self.to_rgb8()))
            .map_err(|_| invalid("the PNG encoder refused the image"))?;
        Ok(out)
    }

    /// Writes the image as a PNG file, atomically (spec §9.2).
    pub fn write_png(&self, path: &std::path::Path) -> Result<()> {
        crate::io::write_bytes_atomic(path, &self.to_png()?)
    }
}
