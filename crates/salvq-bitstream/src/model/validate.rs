//! Model validation (spec §2.3, §2.6): the checks the encoder runs before it writes a byte,
//! and the dimension ranges (§1.4, Table 1-4) that the decoder also applies to `HEAD`.

use super::{names, Basis, Dims, GroupQuantizer, Mlp, SceneModel};
use crate::entropy::SCALE_INDEX_COUNT;
use crate::error::{Error, Field, Result};

/// Largest accepted condition number max|s_i| / min|s_i| of a lattice basis (spec §2.6).
///
/// Reconstruction B u is computed in binary32 (unit roundoff 6e-8); at a condition number
/// of 1e6 the encoder's B^-1 y already loses all but ~1 significant decimal digit of the
/// smallest lattice direction, so larger values cannot be quantized meaningfully.
pub const MAX_BASIS_CONDITION: f64 = 1e6;

/// Largest accepted |(M^T M - I)_ij| for the orthogonal factors U and V (spec §2.6).
pub const ORTHOGONALITY_TOLERANCE: f64 = 1e-3;

/// Largest voxel coordinate bit depth (spec §1.4): 3 x 21 bits fill a 63-bit Morton code.
pub const MAX_COORD_BITS: u8 = 21;

/// The allowed range of each header field / model dimension (spec Table 1-4).
pub fn field_range(field: Field) -> (u64, u64) {
    match field {
        Field::AnchorCount => (1, u32::MAX as u64),
        Field::FeatDim => (1, 1024),
        Field::OffsetCount => (1, 256),
        Field::ScalingDim => (1, 64),
        Field::RateCount => (1, 64),
        Field::CoordBits => (1, MAX_COORD_BITS as u64),
        Field::GridChannels => (1, 16),
        Field::Levels3d | Field::Levels2d => (0, 32),
        Field::Log2Size3d | Field::Log2Size2d => (1, 24),
        Field::Resolution3d | Field::Resolution2d => (1, u16::MAX as u64),
        Field::ContextInputDim => (1, 16 * 128),
        Field::ContextHidden | Field::ScaffoldHidden => (1, 4096),
        Field::ViewDims => (0, 8),
        Field::W0FracBits | Field::W1FracBits => (0, 30),
        Field::Shift0 => (0, 31),
        Field::ScaffoldPrecision | Field::ContextPrecision => (0, 1),
        Field::FeatLattice | Field::ScalingLattice => (0, 3),
        Field::FeatRegions | Field::ScalingRegions => (1, u16::MAX as u64),
        Field::RegionStart => (1, u32::MAX as u64 - 1),
        Field::TileCount => (1, u32::MAX as u64),
        Field::TileAnchors => (1, u32::MAX as u64),
        Field::TileCellLevel => (0, MAX_COORD_BITS as u64),
        Field::TileCell => (0, u32::MAX as u64),
        // The explicit profile's fields (spec §3.2-§3.4, §3.8).
        Field::GaussianCount => (1, u32::MAX as u64),
        Field::ShDegree => (0, 3),
        Field::PredLevel => (0, MAX_COORD_BITS as u64),
        Field::ScaleTable => (0, SCALE_INDEX_COUNT as u64 - 1),
        Field::RotationFreq | Field::RestCountFreq => (1, u16::MAX as u64),
        Field::PredictFlag => (0, 1),
        Field::Refine => (0, 23),
        Field::Factor => (1, 255),
        Field::RateMask => (1, u64::MAX),
        Field::CodedRate
        | Field::FileFlags
        | Field::HeadFlags
        | Field::VoxelSize
        | Field::Origin => (0, u64::MAX),
    }
}

/// Checks `value` against the field's range and returns it.
pub fn check_field(field: Field, value: u64) -> Result<u64> {
    let (min, max) = field_range(field);
    if value < min || value > max {
        return Err(Error::FieldOutOfRange {
            field,
            value,
            min,
            max,
        });
    }
    Ok(value)
}

