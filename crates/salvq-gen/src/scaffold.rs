//! Scaffold-GS decoding MLPs (Annex B.6), calibrated from trained Octree-GS MLPs
//! (tools/calibration.json `mlps`, measured with F = 32, V = 3, hidden 32).

use super::linalg::round_f32;
use super::rng::{tag, Stream};
use salvq_bitstream::model::{Dims, Mlp};

/// Measured statistics of one Scaffold-GS MLP.
pub struct MlpStats {
    /// Layer 0: weight mean, std of the feature columns and of the view columns, bias mean and std.
    pub w0_mean: f64,
    pub w0_feat_std: f64,
    pub w0_view_std: f64,
    pub b0: (f64, f64),
    /// Layer 1: weight mean, std * sqrt(fan_in), bias mean and std.
    pub w1_mean: f64,
    pub w1_gain: f64,
    pub b1: (f64, f64),
}

/// Feature columns measured with 32 feature inputs; rescaled by sqrt(32 / F).
pub const MEASURED_FEAT_DIM: f64 = 32.0;

pub const OPACITY: MlpStats = MlpStats {
    w0_mean: -0.003_969_35,
    w0_feat_std: 0.071_749,
    w0_view_std: 0.359_374,
    b0: (-0.113_998, 0.176_813),
    w1_mean: -0.031_691_1,
    w1_gain: 1.016_76,
    b1: (-0.014_507_3, 0.149_009),
};
pub const COV: MlpStats = MlpStats {
    w0_mean: -0.043_715_7,
    w0_feat_std: 0.243_979,
    w0_view_std: 1.363_5,
    b0: (-0.633_366, 0.748_435),
    w1_mean: -0.016_202_4,
    w1_gain: 3.971_31,
    b1: (-0.029_388_1, 0.628_674),
};
pub const COLOR: MlpStats = MlpStats {
    w0_mean: -0.003_170_63,
    w0_feat_std: 0.163_861,
    w0_view_std: 0.347_959,
    b0: (-0.269_574, 0.546_139),
    w1_mean: -0.018_373_8,
    w1_gain: 1.667_7,
    b1: (-0.200_491, 0.263_415),
};

/// One MLP with `out` outputs from stream SCAFFOLD_MLP/index: W0 row by row (F feature columns,
/// then V view columns), b0, W1 row by row, b1, every value mean + std * normal.
pub fn mlp(d: &Dims, seed: u64, index: u64, st: &MlpStats, out: usize) -> Mlp {
    let mut s = Stream::new(seed, tag::SCAFFOLD_MLP, index);
    let (f, v, h) = (
        usize::from(d.feat_dim),
        usize::from(d.view_dims),
        usize::from(d.scaffold_hidden),
    );
    let feat_std = st.w0_feat_std * (MEASURED_FEAT_DIM / f as f64).sqrt();
    let mut w0 = Vec::with_capacity(h * (f + v));
    for _ in 0..h {
        for _ in 0..f {
            w0.push(round_f32(st.w0_mean + feat_std * s.normal()));
        }
        for _ in 0..v {
            w0.push(round_f32(st.w0_mean + st.w0_view_std * s.normal()));
        }
    }
    let b0 = (0..h)
        .map(|_| round_f32(st.b0.0 + st.b0.1 * s.normal()))
        .collect();
    let std1 = st.w1_gain / (h as f64).sqrt();
    let w1 = (0..out * h)
        .map(|_| round_f32(st.w1_mean + std1 * s.normal()))
        .collect();
    let b1 = (0..out)
        .map(|_| round_f32(st.b1.0 + st.b1.1 * s.normal()))
        .collect();
    Mlp { w0, b0, w1, b1 }
}
