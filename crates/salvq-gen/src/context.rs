//! The context MLP `mlp_grid` (Annex B.4.3): its output layout, and its evaluation at an anchor in
//! f64 from the stored f32 weights. The attributes are drawn around these outputs (B.5).

use super::detmath::{exp, ln};
use salvq_bitstream::model::{Dims, Mlp};

/// mlp_grid layer 0: std * sqrt(fan_in) of the weights (Octree-GS layer 0s measure 0.75-2.8).
pub const CONTEXT_W0_GAIN: f64 = 1.5;
pub const CONTEXT_B0_STD: f64 = 0.3;
/// Feature correlation: singular values of the mixing matrix decay as FEAT_DECAY^i.
pub const FEAT_DECAY: f64 = 0.8;
/// Mean over dimensions of the across-anchor std of mean_feat; per-dimension offsets N(0, 1).
pub const FEAT_MEAN_SPREAD: f64 = 2.0;
pub const FEAT_MEAN_BIAS_STD: f64 = 1.0;
/// sigma_feat = base + spatial part: base ~ U[0.5, 1.0) per dimension, spatial part's median 0.6.
pub const FEAT_SIGMA_BASE: (f64, f64) = (0.5, 1.0);
pub const FEAT_SIGMA_SPATIAL_MEDIAN: f64 = 0.6;
/// Scaling: median of ln(scaling / voxel), log-std of the multiplicative noise, its correlation
/// between the 6 dimensions.
pub const SCALING_LOG_MEDIAN: f64 = -0.3;
pub const SCALING_NOISE_LOG_STD: f64 = 0.8;
pub const SCALING_NOISE_CORR: f64 = 0.6;
/// Right skew of the log-noise (the real distribution's p90 is further from the median than p10).
pub const SCALING_NOISE_SKEW: f64 = 0.15;

/// Multiplicative scaling noise exp(b e + c e^2 - L), e ~ N(0, 1), with
/// L = ln E[exp(b e + c e^2)] = b^2 / (2 (1 - 2c)) - ln(1 - 2c) / 2, so that its mean is 1 and
/// the MLP's mean_scaling is the conditional mean of the scaling. The MLP's scale_scaling is
/// `std_ratio` = sqrt(e^(b^2) - 1) times the mean: the std of the unskewed factor exp(b e - b^2/2).
/// (The skewed factor's own std, sqrt(E[exp(2 b e + 2 c e^2)] e^(-2L) - 1) = 3.2 at b = 0.8,
/// c = 0.15, is set by its rare large values; a Gaussian prior fit to the bulk is what a trained
/// model learns.)
#[derive(Debug, Clone, Copy)]
pub struct ScalingNoise {
    pub b: f64,
    pub c: f64,
    pub log_norm: f64,
    pub std_ratio: f64,
}

impl ScalingNoise {
    pub fn new(b: f64, c: f64) -> Self {
        ScalingNoise {
            b,
            c,
            log_norm: b * b / (2.0 * (1.0 - 2.0 * c)) - 0.5 * ln(1.0 - 2.0 * c),
            std_ratio: (exp(b * b) - 1.0).sqrt(),
        }
    }

    /// The factor for a standard normal e.
    pub fn factor(&self, e: f64) -> f64 {
        exp(self.b * e + self.c * e * e - self.log_norm)
    }
}

/// p90 - p10 of ln(spatial mean): the spread the prior explains (the noise adds the rest).
pub const SCALING_MEAN_LOG_RANGE: f64 = 2.1;
/// Offsets (in units of the anchor's scaling): mean spread and offset, sigma base and spatial part.
pub const OFFSET_MEAN_SPREAD: f64 = 0.4;
pub const OFFSET_MEAN_BIAS_STD: f64 = 0.2;
pub const OFFSET_SIGMA_BASE: (f64, f64) = (0.35, 0.6);
pub const OFFSET_SIGMA_SPATIAL_MEDIAN: f64 = 0.25;
/// Across-anchor std of the three step adjustments q_adj.
pub const QADJ_SPREAD: f64 = 0.2;
/// Anchors used to calibrate the second layer (every (N/P)-th anchor in Morton order).
pub const PROBES: usize = 4096;

/// Output layout of mlp_grid (spec §2.5): [mean_feat F, scale_feat F, mean_scaling S,
/// scale_scaling S, mean_offsets 3K, scale_offsets 3K, q_adj 3].
#[derive(Debug, Clone, Copy)]
pub struct Layout {
    pub f: usize,
    pub s: usize,
    pub k3: usize,
}

