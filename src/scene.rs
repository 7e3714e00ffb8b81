//! What a stream decodes to: the scene of either profile (§3: the first chunk decides).

use crate::anchors::decode_stream;
use crate::container::chunk::ChunkTag;
use crate::error::{Error, Result};
use crate::explicit::Gaussians;
use crate::gaussians::{decode_explicit, DecodedGaussians};
use crate::model::SceneModel;
use crate::neural::{neural_gaussians, NeuralError};
use crate::options::DecodeOptions;

/// A decoded stream: anchors (§1 – §2) or explicit Gaussians (§3).
///
/// ```
/// let path = concat!(env!("CARGO_MANIFEST_DIR"), "/conformance/vectors/g-sh3-rates.salvq");
/// let stream = std::fs::read(path).expect("a conformance vector");
/// match salvq::decode(&stream)? {
///     salvq::Scene::Gaussians(g) => assert_eq!(g.gaussians.len(), g.header.count as usize),
///     salvq::Scene::Anchors(m) => assert!(m.anchors.voxel.len() > 0),
/// }
/// # Ok::<(), salvq::Error>(())
/// ```
#[derive(Debug, Clone, PartialEq)]
pub enum Scene {
    /// An anchors-profile stream: the Scaffold-GS model, whose neural Gaussians follow from
    /// the camera (Annex C.1).
    Anchors(Box<SceneModel>),
    /// An explicit-Gaussians stream: the Gaussians themselves (§3.6).
    Gaussians(Box<DecodedGaussians>),
}

impl Scene {
    /// The Gaussians to draw from a camera at `camera` (world space): an explicit stream's
    /// own (the camera does not matter), or the neural Gaussians an anchors model gives that
    /// camera (Annex C.1, SH degree 0).
    pub fn to_gaussians(&self, camera: [f32; 3]) -> std::result::Result<Gaussians, NeuralError> {
        match self {
            Scene::Gaussians(g) => Ok(g.gaussians.clone()),
            Scene::Anchors(m) => neural_gaussians(m, camera),
        }
    }

    /// The anchors-profile model, if the stream is of that profile.
    pub fn anchors(&self) -> Option<&SceneModel> {
        match self {
            Scene::Anchors(m) => Some(m),
            Scene::Gaussians(_) => None,
        }
    }

    /// The explicit-profile Gaussians, if the stream is of that profile.
    pub fn gaussians(&self) -> Option<&DecodedGaussians> {
        match self {
            Scene::Gaussians(g) => Some(g),
            Scene::Anchors(_) => None,
        }
    }

    /// [`Self::anchors`], by value.
    pub fn into_anchors(self) -> Option<SceneModel> {
        match self {
            Scene::Anchors(m) => Some(*m),
            Scene::Gaussians(_) => None,
        }
    }

    /// [`Self::gaussians`], by value.
    pub fn into_gaussians(self) -> Option<DecodedGaussians> {
        match self {
            Scene::Gaussians(g) => Some(*g),
            Scene::Anchors(_) => None,
        }
    }

    /// [`Self::into_anchors`], or for an explicit-profile stream the error a decoder of the
    /// anchors profile alone reports: `ChunkOrder`, `GHED` where `HEAD` is due (§3).
    pub fn try_into_anchors(self) -> Result<SceneModel> {
        match self {
            Scene::Anchors(m) => Ok(*m),
            Scene::Gaussians(_) => Err(Error::ChunkOrder {
                found: ChunkTag::GHED,
                expected: ChunkTag::HEAD,
            }),
        }
    }

    /// [`Self::into_gaussians`], or for an anchors-profile stream the error a decoder of the
    /// explicit profile alone reports: `ChunkOrder`, `HEAD` where `GHED` is due (§3.7).
    pub fn try_into_gaussians(self) -> Result<DecodedGaussians> {
        match self {
            Scene::Gaussians(g) => Ok(*g),
            Scene::Anchors(_) => Err(Error::ChunkOrder {
                found: ChunkTag::HEAD,
                expected: ChunkTag::GHED,
            }),
        }
    }
}

/// Decodes a stream of either profile (§1.5, §3.7) with `options` on the caller's pool
/// (region and part apply to both; `fault` to the anchors profile).
pub(crate) fn decode_scene(data: &[u8], options: &DecodeOptions) -> Result<Scene> {
    if crate::container::is_explicit(data) {
        return decode_explicit(data, options).map(|d| Scene::Gaussians(Box::new(d)));
    }
    decode_stream(data, options, false).map(|(m, _)| Scene::Anchors(Box::new(m)))
}
