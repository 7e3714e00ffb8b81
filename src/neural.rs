//! Scaffold-GS neural Gaussians from a scene model (spec Annex C.1).
//!
//! Follows `generate_neural_gaussians` of Scaffold-GS (Lu et al., CVPR 2024, Sec. 3.2;
//! `gaussian_renderer/__init__.py` of city-super/Scaffold-GS) as HAC (Chen et al., ECCV 2024;
//! YihangChen-ee/HAC, same file) runs it on decoded anchors. For anchor `a` at
//! `x_a = origin + voxel_size · v_a` (spec §2.2) and a camera centre `x_c`:
//!
//! - view input `δ = (x_a − x_c) / ‖x_a − x_c‖`, MLP input `[f_a, δ]`, or `[f_a, δ, ‖x_a − x_c‖]`
//!   when V = 4 (HAC);
//! - opacity `α_k = tanh(MLP_α)_k`; offset k spawns a Gaussian where `mask_k = 1` and `α_k > 0`;
//! - colour `c_k = sigmoid(MLP_c)_{3k..3k+3}`;
//! - `MLP_cov` gives 7 values per offset: scale `s_k = l_{3..6} · sigmoid(raw_{0..3})`,
//!   rotation `q_k = raw_{3..7} / max(‖raw_{3..7}‖, 10⁻¹²)` (w first);
//! - position `μ_k = x_a + O_k · l_{0..3}`.
//!
//! `l` is `anchor.scaling`, already activated (`exp`) as HAC codes it (spec Table 2-1 row 6),
//! so no `exp` is applied here. The result is a standard 3DGS set ([`Gaussians`]) of SH
//! degree 0: `f_dc = (c − 0.5) / C0`, opacity logit `ln(α / (1 − α))` with α clamped to
//! [10⁻⁷, 1 − 10⁻⁷], log-scales `ln l + ln sigmoid(raw)`. Gaussians are listed anchor by
//! anchor in the model's order, offsets in index order.

use std::fmt;

use crate::error::{Error, Field};
use crate::explicit::Gaussians;
use crate::model::{names, Mlp, SceneModel};
use crate::par::*;

/// Why a model gives no neural Gaussians (Annex C.1).
#[derive(Debug, Clone, PartialEq)]
pub enum NeuralError {
    /// The model's shape is not Scaffold-GS's: the scaling must have 6 dimensions, the view
    /// inputs 3 or 4.
    Unsupported {
        /// The dimension.
        field: Field,
        /// Its value.
        value: u64,
        /// The rule broken.
        rule: &'static str,
    },
    /// A tensor's length disagrees with the model's dimensions (`TensorShape`).
    Shape(Error),
}

impl fmt::Display for NeuralError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            NeuralError::Unsupported { field, value, rule } => write!(
                f,
                "{} = {value}: no Scaffold-GS neural Gaussians: {rule} [§C.1]",
                field.spec_name()
            ),
            NeuralError::Shape(e) => e.fmt(f),
        }
    }
}

impl std::error::Error for NeuralError {}

/// A result of this module.
pub type Result<T> = std::result::Result<T, NeuralError>;

/// SH band-0 constant `1 / (2 √π)` in binary64.
pub const SH_C0: f64 = 0.282_094_791_773_878_14;

/// Clamp of the opacity before its logit is taken (Annex C.1).
pub const OPACITY_CLAMP: f64 = 1e-7;

/// The three Scaffold-GS MLPs (spec §2.5).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ScaffoldMlp {
    /// `mlp_opacity`: K outputs, `tanh`.
    Opacity,
    /// `mlp_cov`: 7K outputs, 3 scales through `sigmoid` and a normalised quaternion each.
    Cov,
    /// `mlp_color`: 3K outputs, `sigmoid`.
    Color,
}

impl ScaffoldMlp {
    /// The three, in stream order.
    pub const ALL: [ScaffoldMlp; 3] = [ScaffoldMlp::Opacity, ScaffoldMlp::Cov, ScaffoldMlp::Color];
}

/// `Linear → ReLU → Linear` (spec §2.5) in binary64; `out` receives the raw outputs
/// ([`PreparedMlp::forward`]; to run one MLP many times, prepare it once). Every build gives
/// the same bits, but for the sign and payload of a NaN, which IEEE 754 leaves open.
pub fn forward(m: &Mlp, x: &[f64], out: &mut Vec<f64>) {
    PreparedMlp::new(m, x.len()).forward(x, &mut Vec::new(), out);
}

