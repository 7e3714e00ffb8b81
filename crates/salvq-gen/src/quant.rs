//! Quantizers (Annex B.7): HAC base steps, per-rate gains, random SALVQ bases.

use super::detmath::{exp, ln};
use super::linalg::{orthogonal, round_f32};
use super::rng::{tag, Stream};
use salvq_bitstream::model::{Basis, GroupQuantizer};

/// HAC's base steps: features 1, offsets 0.2 (in units of the anchor's scaling).
pub const STEP_FEAT: f32 = 1.0;
pub const STEP_OFFSETS: f32 = 0.2;
/// The scaling step in voxels: HAC's absolute 0.001 is about a tenth of its scenes' scalings
/// (which are ~0.74 voxel, calibration); a step relative to the voxel keeps that ratio, and
/// so about 7 steps per predicted sigma, at every scene size.
pub const STEP_SCALING_PER_VOXEL: f64 = 0.1;
/// g_0 = 1, g_i = g_(i-1) * GAIN_RATIO * (1 + U[-GAIN_JITTER, GAIN_JITTER)).
pub const GAIN_RATIO: f64 = 1.5;
pub const GAIN_JITTER: f64 = 0.05;
/// Condition number max(S) / min(S) of a basis: U[2, 5).
pub const BASIS_CONDITION: (f64, f64) = (2.0, 5.0);

/// Group `index` (0 feat, 1 scaling, 2 offsets) of dimension `dim` from stream QUANT/index:
/// M - 1 gain jitters, then (with a basis) the condition number, U's normals, V's normals.
pub fn group(
    seed: u64,
    index: u64,
    step: f32,
    rates: u8,
    dim: usize,
    basis: bool,
) -> GroupQuantizer {
    let mut s = Stream::new(seed, tag::QUANT, index);
    let mut gains = Vec::with_capacity(rates.into());
    let mut g = 1.0f64;
    for i in 0..rates {
        if i > 0 {
            g *= GAIN_RATIO * (1.0 + s.range(-GAIN_JITTER, GAIN_JITTER));
        }
        gains.push(round_f32(g));
    }
    let basis = basis.then(|| {
        let lc = ln(s.range(BASIS_CONDITION.0, BASIS_CONDITION.1));
        // S_i = cond^(1/2 - i/(n-1)): descending, geometric mean 1, max/min = cond.
        let sv = (0..dim)
            .map(|i| {
                let t = if dim > 1 {
                    i as f64 / (dim - 1) as f64
                } else {
                    0.5
                };
                round_f32(exp(lc * (0.5 - t)))
            })
            .collect();
        let u = orthogonal(&mut s, dim).into_iter().map(round_f32).collect();
        let v = orthogonal(&mut s, dim).into_iter().map(round_f32).collect();
        Basis { u, s: sv, v }
    });
    GroupQuantizer {
        step,
        gains,
        basis,
        regions: Vec::new(),
    }
}
