//! The explicit-profile encoder (spec §3, Annex A.8): a trained 3DGS scene (Inria PLY) to a
//! multi-rate stream. The input is validated and put in coding form once
//! ([`PreparedGaussians`]); the quantizers (means, a KLT basis for the higher SH bands,
//! steps per group) are fitted to it, then each rate's layer is coded with its own voxel
//! grid and prior tables.

pub mod curves;
pub mod fit_rates;
pub mod grid;
pub mod input;
pub mod layer;
pub mod plan;
pub mod prepare;
pub mod prior;
pub mod progressive;
mod quantize;
pub mod ratios;
pub mod sample;
pub mod sensitivity;
mod writer;

use half::f16;
use nalgebra::{DMatrix, SymmetricEigen};

pub use fit_rates::{choose_klt, rate_plans, Progress};
pub use layer::{CodedLayer, LayerReport, Variant};
pub use plan::{RatePlan, SizeClasses};
pub use prepare::PreparedGaussians;

use crate::error::{Error, Result};
use crate::writers::write_gqua;
use salvq_bitstream::container::chunk::{write_chunk, ChunkTag};
use salvq_bitstream::container::signature::Signature;
use salvq_bitstream::entropy::GaussianTables;
use salvq_bitstream::explicit::groups::{Group, GroupKind};
use salvq_bitstream::explicit::header::GaussianHeader;
use salvq_bitstream::explicit::Gaussians;

/// Where the rate-distortion curves' trial steps are centred (Annex A.8.2): the voxel edge
/// and each group's step, in scene units, that the trials scale by powers of two.
#[derive(Debug, Clone, PartialEq)]
pub struct TrialSteps {
    /// Voxel edge, in scene units.
    pub position: f64,
    /// Per group present, in Table 3-3 order.
    pub groups: Vec<f64>,
}

impl TrialSteps {
    /// The centres used for every scene: a voxel edge of 2^−12 of the box, and a step in
    /// each group's own units.
    pub fn default_for(p: &PreparedGaussians) -> TrialSteps {
        TrialSteps {
            position: p.extent.max(1e-30) / 4096.0,
            groups: p
                .kinds
                .iter()
                .map(|k| match k {
                    GroupKind::Opacity => 0.2,
                    GroupKind::Scale => 0.1,
                    GroupKind::Rotation => 0.03,
                    GroupKind::Dc => 0.03,
                    GroupKind::Rest => 0.04,
                })
                .collect(),
        }
    }
}

/// How the encoder sets each rate's steps (Annex A.8.2).
#[derive(Debug, Clone, PartialEq)]
pub enum RateControl {
    /// A render-PSNR target (dB, against the input, from the camera ring) per rate, rate 0
    /// first; the steps are fitted by rendering.
    Psnr(Vec<f64>),
    /// The plan of each rate, given.
    Plans(Vec<RatePlan>),
}

impl RateControl {
    /// Rates asked for.
    pub fn rate_count(&self) -> usize {
        match self {
            RateControl::Psnr(t) => t.len(),
            RateControl::Plans(s) => s.len(),
        }
    }
}

/// The reference encoder's default rates: render PSNR targets from near-lossless to a
/// preview (rate 0 is the finest).
pub const DEFAULT_PSNR_TARGETS: [f64; 6] = [62.0, 56.0, 50.0, 45.0, 40.0, 35.0];

/// What the explicit encoder is asked to do.
#[derive(Debug, Clone)]
pub struct ExplicitOptions {
    /// The rates: PSNR targets or fixed plans.
    pub rates: RateControl,
    /// The rates coded (each below M); `None`: all.
    pub coded: Option<Vec<u8>>,
    /// Which groups get a fitted KLT basis (`B = U`, Annex A.8.3): per group in Table 3-3
    /// order; `None`: SH DC and SH rest each when it makes the middle rate's layer, basis
    /// included, smaller.
    pub klt: Option<Vec<bool>>,
    /// Gaussians per tile at most (§10); 0: the reference's automatic tiles
    /// ([`crate::writers::tile_cut::cut_auto`]).
    pub tile_gaussians: u32,
    /// Text for an `encd` chunk (§1.7), written after `GQUA`.
    pub note: Option<String>,
    /// The reference encoder, or a restricted one for ablations (Annex A.8.4).
    pub variant: Variant,
    /// Whether the rates nest (§3.8): the coarsest coded rate a full layer, each finer one
    /// a refinement of the one before; else each rate's layer is coded alone.
    pub progressive: bool,
    /// How hard the rate control searches (Annex A.8.2).
    pub effort: curves::Effort,
}

impl Default for ExplicitOptions {
    fn default() -> Self {
        ExplicitOptions {
            rates: RateControl::Psnr(DEFAULT_PSNR_TARGETS.to_vec()),
            coded: None,
            klt: None,
            tile_gaussians: 0,
            note: None,
            variant: Variant::default(),
            progressive: true,
            effort: curves::Effort::default(),
        }
    }
}

