//! Models for conformance vectors whose dimensions the synthetic generator (Annex B) does not
//! make: the largest values Table 1-4 allows. Values are seeded draws, valid by §2.3 and §2.6,
//! with no scene statistics: these vectors test syntax and arithmetic, not compression.

use salvq_bitstream::model::{
    Anchors, Basis, Dims, GroupQuantizer, HashGrid, Mlp, Region, SceneModel,
};
use salvq_bitstream::quantizer::LatticeKind;
use salvq_gen::linalg::orthogonal;
use salvq_gen::rng::Stream;

/// Draw tags, one per part of the model, so parts do not share draws.
const TAG: u64 = 0x636f_6e66; // "conf"

fn normals(s: &mut Stream, n: usize, scale: f64) -> Vec<f32> {
    (0..n).map(|_| (s.normal() * scale) as f32).collect()
}

fn mlp(s: &mut Stream, input: usize, hidden: usize, output: usize) -> Mlp {
    let w0 = 1.0 / (input as f64).sqrt();
    let w1 = 1.0 / (hidden as f64).sqrt();
    Mlp {
        w0: normals(s, hidden * input, w0),
        b0: normals(s, hidden, 0.1),
        w1: normals(s, output * hidden, w1),
        b1: normals(s, output, 0.1),
    }
}

/// A basis with orthogonal U and V and singular values in [0.5, 2] (condition ≤ 4).
fn basis(s: &mut Stream, d: usize) -> Basis {
    let u = orthogonal(s, d).into_iter().map(|x| x as f32).collect();
    let v = orthogonal(s, d).into_iter().map(|x| x as f32).collect();
    let sv = (0..d).map(|_| s.range(0.5, 2.0) as f32).collect();
    Basis { u, s: sv, v }
}

fn group(
    s: &mut Stream,
    kind: LatticeKind,
    d: usize,
    regions: u16,
    n: u32,
    step: f32,
    rates: u8,
) -> GroupQuantizer {
    let general = kind == LatticeKind::General;
    GroupQuantizer {
        step,
        // Rate i's gain: 2^(−i/8), so every rate has its own step.
        gains: (0..rates).map(|i| (-f32::from(i) / 8.0).exp2()).collect(),
        basis: general.then(|| basis(s, d)),
        regions: if general {
            (1..regions)
                .map(|r| Region {
                    start: (u64::from(n) * u64::from(r) / u64::from(regions)) as u32,
                    basis: basis(s, d),
                })
                .collect()
        } else {
            Vec::new()
        },
    }
}

/// A valid model with dimensions `dims` on `voxels` (any order; `dims.anchors` is set from
/// them), every value a seeded draw.
pub fn synthetic_model(mut dims: Dims, voxels: Vec<[u32; 3]>, seed: u64) -> SceneModel {
    dims.anchors = voxels.len() as u32;
    let n = voxels.len();
    let (f, sd, k) = (
        usize::from(dims.feat_dim),
        usize::from(dims.scaling_dim),
        usize::from(dims.offsets),
    );
    let mut s = Stream::new(seed, TAG, 0);
    let c = usize::from(dims.grid_channels);
    let signs = |s: &mut Stream, entries: u64| -> Vec<i8> {
        (0..entries as usize * c)
            .map(|_| if s.below(2) == 0 { -1 } else { 1 })
            .collect()
    };
    let grid = HashGrid {
        grid_3d: signs(&mut s, dims.entries_3d()),
        grid_xy: signs(&mut s, dims.entries_2d()),
        grid_xz: signs(&mut s, dims.entries_2d()),
        grid_yz: signs(&mut s, dims.entries_2d()),
    };
    let anchors = Anchors {
        voxel: voxels,
        mask: (0..n * k).map(|_| s.below(2) as u8).collect(),
        feat: normals(&mut s, n * f, 1.0),
        scaling: (0..n * sd).map(|_| s.range(0.01, 0.1) as f32).collect(),
        offsets: normals(&mut s, n * k * 3, 1.0),
    };
    let cin = dims.context_input() as usize;
    let cout = dims.context_output() as usize;
    let h = usize::from(dims.context_hidden);
    let hs = usize::from(dims.scaffold_hidden);
    let si = dims.scaffold_input() as usize;
    let mlp_grid = mlp(&mut s, cin, h, cout);
    let mlp_opacity = mlp(&mut s, si, hs, k);
    let mlp_cov = mlp(&mut s, si, hs, 7 * k);
    let mlp_color = mlp(&mut s, si, hs, 3 * k);
    let n32 = dims.anchors;
    let quant_feat = group(
        &mut s,
        dims.feat_lattice,
        f,
        dims.feat_regions,
        n32,
        0.05,
        dims.rates,
    );
    let quant_scaling = group(
        &mut s,
        dims.scaling_lattice,
        sd,
        dims.scaling_regions,
        n32,
        0.002,
        dims.rates,
    );
    let quant_offsets = group(&mut s, LatticeKind::Identity, 3, 1, n32, 0.05, dims.rates);
    SceneModel {
        dims,
        origin: [-1.5, 0.25, 3.0],
        voxel_size: 0.01,
        anchors,
        grid,
        mlp_grid,
        mlp_opacity,
        mlp_cov,
        mlp_color,
        quant_feat,
        quant_scaling,
        quant_offsets,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn synthetic_models_validate_and_round_trip() {
        let dims = Dims {
            anchors: 0,
            feat_dim: 16,
            offsets: 3,
            scaling_dim: 5,
            rates: 3,
            grid_channels: 2,
            res_3d: vec![1, 6],
            res_2d: vec![],
            log2_size_3d: 5,
            log2_size_2d: 5,
            context_hidden: 4,
            scaffold_hidden: 3,
            view_dims: 4,
            feat_lattice: LatticeKind::E8Product,
            scaling_lattice: LatticeKind::General,
            feat_regions: 1,
            scaling_regions: 2,
        };
        let m = synthetic_model(dims, vec![[0, 0, 0], [5, 1, 2], [3, 3, 3]], 9);
        salvq_bitstream::model::validate::validate_model(&m).unwrap();
        let enc = salvq_encoder::encode_full(&m, &Default::default()).unwrap();
        assert_eq!(
            &salvq::decode(&enc.stream)
                .and_then(salvq::Scene::try_into_anchors)
                .unwrap(),
            enc.expected()
        );
    }
}
