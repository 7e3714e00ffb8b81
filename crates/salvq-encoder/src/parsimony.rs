//! Least sufficient structure: hash-grid levels that do not pay for
//! themselves. A level costs `C` bits per touched entry in `GRID` (§1.6.1) on every plane it
//! has; it pays through the context MLP's predictions. The encoder removes a level from the
//! model — its entries, and its inputs to `mlp_grid`, whose mean over the anchors is folded
//! into the layer-0 bias — encodes both, and keeps the smaller stream. No format change: the
//! stream simply describes a model with fewer levels.

use crate::error::Result;
use salvq_bitstream::model::{level_entries, Mlp, SceneModel};

use super::convert::grid_inputs;
use super::{encode_full, EncodeOptions};

/// One hash-grid level: 3D level `i`, or 2D level `i` (on all three planes).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GridLevel {
    /// 3D level `i`.
    ThreeD(usize),
    /// 2D level `i`, on all three planes.
    TwoD(usize),
}

impl std::fmt::Display for GridLevel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            GridLevel::ThreeD(i) => write!(f, "3D level {i}"),
            GridLevel::TwoD(i) => write!(f, "2D level {i} (xy, xz, yz)"),
        }
    }
}

/// The levels of a model, 3D first.
pub fn grid_levels(m: &SceneModel) -> Vec<GridLevel> {
    (0..m.dims.res_3d.len())
        .map(GridLevel::ThreeD)
        .chain((0..m.dims.res_2d.len()).map(GridLevel::TwoD))
        .collect()
}

/// `rows` of width `width` without the columns in `drop` (sorted).
fn drop_columns(rows: &[f32], width: usize, drop: &[usize]) -> Vec<f32> {
    rows.chunks_exact(width.max(1))
        .flat_map(|row| {
            row.iter()
                .enumerate()
                .filter(|(c, _)| drop.binary_search(c).is_err())
                .map(|(_, &v)| v)
        })
        .collect()
}

/// The model without `level`: its grid entries and its `mlp_grid` inputs removed, each removed
/// input's mean over the anchors (§5.1 features, units of 1) times its weights added to the
/// layer-0 bias, so that the hidden layer moves by as little as a constant input allows.
/// `None` when the level does not exist or is the model's only one.
pub fn without_level(m: &SceneModel, level: GridLevel) -> Option<SceneModel> {
    let d = &m.dims;
    let (l3, l2, c) = (d.res_3d.len(), d.res_2d.len(), usize::from(d.grid_channels));
    if l3 + l2 <= 1 {
        return None;
    }
    // Input columns of the level (§2.4: 3D levels, then the xy, xz and yz levels).
    let cols: Vec<usize> = match level {
        GridLevel::ThreeD(i) if i < l3 => (i * c..(i + 1) * c).collect(),
        GridLevel::TwoD(i) if i < l2 => (0..3)
            .flat_map(|p| {
                let start = (l3 + p * l2 + i) * c;
                start..start + c
            })
            .collect(),
        _ => return None,
    };
    let layout = salvq_bitstream::hyperprior::GridLayout::new(d, m.coord_bits());
    let cin = layout.features();
    let x = grid_inputs(m, &layout);
    let n = m.n().max(1) as f64;
    let means: Vec<f64> = cols
        .iter()
        .map(|&col| {
            x.iter()
                .skip(col)
                .step_by(cin)
                .map(|&v| f64::from(v))
                .sum::<f64>()
                / n
                / 256.0
        })
        .collect();
    let mut out = m.clone();
    let g: &Mlp = &m.mlp_grid;
    let hidden = g.b0.len();
    for h in 0..hidden {
        let shift: f64 = cols
            .iter()
            .zip(&means)
            .map(|(&col, &mean)| f64::from(g.w0[h * cin + col]) * mean)
            .sum();
        out.mlp_grid.b0[h] = (f64::from(g.b0[h]) + shift) as f32;
    }
    out.mlp_grid.w0 = drop_columns(&g.w0, cin, &cols);
    // The level's entries: a contiguous run of each grid tensor (§2.4).
    let cut = |grid: &mut Vec<i8>, res: &[u16], dim: u32, log2: u8, i: usize| {
        let start: u64 = res[..i].iter().map(|&r| level_entries(r, dim, log2)).sum();
        let len = level_entries(res[i], dim, log2);
        let (a, b) = (start as usize * c, (start + len) as usize * c);
        grid.drain(a..b);
    };
    match level {
        GridLevel::ThreeD(i) => {
            cut(&mut out.grid.grid_3d, &d.res_3d, 3, d.log2_size_3d, i);
            out.dims.res_3d.remove(i);
        }
        GridLevel::TwoD(i) => {
            for grid in [
                &mut out.grid.grid_xy,
                &mut out.grid.grid_xz,
                &mut out.grid.grid_yz,
            ] {
                cut(grid, &d.res_2d, 2, d.log2_size_2d, i);
            }
            out.dims.res_2d.remove(i);
        }
    }
    Some(out)
}