/// An encoded explicit-profile stream.
pub struct EncodedGaussians {
    /// The stream.
    pub stream: Vec<u8>,
    /// Its preflight (§3.2).
    pub header: GaussianHeader,
    /// Its attribute groups (§3.3).
    pub groups: Vec<Group>,
    /// Bytes of GHED and GQUA (framed): the model shared by every layer.
    pub shared_bytes: usize,
    /// Per coded layer: its report, framed bytes, and the Gaussians the decoder outputs.
    pub layers: Vec<(LayerReport, usize, Gaussians)>,
}

impl EncodedGaussians {
    /// Per coded layer (in [`Self::layers`]' order, the stream's): the bytes of the stream a
    /// decoder of that rate reads, signature, shared chunks and `SEND` included: the layer
    /// alone in a layered stream (what `extract` writes), the prefix up to the layer in a
    /// progressive one (§3.8).
    pub fn rate_stream_bytes(&self) -> Vec<usize> {
        let fixed =
            salvq_bitstream::container::signature::SIGNATURE_LEN + self.shared_bytes + SEND_BYTES;
        let mut prefix = 0;
        self.layers
            .iter()
            .map(|(_, bytes, _)| {
                prefix = if self.header.progressive {
                    prefix + bytes
                } else {
                    *bytes
                };
                fixed + prefix
            })
            .collect()
    }
}

/// A framed `SEND` chunk: length, tag and CRC, no payload (§1.5).
const SEND_BYTES: usize = 12;

/// The KLT of a group's values: `U` (row-major, columns the eigenvectors by decreasing
/// eigenvalue, each signed so its largest component is positive), in binary16.
pub fn klt_basis(values: &[f64], d: usize, mean: &[f32]) -> Vec<f16> {
    let n = values.len() / d;
    let mut cov = DMatrix::<f64>::zeros(d, d);
    for row in values.chunks_exact(d) {
        let r: Vec<f64> = (0..d).map(|j| row[j] - f64::from(mean[j])).collect();
        for a in 0..d {
            for b in a..d {
                cov[(a, b)] += r[a] * r[b];
            }
        }
    }
    for a in 0..d {
        for b in 0..a {
            cov[(a, b)] = cov[(b, a)];
        }
    }
    cov /= n.max(1) as f64;
    let eig = SymmetricEigen::new(cov);
    let mut idx: Vec<usize> = (0..d).collect();
    idx.sort_by(|&a, &b| eig.eigenvalues[b].total_cmp(&eig.eigenvalues[a]));
    let mut u = vec![f16::ZERO; d * d];
    for (col, &e) in idx.iter().enumerate() {
        let v = eig.eigenvectors.column(e);
        let big = (0..d).fold(0, |m, i| if v[i].abs() > v[m].abs() { i } else { m });
        let sign = if v[big] < 0.0 { -1.0 } else { 1.0 };
        for i in 0..d {
            u[i * d + col] = f16::from_f64(sign * v[i]);
        }
    }
    u
}

/// The means of group `gi` (§3.3): per value, except the scale group, whose three values
/// share one mean so that its largest coordinate is its largest log-scale (§3.5's size
/// class).
pub fn group_means(p: &PreparedGaussians, gi: usize) -> Vec<f32> {
    let d = p.dim(gi);
    let v = &p.values[gi];
    let n = p.len() as f64;
    if p.kinds[gi] == GroupKind::Scale {
        let m = (v.iter().sum::<f64>() / (n * d as f64)) as f32;
        return vec![m; d];
    }
    (0..d)
        .map(|j| (v.iter().skip(j).step_by(d).sum::<f64>() / n) as f32)
        .collect()
}

/// Group `gi` with its means, unit step and the identity: what the curves measure with.
pub fn measurement_group(p: &PreparedGaussians, gi: usize) -> Group {
    Group {
        kind: p.kinds[gi],
        dim: p.dim(gi),
        step: 1.0,
        gains: vec![1.0],
        mean: group_means(p, gi),
        basis: None,
    }
}

/// The quantizers (§3.3) for `p`: means, the finest rate's steps as base steps, each rate's
/// steps as gains over them, and a KLT basis for each group where `klt` says so.
pub fn fit_groups(p: &PreparedGaussians, plans: &[RatePlan], klt: &[bool]) -> Vec<Group> {
    p.kinds
        .iter()
        .enumerate()
        .map(|(gi, &kind)| {
            let d = p.dim(gi);
            let mean = group_means(p, gi);
            let basis = klt[gi].then(|| (klt_basis(&p.values[gi], d, &mean), vec![f16::ONE; d]));
            let step = plans[0].steps[gi] as f32;
            Group {
                kind,
                dim: d,
                step,
                gains: plans
                    .iter()
                    .map(|s| (s.steps[gi] / f64::from(step)) as f32)
                    .collect(),
                mean,
                basis,
            }
        })
        .collect()
}

