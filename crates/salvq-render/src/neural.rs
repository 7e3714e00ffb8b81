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

use rayon::prelude::*;

use super::Gaussians;
use crate::error::{Error, Result};
use salvq::error::Field;
use salvq::model::{names, Mlp, SceneModel};

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

/// `Linear → ReLU → Linear` (spec §2.5) in binary64; `out` receives the raw outputs.
pub fn forward(m: &Mlp, x: &[f64], out: &mut Vec<f64>) {
    let (inp, hidden) = (x.len(), m.b0.len());
    let h: Vec<f64> = (0..hidden)
        .map(|j| {
            let s = f64::from(m.b0[j])
                + m.w0[j * inp..(j + 1) * inp]
                    .iter()
                    .zip(x)
                    .map(|(&w, &v)| f64::from(w) * v)
                    .sum::<f64>();
            s.max(0.0)
        })
        .collect();
    out.clear();
    out.extend((0..m.b1.len()).map(|o| {
        f64::from(m.b1[o])
            + m.w1[o * hidden..(o + 1) * hidden]
                .iter()
                .zip(&h)
                .map(|(&w, &v)| f64::from(w) * v)
                .sum::<f64>()
    }));
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

fn shape_error(tensor: &'static str, expected: &[usize], found: usize) -> Error {
    salvq::Error::TensorShape {
        tensor,
        expected: expected.iter().map(|&d| d as u64).collect(),
        found: vec![found as u64],
    }
    .into()
}

/// Checks that the model has Scaffold-GS's shape (S = 6, V = 3 or 4) and that every vector
/// holds what its dimensions say, so that generation cannot index out of bounds.
pub fn check_model(m: &SceneModel) -> Result<()> {
    let d = &m.dims;
    if d.scaling_dim != 6 {
        return Err(Error::NeuralGaussiansUnsupported {
            field: Field::ScalingDim,
            value: d.scaling_dim.into(),
            rule:
                "Scaffold-GS anchors have 6 scaling values (3 for the offsets, 3 for the Gaussians)",
        });
    }
    if !(3..=4).contains(&d.view_dims) {
        return Err(Error::NeuralGaussiansUnsupported {
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
    check_model(m)?;
    let positions = anchor_positions(m);
    let n = m.n();
    let parts: Vec<Gaussians> = (0..n.div_ceil(ANCHORS_PER_JOB))
        .into_par_iter()
        .map(|job| {
            let mut g = Gaussians::default();
            let end = ((job + 1) * ANCHORS_PER_JOB).min(n);
            let mut scratch = Scratch::default();
            let first = job * ANCHORS_PER_JOB;
            for (anchor, &position) in positions.iter().enumerate().take(end).skip(first) {
                anchor_gaussians(m, anchor, position, camera, &mut scratch, &mut g);
            }
            g
        })
        .collect();
    let total = parts.iter().map(Gaussians::len).sum();
    let mut out = Gaussians {
        positions: Vec::with_capacity(total),
        sh_degree: 0,
        f_dc: Vec::with_capacity(total),
        f_rest: Vec::new(),
        opacity_logit: Vec::with_capacity(total),
        log_scales: Vec::with_capacity(total),
        rotations: Vec::with_capacity(total),
    };
    for p in parts {
        out.positions.extend(p.positions);
        out.f_dc.extend(p.f_dc);
        out.opacity_logit.extend(p.opacity_logit);
        out.log_scales.extend(p.log_scales);
        out.rotations.extend(p.rotations);
    }
    Ok(out)
}

/// Per-thread buffers of [`anchor_gaussians`].
#[derive(Default)]
struct Scratch {
    input: Vec<f64>,
    opacity: Vec<f64>,
    cov: Vec<f64>,
    colour: Vec<f64>,
}

/// Appends anchor `i`'s Gaussians to `g`.
fn anchor_gaussians(
    m: &SceneModel,
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
    forward(&m.mlp_opacity, &s.input, &mut s.opacity);
    activate(ScaffoldMlp::Opacity, &mut s.opacity);
    let kept = |o: usize| mask[o] == 1 && s.opacity[o] > 0.0;
    if !(0..k).any(kept) {
        return;
    }
    forward(&m.mlp_cov, &s.input, &mut s.cov);
    forward(&m.mlp_color, &s.input, &mut s.colour);
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
