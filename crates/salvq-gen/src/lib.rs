//! The synthetic scene generator (spec Annex B, informative).
//!
//! [`generate`] makes a realistic [`SceneModel`] of any size from a seed, so the tools run with no
//! downloads and benchmarks can scale the scene:
//!
//! | step | module | Annex B |
//! |------|--------|---------|
//! | random streams (SplitMix64, counter-based) | [`rng`] | B.1 |
//! | deterministic exp / ln / sin / cos, Householder QR | [`detmath`], [`linalg`] | B.2 |
//! | primitive surfaces, density field, roughness, clusters | [`scene`] | B.3.1-B.3.2 |
//! | voxel size, floaters, N distinct voxels, Morton order | [`surfaces`] | B.3.3-B.3.4 |
//! | binary hash grid and its interpolation | [`grid`] | B.4.1-B.4.2 |
//! | the context MLP `mlp_grid`: layout, evaluation, construction | [`context`] | B.4.3 |
//! | features, scalings, offsets, masks drawn around the MLP's predictions | [`attributes`] | B.5 |
//! | Scaffold-GS MLPs (opacity, cov, color) | [`scaffold`] | B.6 |
//! | steps, per-rate gains, lattice bases | [`quant`] | B.7 |
//!
//! The output is a pure function of [`GenParams`]: the same bytes on every machine, in debug or
//! release, with any number of threads. Only IEEE-754 basic operations are used on floats (no
//! libm calls, no fused multiply-add), every random value comes from a stream named by what it
//! is for (anchor `a` uses stream `(seed, ANCHOR, a)` with `a` its index in Morton order), and no
//! hash-set iteration order reaches the output.

pub mod attributes;
pub mod context;
mod context_build;
pub mod detmath;
pub mod gaussians;
pub mod grid;
pub mod linalg;
pub mod quant;
pub mod rng;
pub mod scaffold;
pub mod scene;
pub mod stats;
pub mod surfaces;

#[cfg(test)]
mod tests;
#[cfg(test)]
mod tests_report;

use salvq_bitstream::model::validate::check_dims;
use salvq_bitstream::model::{Dims, LatticeKind, SceneModel};

/// What to generate: the scene size and seed, and the model dimensions (spec §2.1).
#[derive(Debug, Clone, PartialEq)]
pub struct GenParams {
    /// N: number of anchors (distinct voxels).
    pub anchors: u32,
    pub seed: u64,
    /// F.
    pub feat_dim: u16,
    /// K.
    pub offsets: u16,
    /// M.
    pub rates: u8,
    /// C.
    pub grid_channels: u8,
    pub res_3d: Vec<u16>,
    pub res_2d: Vec<u16>,
    pub log2_size_3d: u8,
    pub log2_size_2d: u8,
    /// H.
    pub context_hidden: u16,
    /// Hs.
    pub scaffold_hidden: u16,
    /// V.
    pub view_dims: u8,
    pub feat_basis: bool,
    pub scaling_basis: bool,
    /// Feature correlation (Annex B.4.3 part 1): the mixing matrix's singular values decay
    /// as `feat_decay^i`; 1 gives uncorrelated residuals. Default [`context::FEAT_DECAY`].
    pub feat_decay: f64,
}

/// Scaling dimensions: always 6 (Scaffold-GS).
pub const SCALING_DIM: u16 = 6;

impl GenParams {
    /// HAC defaults: F = 50, K = 10, M = 4 rates, C = 4 channels,
    /// res_3d = (18, 24, 33, 44, 59, 80, 108, 148, 201, 275, 376, 514),
    /// res_2d = (130, 258, 514, 1026), log2 sizes 13 / 15, context hidden 2F = 100,
    /// scaffold hidden F = 50, view_dims 3, feature basis on, scaling basis off.
    pub fn new(anchors: u32, seed: u64) -> Self {
        GenParams {
            anchors,
            seed,
            feat_dim: 50,
            offsets: 10,
            rates: 4,
            grid_channels: 4,
            res_3d: vec![18, 24, 33, 44, 59, 80, 108, 148, 201, 275, 376, 514],
            res_2d: vec![130, 258, 514, 1026],
            log2_size_3d: 13,
            log2_size_2d: 15,
            context_hidden: 100,
            scaffold_hidden: 50,
            view_dims: 3,
            feat_basis: true,
            scaling_basis: false,
            feat_decay: context::FEAT_DECAY,
        }
    }

