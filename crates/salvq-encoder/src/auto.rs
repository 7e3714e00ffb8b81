//! `--auto` (Annex A.5.3): the feature group's quantizer — its kind
//! (identity or a general basis) and its number of spatial regions (Sp-SALVQ, §7.6) — chosen
//! by **total stream bytes at equal distortion**.
//!
//! Candidates cost different model bytes (a general basis stores `2F² + F` binary32 values per
//! region in `QUAN`, 20 KB at F = 50) and give different errors at the same step, so neither
//! bytes nor error alone can rank them. Each candidate's step is scaled until its feature MSE
//! is within [`DISTORTION_TOLERANCE`] of what the model's own quantizer gives at the model's
//! step (the user's operating point); its bytes are read there, and the smallest wins. No
//! format change: the chosen stream simply carries the chosen `QUAN`.

use serde::Serialize;

use crate::error::{Error, Result};
use crate::writers::surgery;
use salvq_bitstream::container::chunk::ChunkTag;
use salvq_bitstream::model::{names, LatticeKind, SceneModel};

use super::parsimony::{feature_mse, subsample};
use super::{encode_full, EncodeOptions};

/// Largest relative difference of feature MSE that counts as equal distortion.
pub const DISTORTION_TOLERANCE: f64 = 0.01;

/// Anchors above which candidates are measured on an evenly spaced sample.
pub const AUTO_SAMPLE: usize = 40_000;

/// Step-matching rounds per candidate (each is one encode).
const MAX_ROUNDS: usize = 6;

/// Fewest sampled anchors per region for a fitted basis (its F×F covariance needs many more
/// anchors than dimensions).
pub const ANCHORS_PER_DIM_AND_REGION: usize = 50;

/// How a candidate codes the feature group.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum FeatureQuantizer {
    /// Uniform scalar quantization (the identity lattice, §7.1).
    Identity,
    /// The model's own lattice (its basis and regions, as trained; or D_n, E8).
    Model,
    /// A basis fitted by the encoder (the KLT, Annex A.5), one per region.
    Fitted {
        /// Regions, each with its own basis.
        regions: u16,
    },
}

impl std::fmt::Display for FeatureQuantizer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            FeatureQuantizer::Identity => write!(f, "identity (USQ)"),
            FeatureQuantizer::Model => write!(f, "model's own lattice"),
            FeatureQuantizer::Fitted { regions: 1 } => write!(f, "fitted basis (KLT)"),
            FeatureQuantizer::Fitted { regions } => {
                write!(f, "fitted bases, {regions} regions (Sp-SALVQ)")
            }
        }
    }
}

impl FeatureQuantizer {
    /// The encoder options that code the feature group this way; every lattice other than
    /// the model's own gets its scales refitted (Annex A.5), as training for it would.
    pub fn options(self, model: &SceneModel, base: &EncodeOptions) -> EncodeOptions {
        let mut o = base.clone();
        let own = model.dims.feat_lattice;
        match self {
            FeatureQuantizer::Identity => {
                o.feat_lattice = Some(LatticeKind::Identity);
                o.fit_basis = false;
                o.fit_scales = own != LatticeKind::Identity;
            }
            FeatureQuantizer::Model => {
                o.feat_lattice = None;
                o.fit_basis = false;
                o.fit_scales = false;
            }
            FeatureQuantizer::Fitted { regions } => {
                o.feat_lattice = None;
                o.fit_basis = true;
                o.feat_regions = regions;
                o.fit_scales = true;
            }
        }
        o
    }
}

/// One candidate, measured at the step that matches the target distortion.
#[derive(Debug, Clone, Serialize)]
pub struct Candidate {
    /// The feature quantizer.
    pub quantizer: FeatureQuantizer,
    /// Factor on the feature step (`quant.feat.step`) that gives the target MSE.
    pub step_factor: f64,
    /// Feature MSE at that factor.
    pub mse: f64,
    /// Stream bytes at the target MSE (interpolated between the two nearest measured steps;
    /// scaled to every anchor when measured on a sample).
    pub bytes: u64,
    /// Of those, model bytes (`HEAD`, `MLPS`, `QUAN`, `GRID`), which a sample does not scale.
    pub model_bytes: u64,
    /// Encodes it took.
    pub encodes: usize,
}