/// §7.1: each group's lattice fits its dimension.
pub fn check_lattices(d: &Dims) -> Result<()> {
    for (field, kind, dim) in [
        (Field::FeatLattice, d.feat_lattice, d.feat_dim),
        (Field::ScalingLattice, d.scaling_lattice, d.scaling_dim),
    ] {
        if let Err(rule) = kind.check_dim(dim.into()) {
            return Err(Error::LatticeDimension {
                field,
                lattice: kind.name(),
                dim: dim.into(),
                rule,
            });
        }
    }
    // §1.4 / §7.6: regions need a general lattice, and at most one per anchor.
    for (field, kind, regions) in [
        (Field::FeatRegions, d.feat_lattice, d.feat_regions),
        (Field::ScalingRegions, d.scaling_lattice, d.scaling_regions),
    ] {
        let max = if kind.has_factors() {
            u64::from(d.anchors).clamp(1, u64::from(u16::MAX))
        } else {
            1
        };
        if regions == 0 || u64::from(regions) > max {
            return Err(Error::FieldOutOfRange {
                field,
                value: regions.into(),
                min: 1,
                max,
            });
        }
    }
    Ok(())
}

/// Checks every dimension against spec Table 1-4, then the lattices (§7.1, §7.6).
pub fn check_dims(d: &Dims) -> Result<()> {
    check_dim_fields(d)?;
    check_lattices(d)
}

/// §1.4 step 4, up to `view_dims`: the dimension fields in the spec's order (the lattices are
/// checked after `coord_bits`, which models do not carry).
pub fn check_dim_fields(d: &Dims) -> Result<()> {
    check_field(Field::AnchorCount, d.anchors.into())?;
    check_field(Field::FeatDim, d.feat_dim.into())?;
    check_field(Field::OffsetCount, d.offsets.into())?;
    check_field(Field::ScalingDim, d.scaling_dim.into())?;
    check_field(Field::RateCount, d.rates.into())?;
    check_field(Field::GridChannels, d.grid_channels.into())?;
    check_field(Field::Levels3d, d.res_3d.len() as u64)?;
    check_field(Field::Levels2d, d.res_2d.len() as u64)?;
    check_field(Field::Log2Size3d, d.log2_size_3d.into())?;
    check_field(Field::Log2Size2d, d.log2_size_2d.into())?;
    for &r in &d.res_3d {
        check_field(Field::Resolution3d, r.into())?;
    }
    for &r in &d.res_2d {
        check_field(Field::Resolution2d, r.into())?;
    }
    check_field(Field::ContextInputDim, d.context_input())?;
    check_field(Field::ContextHidden, d.context_hidden.into())?;
    check_field(Field::ScaffoldHidden, d.scaffold_hidden.into())?;
    check_field(Field::ViewDims, d.view_dims.into())?;
    Ok(())
}

/// Checks the geometry header values (§1.4): finite origin, finite positive voxel size.
pub fn check_geometry(origin: &[f32; 3], voxel_size: f32) -> Result<()> {
    for (i, o) in origin.iter().enumerate() {
        if !o.is_finite() {
            return Err(Error::NonFiniteValue {
                tensor: names::ORIGIN,
                index: vec![i as u64],
            });
        }
    }
    if !voxel_size.is_finite() {
        return Err(Error::NonFiniteValue {
            tensor: names::VOXEL_SIZE,
            index: vec![0],
        });
    }
    if voxel_size <= 0.0 {
        return Err(Error::ValueNotPositive {
            tensor: names::VOXEL_SIZE,
            index: vec![0],
            value: voxel_size,
        });
    }
    Ok(())
}

/// Converts a flat index into a multi-dimensional one for error messages.
fn unflatten(flat: usize, shape: &[u64]) -> Vec<u64> {
    let mut rest = flat as u64;
    let mut idx = vec![0; shape.len()];
    for (slot, &dim) in idx.iter_mut().zip(shape).rev() {
        let dim = dim.max(1);
        *slot = rest % dim;
        rest /= dim;
    }
    idx
}

