//! The realism statistics of Annex B Table B-3, measured on a generated [`SceneModel`]: what
//! the generator's tests check, and what `examples/statistics.rs` prints.

use std::collections::HashSet;

use crate::grid::Interp;
use crate::linalg::sym_eigenvalues;
use salvq_bitstream::model::SceneModel;

/// Each voxel's Euclidean distance to its nearest other voxel, in voxels (searched within 64).
pub fn nn_distances(voxels: &[[u32; 3]]) -> Vec<f64> {
    let set: HashSet<[i64; 3]> = voxels.iter().map(|v| v.map(i64::from)).collect();
    voxels
        .iter()
        .map(|v| {
            let v = v.map(i64::from);
            let mut best = i64::MAX;
            for r in 1i64..=64 {
                if best <= r * r {
                    break;
                }
                for dx in -r..=r {
                    for dy in -r..=r {
                        for dz in -r..=r {
                            if dx.abs().max(dy.abs()).max(dz.abs()) == r
                                && set.contains(&[v[0] + dx, v[1] + dy, v[2] + dz])
                            {
                                best = best.min(dx * dx + dy * dy + dz * dz);
                            }
                        }
                    }
                }
            }
            (best as f64).sqrt()
        })
        .collect()
}

/// The `q` quantile of `v` (0 to 1; the lower of the two values around it).
pub fn quantile(mut v: Vec<f64>, q: f64) -> f64 {
    v.sort_by(f64::total_cmp);
    v[((v.len() - 1) as f64 * q) as usize]
}

/// The stored mlp_grid evaluated at every anchor, from the model's tensors alone.
pub fn context_outputs(m: &SceneModel) -> Vec<Vec<f64>> {
    let d = &m.dims;
    let interp = Interp::new(d, m.coord_bits());
    let (i, h, o) = (
        d.context_input() as usize,
        usize::from(d.context_hidden),
        d.context_output() as usize,
    );
    let g = &m.mlp_grid;
    m.anchors
        .voxel
        .iter()
        .map(|&v| {
            let mut x = vec![0.0; i];
            interp.features(&m.grid, v, &mut x);
            let hv: Vec<f64> = (0..h)
                .map(|r| {
                    (f64::from(g.b0[r])
                        + (0..i)
                            .map(|c| f64::from(g.w0[r * i + c]) * x[c])
                            .sum::<f64>())
                    .max(0.0)
                })
                .collect();
            (0..o)
                .map(|r| {
                    f64::from(g.b1[r])
                        + (0..h)
                            .map(|c| f64::from(g.w1[r * h + c]) * hv[c])
                            .sum::<f64>()
                })
                .collect()
        })
        .collect()
}

/// The fraction of active offsets, and of anchors whose offsets are all inactive.
pub fn mask_fractions(m: &SceneModel) -> (f64, f64) {
    let k = usize::from(m.dims.offsets);
    let active =
        m.anchors.mask.iter().filter(|&&b| b == 1).count() as f64 / m.anchors.mask.len() as f64;
    let dead = m
        .anchors
        .mask
        .chunks(k)
        .filter(|c| c.iter().all(|&b| b == 0))
        .count() as f64
        / m.n() as f64;
    (active, dead)
}

/// Share of the total feature variance carried by the top `t` principal components.
pub fn pca_share(m: &SceneModel, t: usize) -> f64 {
    let f = usize::from(m.dims.feat_dim);
    let n = m.n() as f64;
    let mean: Vec<f64> = (0..f)
        .map(|d| {
            m.anchors
                .feat
                .chunks(f)
                .map(|r| f64::from(r[d]))
                .sum::<f64>()
                / n
        })
        .collect();
    let mut cov = vec![0.0; f * f];
    for r in m.anchors.feat.chunks(f) {
        for a in 0..f {
            for b in 0..f {
                cov[a * f + b] += (f64::from(r[a]) - mean[a]) * (f64::from(r[b]) - mean[b]) / n;
            }
        }
    }
    let ev = sym_eigenvalues(cov, f);
    ev.iter().take(t).sum::<f64>() / ev.iter().sum::<f64>()
}
