//! The scene model (spec §2): every tensor a stream carries, with its name, dtype and shape.
//!
//! [`SceneModel`] is both the encoder's input and the decoder's output. Its tensors are
//! listed, in the spec's order, by [`tensor_table`] (spec Table 2-1); the interchange file
//! (Annex A, written by the encoder crate) and the preflight's `decoded_bytes` (§1.4) are both derived
//! from that one table.

pub mod lattice_kind;
pub mod validate;

use std::fmt;

pub use lattice_kind::LatticeKind;

/// Element type of a tensor (spec §0.2).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Dtype {
    /// IEEE 754 binary32, little-endian.
    F32,
    /// Two's-complement 32-bit integer, little-endian.
    I32,
    /// Unsigned byte.
    U8,
    /// Signed byte.
    I8,
}

impl Dtype {
    /// Bytes per element.
    pub fn size(self) -> u64 {
        match self {
            Dtype::F32 | Dtype::I32 => 4,
            Dtype::U8 | Dtype::I8 => 1,
        }
    }
}

impl fmt::Display for Dtype {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Dtype::F32 => "F32",
            Dtype::I32 => "I32",
            Dtype::U8 => "U8",
            Dtype::I8 => "I8",
        })
    }
}

/// The dimensions that fix every tensor's shape (spec §2.1, carried by `HEAD`, §1.4).
#[derive(Debug, Clone, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
pub struct Dims {
    /// N: number of anchors.
    pub anchors: u32,
    /// F: latent feature dimensions per anchor.
    pub feat_dim: u16,
    /// K: offsets (neural Gaussians) per anchor.
    pub offsets: u16,
    /// S: scaling dimensions per anchor (6 in Scaffold-GS / HAC).
    pub scaling_dim: u16,
    /// M: rates, i.e. gains per attribute group.
    pub rates: u8,
    /// C: hash-grid feature channels per level.
    pub grid_channels: u8,
    /// Resolutions of the 3D hash-grid levels (L3 of them).
    pub res_3d: Vec<u16>,
    /// Resolutions of the 2D plane levels (L2 of them, shared by the xy, xz and yz planes).
    pub res_2d: Vec<u16>,
    /// log2 of the largest table size of a 3D level.
    pub log2_size_3d: u8,
    /// log2 of the largest table size of a 2D level.
    pub log2_size_2d: u8,
    /// H: hidden width of the hyperprior context MLP (`mlp_grid`).
    pub context_hidden: u16,
    /// Hs: hidden width of the Scaffold-GS MLPs (`mlp_opacity`, `mlp_cov`, `mlp_color`).
    pub scaffold_hidden: u16,
    /// V: view inputs of the Scaffold-GS MLPs after the feature (3: direction; 4: + distance).
    pub view_dims: u8,
    /// The feature group's lattice (spec §7.1); `General` stores `quant.feat.basis_*`.
    pub feat_lattice: LatticeKind,
    /// The scaling group's lattice (FS-SALVQ when not the identity).
    pub scaling_lattice: LatticeKind,
    /// Spatial regions of the feature group, each with its own basis (Sp-SALVQ, spec §7.6):
    /// 1, or more with a general lattice.
    pub feat_regions: u16,
    /// Spatial regions of the scaling group (as `feat_regions`).
    pub scaling_regions: u16,
}

/// Entries in one hash-grid level of dimension `d` (spec §2.4): the dense grid
/// `(res + 1)^d` when it fits in `2^log2`, else `2^log2` (hashed).
pub fn level_entries(res: u16, d: u32, log2: u8) -> u64 {
    let dense = (u64::from(res) + 1).saturating_pow(d);
    dense.min(1u64 << log2.min(63))
}

impl Dims {
    /// E3: entries of all 3D levels together.
    pub fn entries_3d(&self) -> u64 {
        self.res_3d
            .iter()
            .map(|&r| level_entries(r, 3, self.log2_size_3d))
            .sum()
    }

