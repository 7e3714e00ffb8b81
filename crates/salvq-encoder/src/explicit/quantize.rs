//! A layer's Gaussians quantized to a rate's plan (spec §3.5, Annex A.8.3): size classes
//! from the coded scales, position refinement within the voxel, and every group's lattice
//! coordinates at its shifted step.

use super::grid::{group_coordinates, Grid};
use super::plan::{RatePlan, SizeClasses};
use super::prepare::PreparedGaussians;
use salvq_bitstream::explicit::groups::Group;
use salvq_bitstream::explicit::layer::SIZE_CLASSES;

/// A layer's Gaussians quantized to the rate's plan (§3.5), in canonical order.
pub(super) struct Quantized {
    /// Lattice coordinates, `values` per Gaussian: every group's, side by side.
    pub(super) coords: Vec<i32>,
    /// Coded values per Gaussian.
    pub(super) values: usize,
    /// Size class of each Gaussian.
    pub(super) size_class: Vec<u8>,
    /// GLAY's `size_threshold`: the class bounds on the scale group's coordinates.
    pub(super) size_threshold: [i32; SIZE_CLASSES - 1],
    /// Per group, the step shift of each Gaussian (the scale group's are 0).
    pub(super) shifts: Vec<Vec<i8>>,
    /// Position bits below the voxel of each Gaussian, per axis.
    pub(super) refinement: Vec<[u32; 3]>,
    /// Index of each Gaussian's largest rotation component.
    pub(super) rotation: Vec<u8>,
}

/// Quantizes `p` on `grid` with the rate's `plan`: size classes, position refinement,
/// every group's coordinates and the rotation indices.
pub(super) fn quantize(
    p: &PreparedGaussians,
    groups: &[Group],
    classes: &SizeClasses,
    plan: &RatePlan,
    grid: &Grid,
    origin: [f32; 3],
    rate: u8,
) -> Quantized {
    let values: usize = groups.iter().map(|g| g.dim).sum();
    let (scale_coords, size_threshold, size_class) =
        scale_classes(p, &groups[0], rate, classes, &grid.order);
    let refinement = position_refinement(p, grid, origin, &plan.refine, &size_class);
    let (coords, shifts) =
        layer_coordinates(p, groups, plan, rate, grid, &size_class, &scale_coords);
    let rotation = grid.order.iter().map(|&i| p.rotation_index[i]).collect();
    Quantized {
        coords,
        values,
        size_class,
        size_threshold,
        shifts,
        refinement,
        rotation,
    }
}

/// The scale group's coordinates (its step unshifted) and, from them, GLAY's size
/// thresholds and each Gaussian's size class (§3.5): the decoder classes Gaussians by
/// their coded scales, so the encoder must too.
fn scale_classes(
    p: &PreparedGaussians,
    scale: &Group,
    rate: u8,
    classes: &SizeClasses,
    order: &[usize],
) -> (Vec<i32>, [i32; SIZE_CLASSES - 1], Vec<u8>) {
    let scale_delta = scale.rate_step(rate);
    let scale_coords = group_coordinates(&p.values[0], scale, scale_delta, &|_| 0, order);
    let threshold_u = classes.thresholds.map(|t| {
        let u = ((t - f64::from(scale.mean[0])) / f64::from(scale_delta)).round();
        u.clamp(f64::from(i32::MIN), f64::from(i32::MAX)) as i32
    });
    let size_class = scale_coords
        .chunks_exact(scale.dim)
        .map(|c| {
            let largest = c.iter().copied().max().unwrap_or(0);
            threshold_u.iter().filter(|&&t| t <= largest).count() as u8
        })
        .collect();
    (scale_coords, threshold_u, size_class)
}

/// Each Gaussian's position refinement (canonical order): the fine cell within its coarse
/// voxel, `refine[class]` bits per axis.
fn position_refinement(
    p: &PreparedGaussians,
    grid: &Grid,
    origin: [f32; 3],
    refine: &[u8; SIZE_CLASSES],
    size_class: &[u8],
) -> Vec<[u32; 3]> {
    (0..grid.order.len())
        .map(|k| {
            let e = refine[usize::from(size_class[k])];
            let h = f64::from(grid.voxel_size) / f64::from(1u32 << e);
            let q = p.positions[grid.order[k]];
            std::array::from_fn(|a| {
                let fine = ((q[a] - f64::from(origin[a])) / h).floor().max(0.0) as u64;
                let lo = u64::from(grid.voxels[k][a]) << e;
                (fine.clamp(lo, lo + (1u64 << e) - 1) - lo) as u32
            })
        })
        .collect()
}

/// Every group's coordinates side by side (all values of each Gaussian together), and
/// each group's step shift per Gaussian; the scale group's are `scale_coords`.
fn layer_coordinates(
    p: &PreparedGaussians,
    groups: &[Group],
    plan: &RatePlan,
    rate: u8,
    grid: &Grid,
    size_class: &[u8],
    scale_coords: &[i32],
) -> (Vec<i32>, Vec<Vec<i8>>) {
    let values: usize = groups.iter().map(|g| g.dim).sum();
    let n = grid.order.len();
    let mut coords = vec![0i32; n * values];
    let mut shifts_of: Vec<Vec<i8>> = Vec::with_capacity(groups.len());
    let mut at = 0;
    for (gi, g) in groups.iter().enumerate() {
        let shifts: Vec<i8> = (0..n)
            .map(|k| plan.class_shifts(gi)[usize::from(size_class[k])])
            .collect();
        let c = if gi == 0 {
            scale_coords.to_vec()
        } else {
            group_coordinates(
                &p.values[gi],
                g,
                g.rate_step(rate),
                &|k| shifts[k],
                &grid.order,
            )
        };
        for (k, row) in c.chunks_exact(g.dim).enumerate() {
            coords[k * values + at..k * values + at + g.dim].copy_from_slice(row);
        }
        shifts_of.push(shifts);
        at += g.dim;
    }
    (coords, shifts_of)
}
