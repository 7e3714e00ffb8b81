//! The float model the integer prior replaces (measurement only, never on a decoding path):
//! multilinear grid interpolation in f64, the stored f32 MLP evaluated in f64, HAC's step
//! `G (1 + tanh(adj))`, and the exact discretized Gaussian. It answers "what would the
//! trained float model have spent", the baseline of the conversion cost (spec §5, issue 4).

use crate::gen::grid::Interp;
use crate::hyperprior::prior::Group;
use crate::model::SceneModel;

/// Smallest probability the float model assigns (as HAC's likelihood lower bound).
const P_MIN: f64 = 1e-9;

/// erfc(x) with relative error < 1.2e-7 (Numerical Recipes `erfcc`, Chebyshev fit).
pub fn erfc(x: f64) -> f64 {
    let z = x.abs();
    let t = 1.0 / (1.0 + 0.5 * z);
    let poly = -z * z - 1.265_512_23
        + t * (1.000_023_68
            + t * (0.374_091_96
                + t * (0.096_784_18
                    + t * (-0.186_288_06
                        + t * (0.278_868_07
                            + t * (-1.135_203_98
                                + t * (1.488_515_87 + t * (-0.822_152_23 + t * 0.170_872_77))))))));
    let r = t * poly.exp();
    if x >= 0.0 {
        r
    } else {
        2.0 - r
    }
}

/// P(u) of the Gaussian N(0, sigma^2) convolved with the unit uniform, at integer u.
pub fn discretized_gaussian(u: f64, sigma: f64) -> f64 {
    let s = std::f64::consts::SQRT_2 * sigma;
    let (a, b) = ((u - 0.5) / s, (u + 0.5) / s);
    // Evaluate on the side where erfc keeps its precision.
    let p = if a >= 0.0 {
        0.5 * (erfc(a) - erfc(b))
    } else if b <= 0.0 {
        0.5 * (erfc(-b) - erfc(-a))
    } else {
        1.0 - 0.5 * (erfc(-a) + erfc(b))
    };
    p.max(P_MIN)
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
        let g = |q: &crate::model::GroupQuantizer| {
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

    pub fn eval(&self, m: &SceneModel, v: [u32; 3]) -> FloatAnchor<'_> {
        let mut x = vec![0f64; self.cin];
        self.interp.features(&m.grid, v, &mut x);
        let h: Vec<f64> = self
            .w0
            .chunks_exact(self.cin.max(1))
            .zip(&self.b0)
            .map(|(row, b)| (row.iter().zip(&x).map(|(w, x)| w * x).sum::<f64>() + b).max(0.0))
            .collect();
        let y = self
            .w1
            .chunks_exact(self.hidden.max(1))
            .zip(&self.b1)
            .map(|(row, b)| row.iter().zip(&h).map(|(w, h)| w * h).sum::<f64>() + b)
            .collect();
        FloatAnchor { prior: self, y }
    }
}

impl FloatAnchor<'_> {
    /// -log2 P(u) of value `j` of group `g` for the symbol the float model would code.
    pub fn ideal_bits(&self, g: Group, j: usize, x: f32) -> f64 {
        let p = self.prior;
        let gi = g as usize;
        let delta = p.base[gi] * (1.0 + self.y[p.adj_at + gi].tanh());
        let mu = self.y[p.mean_at[gi] + j];
        let sigma = self.y[p.scale_at[gi] + j].max(1e-9);
        let u = ((f64::from(x) - mu) / delta).round();
        -discretized_gaussian(u, sigma / delta).log2()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn discretized_gaussian_sums_to_one() {
        for sigma in [0.1, 0.7, 3.0, 20.0] {
            let total: f64 = (-200..=200)
                .map(|u| discretized_gaussian(f64::from(u), sigma))
                .sum();
            assert!(
                (total - 1.0).abs() < 1e-5 + 401.0 * P_MIN,
                "sigma {sigma}: {total}"
            );
        }
        assert!((erfc(0.0) - 1.0).abs() < 1e-7);
        assert!((erfc(1.0) - 0.157_299_207_050_285_1).abs() < 1e-7);
    }
}