/// What removing one level did.
#[derive(Debug, Clone)]
pub struct LevelTrial {
    /// The level, indexed in the model it was removed from.
    pub level: GridLevel,
    /// Its resolution.
    pub resolution: u16,
    /// Stream bytes with the level and without it.
    pub bytes_with: u64,
    /// Stream bytes without the level.
    pub bytes_without: u64,
    /// Feature reconstruction MSE (lowest coded rate) with the level and without it.
    pub mse_with: f64,
    /// Feature MSE without the level.
    pub mse_without: f64,
    /// Anchors the decision was measured on (all of them up to [`PRUNE_SAMPLE`]); with fewer
    /// than the model has, the byte counts are estimates.
    pub sample_anchors: usize,
}

pub(crate) fn feature_mse(a: &SceneModel, b: &SceneModel) -> f64 {
    super::values_mse(&a.anchors.feat, &b.anchors.feat)
}

/// Anchors above which [`prune_grid_levels`] decides on a subsample.
pub const PRUNE_SAMPLE: usize = 40_000;

/// `GRID` payload bytes of `m`'s grid for `voxels` (§1.6.1: method byte, then C bits per
/// touched entry, zero-padded).
pub(crate) fn grid_payload_bytes(m: &SceneModel, voxels: &[[u32; 3]]) -> u64 {
    let d = &m.dims;
    let layout = salvq_bitstream::hyperprior::GridLayout::new(d, m.coord_bits());
    let touched: u64 = layout
        .touched(voxels, d.entries_3d(), d.entries_2d())
        .iter()
        .map(|t| t.iter().filter(|&&u| u).count() as u64)
        .sum();
    1 + (touched * u64::from(d.grid_channels)).div_ceil(8)
}

/// Every `k`-th anchor of `m` (canonical order kept), one region per group.
pub(crate) fn subsample(m: &SceneModel, k: usize) -> SceneModel {
    let mut s = m.clone();
    let (f, sd, kk) = (
        usize::from(m.dims.feat_dim),
        usize::from(m.dims.scaling_dim),
        usize::from(m.dims.offsets),
    );
    let rows = |v: &[f32], w: usize| -> Vec<f32> {
        v.chunks_exact(w.max(1))
            .step_by(k)
            .flatten()
            .copied()
            .collect()
    };
    let a = &m.anchors;
    s.anchors.voxel = a.voxel.iter().step_by(k).copied().collect();
    s.anchors.mask = a
        .mask
        .chunks_exact(kk.max(1))
        .step_by(k)
        .flatten()
        .copied()
        .collect();
    s.anchors.feat = rows(&a.feat, f);
    s.anchors.scaling = rows(&a.scaling, sd);
    s.anchors.offsets = rows(&a.offsets, 3 * kk);
    s.dims.anchors = s.anchors.voxel.len() as u32;
    s.quant_feat.regions.clear();
    s.quant_scaling.regions.clear();
    s.dims.feat_regions = 1;
    s.dims.scaling_regions = 1;
    s
}