    /// The same scene process with a tiny model, for unit and snapshot tests: F = 8, K = 4,
    /// M = 2, C = 2, res_3d = (4, 8), res_2d = (8), log2 sizes 6 / 6, hidden 8 / 8, view_dims 3,
    /// feature basis on, scaling basis off (about 6 KB of model tensors; the anchors add
    /// 120 bytes each).
    pub fn small(anchors: u32, seed: u64) -> Self {
        GenParams {
            anchors,
            seed,
            feat_dim: 8,
            offsets: 4,
            rates: 2,
            grid_channels: 2,
            res_3d: vec![4, 8],
            res_2d: vec![8],
            log2_size_3d: 6,
            log2_size_2d: 6,
            context_hidden: 8,
            scaffold_hidden: 8,
            view_dims: 3,
            feat_basis: true,
            scaling_basis: false,
            feat_decay: context::FEAT_DECAY,
        }
    }

    /// The model dimensions these parameters produce.
    pub fn dims(&self) -> Dims {
        Dims {
            anchors: self.anchors,
            feat_dim: self.feat_dim,
            offsets: self.offsets,
            scaling_dim: SCALING_DIM,
            rates: self.rates,
            grid_channels: self.grid_channels,
            res_3d: self.res_3d.clone(),
            res_2d: self.res_2d.clone(),
            log2_size_3d: self.log2_size_3d,
            log2_size_2d: self.log2_size_2d,
            context_hidden: self.context_hidden,
            scaffold_hidden: self.scaffold_hidden,
            view_dims: self.view_dims,
            feat_lattice: lattice(self.feat_basis),
            scaling_lattice: lattice(self.scaling_basis),
            feat_regions: 1,
            scaling_regions: 1,
        }
    }
}

/// The lattice a generated group gets: a general basis or the identity (Annex B.7).
fn lattice(basis: bool) -> LatticeKind {
    if basis {
        LatticeKind::General
    } else {
        LatticeKind::Identity
    }
}

/// Smallest bit count holding every coordinate (at least 1), as `SceneModel::coord_bits`.
fn coord_bits(voxels: &[[u32; 3]]) -> u8 {
    let max = voxels
        .iter()
        .flat_map(|v| v.iter().copied())
        .max()
        .unwrap_or(0);
    (32 - max.leading_zeros()).max(1) as u8
}

/// Generates a scene model (Annex B), in canonical (Morton) order, that passes
/// [`validate_model`](salvq_bitstream::model::validate::validate_model).
///
/// # Panics
/// Only if the dimensions of `p` break a range of spec Table 1-4 (`check_dims`): callers
/// validate parameters first. Any seed is fine. The result holds about N (4F + 13K + 36) bytes
/// of anchor tensors plus the model; sampling the geometry needs about 40 N bytes more.
pub fn generate(p: &GenParams) -> SceneModel {
    let dims = p.dims();
    if let Err(e) = check_dims(&dims) {
        panic!("crate::generate: invalid dimensions: {e}");
    }
    let seed = p.seed;
    let n = p.anchors as usize;
    // B.3 geometry.
    let geo = surfaces::generate(seed, p.anchors);
    let voxel = f64::from(geo.voxel_size);
    // B.4 hyperprior.
    let grid = grid::grid(&dims, seed);
    let interp = grid::Interp::new(&dims, coord_bits(&geo.voxels));
    let plan = context_build::context_plan(&dims, seed, voxel, n, p.feat_decay, |a, x| {
        interp.features(&grid, geo.voxels[a], x)
    });
    // B.5 attributes.
    let anchors = attributes::generate(&attributes::Inputs {
        dims: &dims,
        seed,
        plan: &plan,
        interp: &interp,
        grid: &grid,
        voxels: &geo.voxels,
    });
    // B.6 Scaffold-GS MLPs, B.7 quantizers.
    let k = usize::from(p.offsets);
    let mlp_opacity = scaffold::mlp(&dims, seed, 0, &scaffold::OPACITY, k);
    let mlp_cov = scaffold::mlp(&dims, seed, 1, &scaffold::COV, 7 * k);
    let mlp_color = scaffold::mlp(&dims, seed, 2, &scaffold::COLOR, 3 * k);
    let quant_feat = quant::group(
        seed,
        0,
        quant::STEP_FEAT,
        p.rates,
        p.feat_dim.into(),
        p.feat_basis,
    );
    let quant_scaling = quant::group(
        seed,
        1,
        linalg::round_f32(quant::STEP_SCALING_PER_VOXEL * voxel),
        p.rates,
        SCALING_DIM.into(),
        p.scaling_basis,
    );
    let quant_offsets = quant::group(seed, 2, quant::STEP_OFFSETS, p.rates, 3, false);
    SceneModel {
        dims,
        origin: geo.origin,
        voxel_size: geo.voxel_size,
        anchors,
        grid,
        mlp_grid: plan.mlp,
        mlp_opacity,
        mlp_cov,
        mlp_color,
        quant_feat,
        quant_scaling,
        quant_offsets,
    }
}
