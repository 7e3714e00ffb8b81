//! The layer's coarse voxel grid and canonical order, and each group's lattice coordinates
//! on it (Annex A.8.3).

use nalgebra::DMatrix;

use super::prepare::PreparedGaussians;
use salvq_bitstream::explicit::attributes::MAX_COORDINATE;
use salvq_bitstream::explicit::groups::Group;
use salvq_bitstream::explicit::layer::MAX_COORD_BITS;
use salvq_bitstream::model::morton3;

/// The layer's grid: the voxel of each Gaussian and the canonical order.
#[derive(Debug, Clone)]
pub struct Grid {
    /// Bits per voxel coordinate.
    pub coord_bits: u8,
    /// Edge of a voxel in world units.
    pub voxel_size: f32,
    /// World position of voxel (0, 0, 0)'s corner.
    pub origin: [f32; 3],
    /// Canonical order: `order[k]` is the input index of the k-th Gaussian.
    pub order: Vec<usize>,
    /// Voxels in canonical order.
    pub voxels: Vec<[u32; 3]>,
}

/// The grid whose voxel edge is about `step` (Annex A.8.3): the fewest bits whose voxels of
/// edge `step` cover the box, at most 21 (then the edge grows to cover it).
pub fn grid(p: &PreparedGaussians, origin: [f32; 3], step: f64) -> Grid {
    let extent = p.extent.max(f64::MIN_POSITIVE);
    let mut bits = ((extent / step).log2().ceil() as i64 + 1).clamp(1, MAX_COORD_BITS.into()) as u8;
    let mut size = step as f32;
    let cells = |size: f32| extent / f64::from(size) + 1.0;
    while cells(size) >= (1u64 << bits) as f64 {
        if bits < MAX_COORD_BITS {
            bits += 1;
        } else {
            size *= 1.0 + 1.0 / 1024.0;
        }
    }
    let max = (1u32 << bits) - 1;
    let vox: Vec<[u32; 3]> = p
        .positions
        .iter()
        .map(|q| {
            std::array::from_fn(|a| {
                let t = (q[a] - f64::from(origin[a])) / f64::from(size);
                (t.floor().max(0.0) as u64).min(u64::from(max)) as u32
            })
        })
        .collect();
    let mut order: Vec<usize> = (0..p.len()).collect();
    order.sort_by_key(|&i| (morton3(vox[i]), i));
    let voxels = order.iter().map(|&i| vox[i]).collect();
    Grid {
        coord_bits: bits,
        voxel_size: size,
        origin,
        order,
        voxels,
    }
}

/// One group's lattice coordinates (`dim` per Gaussian, canonical `order`) with step
/// `delta · 2^shift[k]` for the k-th Gaussian ([`group_coordinates_at`]).
pub fn group_coordinates(
    values: &[f64],
    g: &Group,
    delta: f32,
    shift: &dyn Fn(usize) -> i8,
    order: &[usize],
) -> Vec<i32> {
    let step = |k: usize| delta * salvq_bitstream::explicit::refinement::pow2(shift(k).into());
    group_coordinates_at(values, g, &step, order)
}

/// One group's lattice coordinates (`dim` per Gaussian, canonical `order`) with the step
/// `step(k)` for the k-th Gaussian: `round(B⁻¹ (x − mean) / Δ)`, the nearest lattice point
/// for the identity and for `B = U·diag(s)` with orthogonal columns.
pub fn group_coordinates_at(
    values: &[f64],
    g: &Group,
    step: &dyn Fn(usize) -> f32,
    order: &[usize],
) -> Vec<i32> {
    let d = g.dim;
    let inverse = g.basis.as_ref().map(|_| {
        let b = DMatrix::from_row_slice(d, d, &g.matrix().to_f64());
        b.try_inverse().unwrap_or_else(|| DMatrix::identity(d, d))
    });
    let limit = MAX_COORDINATE as f64;
    let mut out = Vec::with_capacity(order.len() * d);
    let mut t = vec![0.0f64; d];
    for (k, &i) in order.iter().enumerate() {
        let s = f64::from(step(k));
        let x = &values[i * d..(i + 1) * d];
        for j in 0..d {
            t[j] = (x[j] - f64::from(g.mean[j])) / s;
        }
        for j in 0..d {
            let w = match &inverse {
                None => t[j],
                Some(inv) => (0..d).map(|c| inv[(j, c)] * t[c]).sum(),
            };
            out.push(w.round().clamp(-limit, limit) as i32);
        }
    }
    out
}