/// Rows of a [`PreparedMlp`] block: eight sums in flight at once.
const BLOCK: usize = 8;

/// One Scaffold-GS MLP laid out for [`PreparedMlp::forward`]: each layer's rows in blocks of eight
/// (`BLOCK`; the last padded with zero rows), each block column by column, in binary64
/// (`f64::from` of a binary32 weight is exact, so converting once changes no product).
///
/// Why: a row's sum is a chain of dependent additions, and one row at a time waited on each
/// addition (most of a Scaffold-GS anchor's time, natively and in WebAssembly). With a
/// block's weights for one input side by side, the eight sums advance together in vector
/// registers.
#[derive(Debug, Clone)]
pub struct PreparedMlp {
    layers: [Layer; 2],
}

/// One `Linear` layer of a [`PreparedMlp`].
#[derive(Debug, Clone)]
struct Layer {
    /// Inputs.
    n: usize,
    /// Outputs (the rows before padding).
    rows: usize,
    /// `[block][input][BLOCK]`.
    w: Vec<f64>,
    /// `[block · BLOCK]`, padded with zeros.
    b: Vec<f64>,
}

impl Layer {
    /// Rows `w` (`[rows, n]`, row-major) and biases `b` (`[rows]`); rows that `w` or `b` lack
    /// (a model [`check_model`] would refuse) are zero.
    fn new(w: &[f32], b: &[f32], n: usize) -> Layer {
        let rows = b.len();
        let blocks = rows.div_ceil(BLOCK);
        let mut wt = vec![0.0; blocks * n * BLOCK];
        for (r, row) in w.chunks_exact(n.max(1)).take(rows).enumerate() {
            let (block, k) = (r / BLOCK, r % BLOCK);
            for (j, &v) in row.iter().enumerate() {
                wt[(block * n + j) * BLOCK + k] = f64::from(v);
            }
        }
        let mut bias: Vec<f64> = b.iter().map(|&v| f64::from(v)).collect();
        bias.resize(blocks * BLOCK, 0.0);
        Layer {
            n,
            rows,
            w: wt,
            b: bias,
        }
    }

    /// `out[r] = b[r] + Σ_j w[r][j]·x[j]` for every padded row, each sum from −0 (which
    /// adding leaves every value as it is) in increasing j: the order [`Iterator::sum`]
    /// takes, so the same bits as a plain loop over one row.
    fn apply(&self, x: &[f64], out: &mut Vec<f64>) {
        out.clear();
        let x = &x[..self.n.min(x.len())];
        let block_len = self.n * BLOCK;
        for (i, bias) in self.b.chunks_exact(BLOCK).enumerate() {
            let block = &self.w[i * block_len..(i + 1) * block_len];
            let mut acc = [-0.0f64; BLOCK];
            for (column, &v) in block.chunks_exact(BLOCK).zip(x) {
                for (a, &w) in acc.iter_mut().zip(column) {
                    *a += w * v;
                }
            }
            out.extend(bias.iter().zip(acc).map(|(&b, a)| b + a));
        }
    }
}

impl PreparedMlp {
    /// `m` for inputs of `inputs` values.
    pub fn new(m: &Mlp, inputs: usize) -> PreparedMlp {
        let hidden = m.b0.len();
        PreparedMlp {
            layers: [
                Layer::new(&m.w0, &m.b0, inputs),
                Layer::new(&m.w1, &m.b1, hidden),
            ],
        }
    }

    /// The raw outputs of input `x` into `out`; `hidden` is scratch. The ReLU takes a NaN
    /// and −0 to +0 (`f64::max` leaves the sign of a zero result open).
    pub fn forward(&self, x: &[f64], hidden: &mut Vec<f64>, out: &mut Vec<f64>) {
        let [first, second] = &self.layers;
        first.apply(x, hidden);
        hidden.truncate(first.rows);
        for v in hidden.iter_mut() {
            *v = if *v > 0.0 { *v } else { 0.0 };
        }
        second.apply(hidden, out);
        out.truncate(second.rows);
    }
}

/// The logistic function.
pub fn sigmoid(x: f64) -> f64 {
    1.0 / (1.0 + (-x).exp())
}

/// `ln sigmoid(x)` without underflow for large negative `x`.
fn ln_sigmoid(x: f64) -> f64 {
    if x >= 0.0 {
        -(-x).exp().ln_1p()
    } else {
        x - x.exp().ln_1p()
    }
}

