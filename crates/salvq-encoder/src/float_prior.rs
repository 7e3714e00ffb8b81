//! The float model the integer prior replaces (measurement only, never on a decoding path):
//! multilinear grid interpolation in f64, the stored f32 MLP evaluated in f64, HAC's step
//! `G (1 + tanh(adj))`, and the exact discretized Gaussian. It answers "what would the
//! trained float model have spent", the baseline of the conversion cost (spec §5).

use crate::float_grid::Interp;
use salvq_bitstream::hyperprior::prior::Group;
use salvq_bitstream::model::SceneModel;

/// Smallest probability the float model assigns (as HAC's likelihood lower bound).
const P_MIN: f64 = 1e-9;

/// P(u) of the Gaussian N(0, sigma^2) convolved with the unit uniform, at integer u, floored
/// at HAC's likelihood bound.
fn discretized_gaussian(u: f64, sigma: f64) -> f64 {
    crate::entropy_analysis::discretized_gaussian(u as i64, sigma).max(P_MIN)
}

/// The float model of one stream: interpolation, MLP weights in f64, base steps.
pub struct FloatPrior {
    interp: Interp,
    w0: Vec<f64>,
    b0: Vec<f64>,
    w1: Vec<f64>,
    b1: Vec<f64>,
    cin: usize,
    hidden: usize,
    base: [f64; 3],
    mean_at: [usize; 3],
    scale_at: [usize; 3],
    adj_at: usize,
}

/// The float model's outputs at one anchor.
pub struct FloatAnchor<'a> {
    prior: &'a FloatPrior,
    y: Vec<f64>,
}

impl FloatPrior {
    /// The float model of `m` (its own `mlp_grid`, before conversion) at rate `rate`.
    pub fn new(m: &SceneModel, coord_bits: u8, rate: usize) -> Self {
        let d = &m.dims;
        let f64s = |v: &[f32]| v.iter().map(|&x| f64::from(x)).collect::<Vec<f64>>();
        let (f, s, k3) = (
            usize::from(d.feat_dim),
            usize::from(d.scaling_dim),
            3 * usize::from(d.offsets),
        );
        let g = |q: &salvq_bitstream::model::GroupQuantizer| {
            f64::from(q.step) * f64::from(q.gains.get(rate).copied().unwrap_or(1.0))
        };
        FloatPrior {
            interp: Interp::new(d, coord_bits),
            w0: f64s(&m.mlp_grid.w0),
            b0: f64s(&m.mlp_grid.b0),
            w1: f64s(&m.mlp_grid.w1),
            b1: f64s(&m.mlp_grid.b1),
            cin: d.context_input() as usize,
            hidden: usize::from(d.context_hidden),
            base: [g(&m.quant_feat), g(&m.quant_scaling), g(&m.quant_offsets)],
            mean_at: [0, 2 * f, 2 * f + 2 * s],
            scale_at: [f, 2 * f + s, 2 * f + 2 * s + k3],
            adj_at: 2 * f + 2 * s + 2 * k3,
        }
    }

    /// The float prior of the anchor at voxel `v`.
    pub fn eval(&self, m: &SceneModel, v: [u32; 3]) -> FloatAnchor<'_> {
        let h = self.hidden(m, v);
        FloatAnchor {
            prior: self,
            y: self.outputs(&h),
        }
    }

    /// The context MLP's hidden activations (after ReLU) at voxel `v`.
    pub fn hidden(&self, m: &SceneModel, v: [u32; 3]) -> Vec<f64> {
        let mut x = vec![0f64; self.cin];
        self.interp.features(&m.grid, v, &mut x);
        self.w0
            .chunks_exact(self.cin.max(1))
            .zip(&self.b0)
            .map(|(row, b)| (row.iter().zip(&x).map(|(w, x)| w * x).sum::<f64>() + b).max(0.0))
            .collect()
    }

    /// The context MLP's outputs for hidden activations `h`.
    pub fn outputs(&self, h: &[f64]) -> Vec<f64> {
        self.w1
            .chunks_exact(self.hidden.max(1))
            .zip(&self.b1)
            .map(|(row, b)| row.iter().zip(h).map(|(w, h)| w * h).sum::<f64>() + b)
            .collect()
    }
}

impl FloatAnchor<'_> {
    /// The float model's step of group `g` at this anchor.
    fn delta(&self, g: Group) -> f64 {
        let gi = g as usize;
        self.prior.base[gi] * (1.0 + self.y[self.prior.adj_at + gi].tanh())
    }

    /// -log2 P(u) of value `j` of group `g` with scale σ/Δ.
    fn bits(&self, g: Group, j: usize, u: f64, delta: f64) -> f64 {
        let sigma = self.y[self.prior.scale_at[g as usize] + j].max(1e-9);
        -discretized_gaussian(u, sigma / delta).log2()
    }

    /// -log2 P(u) of value `j` of group `g` for the symbol the float model would code.
    pub fn ideal_bits(&self, g: Group, j: usize, x: f32) -> f64 {
        let delta = self.delta(g);
        let mu = self.y[self.prior.mean_at[g as usize] + j];
        let u = ((f64::from(x) - mu) / delta).round();
        self.bits(g, j, u, delta)
    }

    /// The float model's bits for a whole group coded with a lattice: its own targets
    /// `(x − μ) / Δ`, quantized by `search`, each coordinate under its Gaussian.
    pub fn ideal_bits_lattice(
        &self,
        g: Group,
        x: &[f32],
        search: impl Fn(&[f64]) -> Option<Vec<i64>>,
    ) -> f64 {
        let delta = self.delta(g);
        let at = self.prior.mean_at[g as usize];
        let t: Vec<f64> = x
            .iter()
            .enumerate()
            .map(|(j, &v)| (f64::from(v) - self.y[at + j]) / delta)
            .collect();
        match search(&t) {
            Some(u) => (0..x.len())
                .map(|j| self.bits(g, j, u[j] as f64, delta))
                .sum(),
            None => f64::INFINITY,
        }
    }
}