    /// E2: entries of all 2D levels of one plane together.
    pub fn entries_2d(&self) -> u64 {
        self.res_2d
            .iter()
            .map(|&r| level_entries(r, 2, self.log2_size_2d))
            .sum()
    }

    /// Input width of the context MLP: C * (L3 + 3 L2).
    pub fn context_input(&self) -> u64 {
        u64::from(self.grid_channels) * (self.res_3d.len() as u64 + 3 * self.res_2d.len() as u64)
    }

    /// Output width of the context MLP: 2 (F + S + 3K) + 3 (spec §2.5).
    pub fn context_output(&self) -> u64 {
        2 * (u64::from(self.feat_dim) + u64::from(self.scaling_dim) + 3 * u64::from(self.offsets))
            + 3
    }

    /// Input width of the Scaffold-GS MLPs: F + V.
    pub fn scaffold_input(&self) -> u64 {
        u64::from(self.feat_dim) + u64::from(self.view_dims)
    }
}

/// Tensor names of the schema (spec Table 2-1), as constants so code and spec share one spelling.
pub mod names {
    /// Tensor name of Table 2-1.
    pub const ORIGIN: &str = "geometry.origin";
    /// Tensor name of Table 2-1.
    pub const VOXEL_SIZE: &str = "geometry.voxel_size";
    /// Tensor name of Table 2-1.
    pub const VOXEL: &str = "anchor.voxel";
    /// Tensor name of Table 2-1.
    pub const MASK: &str = "anchor.mask";
    /// Tensor name of Table 2-1.
    pub const FEAT: &str = "anchor.feat";
    /// Tensor name of Table 2-1.
    pub const SCALING: &str = "anchor.scaling";
    /// Tensor name of Table 2-1.
    pub const OFFSETS: &str = "anchor.offsets";
    /// Tensor name of Table 2-1.
    pub const RES_3D: &str = "hyperprior.resolutions_3d";
    /// Tensor name of Table 2-1.
    pub const RES_2D: &str = "hyperprior.resolutions_2d";
    /// Tensor name of Table 2-1.
    pub const LOG2_SIZE: &str = "hyperprior.log2_size";
    /// Tensor name of Table 2-1.
    pub const GRID_3D: &str = "hyperprior.grid_3d";
    /// Tensor name of Table 2-1.
    pub const GRID_XY: &str = "hyperprior.grid_xy";
    /// Tensor name of Table 2-1.
    pub const GRID_XZ: &str = "hyperprior.grid_xz";
    /// Tensor name of Table 2-1.
    pub const GRID_YZ: &str = "hyperprior.grid_yz";
    /// Tensor names of Table 2-1.
    pub const MLP_GRID: [&str; 4] = [
        "mlp_grid.0.weight",
        "mlp_grid.0.bias",
        "mlp_grid.2.weight",
        "mlp_grid.2.bias",
    ];
    /// Tensor names of Table 2-1.
    pub const MLP_OPACITY: [&str; 4] = [
        "mlp_opacity.0.weight",
        "mlp_opacity.0.bias",
        "mlp_opacity.2.weight",
        "mlp_opacity.2.bias",
    ];
    /// Tensor names of Table 2-1.
    pub const MLP_COV: [&str; 4] = [
        "mlp_cov.0.weight",
        "mlp_cov.0.bias",
        "mlp_cov.2.weight",
        "mlp_cov.2.bias",
    ];
    /// Tensor names of Table 2-1.
    pub const MLP_COLOR: [&str; 4] = [
        "mlp_color.0.weight",
        "mlp_color.0.bias",
        "mlp_color.2.weight",
        "mlp_color.2.bias",
    ];
    /// Per group (feat, scaling, offsets): step, gains, basis_u, basis_s, basis_v.
    pub const QUANT_FEAT: [&str; 5] = [
        "quant.feat.step",
        "quant.feat.gains",
        "quant.feat.basis_u",
        "quant.feat.basis_s",
        "quant.feat.basis_v",
    ];
    /// Regions 1 … R−1 of the feature group (Sp-SALVQ, §7.6): first anchor, then the factors.
    pub const QUANT_FEAT_REGIONS: [&str; 4] = [
        "quant.feat.regions.start",
        "quant.feat.regions.basis_u",
        "quant.feat.regions.basis_s",
        "quant.feat.regions.basis_v",
    ];
    /// Regions 1 … R−1 of the scaling group.
    pub const QUANT_SCALING_REGIONS: [&str; 4] = [
        "quant.scaling.regions.start",
        "quant.scaling.regions.basis_u",
        "quant.scaling.regions.basis_s",
        "quant.scaling.regions.basis_v",
    ];
    /// Tensor names of Table 2-1.
    pub const QUANT_SCALING: [&str; 5] = [
        "quant.scaling.step",
        "quant.scaling.gains",
        "quant.scaling.basis_u",
        "quant.scaling.basis_s",
        "quant.scaling.basis_v",
    ];
    /// Tensor names of Table 2-1.
    pub const QUANT_OFFSETS: [&str; 2] = ["quant.offsets.step", "quant.offsets.gains"];
}