/// Scaffold-GS's output activations, in place: opacity `tanh`; covariance: per offset the 3
/// scales through `sigmoid` and the 4 rotation values normalised; colour `sigmoid`.
pub fn activate(which: ScaffoldMlp, raw: &mut [f64]) {
    match which {
        ScaffoldMlp::Opacity => raw.iter_mut().for_each(|v| *v = v.tanh()),
        ScaffoldMlp::Cov => {
            for g in raw.chunks_mut(7) {
                g[..3].iter_mut().for_each(|v| *v = sigmoid(*v));
                let n = g[3..].iter().map(|v| v * v).sum::<f64>().sqrt().max(1e-12);
                g[3..].iter_mut().for_each(|v| *v /= n);
            }
        }
        ScaffoldMlp::Color => raw.iter_mut().for_each(|v| *v = sigmoid(*v)),
    }
}

/// World positions of the anchors, `origin + voxel_size · voxel` per axis in binary32
/// (spec §2.2).
pub fn anchor_positions(m: &SceneModel) -> Vec<[f32; 3]> {
    m.anchors
        .voxel
        .iter()
        .map(|v| std::array::from_fn(|a| m.origin[a] + m.voxel_size * v[a] as f32))
        .collect()
}

fn shape_error(tensor: &'static str, expected: &[usize], found: usize) -> NeuralError {
    NeuralError::Shape(Error::TensorShape {
        tensor,
        expected: expected.iter().map(|&d| d as u64).collect(),
        found: vec![found as u64],
    })
}