impl Layout {
    pub fn new(d: &Dims) -> Self {
        Layout {
            f: d.feat_dim.into(),
            s: d.scaling_dim.into(),
            k3: 3 * usize::from(d.offsets),
        }
    }
    pub fn mean_feat(&self) -> usize {
        0
    }
    pub fn scale_feat(&self) -> usize {
        self.f
    }
    pub fn mean_scaling(&self) -> usize {
        2 * self.f
    }
    pub fn scale_scaling(&self) -> usize {
        2 * self.f + self.s
    }
    pub fn mean_offsets(&self) -> usize {
        2 * self.f + 2 * self.s
    }
    pub fn scale_offsets(&self) -> usize {
        2 * self.f + 2 * self.s + self.k3
    }
    pub fn q_adj(&self) -> usize {
        2 * self.f + 2 * self.s + 2 * self.k3
    }
    /// Context outputs plus one internal row (the mask field, not stored).
    pub fn rows(&self) -> usize {
        self.q_adj() + 4
    }
}

/// The context MLP and what the attribute generator derives from it.
pub struct ContextPlan {
    pub mlp: Mlp,
    pub layout: Layout,
    d_in: usize,
    h: usize,
    /// Layer 0 transposed, `[D_in][H]`, and bias (the stored f32 values, widened).
    w0t: Vec<f64>,
    b0: Vec<f64>,
    /// Layer 1 transposed, `[H][rows]`, and bias; the last row is the mask field.
    w1t: Vec<f64>,
    b1: Vec<f64>,
    /// Feature residual mixing matrix L, F x F row-major, rows of unit norm.
    pub mix: Vec<f64>,
    /// Anchors whose mask field (the last row, standardised over the probes) is below this have
    /// all-zero masks (Annex B.5.3).
    pub dead_below: f64,
    /// The multiplicative scaling noise the scale_scaling rows describe.
    pub noise: ScalingNoise,
}

impl ContextPlan {
    /// Evaluation tables for a stored `mlp` (widened to f64) plus the internal mask-field row.
    pub fn new(
        mlp: Mlp,
        layout: Layout,
        d_in: usize,
        h: usize,
        mask_row: &[f64],
        mask_bias: f64,
    ) -> Self {
        let out = layout.rows() - 1;
        let w0t = (0..d_in)
            .flat_map(|i| (0..h).map(move |o| (o, i)))
            .map(|(o, i)| f64::from(mlp.w0[o * d_in + i]))
            .collect();
        let b0 = mlp.b0.iter().map(|&v| f64::from(v)).collect();
        let w1t = (0..h)
            .flat_map(|j| (0..=out).map(move |i| (i, j)))
            .map(|(i, j)| {
                if i < out {
                    f64::from(mlp.w1[i * h + j])
                } else {
                    mask_row[j]
                }
            })
            .collect();
        let b1 = mlp
            .b1
            .iter()
            .map(|&v| f64::from(v))
            .chain([mask_bias])
            .collect();
        ContextPlan {
            mlp,
            layout,
            d_in,
            h,
            w0t,
            b0,
            w1t,
            b1,
            mix: Vec::new(),
            dead_below: f64::NEG_INFINITY,
            noise: ScalingNoise::new(SCALING_NOISE_LOG_STD, SCALING_NOISE_SKEW),
        }
    }

    /// Hidden activations h = ReLU(W0 x + b0).
    pub fn hidden(&self, x: &[f64], h: &mut [f64]) {
        h.copy_from_slice(&self.b0);
        for (i, &xi) in x.iter().enumerate() {
            let col = &self.w0t[i * self.h..(i + 1) * self.h];
            for (acc, &w) in h.iter_mut().zip(col) {
                *acc += w * xi;
            }
        }
        for v in h.iter_mut() {
            *v = v.max(0.0);
        }
    }

    /// All rows W1 h + b1, summing over the active (non-zero) hidden units in index order.
    pub fn outputs(&self, h: &[f64], out: &mut [f64]) {
        let r = self.layout.rows();
        out.copy_from_slice(&self.b1);
        for (j, &hj) in h.iter().enumerate() {
            if hj != 0.0 {
                let row = &self.w1t[j * r..(j + 1) * r];
                for (acc, &w) in out.iter_mut().zip(row) {
                    *acc += w * hj;
                }
            }
        }
    }

    /// The mask field (the internal last row) at hidden activations `h`.
    pub fn mask_field(&self, h: &[f64]) -> f64 {
        let r = self.layout.rows();
        let mut acc = self.b1[r - 1];
        for (j, &hj) in h.iter().enumerate() {
            if hj != 0.0 {
                acc += self.w1t[j * r + r - 1] * hj;
            }
        }
        acc
    }

    pub fn input_dim(&self) -> usize {
        self.d_in
    }
    pub fn hidden_dim(&self) -> usize {
        self.h
    }
}