/// What `--auto` measured and chose.
#[derive(Debug, Clone, Serialize)]
pub struct AutoChoice {
    /// Feature MSE of the model's own quantizer at the model's step: the distortion every
    /// candidate is matched to.
    pub target_mse: f64,
    /// Relative tolerance of the distortion match.
    pub tolerance: f64,
    /// Anchors measured on (all when the model has at most [`AUTO_SAMPLE`]).
    pub sample_anchors: usize,
    /// Every candidate measured.
    pub candidates: Vec<Candidate>,
    /// Index into `candidates` of the choice.
    pub chosen: usize,
}

impl AutoChoice {
    /// The candidate chosen.
    pub fn chosen(&self) -> &Candidate {
        &self.candidates[self.chosen]
    }

    /// The model and options to encode with: the chosen quantizer at its matched step.
    pub fn apply(&self, model: &SceneModel, base: &EncodeOptions) -> (SceneModel, EncodeOptions) {
        let c = self.chosen();
        (
            with_step_factor(model, c.step_factor),
            c.quantizer.options(model, base),
        )
    }
}

/// The candidates for `model`: the identity, the model's own lattice when it is another, and fitted
/// bases with 1, 2, 4 and 8 regions while each region keeps
/// 50·F sampled anchors.
pub fn candidates(model: &SceneModel, sample_anchors: usize) -> Vec<FeatureQuantizer> {
    let mut out = vec![FeatureQuantizer::Identity];
    if model.dims.feat_lattice != LatticeKind::Identity {
        out.push(FeatureQuantizer::Model);
    }
    let per_region = ANCHORS_PER_DIM_AND_REGION * usize::from(model.dims.feat_dim).max(1);
    for regions in [1u16, 2, 4, 8] {
        if regions == 1 || sample_anchors / usize::from(regions) >= per_region {
            out.push(FeatureQuantizer::Fitted { regions });
        }
    }
    out
}

/// `model` with its feature step multiplied by `factor` (rounded to binary32).
pub fn with_step_factor(model: &SceneModel, factor: f64) -> SceneModel {
    let mut m = model.clone();
    m.quant_feat.step = (f64::from(m.quant_feat.step) * factor) as f32;
    m
}

/// Measures every candidate and picks the one with the fewest bytes at the model's own
/// feature distortion. `model` need not be in canonical order.
pub fn choose(model: &SceneModel, base: &EncodeOptions) -> Result<AutoChoice> {
    let full = model.to_canonical_order();
    let k = full.n().div_ceil(AUTO_SAMPLE).max(1);
    let sample = if k > 1 {
        subsample(&full, k)
    } else {
        full.clone()
    };
    let scale = full.n() as f64 / sample.n().max(1) as f64;
    // The grid's touched entries depend on every anchor: measure GRID on the full model once.
    let grid_full = if k > 1 { grid_bytes_of(&full) } else { 0 };
    // Rate 0 only: the choice depends on the model alone, whatever rates the stream codes
    // (an extracted rate then equals that rate encoded alone with --auto, §7.5).
    let base = &EncodeOptions {
        rates: vec![0],
        ..base.clone()
    };
    let measure = |q: FeatureQuantizer, factor: f64| -> Result<Point> {
        let m = with_step_factor(&sample, factor);
        let e = encode_full(&m, &q.options(&sample, base))?;
        let mse = feature_mse(&sample, e.expected());
        let (model_bytes, anchor_bytes) = split_bytes(&e.stream)?;
        let (model_bytes, bytes) = if k > 1 {
            let grid_sample = grid_bytes(&e.stream)?;
            let model_full = model_bytes - grid_sample + grid_full;
            (
                model_full,
                model_full + (anchor_bytes as f64 * scale).round() as u64,
            )
        } else {
            (model_bytes, model_bytes + anchor_bytes)
        };
        Ok(Point {
            factor,
            mse,
            bytes,
            model_bytes,
        })
    };
    let own = if sample.dims.feat_lattice == LatticeKind::Identity {
        FeatureQuantizer::Identity
    } else {
        FeatureQuantizer::Model
    };
    let target = measure(own, 1.0)?.mse;
    let mut out = Vec::new();
    for q in candidates(&sample, sample.n()) {
        // A candidate the encoder cannot fit (e.g. a singular region) is skipped, not fatal.
        if let Ok(c) = match_distortion(q, target, &measure) {
            out.push(c);
        }
    }
    // Every candidate failing (the model's own quantizer already encoded once above) leaves
    // nothing to choose: an error, never an empty choice.
    let chosen = (0..out.len())
        .min_by_key(|&i| out[i].bytes)
        .ok_or_else(|| Error::FitFailed {
            tensor: names::QUANT_FEAT[0],
            reason: "--auto: no candidate feature quantizer could be encoded".into(),
        })?;
    Ok(AutoChoice {
        target_mse: target,
        tolerance: DISTORTION_TOLERANCE,
        sample_anchors: sample.n(),
        candidates: out,
        chosen,
    })
}

