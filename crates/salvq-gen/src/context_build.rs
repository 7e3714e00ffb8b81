//! Construction of the context MLP (Annex B.4.3). Layer 0 is random; each block of layer 1 is a
//! random structure scaled and offset so that, over probe anchors, its outputs have the target
//! statistics (context.rs constants). Stream CONTEXT_MLP/i for part i, in this order.

use rayon::prelude::*;

use super::attributes::DEAD_FRACTION;
use super::context::*;
use super::detmath::{exp, ln};
use super::linalg::{fsum, orthogonal, round_f32};
use super::rng::{tag, Stream};
use salvq_bitstream::model::{Dims, Mlp};

fn gaussian(s: &mut Stream, n: usize, std: f64) -> Vec<f64> {
    (0..n).map(|_| s.normal() * std).collect()
}

/// `rows` x H non-negative sparse rows: each row gets `own` taps |N(0,1)| * w at uniformly chosen
/// hidden units, then every row gets the same `shared` taps |N(0,1)|.
fn taps(s: &mut Stream, rows: usize, h: usize, own: usize, w: f64, shared: usize) -> Vec<f64> {
    let mut out = vec![0.0; rows * h];
    for r in 0..rows {
        for _ in 0..own {
            let j = s.below(h as u64) as usize;
            out[r * h + j] += s.normal().abs() * w;
        }
    }
    let mut common = vec![0.0; h];
    for _ in 0..shared {
        let j = s.below(h as u64) as usize;
        common[j] += s.normal().abs();
    }
    for r in out.chunks_mut(h) {
        for (a, b) in r.iter_mut().zip(&common) {
            *a += b;
        }
    }
    out
}

/// Values of each row (R x H) at each probe: probe-major.
fn probe_values(rows: &[f64], hs: &[Vec<f64>], h: usize) -> Vec<Vec<f64>> {
    hs.iter()
        .map(|hv| {
            rows.chunks(h)
                .map(|r| fsum(r.iter().zip(hv).map(|(a, b)| a * b)))
                .collect()
        })
        .collect()
}

/// Mean of each row over the probes, and the root of the mean over rows of their variances.
fn spread(vals: &[Vec<f64>]) -> (Vec<f64>, f64) {
    let n = vals.len().max(1) as f64;
    let r = vals.first().map_or(0, |v| v.len());
    let mean: Vec<f64> = (0..r)
        .map(|i| fsum(vals.iter().map(|v| v[i])) / n)
        .collect();
    let var =
        fsum((0..r).map(|i| fsum(vals.iter().map(|v| (v[i] - mean[i]) * (v[i] - mean[i]))) / n));
    (mean, (var / r.max(1) as f64).sqrt())
}

/// Element at quantile q (index floor((len - 1) q)) of the values, sorted by `total_cmp`.
fn quantile(mut v: Vec<f64>, q: f64) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(f64::total_cmp);
    v[((v.len() - 1) as f64 * q) as usize]
}

