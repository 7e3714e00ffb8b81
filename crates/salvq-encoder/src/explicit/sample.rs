//! A spatial sample of a large scene (Annex A.8.2): runs of Gaussians neighbouring in the
//! canonical (Morton) order, evenly spread over it, so that what the rate control counts on
//! it (bits per Gaussian, render error per unit of predicted error, which colour groups a
//! KLT shrinks) costs the same at a million Gaussians as at sixty thousand, and keeps the
//! local density the octree and the attribute contexts see.

use super::grid::grid;
use super::prepare::PreparedGaussians;
use super::TrialSteps;
use salvq_bitstream::explicit::Gaussians;

/// Gaussians in a sample at most (about: whole runs are taken).
pub const SAMPLE_GAUSSIANS: usize = 1 << 16;

/// Gaussians in one run of the sample: a few of the tiles §10 cuts.
const RUN: usize = 2048;

/// A scene's sample: which Gaussians (ascending input indices) and their two forms.
pub struct Sample {
    /// Input indices of the sampled Gaussians, ascending.
    pub indices: Vec<usize>,
    /// Their prepared form (the box, `min` and `extent`, of the whole scene, so that grids
    /// at a step have the whole scene's voxels).
    pub prepared: PreparedGaussians,
    /// Their input form.
    pub gaussians: Gaussians,
}

/// The sample of `g` (prepared as `p`) with at most about `max` Gaussians, or `None` when
/// the scene is no larger: then the rate control measures on all of it.
pub fn spatial_sample(g: &Gaussians, p: &PreparedGaussians, max: usize) -> Option<Sample> {
    let n = p.len();
    if n <= max {
        return None;
    }
    let every = n.div_ceil(max.max(RUN)).max(2);
    let reference = grid(
        p,
        p.min.map(|v| v as f32),
        TrialSteps::default_for(p).position,
    );
    let mut indices: Vec<usize> = reference
        .order
        .chunks(RUN)
        .step_by(every)
        .flatten()
        .copied()
        .collect();
    indices.sort_unstable();
    Some(Sample {
        prepared: p.subset(&indices),
        gaussians: subset(g, &indices),
        indices,
    })
}

/// The Gaussians of `g` at `indices`, in that order.
pub fn subset(g: &Gaussians, indices: &[usize]) -> Gaussians {
    let b = 3 * g.rest_per_channel();
    let mut out = Gaussians::with_capacity(g.sh_degree, indices.len());
    for &i in indices {
        out.positions.push(g.positions[i]);
        out.f_dc.push(g.f_dc[i]);
        out.f_rest.extend_from_slice(&g.f_rest[i * b..(i + 1) * b]);
        out.opacity_logit.push(g.opacity_logit[i]);
        out.log_scales.push(g.log_scales[i]);
        out.rotations.push(g.rotations[i]);
    }
    out
}