/// One row of spec Table 2-1.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TensorEntry {
    /// The tensor's name (Table 2-1).
    pub name: &'static str,
    /// Its element type.
    pub dtype: Dtype,
    /// Its shape, outermost dimension first.
    pub shape: Vec<u64>,
}

impl TensorEntry {
    /// Number of elements (saturating: used only after the dimensions passed their range checks).
    pub fn elements(&self) -> u64 {
        self.shape.iter().fold(1u64, |a, &d| a.saturating_mul(d))
    }

    /// Bytes in the decoded form.
    pub fn bytes(&self) -> u64 {
        self.elements().saturating_mul(self.dtype.size())
    }
}

/// Every tensor of a model with these dimensions, in the spec's order (Table 2-1).
pub fn tensor_table(d: &Dims) -> Vec<TensorEntry> {
    use names::*;
    let n = u64::from(d.anchors);
    let f = u64::from(d.feat_dim);
    let k = u64::from(d.offsets);
    let s = u64::from(d.scaling_dim);
    let m = u64::from(d.rates);
    let c = u64::from(d.grid_channels);
    let h = u64::from(d.context_hidden);
    let hs = u64::from(d.scaffold_hidden);
    let e = |name, dtype, shape: &[u64]| TensorEntry {
        name,
        dtype,
        shape: shape.to_vec(),
    };
    let mut t = vec![
        e(ORIGIN, Dtype::F32, &[3]),
        e(VOXEL_SIZE, Dtype::F32, &[1]),
        e(VOXEL, Dtype::I32, &[n, 3]),
        e(MASK, Dtype::U8, &[n, k]),
        e(FEAT, Dtype::F32, &[n, f]),
        e(SCALING, Dtype::F32, &[n, s]),
        e(OFFSETS, Dtype::F32, &[n, k, 3]),
        e(RES_3D, Dtype::I32, &[d.res_3d.len() as u64]),
        e(RES_2D, Dtype::I32, &[d.res_2d.len() as u64]),
        e(LOG2_SIZE, Dtype::I32, &[2]),
        e(GRID_3D, Dtype::I8, &[d.entries_3d(), c]),
        e(GRID_XY, Dtype::I8, &[d.entries_2d(), c]),
        e(GRID_XZ, Dtype::I8, &[d.entries_2d(), c]),
        e(GRID_YZ, Dtype::I8, &[d.entries_2d(), c]),
    ];
    let mlp = |t: &mut Vec<TensorEntry>, names: [&'static str; 4], i: u64, hid: u64, o: u64| {
        t.push(e(names[0], Dtype::F32, &[hid, i]));
        t.push(e(names[1], Dtype::F32, &[hid]));
        t.push(e(names[2], Dtype::F32, &[o, hid]));
        t.push(e(names[3], Dtype::F32, &[o]));
    };
    mlp(&mut t, MLP_GRID, d.context_input(), h, d.context_output());
    let si = d.scaffold_input();
    mlp(&mut t, MLP_OPACITY, si, hs, k);
    mlp(&mut t, MLP_COV, si, hs, 7 * k);
    mlp(&mut t, MLP_COLOR, si, hs, 3 * k);
    let group = |t: &mut Vec<TensorEntry>,
                 names: &[&'static str],
                 region_names: &[&'static str; 4],
                 dim: u64,
                 basis: bool,
                 regions: u16| {
        t.push(e(names[0], Dtype::F32, &[1]));
        t.push(e(names[1], Dtype::F32, &[m]));
        if basis {
            t.push(e(names[2], Dtype::F32, &[dim, dim]));
            t.push(e(names[3], Dtype::F32, &[dim]));
            t.push(e(names[4], Dtype::F32, &[dim, dim]));
            let more = u64::from(regions.max(1)) - 1;
            if more > 0 {
                t.push(e(region_names[0], Dtype::I32, &[more]));
                t.push(e(region_names[1], Dtype::F32, &[more, dim, dim]));
                t.push(e(region_names[2], Dtype::F32, &[more, dim]));
                t.push(e(region_names[3], Dtype::F32, &[more, dim, dim]));
            }
        }
    };
    group(
        &mut t,
        &QUANT_FEAT,
        &QUANT_FEAT_REGIONS,
        f,
        d.feat_lattice.has_factors(),
        d.feat_regions,
    );
    group(
        &mut t,
        &QUANT_SCALING,
        &QUANT_SCALING_REGIONS,
        s,
        d.scaling_lattice.has_factors(),
        d.scaling_regions,
    );
    group(&mut t, &QUANT_OFFSETS, &[""; 4], 3, false, 1);
    t
}

/// Total bytes of the decoded model: the sum over Table 2-1 (the preflight's `decoded_bytes`).
pub fn decoded_bytes(d: &Dims) -> u64 {
    tensor_table(d)
        .iter()
        .fold(0u64, |a, t| a.saturating_add(t.bytes()))
}

/// A two-layer MLP `Linear(in, hidden) -> activation -> Linear(hidden, out)` (spec §2.5),
/// weights row-major `[out, in]` as PyTorch stores them.
#[derive(Debug, Clone, PartialEq)]
pub struct Mlp {
    /// Layer 0 weights `[hidden, in]`.
    pub w0: Vec<f32>,
    /// Layer 0 biases `[hidden]`.
    pub b0: Vec<f32>,
    /// Layer 1 weights `[out, hidden]`.
    pub w1: Vec<f32>,
    /// Layer 1 biases `[out]`.
    pub b1: Vec<f32>,
}

/// Lattice basis B = U diag(s) V^T of one attribute group (spec §2.6), U and V row-major.
#[derive(Debug, Clone, PartialEq)]
pub struct Basis {
    /// U, `[d, d]` row-major.
    pub u: Vec<f32>,
    /// The diagonal s, `[d]`, every entry positive.
    pub s: Vec<f32>,
    /// V, `[d, d]` row-major.
    pub v: Vec<f32>,
}

/// Quantizer of one attribute group: base step, per-rate gains, optional general basis.
#[derive(Debug, Clone, PartialEq)]
pub struct GroupQuantizer {
    /// The base step Δ (§7.3), positive.
    pub step: f32,
    /// One gain per rate (§7.4): rate r quantizes with step Δ·`gains[r]`.
    pub gains: Vec<f32>,
    /// The factors of a general lattice basis (`Some` exactly when the group's
    /// [`LatticeKind`] in [`Dims`] is `General`); with regions, region 0's.
    pub basis: Option<Basis>,
    /// Regions 1 … R−1 of a general lattice (Sp-SALVQ, spec §7.6), by increasing first
    /// anchor; empty for one region.
    pub regions: Vec<Region>,
}

/// A spatial region of a group's anchors with its own basis (Sp-SALVQ, spec §7.6): anchors
/// `start` … (the next region's start − 1), in canonical order.
#[derive(Debug, Clone, PartialEq)]
pub struct Region {
    /// The region's first anchor, in canonical order.
    pub start: u32,
    /// The region's basis factors.
    pub basis: Basis,
}

impl GroupQuantizer {
    /// The basis of the region holding canonical anchor `anchor` (`None` without a basis).
    pub fn basis_of(&self, anchor: u32) -> Option<&Basis> {
        let later = self.regions.partition_point(|r| r.start <= anchor);
        match later {
            0 => self.basis.as_ref(),
            k => Some(&self.regions[k - 1].basis),
        }
    }

    /// Every region's basis in order, region 0 first (empty without a basis).
    pub fn bases(&self) -> Vec<&Basis> {
        self.basis
            .iter()
            .chain(self.regions.iter().map(|r| &r.basis))
            .collect()
    }

    /// First anchor of every region, region 0 (anchor 0) first.
    pub fn region_starts(&self) -> Vec<u32> {
        std::iter::once(0)
            .chain(self.regions.iter().map(|r| r.start))
            .collect()
    }
}

/// The binary hash grid (spec §2.4): values are -1 or +1, row-major `[entries, C]`.
#[derive(Debug, Clone, PartialEq)]
pub struct HashGrid {
    /// The 3D levels' entries, level after level.
    pub grid_3d: Vec<i8>,
    /// The xy plane's 2D levels' entries.
    pub grid_xy: Vec<i8>,
    /// The xz plane's 2D levels' entries.
    pub grid_xz: Vec<i8>,
    /// The yz plane's 2D levels' entries.
    pub grid_yz: Vec<i8>,
}

/// Per-anchor attributes (spec §2.2, §2.3), row-major with the anchor index first.
#[derive(Debug, Clone, PartialEq)]
pub struct Anchors {
    /// Integer voxel coordinates `[N, 3]`; position = origin + voxel_size * voxel.
    pub voxel: Vec<[u32; 3]>,
    /// Offset masks `[N, K]`, each 0 or 1.
    pub mask: Vec<u8>,
    /// Latent features `[N, F]`.
    pub feat: Vec<f32>,
    /// Scalings `[N, S]` (activated, as HAC codes them).
    pub scaling: Vec<f32>,
    /// Offsets `[N, K, 3]`.
    pub offsets: Vec<f32>,
}

/// A complete scene model: the encoder's input and the decoder's output.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneModel {
    /// The scene's dimensions (Table 1-4).
    pub dims: Dims,
    /// World position of voxel (0, 0, 0)'s corner (§2.2).
    pub origin: [f32; 3],
    /// Edge length of a voxel in world units (§2.2).
    pub voxel_size: f32,
    /// The anchors, in canonical (Morton) order (§2.2).
    pub anchors: Anchors,
    /// The hyperprior's binary hash grid (§2.4).
    pub grid: HashGrid,
    /// The hyperprior's context MLP (§2.5, §5.3).
    pub mlp_grid: Mlp,
    /// Scaffold-GS opacity MLP (§2.5, Annex C.1).
    pub mlp_opacity: Mlp,
    /// Scaffold-GS covariance MLP: scales and rotations (§2.5, Annex C.1).
    pub mlp_cov: Mlp,
    /// Scaffold-GS colour MLP (§2.5, Annex C.1).
    pub mlp_color: Mlp,
    /// The feature group's quantizer (§7).
    pub quant_feat: GroupQuantizer,
    /// The scaling group's quantizer (§7).
    pub quant_scaling: GroupQuantizer,
    /// The offset group's quantizer (§7; always the identity lattice).
    pub quant_offsets: GroupQuantizer,
}

/// 3D Morton code of a voxel (spec §2.2): bit 3i is x's bit i, 3i+1 is y's, 3i+2 is z's.
pub fn morton3(v: [u32; 3]) -> u64 {
    fn spread(x: u32) -> u64 {
        // Spreads the low 21 bits of x so that bit i lands at bit 3i.
        let mut x = u64::from(x) & 0x1f_ffff;
        x = (x | (x << 32)) & 0x001f_0000_0000_ffff;
        x = (x | (x << 16)) & 0x001f_0000_ff00_00ff;
        x = (x | (x << 8)) & 0x100f_00f0_0f00_f00f;
        x = (x | (x << 4)) & 0x10c3_0c30_c30c_30c3;
        x = (x | (x << 2)) & 0x1249_2492_4924_9249;
        x
    }
    spread(v[0]) | (spread(v[1]) << 1) | (spread(v[2]) << 2)
}

impl SceneModel {
    /// Number of anchors as a `usize`.
    pub fn n(&self) -> usize {
        self.dims.anchors as usize
    }

    /// The model with its anchors sorted into canonical Morton order (spec §2.2),
    /// ties kept in input order. Streams always carry anchors in this order.
    pub fn to_canonical_order(&self) -> SceneModel {
        let n = self.n();
        let mut order: Vec<usize> = (0..n).collect();
        order.sort_by_key(|&i| morton3(self.anchors.voxel[i]));
        if order.iter().enumerate().all(|(i, &o)| i == o) {
            return self.clone();
        }
        let d = &self.dims;
        let gather = |src: &[f32], w: usize| -> Vec<f32> {
            order
                .iter()
                .flat_map(|&i| src[i * w..(i + 1) * w].iter().copied())
                .collect()
        };
        let k = usize::from(d.offsets);
        let anchors = Anchors {
            voxel: order.iter().map(|&i| self.anchors.voxel[i]).collect(),
            mask: order
                .iter()
                .flat_map(|&i| self.anchors.mask[i * k..(i + 1) * k].iter().copied())
                .collect(),
            feat: gather(&self.anchors.feat, usize::from(d.feat_dim)),
            scaling: gather(&self.anchors.scaling, usize::from(d.scaling_dim)),
            offsets: gather(&self.anchors.offsets, 3 * k),
        };
        SceneModel {
            anchors,
            ..self.clone()
        }
    }

    /// Whether the anchors are in non-decreasing Morton order.
    pub fn is_canonical(&self) -> bool {
        self.anchors
            .voxel
            .windows(2)
            .all(|w| morton3(w[0]) <= morton3(w[1]))
    }

    /// Smallest `coord_bits` (§1.4) that holds every voxel coordinate (at least 1).
    pub fn coord_bits(&self) -> u8 {
        let max = self
            .anchors
            .voxel
            .iter()
            .flat_map(|v| v.iter().copied())
            .max()
            .unwrap_or(0);
        (32 - max.leading_zeros()).max(1) as u8
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn morton_interleaves_x_lowest() {
        assert_eq!(morton3([1, 0, 0]), 0b001);
        assert_eq!(morton3([0, 1, 0]), 0b010);
        assert_eq!(morton3([0, 0, 1]), 0b100);
        assert_eq!(morton3([2, 0, 0]), 0b001_000);
        assert_eq!(morton3([0x1f_ffff, 0, 0]), 0x1249_2492_4924_9249);
        assert_eq!(morton3([0x1f_ffff; 3]), (1u64 << 63) - 1);
    }

    #[test]
    fn level_entries_dense_then_hashed() {
        assert_eq!(level_entries(18, 3, 13), 19 * 19 * 19);
        assert_eq!(level_entries(24, 3, 13), 8192);
        assert_eq!(level_entries(130, 2, 15), 131 * 131);
        assert_eq!(level_entries(258, 2, 15), 32768);
    }
}