/// The c > 0 with ln((p90 + c) / (p10 + c)) = `range` for non-negative values (bisection on
/// ln c, 64 steps); 1 if p90 <= p10.
fn scaling_floor(vals: &[f64], range: f64) -> f64 {
    let (p10, p90) = (quantile(vals.to_vec(), 0.1), quantile(vals.to_vec(), 0.9));
    if p90 <= p10 || p90 <= 0.0 {
        return 1.0;
    }
    let (mut lo, mut hi) = (ln(p90) - 40.0, ln(p90) + 40.0);
    for _ in 0..64 {
        let mid = 0.5 * (lo + hi);
        let c = exp(mid);
        if ln((p90 + c) / (p10 + c)) > range {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    exp(0.5 * (lo + hi))
}

/// `target / value`, or 0 when the value is ~0 (every probe inactive: the block becomes constant).
fn ratio(target: f64, value: f64) -> f64 {
    if value > 1e-12 {
        target / value
    } else {
        0.0
    }
}

/// Layer 1 under construction, f64, row-major `[rows][H]`.
struct Layer1 {
    w: Vec<f64>,
    b: Vec<f64>,
    h: usize,
}

impl Layer1 {
    /// Rows `first..` = gain * `rows`, biases from `bias(row)`.
    fn set(&mut self, first: usize, rows: &[f64], gain: f64, bias: impl FnMut(usize) -> f64) {
        let mut bias = bias;
        for (r, row) in rows.chunks(self.h).enumerate() {
            for (dst, &v) in self.w[(first + r) * self.h..].iter_mut().zip(row) {
                *dst = gain * v;
            }
            self.b[first + r] = bias(r);
        }
    }
}

/// Builds mlp_grid and its evaluation plan. `features(a, x)` writes anchor a's context features.
pub fn context_plan(
    d: &Dims,
    seed: u64,
    voxel: f64,
    n: usize,
    feat_decay: f64,
    features: impl Fn(usize, &mut [f64]) + Sync,
) -> ContextPlan {
    let lay = Layout::new(d);
    let (d_in, h) = (d.context_input() as usize, usize::from(d.context_hidden));
    let out_dim = d.context_output() as usize;
    let mut mlp = layer0(d, seed);
    // Hidden activations at the probes: anchors floor(i N / P), i < P = min(N, PROBES).
    let layer0 = ContextPlan::new(mlp.clone(), lay, d_in, h, &vec![0.0; h], 0.0);
    let p = n.clamp(1, PROBES);
    let hs: Vec<Vec<f64>> = (0..p)
        .into_par_iter()
        .map(|i| {
            let mut x = vec![0.0; d_in];
            features(i * n / p, &mut x);
            let mut hv = vec![0.0; h];
            layer0.hidden(&x, &mut hv);
            hv
        })
        .collect();
    let mut l1 = Layer1 {
        w: vec![0.0; (out_dim + 1) * h],
        b: vec![0.0; out_dim + 1],
        h,
    };
    let mix = l1.feature_mean(&lay, seed, &hs, feat_decay);
    l1.feature_scale(&lay, seed, &hs);
    let noise = l1.scaling(&lay, seed, &hs, voxel);
    l1.offsets(&lay, seed, &hs);
    l1.q_adj_and_mask(&lay, seed, &hs);

    // Store layer 1 in f32; the attributes are drawn from exactly the stored values.
    mlp.w1 = l1.w[..out_dim * h].iter().map(|&v| round_f32(v)).collect();
    mlp.b1 = l1.b[..out_dim].iter().map(|&v| round_f32(v)).collect();
    let mut plan = ContextPlan::new(mlp, lay, d_in, h, &l1.w[out_dim * h..], l1.b[out_dim]);
    plan.mix = mix;
    plan.noise = noise;
    // Dead anchors: the mask field below its DEAD_FRACTION quantile over the probes.
    let field: Vec<f64> = hs.iter().map(|hv| plan.mask_field(hv)).collect();
    plan.dead_below = quantile(field, DEAD_FRACTION);
    plan
}

/// Part 0, layer 0: W0 row by row, then b0; layer 1 zero. Column gain by level: 3D level l:
/// 1 / (1 + l/4); 2D level l (any plane): 0.5 / (1 + l/2). Coarse levels dominate: smooth
/// fields.
fn layer0(d: &Dims, seed: u64) -> Mlp {
    let (d_in, h) = (d.context_input() as usize, usize::from(d.context_hidden));
    let out_dim = d.context_output() as usize;
    let mut s = Stream::new(seed, tag::CONTEXT_MLP, 0);
    let (l3, c) = (d.res_3d.len(), usize::from(d.grid_channels));
    let l2 = d.res_2d.len().max(1);
    let col_gain = |i: usize| {
        let lv = i / c;
        if lv < l3 {
            1.0 / (1.0 + 0.25 * lv as f64)
        } else {
            0.5 / (1.0 + 0.5 * ((lv - l3) % l2) as f64)
        }
    };
    let std0 = CONTEXT_W0_GAIN / (d_in as f64).sqrt();
    let w0: Vec<f32> = (0..h * d_in)
        .map(|k| round_f32(s.normal() * std0 * col_gain(k % d_in)))
        .collect();
    let b0: Vec<f32> = (0..h)
        .map(|_| round_f32(s.normal() * CONTEXT_B0_STD))
        .collect();
    Mlp {
        w0,
        b0,
        w1: vec![0.0; out_dim * h],
        b1: vec![0.0; out_dim],
    }
}

/// Layer 1's parts, each from its own stream and scaled to its statistics over the probes'
/// hidden activations `hs`.
impl Layer1 {
    /// Part 1, feature mean: Q (F x F normals, Householder), G (F x H normals), beta (F
    /// normals). rows = Q diag(feat_decay^i) G, scaled to FEAT_MEAN_SPREAD, centred on beta *
    /// FEAT_MEAN_BIAS_STD. Returns the residual mixing L = Q diag(sv) with rows normalised:
    /// (L L^T)_dd = 1.
    fn feature_mean(
        &mut self,
        lay: &Layout,
        seed: u64,
        hs: &[Vec<f64>],
        feat_decay: f64,
    ) -> Vec<f64> {
        let (f, h) = (lay.f, self.h);
        let mut s = Stream::new(seed, tag::CONTEXT_MLP, 1);
        let q = orthogonal(&mut s, f);
        let mut sv = vec![1.0; f];
        for i in 1..f {
            sv[i] = sv[i - 1] * feat_decay;
        }
        let g = gaussian(&mut s, f * h, 1.0);
        let mut rows = vec![0.0; f * h];
        for a in 0..f {
            for b in 0..f {
                let qs = q[a * f + b] * sv[b];
                for j in 0..h {
                    rows[a * h + j] += qs * g[b * h + j];
                }
            }
        }
        let beta = gaussian(&mut s, f, FEAT_MEAN_BIAS_STD);
        let (m, sp) = spread(&probe_values(&rows, hs, h));
        let gain = ratio(FEAT_MEAN_SPREAD, sp);
        self.set(lay.mean_feat(), &rows, gain, |a| beta[a] - gain * m[a]);
        let mut mix = vec![0.0; f * f];
        for a in 0..f {
            let norm = fsum((0..f).map(|b| q[a * f + b] * sv[b] * q[a * f + b] * sv[b])).sqrt();
            for b in 0..f {
                mix[a * f + b] = q[a * f + b] * sv[b] / norm;
            }
        }
        mix
    }

    /// Part 2, feature scale: taps (6 own, 6 shared) scaled to median
    /// FEAT_SIGMA_SPATIAL_MEDIAN, then F biases U[FEAT_SIGMA_BASE).
    fn feature_scale(&mut self, lay: &Layout, seed: u64, hs: &[Vec<f64>]) {
        let h = self.h;
        let mut s = Stream::new(seed, tag::CONTEXT_MLP, 2);
        let rows = taps(&mut s, lay.f, h, 6, 1.0, 6);
        let gain = ratio(
            FEAT_SIGMA_SPATIAL_MEDIAN,
            quantile(probe_values(&rows, hs, h).concat(), 0.5),
        );
        self.set(lay.scale_feat(), &rows, gain, |_| {
            s.range(FEAT_SIGMA_BASE.0, FEAT_SIGMA_BASE.1)
        });
    }

    /// Part 3, scaling: mu = gain (floor + taps) with taps (2 own of weight 1/2, 4 shared),
    /// floor from SCALING_MEAN_LOG_RANGE, gain placing the median of ln(scaling / voxel) at
    /// SCALING_LOG_MEDIAN; scale rows = std_ratio * mean rows (the noise's exact std).
    /// Returns the scaling noise.
    fn scaling(&mut self, lay: &Layout, seed: u64, hs: &[Vec<f64>], voxel: f64) -> ScalingNoise {
        let h = self.h;
        let mut s = Stream::new(seed, tag::CONTEXT_MLP, 3);
        let rows = taps(&mut s, lay.s, h, 2, 0.5, 4);
        let vals = probe_values(&rows, hs, h).concat();
        let floor = scaling_floor(&vals, SCALING_MEAN_LOG_RANGE);
        let ln_med = quantile(vals.iter().map(|v| ln(v + floor)).collect(), 0.5);
        let noise = ScalingNoise::new(SCALING_NOISE_LOG_STD, SCALING_NOISE_SKEW);
        // median ln s ~ median ln mu + median(noise), median(noise) = 0.455 c - L (0.455 = median e^2).
        let gain = exp(ln(voxel) + SCALING_LOG_MEDIAN + noise.log_norm - 0.455 * noise.c - ln_med);
        self.set(lay.mean_scaling(), &rows, gain, |_| gain * floor);
        let gain_s = noise.std_ratio * gain;
        self.set(lay.scale_scaling(), &rows, gain_s, |_| gain_s * floor);
        noise
    }

    /// Part 4, offsets: mean rows 3K x H normals scaled to OFFSET_MEAN_SPREAD, centred on 3K
    /// normals * OFFSET_MEAN_BIAS_STD; scale rows: taps (4 own, 0 shared) scaled to median
    /// OFFSET_SIGMA_SPATIAL_MEDIAN, biases U[OFFSET_SIGMA_BASE).
    fn offsets(&mut self, lay: &Layout, seed: u64, hs: &[Vec<f64>]) {
        let (k3, h) = (lay.k3, self.h);
        let mut s = Stream::new(seed, tag::CONTEXT_MLP, 4);
        let rows = gaussian(&mut s, k3 * h, 1.0);
        let (m, sp) = spread(&probe_values(&rows, hs, h));
        let gain = ratio(OFFSET_MEAN_SPREAD, sp);
        self.set(lay.mean_offsets(), &rows, gain, |a| {
            s.normal() * OFFSET_MEAN_BIAS_STD - gain * m[a]
        });
        let rows = taps(&mut s, k3, h, 4, 1.0, 0);
        let gain = ratio(
            OFFSET_SIGMA_SPATIAL_MEDIAN,
            quantile(probe_values(&rows, hs, h).concat(), 0.5),
        );
        self.set(lay.scale_offsets(), &rows, gain, |_| {
            s.range(OFFSET_SIGMA_BASE.0, OFFSET_SIGMA_BASE.1)
        });
    }

    /// Part 5, q_adj (3 rows) and the mask field (1 internal row): normals, each row scaled
    /// to std QADJ_SPREAD (mask field: 1) and centred at 0 over the probes.
    fn q_adj_and_mask(&mut self, lay: &Layout, seed: u64, hs: &[Vec<f64>]) {
        let h = self.h;
        let mut s = Stream::new(seed, tag::CONTEXT_MLP, 5);
        let rows = gaussian(&mut s, 4 * h, 1.0);
        for (a, row) in rows.chunks(h).enumerate() {
            let (m, sp) = spread(&probe_values(row, hs, h));
            let gain = ratio(if a < 3 { QADJ_SPREAD } else { 1.0 }, sp);
            self.set(lay.q_adj() + a, row, gain, |_| -gain * m[0]);
        }
    }
}