/// Checks that the model has Scaffold-GS's shape (S = 6, V = 3 or 4) and that every vector
/// holds what its dimensions say, so that generation cannot index out of bounds.
pub fn check_model(m: &SceneModel) -> Result<()> {
    let d = &m.dims;
    if d.scaling_dim != 6 {
        return Err(NeuralError::Unsupported {
            field: Field::ScalingDim,
            value: d.scaling_dim.into(),
            rule:
                "Scaffold-GS anchors have 6 scaling values (3 for the offsets, 3 for the Gaussians)",
        });
    }
    if !(3..=4).contains(&d.view_dims) {
        return Err(NeuralError::Unsupported {
            field: Field::ViewDims,
            value: d.view_dims.into(),
            rule: "the view inputs are the direction (3) or the direction and distance (4)",
        });
    }
    let (n, f, k, hs) = (
        m.n(),
        usize::from(d.feat_dim),
        usize::from(d.offsets),
        usize::from(d.scaffold_hidden),
    );
    let inp = f + usize::from(d.view_dims);
    let a = &m.anchors;
    let checks: [(&'static str, &[usize], usize); 5] = [
        (names::VOXEL, &[n, 3], a.voxel.len() * 3),
        (names::MASK, &[n, k], a.mask.len()),
        (names::FEAT, &[n, f], a.feat.len()),
        (names::SCALING, &[n, 6], a.scaling.len()),
        (names::OFFSETS, &[n, k, 3], a.offsets.len()),
    ];
    for (tensor, shape, found) in checks {
        if shape.iter().product::<usize>() != found {
            return Err(shape_error(tensor, shape, found));
        }
    }
    let mlps = [
        (&m.mlp_opacity, names::MLP_OPACITY, k),
        (&m.mlp_cov, names::MLP_COV, 7 * k),
        (&m.mlp_color, names::MLP_COLOR, 3 * k),
    ];
    for (mlp, tensor, out) in mlps {
        let parts: [(&[f32], &[usize]); 4] = [
            (&mlp.w0, &[hs, inp]),
            (&mlp.b0, &[hs]),
            (&mlp.w1, &[out, hs]),
            (&mlp.b1, &[out]),
        ];
        for (i, (values, shape)) in parts.into_iter().enumerate() {
            if shape.iter().product::<usize>() != values.len() {
                return Err(shape_error(tensor[i], shape, values.len()));
            }
        }
    }
    Ok(())
}

/// Anchors per parallel work item.
const ANCHORS_PER_JOB: usize = 512;

/// The neural Gaussians that a camera at `camera` sees (Annex C.1), as standard 3DGS
/// Gaussians of SH degree 0.
pub fn neural_gaussians(m: &SceneModel, camera: [f32; 3]) -> Result<Gaussians> {
    neural_gaussians_counted(m, camera).map(|(g, _)| g)
}

/// [`neural_gaussians`], and how many of them each anchor gave (the opacity test of Annex
/// C.1 keeps 0 … k): anchor `i`'s are the next `counts[i]` after those of anchors `0 … i`.
pub fn neural_gaussians_counted(m: &SceneModel, camera: [f32; 3]) -> Result<(Gaussians, Vec<u32>)> {
    check_model(m)?;
    let positions = anchor_positions(m);
    let n = m.n();
    let inputs = usize::from(m.dims.feat_dim) + usize::from(m.dims.view_dims);
    let mlps = [&m.mlp_opacity, &m.mlp_cov, &m.mlp_color].map(|mlp| PreparedMlp::new(mlp, inputs));
    let parts: Vec<(Gaussians, Vec<u32>)> = (0..n.div_ceil(ANCHORS_PER_JOB))
        .into_par_iter()
        .map(|job| {
            let mut g = Gaussians::default();
            let end = ((job + 1) * ANCHORS_PER_JOB).min(n);
            let mut scratch = Scratch::default();
            let first = job * ANCHORS_PER_JOB;
            let mut counts = Vec::with_capacity(end - first);
            for (anchor, &position) in positions.iter().enumerate().take(end).skip(first) {
                let before = g.len();
                anchor_gaussians(m, &mlps, anchor, position, camera, &mut scratch, &mut g);
                counts.push((g.len() - before) as u32);
            }
            (g, counts)
        })
        .collect();
    let total = parts.iter().map(|(g, _)| g.len()).sum();
    let mut counts = Vec::with_capacity(n);
    let mut out = Gaussians {
        positions: Vec::with_capacity(total),
        sh_degree: 0,
        f_dc: Vec::with_capacity(total),
        f_rest: Vec::new(),
        opacity_logit: Vec::with_capacity(total),
        log_scales: Vec::with_capacity(total),
        rotations: Vec::with_capacity(total),
    };
    for (p, c) in parts {
        out.positions.extend(p.positions);
        out.f_dc.extend(p.f_dc);
        out.opacity_logit.extend(p.opacity_logit);
        out.log_scales.extend(p.log_scales);
        out.rotations.extend(p.rotations);
        counts.extend(c);
    }
    Ok((out, counts))
}

/// Per-thread buffers of [`anchor_gaussians`].
#[derive(Default)]
struct Scratch {
    input: Vec<f64>,
    hidden: Vec<f64>,
    opacity: Vec<f64>,
    cov: Vec<f64>,
    colour: Vec<f64>,
}

/// Appends anchor `i`'s Gaussians to `g`.
fn anchor_gaussians(
    m: &SceneModel,
    [opacity, cov, colour]: &[PreparedMlp; 3],
    i: usize,
    anchor: [f32; 3],
    camera: [f32; 3],
    s: &mut Scratch,
    g: &mut Gaussians,
) {
    let f = usize::from(m.dims.feat_dim);
    let k = usize::from(m.dims.offsets);
    let mask = &m.anchors.mask[i * k..(i + 1) * k];
    if mask.iter().all(|&b| b == 0) {
        return; // every offset is masked: HAC multiplies their opacities by 0
    }
    let view: [f64; 3] = std::array::from_fn(|a| f64::from(anchor[a]) - f64::from(camera[a]));
    let dist = view.iter().map(|v| v * v).sum::<f64>().sqrt();
    // A camera exactly at the anchor has no direction; 0 stands in for PyTorch's NaN.
    let dir = view.map(|v| if dist > 0.0 { v / dist } else { 0.0 });
    s.input.clear();
    s.input.extend(
        m.anchors.feat[i * f..(i + 1) * f]
            .iter()
            .map(|&x| f64::from(x)),
    );
    s.input.extend(dir);
    if m.dims.view_dims == 4 {
        s.input.push(dist);
    }
    opacity.forward(&s.input, &mut s.hidden, &mut s.opacity);
    activate(ScaffoldMlp::Opacity, &mut s.opacity);
    let kept = |o: usize| mask[o] == 1 && s.opacity[o] > 0.0;
    if !(0..k).any(kept) {
        return;
    }
    cov.forward(&s.input, &mut s.hidden, &mut s.cov);
    colour.forward(&s.input, &mut s.hidden, &mut s.colour);
    activate(ScaffoldMlp::Color, &mut s.colour);
    let scaling = &m.anchors.scaling[i * 6..(i + 1) * 6];
    let offsets = &m.anchors.offsets[i * 3 * k..(i + 1) * 3 * k];
    for o in (0..k).filter(|&o| kept(o)) {
        g.positions.push(std::array::from_fn(|a| {
            anchor[a] + offsets[3 * o + a] * scaling[a]
        }));
        let raw = &s.cov[7 * o..7 * o + 7];
        g.log_scales.push(std::array::from_fn(|a| {
            let l = f64::from(scaling[3 + a].abs()).max(f64::from(f32::MIN_POSITIVE));
            (l.ln() + ln_sigmoid(raw[a])) as f32
        }));
        let norm = raw[3..]
            .iter()
            .map(|v| v * v)
            .sum::<f64>()
            .sqrt()
            .max(1e-12);
        g.rotations
            .push(std::array::from_fn(|j| (raw[3 + j] / norm) as f32));
        g.f_dc.push(std::array::from_fn(|c| {
            ((s.colour[3 * o + c] - 0.5) / SH_C0) as f32
        }));
        let alpha = s.opacity[o].clamp(OPACITY_CLAMP, 1.0 - OPACITY_CLAMP);
        g.opacity_logit.push((alpha / (1.0 - alpha)).ln() as f32);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One row at a time, each sum by [`Iterator::sum`]: the definition the blocked layout
    /// must reproduce bit for bit.
    fn forward_by_rows(m: &Mlp, x: &[f64]) -> Vec<f64> {
        let linear = |w: &[f32], b: &[f32], x: &[f64]| -> Vec<f64> {
            b.iter()
                .enumerate()
                .map(|(r, &bias)| {
                    let row = &w[r * x.len()..(r + 1) * x.len()];
                    f64::from(bias)
                        + row
                            .iter()
                            .zip(x)
                            .map(|(&w, &v)| f64::from(w) * v)
                            .sum::<f64>()
                })
                .collect()
        };
        let h: Vec<f64> = linear(&m.w0, &m.b0, x)
            .into_iter()
            .map(|v| if v > 0.0 { v } else { 0.0 })
            .collect();
        linear(&m.w1, &m.b1, &h)
    }

    fn xorshift(seed: u64) -> impl FnMut() -> u64 {
        let mut s = seed;
        move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            s
        }
    }

    /// Weights and inputs over many magnitudes (so that the order of the additions shows in
    /// the last bits), with zeros of both signs, infinities and NaN now and then.
    fn value(next: &mut impl FnMut() -> u64) -> f64 {
        match next() % 64 {
            0 => f64::NAN,
            1 => f64::INFINITY,
            2 => f64::NEG_INFINITY,
            3 => 0.0,
            4 => -0.0,
            5 => f64::from(f32::MIN_POSITIVE) / 8.0,
            _ => {
                let mantissa = (next() % 2000) as f64 / 1000.0 - 1.0;
                mantissa * 2f64.powi((next() % 40) as i32 - 20)
            }
        }
    }

    #[test]
    fn prepared_mlp_gives_the_bits_of_one_row_at_a_time() {
        let mut next = xorshift(0x5eed);
        let mut compared = 0;
        for (inputs, hidden, outputs) in [
            (53, 50, 10),
            (54, 50, 70),
            (53, 50, 30),
            (1, 1, 1),
            (3, 7, 9),
            (0, 8, 3),
            (5, 0, 4),
            (17, 16, 17),
        ] {
            for _ in 0..20 {
                let mut w =
                    |n: usize| -> Vec<f32> { (0..n).map(|_| value(&mut next) as f32).collect() };
                let m = Mlp {
                    w0: w(hidden * inputs),
                    b0: w(hidden),
                    w1: w(outputs * hidden),
                    b1: w(outputs),
                };
                let x: Vec<f64> = (0..inputs).map(|_| value(&mut next)).collect();
                let want = forward_by_rows(&m, &x);
                let mut got = Vec::new();
                forward(&m, &x, &mut got);
                assert_eq!(got.len(), outputs);
                for (o, (g, w)) in got.iter().zip(&want).enumerate() {
                    // A NaN's sign and payload are left open (IEEE 754, and WebAssembly's
                    // NaNs are nondeterministic): any NaN stands for any other.
                    let same = g.to_bits() == w.to_bits() || (g.is_nan() && w.is_nan());
                    assert!(
                        same,
                        "{inputs}/{hidden}/{outputs}: output {o}: {g:e} vs {w:e}"
                    );
                }
                compared += outputs;
            }
        }
        assert!(compared > 0);
        // The order of the additions shows: (2^53 + 1) − 2^53 is 0 in increasing order.
        let big = 2f32.powi(53);
        let m = Mlp {
            w0: vec![big, 1.0, -big],
            b0: vec![0.0],
            w1: vec![1.0],
            b1: vec![0.0],
        };
        let mut got = Vec::new();
        forward(&m, &[1.0, 1.0, 1.0], &mut got);
        assert_eq!(got, [0.0]);
    }
}
