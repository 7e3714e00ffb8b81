//! What the renderer and the PLY export take as input: a scene model (from a SALVQ stream or
//! a safetensors model file) or a set of standard Gaussians (from a 3DGS PLY file).

use std::borrow::Cow;

use super::camera::Bounds;
use super::{neural, ply, Gaussians};
use crate::error::{Error, Result};
use salvq_bitstream::container::signature::MAGIC;
use salvq_bitstream::model::SceneModel;

/// A renderable scene.
#[derive(Debug, Clone)]
pub enum Scene {
    /// A Scaffold-GS scene model: its Gaussians depend on the camera (Annex C.1).
    Model(Box<SceneModel>),
    /// Standard 3DGS Gaussians.
    Gaussians {
        /// The Gaussians.
        gaussians: Gaussians,
        /// The bounds a PLY file exported from a scene model records for its camera ring
        /// (Annex C.3): the model's anchors', so that the PLY's views are the model's.
        ring_bounds: Option<Bounds>,
    },
}

impl Scene {
    /// Reads a scene by its content: a SALVQ stream (decoded at `rate`, default the lowest
    /// coded rate), a PLY file (`ply` first), else a safetensors model (spec Annex A).
    /// `rate` applies to streams only.
    pub fn from_bytes(bytes: &[u8], rate: Option<u8>) -> Result<Scene> {
        let stream = bytes.starts_with(&MAGIC);
        if rate.is_some() && !stream {
            return Err(Error::RenderSettingInvalid {
                setting: "rate",
                value: f64::from(rate.unwrap_or(0)),
                rule: "a rate can be chosen only for a SALVQ stream",
            });
        }
        if stream {
            let options = salvq::Decoder::builder()
                .limits(salvq::Limits::desktop())
                .rate(rate);
            return Ok(match options.build().decode(bytes)? {
                salvq::Scene::Anchors(m) => Scene::Model(m),
                // An explicit-profile stream decodes to the Gaussians themselves (§3).
                salvq::Scene::Gaussians(d) => Scene::Gaussians {
                    gaussians: d.gaussians,
                    ring_bounds: None,
                },
            });
        }
        if bytes.starts_with(b"ply") {
            return Ok(Scene::Gaussians {
                gaussians: ply::read_ply(bytes)?,
                ring_bounds: ply::recorded_ring_bounds(bytes)?,
            });
        }
        Ok(Scene::Model(Box::new(
            crate::interchange::model_from_safetensors(bytes)?,
        )))
    }

    /// The bounds the camera ring is placed around (Annex C.2 step 1): of the anchor
    /// positions for a model; for Gaussians, those their PLY file records, else of the means.
    pub fn bounds(&self) -> Bounds {
        match self {
            Scene::Model(m) => Bounds::of_points(&neural::anchor_positions(m)),
            Scene::Gaussians {
                ring_bounds: Some(b),
                ..
            } => *b,
            Scene::Gaussians { gaussians, .. } => Bounds::of_points(&gaussians.positions),
        }
    }

    /// The Gaussians seen from a camera at `camera`: the neural Gaussians of a model, or
    /// the Gaussians themselves.
    pub fn gaussians(&self, camera: [f32; 3]) -> Result<Cow<'_, Gaussians>> {
        match self {
            Scene::Model(m) => Ok(Cow::Owned(neural::neural_gaussians(m, camera)?)),
            Scene::Gaussians { gaussians, .. } => Ok(Cow::Borrowed(gaussians)),
        }
    }
}