/// Every value finite; the first offender is named with its index.
pub fn check_finite(tensor: &'static str, values: &[f32], shape: &[u64]) -> Result<()> {
    match values.iter().position(|v| !v.is_finite()) {
        Some(i) => Err(Error::NonFiniteValue {
            tensor,
            index: unflatten(i, shape),
        }),
        None => Ok(()),
    }
}

/// Every value finite and > 0 (steps, gains).
pub fn check_positive(tensor: &'static str, values: &[f32]) -> Result<()> {
    check_finite(tensor, values, &[values.len() as u64])?;
    match values.iter().position(|&v| v <= 0.0) {
        Some(i) => Err(Error::ValueNotPositive {
            tensor,
            index: vec![i as u64],
            value: values[i],
        }),
        None => Ok(()),
    }
}

/// §5.4: every rate's step `step ⊗ gain_r` (binary32) is finite and non-zero, so that its
/// exact decomposition exists; reported on the gain: **NonFiniteValue** for an overflow,
/// **ValueNotPositive** (value: the product) for an underflow to 0.
pub fn check_rate_steps(tensor: &'static str, step: f32, gains: &[f32]) -> Result<()> {
    for (r, &g) in gains.iter().enumerate() {
        let product = step * g;
        if !product.is_finite() {
            return Err(Error::NonFiniteValue {
                tensor,
                index: vec![r as u64],
            });
        }
        if product == 0.0 {
            return Err(Error::ValueNotPositive {
                tensor,
                index: vec![r as u64],
                value: product,
            });
        }
    }
    Ok(())
}

fn check_len(tensor: &'static str, found: usize, shape: &[u64]) -> Result<()> {
    let expected: u64 = shape.iter().product();
    if found as u64 != expected {
        return Err(Error::TensorShape {
            tensor,
            expected: shape.to_vec(),
            found: vec![found as u64],
        });
    }
    Ok(())
}

