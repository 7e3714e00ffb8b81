//! Per-anchor attributes (Annex B.5): drawn around the context MLP's own predictions, so the
//! hyperprior really predicts the data. Anchor `a` draws only from stream (seed, ANCHOR, a).

use rayon::prelude::*;

use super::context::{ContextPlan, SCALING_NOISE_CORR};
use super::detmath::sigmoid;
use super::grid::Interp;
use super::linalg::{fsum, round_f32};
use super::rng::{tag, Stream};
use salvq_bitstream::model::{Anchors, Dims, HashGrid};

/// Fraction of anchors with an all-zero mask (the lowest values of the mask field).
pub const DEAD_FRACTION: f64 = 0.01;
/// Per-offset activity q = MASK_FLOOR + (1 - MASK_FLOOR) sigmoid(MASK_SLOPE * field + MASK_SHIFT).
pub const MASK_FLOOR: f64 = 0.15;
pub const MASK_SLOPE: f64 = 2.0;
pub const MASK_SHIFT: f64 = 0.2;

struct Scratch {
    x: Vec<f64>,
    h: Vec<f64>,
    o: Vec<f64>,
    z: Vec<f64>,
}

/// Everything one anchor's generation reads.
pub struct Inputs<'a> {
    pub dims: &'a Dims,
    pub seed: u64,
    pub plan: &'a ContextPlan,
    pub interp: &'a Interp,
    pub grid: &'a HashGrid,
    pub voxels: &'a [[u32; 3]],
}

/// One anchor (Annex B.5). Draw order: F normals (feature), 1 + S normals (scaling),
/// K + 1 uniforms (mask), 3K normals (offsets).
#[allow(clippy::too_many_arguments)]
fn anchor(
    inp: &Inputs,
    a: usize,
    sc: &mut Scratch,
    feat: &mut [f32],
    scaling: &mut [f32],
    mask: &mut [u8],
    offsets: &mut [f32],
) {
    let plan = inp.plan;
    let lay = plan.layout;
    inp.interp.features(inp.grid, inp.voxels[a], &mut sc.x);
    plan.hidden(&sc.x, &mut sc.h);
    plan.outputs(&sc.h, &mut sc.o);
    let o = &sc.o;
    let mut s = Stream::new(inp.seed, tag::ANCHOR, a as u64);
    // B.5.1 feature: mean + sigma * (L z).
    let f = lay.f;
    for z in sc.z.iter_mut() {
        *z = s.normal();
    }
    for (d, out) in feat.iter_mut().enumerate() {
        let row = &plan.mix[d * f..(d + 1) * f];
        let y = fsum(row.iter().zip(&sc.z).map(|(l, z)| l * z));
        *out = round_f32(o[lay.mean_feat() + d] + o[lay.scale_feat() + d] * y);
    }
    // B.5.2 scaling: mean * exp(b e + c e^2 - L), e correlated across dimensions.
    let common = s.normal();
    let (wc, wo) = (SCALING_NOISE_CORR.sqrt(), (1.0 - SCALING_NOISE_CORR).sqrt());
    for (d, out) in scaling.iter_mut().enumerate() {
        let e = wc * common + wo * s.normal();
        *out = round_f32(o[lay.mean_scaling() + d] * plan.noise.factor(e));
    }
    // B.5.3 mask: dead anchors all zero; others Bernoulli(q), at least one offset active.
    let field = o[lay.rows() - 1];
    let q = MASK_FLOOR + (1.0 - MASK_FLOOR) * sigmoid(MASK_SLOPE * field + MASK_SHIFT);
    let dead = field < plan.dead_below;
    for m in mask.iter_mut() {
        let u = s.uniform(); // drawn for dead anchors too: a fixed number of draws per anchor
        *m = u8::from(!dead && u < q);
    }
    let force = s.uniform();
    if !dead && mask.iter().all(|&m| m == 0) {
        let k = ((force * mask.len() as f64) as usize).min(mask.len() - 1);
        mask[k] = 1;
    }
    // B.5.4 offsets: mean + sigma z where the mask is 1, else 0.
    for (i, out) in offsets.iter_mut().enumerate() {
        let z = s.normal();
        *out = if mask[i / 3] == 1 {
            round_f32(o[lay.mean_offsets() + i] + o[lay.scale_offsets() + i] * z)
        } else {
            0.0
        };
    }
}

/// All anchors, in parallel; the result does not depend on the thread count.
pub fn generate(inp: &Inputs) -> Anchors {
    let n = inp.voxels.len();
    let d = inp.dims;
    let (f, s, k) = (
        usize::from(d.feat_dim),
        usize::from(d.scaling_dim),
        usize::from(d.offsets),
    );
    let mut feat = vec![0.0f32; n * f];
    let mut scaling = vec![0.0f32; n * s];
    let mut mask = vec![0u8; n * k];
    let mut offsets = vec![0.0f32; n * 3 * k];
    let new_scratch = || Scratch {
        x: vec![0.0; inp.plan.input_dim()],
        h: vec![0.0; inp.plan.hidden_dim()],
        o: vec![0.0; inp.plan.layout.rows()],
        z: vec![0.0; f],
    };
    feat.par_chunks_mut(f)
        .zip(scaling.par_chunks_mut(s))
        .zip(mask.par_chunks_mut(k))
        .zip(offsets.par_chunks_mut(3 * k))
        .enumerate()
        .with_min_len(256)
        .for_each_init(new_scratch, |sc, (a, (((fe, sca), ma), off))| {
            anchor(inp, a, sc, fe, sca, ma, off);
        });
    Anchors {
        voxel: inp.voxels.to_vec(),
        mask,
        feat,
        scaling,
        offsets,
    }
}