#[derive(Debug, Clone, Copy)]
struct Point {
    factor: f64,
    mse: f64,
    bytes: u64,
    model_bytes: u64,
}

/// Secant search on `ln mse` against `ln factor` (MSE grows about as the step squared) until
/// the MSE is within the tolerance of `target`; the bytes at `target` are interpolated
/// log-linearly between the two measured points nearest to it.
fn match_distortion(
    q: FeatureQuantizer,
    target: f64,
    measure: &dyn Fn(FeatureQuantizer, f64) -> Result<Point>,
) -> Result<Candidate> {
    let mut points = vec![measure(q, 1.0)?];
    let close = |p: &Point| (p.mse / target - 1.0).abs() <= DISTORTION_TOLERANCE;
    while !close(points.last().expect("one point")) && points.len() < MAX_ROUNDS {
        let last = *points.last().expect("one point");
        let slope = match points.len() {
            1 => 2.0,
            n => {
                let prev = points[n - 2];
                let s = (last.mse.ln() - prev.mse.ln()) / (last.factor.ln() - prev.factor.ln());
                if s.is_finite() {
                    s.clamp(0.5, 4.0)
                } else {
                    2.0
                }
            }
        };
        let step = ((target.ln() - last.mse.ln()) / slope).clamp(-2.0, 2.0);
        points.push(measure(q, last.factor * step.exp())?);
    }
    let encodes = points.len();
    // The final point is the one used; the two nearest to the target give the bytes there.
    let used = *points.last().expect("one point");
    points.sort_by(|a, b| {
        (a.mse.ln() - target.ln())
            .abs()
            .total_cmp(&(b.mse.ln() - target.ln()).abs())
    });
    let bytes = match points.as_slice() {
        [a, b, ..] if (a.mse.ln() - b.mse.ln()).abs() > 1e-12 => {
            let t = (target.ln() - a.mse.ln()) / (b.mse.ln() - a.mse.ln());
            let lb = (a.bytes as f64).ln() + t * ((b.bytes as f64).ln() - (a.bytes as f64).ln());
            lb.exp().round() as u64
        }
        [a, ..] => a.bytes,
        [] => used.bytes,
    };
    Ok(Candidate {
        quantizer: q,
        step_factor: used.factor,
        mse: used.mse,
        bytes,
        model_bytes: used.model_bytes,
        encodes,
    })
}

/// (model bytes, anchor bytes) of a stream: the model chunks `HEAD`, `MLPS`, `QUAN`, `GRID`
/// against everything else, each with its 12 bytes of chunk framing.
fn split_bytes(stream: &[u8]) -> Result<(u64, u64)> {
    let mut model = 0u64;
    let mut rest = 0u64;
    for (tag, payload) in surgery::chunks(stream)? {
        let n = payload.len() as u64 + salvq_bitstream::container::chunk::CHUNK_OVERHEAD;
        if [
            ChunkTag::HEAD,
            ChunkTag::MLPS,
            ChunkTag::QUAN,
            ChunkTag::GRID,
        ]
        .contains(&tag)
        {
            model += n;
        } else {
            rest += n;
        }
    }
    Ok((model, rest))
}

fn grid_bytes(stream: &[u8]) -> Result<u64> {
    Ok(surgery::chunks(stream)?
        .iter()
        .filter(|(t, _)| *t == ChunkTag::GRID)
        .map(|(_, p)| p.len() as u64 + salvq_bitstream::container::chunk::CHUNK_OVERHEAD)
        .sum())
}

/// `GRID` chunk bytes for all of `model`'s anchors (§1.6.1), without encoding them.
fn grid_bytes_of(model: &SceneModel) -> u64 {
    super::parsimony::grid_payload_bytes(model, &model.anchors.voxel)
        + salvq_bitstream::container::chunk::CHUNK_OVERHEAD
}