fn check_mlp(names: [&'static str; 4], mlp: &Mlp, i: u64, h: u64, o: u64) -> Result<()> {
    let parts: [(&[f32], Vec<u64>); 4] = [
        (&mlp.w0, vec![h, i]),
        (&mlp.b0, vec![h]),
        (&mlp.w1, vec![o, h]),
        (&mlp.b1, vec![o]),
    ];
    for (name, (values, shape)) in names.iter().zip(parts.iter()) {
        check_len(name, values.len(), shape)?;
        check_finite(name, values, shape)?;
    }
    Ok(())
}

/// Checks that `m` is orthogonal: |(M^T M - I)_ij| <= tolerance for all i, j.
fn check_orthogonal(tensor: &'static str, m: &[f32], n: usize) -> Result<()> {
    for i in 0..n {
        for j in 0..n {
            let dot: f64 = (0..n)
                .map(|r| f64::from(m[r * n + i]) * f64::from(m[r * n + j]))
                .sum();
            let deviation = (dot - if i == j { 1.0 } else { 0.0 }).abs();
            if deviation > ORTHOGONALITY_TOLERANCE {
                return Err(Error::BasisNotOrthogonal {
                    tensor,
                    index: [i as u64, j as u64],
                    deviation,
                    tolerance: ORTHOGONALITY_TOLERANCE,
                });
            }
        }
    }
    Ok(())
}

/// Checks a lattice basis (spec §2.6): finite, U and V orthogonal, s non-zero, bounded condition.
pub fn check_basis(names: &[&'static str; 5], basis: &Basis, dim: u64) -> Result<()> {
    let n = dim as usize;
    check_len(names[2], basis.u.len(), &[dim, dim])?;
    check_len(names[3], basis.s.len(), &[dim])?;
    check_len(names[4], basis.v.len(), &[dim, dim])?;
    check_finite(names[2], &basis.u, &[dim, dim])?;
    check_finite(names[3], &basis.s, &[dim])?;
    check_finite(names[4], &basis.v, &[dim, dim])?;
    if let Some(i) = basis.s.iter().position(|&s| s == 0.0) {
        return Err(Error::BasisSingular {
            tensor: names[3],
            index: i as u64,
        });
    }
    let abs = basis.s.iter().map(|s| f64::from(s.abs()));
    let max = abs.clone().fold(0.0f64, f64::max);
    let min = abs.fold(f64::INFINITY, f64::min);
    let condition = max / min;
    if condition > MAX_BASIS_CONDITION {
        return Err(Error::BasisIllConditioned {
            tensor: names[3],
            condition,
            max: MAX_BASIS_CONDITION,
        });
    }
    if let Some((i, j)) = crate::quantizer::general_matrix_non_finite(n, basis) {
        return Err(Error::NonFiniteValue {
            tensor: names[2],
            index: vec![i as u64, j as u64],
        });
    }
    check_orthogonal(names[2], &basis.u, n)?;
    check_orthogonal(names[4], &basis.v, n)?;
    Ok(())
}

fn check_group(
    names: &[&'static str],
    basis_names: Option<&[&'static str; 5]>,
    q: &GroupQuantizer,
    rates: u8,
    dim: u64,
    flagged: bool,
) -> Result<()> {
    check_positive(names[0], &[q.step])?;
    check_len(names[1], q.gains.len(), &[rates.into()])?;
    check_positive(names[1], &q.gains)?;
    check_rate_steps(names[1], q.step, &q.gains)?;
    match (&q.basis, basis_names, flagged) {
        (Some(b), Some(bn), true) => check_basis(bn, b, dim),
        (None, Some(bn), true) => Err(Error::TensorMissing { tensor: bn[2] }),
        (Some(_), _, _) => Err(Error::TensorUnexpected {
            name: format!("{}.basis_u", names[0].trim_end_matches(".step")),
        }),
        (None, _, _) => Ok(()),
    }
}

/// Validates a whole model (spec §2): shapes against its dimensions, then values,
/// in Table 2-1 order, so the first broken rule is reported.
pub fn validate_model(m: &SceneModel) -> Result<()> {
    check_dims(&m.dims)?;
    check_geometry(&m.origin, m.voxel_size)?;
    check_anchors(m)?;
    check_grid(m)?;
    let d = &m.dims;
    let k = u64::from(d.offsets);
    let hs = u64::from(d.scaffold_hidden);
    let si = d.scaffold_input();
    check_mlp(
        names::MLP_GRID,
        &m.mlp_grid,
        d.context_input(),
        d.context_hidden.into(),
        d.context_output(),
    )?;
    check_mlp(names::MLP_OPACITY, &m.mlp_opacity, si, hs, k)?;
    check_mlp(names::MLP_COV, &m.mlp_cov, si, hs, 7 * k)?;
    check_mlp(names::MLP_COLOR, &m.mlp_color, si, hs, 3 * k)?;
    check_quantizers(m)
}

/// The anchors' tensors (§2.2, §2.3): voxels within 2^21, masks 0 or 1, attributes finite.
fn check_anchors(m: &SceneModel) -> Result<()> {
    let d = &m.dims;
    let n = u64::from(d.anchors);
    let k = u64::from(d.offsets);
    let f = u64::from(d.feat_dim);
    let s = u64::from(d.scaling_dim);
    let a = &m.anchors;
    check_len(names::VOXEL, a.voxel.len(), &[n])
        .map_err(|_| shape_err(names::VOXEL, &[n, 3], a.voxel.len() as u64 * 3))?;
    for (i, v) in a.voxel.iter().enumerate() {
        for (axis, &c) in v.iter().enumerate() {
            if c >> MAX_COORD_BITS != 0 {
                return Err(Error::CoordinateOutOfRange {
                    anchor: i as u64,
                    axis: axis as u8,
                    value: c.into(),
                    coord_bits: MAX_COORD_BITS,
                });
            }
        }
    }
    check_len(names::MASK, a.mask.len(), &[n, k])?;
    if let Some(i) = a.mask.iter().position(|&b| b > 1) {
        return Err(Error::ValueInvalid {
            tensor: names::MASK,
            index: unflatten(i, &[n, k]),
            value: a.mask[i].into(),
            allowed: "0 or 1",
        });
    }
    for (name, values, shape) in [
        (names::FEAT, &a.feat, vec![n, f]),
        (names::SCALING, &a.scaling, vec![n, s]),
        (names::OFFSETS, &a.offsets, vec![n, k, 3]),
    ] {
        check_len(name, values.len(), &shape)?;
        check_finite(name, values, &shape)?;
    }
    Ok(())
}

/// The hash grid's four tables (§2.3, §2.4): every entry −1 or +1.
fn check_grid(m: &SceneModel) -> Result<()> {
    let d = &m.dims;
    let c = u64::from(d.grid_channels);
    for (name, values, entries) in [
        (names::GRID_3D, &m.grid.grid_3d, d.entries_3d()),
        (names::GRID_XY, &m.grid.grid_xy, d.entries_2d()),
        (names::GRID_XZ, &m.grid.grid_xz, d.entries_2d()),
        (names::GRID_YZ, &m.grid.grid_yz, d.entries_2d()),
    ] {
        check_len(name, values.len(), &[entries, c])?;
        if let Some(i) = values.iter().position(|&b| b != 1 && b != -1) {
            return Err(Error::ValueInvalid {
                tensor: name,
                index: unflatten(i, &[entries, c]),
                value: values[i].into(),
                allowed: "-1 or +1",
            });
        }
    }
    Ok(())
}

/// The three groups' quantizers and the feature and scaling regions (§2.6).
fn check_quantizers(m: &SceneModel) -> Result<()> {
    let d = &m.dims;
    let f = u64::from(d.feat_dim);
    let s = u64::from(d.scaling_dim);
    let (qf, qs) = (&names::QUANT_FEAT, &names::QUANT_SCALING);
    check_group(
        qf,
        Some(qf),
        &m.quant_feat,
        d.rates,
        f,
        d.feat_lattice.has_factors(),
    )?;
    check_group(
        qs,
        Some(qs),
        &m.quant_scaling,
        d.rates,
        s,
        d.scaling_lattice.has_factors(),
    )?;
    check_regions(
        qf,
        &names::QUANT_FEAT_REGIONS,
        &m.quant_feat,
        d.feat_regions,
        d.anchors,
        f,
    )?;
    check_regions(
        qs,
        &names::QUANT_SCALING_REGIONS,
        &m.quant_scaling,
        d.scaling_regions,
        d.anchors,
        s,
    )?;
    check_group(
        &names::QUANT_OFFSETS,
        None,
        &m.quant_offsets,
        d.rates,
        3,
        false,
    )
}

/// §7.6: `regions − 1` extra regions with strictly increasing starts in 1 … N − 1, each basis
/// obeying §2.6.
fn check_regions(
    names: &[&'static str; 5],
    region_names: &[&'static str; 4],
    q: &GroupQuantizer,
    regions: u16,
    anchors: u32,
    dim: u64,
) -> Result<()> {
    let more = u64::from(regions.max(1)) - 1;
    check_len(region_names[0], q.regions.len(), &[more])?;
    let mut min = 1u64;
    let max = u64::from(anchors).saturating_sub(1).min(i32::MAX as u64);
    let basis_names = [
        names[0],
        names[1],
        region_names[1],
        region_names[2],
        region_names[3],
    ];
    for r in &q.regions {
        let start = u64::from(r.start);
        if start < min || start > max {
            return Err(Error::FieldOutOfRange {
                field: Field::RegionStart,
                value: start,
                min,
                max,
            });
        }
        min = start + 1;
        check_basis(&basis_names, &r.basis, dim)?;
    }
    Ok(())
}

fn shape_err(tensor: &'static str, expected: &[u64], found: u64) -> Error {
    Error::TensorShape {
        tensor,
        expected: expected.to_vec(),
        found: vec![found],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unflatten_is_row_major() {
        assert_eq!(unflatten(7, &[3, 4]), vec![1, 3]);
        assert_eq!(unflatten(0, &[3, 4]), vec![0, 0]);
        assert_eq!(unflatten(23, &[2, 3, 4]), vec![1, 2, 3]);
    }
}