/// Greedy backward elimination: encode the model without each remaining level, drop the level
/// whose removal shrinks the stream most while the feature MSE stays within `1 + mse_slack`
/// times the full model's, and repeat until no removal shrinks it. Returns the pruned model and
/// every accepted removal, in order. Above [`PRUNE_SAMPLE`] anchors, byte counts in the trials
/// are estimates (the sample's symbol bytes scaled, the exact grid bytes). `model` must be in canonical order (the encoder's own input
/// order is kept by `encode_full`, which sorts; distortion is compared after sorting).
pub fn prune_grid_levels(
    model: &SceneModel,
    options: &EncodeOptions,
    mse_slack: f64,
) -> Result<(SceneModel, Vec<LevelTrial>)> {
    prune_grid_levels_sampled(model, options, mse_slack, PRUNE_SAMPLE)
}

/// [`prune_grid_levels`] deciding on about `sample` anchors.
pub fn prune_grid_levels_sampled(
    model: &SceneModel,
    options: &EncodeOptions,
    mse_slack: f64,
    sample: usize,
) -> Result<(SceneModel, Vec<LevelTrial>)> {
    let full = model.to_canonical_order();
    // Above PRUNE_SAMPLE anchors the decisions are taken on every k-th anchor: its symbol bytes
    // scaled by N/n, plus the exact GRID bytes of all anchors (touched entries do not scale).
    let k = full.n().div_ceil(sample.max(1)).max(1);
    let model = if k > 1 {
        subsample(&full, k)
    } else {
        full.clone()
    };
    let scale = full.n() as f64 / model.n().max(1) as f64;
    let measure = |m: &SceneModel| -> Result<(u64, f64)> {
        let e = encode_full(m, options)?;
        let mse = feature_mse(&model, e.expected());
        if k == 1 {
            return Ok((e.stream.len() as u64, mse));
        }
        let grid_sample = grid_payload_bytes(m, &m.anchors.voxel);
        let grid_full = grid_payload_bytes(m, &full.anchors.voxel);
        let rest = (e.stream.len() as u64).saturating_sub(grid_sample) as f64 * scale;
        Ok((rest.round() as u64 + grid_full, mse))
    };
    let (mut bytes, mut mse) = measure(&model)?;
    // The slack is against the full model's error, so removals cannot drift it step by step.
    let mse_limit = mse * (1.0 + mse_slack);
    let mut current = model.clone();
    let mut accepted = Vec::new();
    loop {
        let mut best: Option<(SceneModel, LevelTrial)> = None;
        for level in grid_levels(&current) {
            let Some(candidate) = without_level(&current, level) else {
                continue;
            };
            let Ok((b, e)) = measure(&candidate) else {
                continue;
            };
            let fits = e <= mse_limit;
            if fits && b < bytes && best.as_ref().is_none_or(|(_, t)| b < t.bytes_without) {
                best = Some((
                    candidate,
                    LevelTrial {
                        level,
                        resolution: match level {
                            GridLevel::ThreeD(i) => current.dims.res_3d[i],
                            GridLevel::TwoD(i) => current.dims.res_2d[i],
                        },
                        bytes_with: bytes,
                        bytes_without: b,
                        mse_with: mse,
                        mse_without: e,
                        sample_anchors: model.n(),
                    },
                ));
            }
        }
        let Some((m, trial)) = best else {
            break;
        };
        (bytes, mse) = (trial.bytes_without, trial.mse_without);
        accepted.push(trial);
        current = m;
    }
    if k == 1 {
        return Ok((current, accepted));
    }
    // The grid and the context MLP do not depend on the anchors: the sample's pruned
    // structure applies to every anchor.
    let mut pruned = full;
    pruned.dims.res_3d = current.dims.res_3d;
    pruned.dims.res_2d = current.dims.res_2d;
    pruned.grid = current.grid;
    pruned.mlp_grid = current.mlp_grid;
    Ok((pruned, accepted))
}