/// Encodes `p` (the prepared form of `g`) with each rate's `steps` (Annex A.8).
pub fn encode_prepared(
    p: &PreparedGaussians,
    plans: &[RatePlan],
    options: &ExplicitOptions,
) -> Result<EncodedGaussians> {
    let m = plans.len();
    let classes = SizeClasses::for_variant(p, options.variant);
    let coded = options
        .coded
        .clone()
        .unwrap_or_else(|| (0..m as u8).collect());
    let rate_mask = rate_mask(m, &coded)?;
    let tables = GaussianTables::standard();
    let origin = p.min.map(|v| v as f32);
    let header = GaussianHeader {
        count: p.len() as u32,
        sh_degree: p.sh_degree,
        rate_count: m as u8,
        rate_mask,
        origin,
        progressive: options.progressive,
    };
    let tile_gaussians = options.tile_gaussians;
    let code_layer = |groups: &[Group], r: u8| {
        layer::encode_layer(
            p,
            groups,
            &classes,
            &plans[usize::from(r)],
            origin,
            r,
            tile_gaussians,
            options.variant,
            tables,
        )
    };
    let klt = klt_choice(p, plans, options.klt.as_deref(), &code_layer)?;
    let groups = fit_groups(p, plans, &klt);
    let mut stream = Signature::current().to_bytes().to_vec();
    write_chunk(&mut stream, ChunkTag::GHED, &header.to_payload());
    write_chunk(&mut stream, ChunkTag::GQUA, &write_gqua(&groups));
    if let Some(note) = &options.note {
        write_chunk(&mut stream, ChunkTag::ENCD, note.as_bytes());
    }
    let shared_bytes = stream.len() - salvq_bitstream::container::signature::SIGNATURE_LEN;
    let mut layers = Vec::new();
    let mut state: Option<layer::LayerState> = None;
    for r in header.stream_rates() {
        let l = match &state {
            Some(before) if options.progressive => progressive::encode_refinement(
                p,
                &groups,
                before,
                &plans[usize::from(r)],
                origin,
                r,
                tables,
            )?,
            _ => code_layer(&groups, r)?,
        };
        stream.extend_from_slice(&l.chunks);
        layers.push((l.report, l.chunks.len(), l.expected));
        state = Some(l.state);
    }
    write_chunk(&mut stream, ChunkTag::SEND, &[]);
    Ok(EncodedGaussians {
        stream,
        header,
        groups,
        shared_bytes,
        layers,
    })
}

/// The header's `rate_mask` (§3.2 Table 3-1) of the `coded` rates among `m`, after checking
/// that there are 1 … 64 rates, at least one coded, and each coded rate below `m`.
fn rate_mask(m: usize, coded: &[u8]) -> Result<u64> {
    if m == 0 || m > 64 || coded.is_empty() {
        return Err(Error::FitFailed {
            tensor: "rates",
            reason: format!(
                "1 … 64 rates with at least one coded, not {m} with {} coded",
                coded.len()
            ),
        });
    }
    let mut rate_mask = 0u64;
    for &r in coded {
        if usize::from(r) >= m {
            return Err(salvq::Error::FieldOutOfRange {
                field: salvq_bitstream::error::Field::CodedRate,
                value: r.into(),
                min: 0,
                max: m as u64 - 1,
            }
            .into());
        }
        rate_mask |= 1 << r;
    }
    Ok(rate_mask)
}

/// Which groups get a KLT basis: `given` (one choice per group), or those whose KLT makes the
/// middle rate's layer, coded by `code_layer`, and its basis smaller, so that the choice does
/// not depend on which rates are coded (extraction, §7.5).
fn klt_choice(
    p: &PreparedGaussians,
    plans: &[RatePlan],
    given: Option<&[bool]>,
    code_layer: &dyn Fn(&[Group], u8) -> Result<layer::CodedLayer>,
) -> Result<Vec<bool>> {
    Ok(match given {
        Some(k) if k.len() == p.kinds.len() => k.to_vec(),
        Some(k) => {
            return Err(Error::FitFailed {
                tensor: "klt",
                reason: format!("one choice per group ({}), not {}", p.kinds.len(), k.len()),
            })
        }
        None => {
            choose_klt(p, plans, &|groups: &[Group]| {
                Ok(write_gqua(groups).len()
                    + code_layer(groups, (plans.len() / 2) as u8)?.chunks.len())
            })?
        }
    })
}

/// Encodes the Gaussians `g`: validated and prepared once (Annex A.8.1), steps fitted per
/// rate (A.8.2), then coded (A.8.3). `progress` hears what the encoder is doing and how far
/// it is.
pub fn encode_gaussians(
    g: &Gaussians,
    options: &ExplicitOptions,
    progress: &dyn Fn(Progress<'_>),
) -> Result<EncodedGaussians> {
    let p = PreparedGaussians::new(g)?;
    let (plans, klt) = rate_plans(g, &p, options, progress)?;
    let options = ExplicitOptions {
        klt,
        ..options.clone()
    };
    let total = fit_rates::work_units(&p, &options);
    let coding = fit_rates::coding_units(plans.len());
    let step = format!("coding {} rates", plans.len());
    progress(Progress {
        step: &step,
        done: total - coding,
        total,
    });
    let encoded = encode_prepared(&p, &plans, &options)?;
    progress(Progress {
        step: &step,
        done: total,
        total,
    });
    Ok(encoded)
}
