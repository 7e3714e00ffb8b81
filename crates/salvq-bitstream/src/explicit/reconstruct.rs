//! Reconstruction of the explicit profile (spec §3.6): decoded voxels and lattice coordinates
//! to binary32 Gaussians, every operation an IEEE 754 binary32 operation with
//! round-to-nearest-even in the order given, so every decoder outputs the same bits.

use crate::explicit::attributes::TileSymbolsRef;
use crate::explicit::gaussians::GaussiansMut;
use crate::explicit::groups::{Group, GroupKind};
use crate::explicit::refinement::{pow2, Precision};
use crate::hyperprior::step::canonical_nan;
use crate::quantizer::LatticeMatrix;

/// §3.6 step 1: a Gaussian's position from its voxel `v`, its `e` refinement bits `w` per
/// axis: with `c = v·2^e + w` (exact: below 2^24) and the refined edge
/// `h = voxel_size ⊗ 2^−e`, `origin ⊕ ((float32(c) ⊕ 0.5) ⊗ h)` per axis.
#[inline]
pub fn position(origin: [f32; 3], voxel_size: f32, v: [u32; 3], e: u8, w: [u32; 3]) -> [f32; 3] {
    let h = voxel_size * pow2(-i32::from(e));
    std::array::from_fn(|a| {
        let c = (v[a] << e) | w[a];
        canonical_nan(origin[a] + (c as f32 + 0.5) * h)
    })
}

/// §3.6 step 3: the quaternion (w, x, y, z) from its three smallest components `small` (in
/// increasing component order, the largest left out) and the largest's index.
///
/// In binary64 the squares of binary32 values are exact, so a compiler that fuses a multiply
/// and an add gets the same `t` (near the unit sphere a binary32 `t` loses every bit to one
/// such fusion, and the square root magnifies it).
#[inline]
pub fn quaternion(small: [f32; 3], largest: u8) -> [f32; 4] {
    let [a, b, c] = small.map(f64::from);
    let t = 1.0 - ((a * a + b * b) + c * c);
    // max(t, +0), with a NaN t (from a non-finite component) taken as +0.
    let t = if t > 0.0 { t } else { 0.0 };
    let big = t.sqrt() as f32;
    let mut q = [0.0f32; 4];
    let mut k = 0;
    for (c, out) in q.iter_mut().enumerate() {
        if c == usize::from(largest) {
            *out = big;
        } else {
            *out = small[k];
            k += 1;
        }
    }
    q
}

/// §3.6: the Gaussians of one tile at `precision` (a layer's, [`Precision::of_layer`], or a
/// refinement's, §3.8), written into `out` (room for exactly the tile's; to append them to a
/// [`crate::explicit::Gaussians`], [`crate::explicit::Gaussians::extend_zeroed`]).
///
/// `matrices` are the groups' ([`Group::matrix`]), computed once per layer by the caller: a
/// learned basis's is d³ work, which per tile took 7 % of a small scene's decode.
#[allow(clippy::too_many_arguments)]
pub fn reconstruct_tile_into(
    origin: [f32; 3],
    voxel_size: f32,
    precision: &Precision,
    groups: &[Group],
    matrices: &[LatticeMatrix],
    voxels: &[[u32; 3]],
    symbols: TileSymbolsRef,
    out: GaussiansMut,
) {
    debug_assert_eq!(matrices.len(), groups.len());
    let values: usize = groups.iter().map(|g| g.dim).sum();
    let deltas = &precision.delta;
    let widest = groups.iter().map(|g| g.dim).max().unwrap_or(0);
    let mut z = vec![0.0f32; widest];
    let rest = out.rest_per_gaussian;
    for (i, &voxel) in voxels.iter().enumerate().take(out.len()) {
        let class = usize::from(symbols.size_class[i]);
        out.positions[i] = position(
            origin,
            voxel_size,
            voxel,
            precision.refine[class],
            symbols.refinement[i],
        );
        let mut coords = &symbols.coords[i * values..(i + 1) * values];
        for ((g, matrix), delta) in groups.iter().zip(matrices).zip(deltas) {
            let (u, later) = coords.split_at(g.dim.min(coords.len()));
            coords = later;
            let delta = delta[class];
            // Step 2: z = B·float32(u) (§7.3), x = mean ⊕ (Δ ⊗ z), written straight into
            // the group's output. The groups of three values go through an array, so that
            // their loops unroll.
            match g.kind {
                GroupKind::Opacity => {
                    let [x] = group_values::<1>(matrix, u, &g.mean, delta);
                    out.opacity_logit[i] = x;
                }
                GroupKind::Scale => out.log_scales[i] = group_values(matrix, u, &g.mean, delta),
                GroupKind::Rotation => {
                    let small = group_values(matrix, u, &g.mean, delta);
                    out.rotations[i] = quaternion(small, symbols.rotation_index[i]);
                }
                GroupKind::Dc => out.f_dc[i] = group_values(matrix, u, &g.mean, delta),
                // Table 3-3: the group holds all 3·B values.
                GroupKind::Rest => {
                    let z = &mut z[..g.dim];
                    matrix.apply(u, z);
                    let x = &mut out.f_rest[i * rest..(i + 1) * rest];
                    for ((xj, &mean), &zj) in x.iter_mut().zip(&g.mean).zip(&*z) {
                        *xj = canonical_nan(mean + delta * zj);
                    }
                }
            }
        }
    }
}

/// §3.6 step 2 for a group of `D` values: `mean ⊕ (Δ ⊗ B·float32(u))`. `u` and `mean` hold
/// `D` values (Table 3-3 fixes the groups' sizes, `GQUA`'s reader checks them).
#[inline(always)]
fn group_values<const D: usize>(
    matrix: &LatticeMatrix,
    u: &[i32],
    mean: &[f32],
    delta: f32,
) -> [f32; D] {
    let (Some(u), Some(mean)) = (u.first_chunk::<D>(), mean.first_chunk::<D>()) else {
        return [0.0; D];
    };
    let z: [f32; D] = matrix.apply_fixed(u);
    std::array::from_fn(|j| canonical_nan(mean[j] + delta * z[j]))
}

#[cfg(test)]
mod tests {
    use super::quaternion;

    /// Near the unit sphere a binary32 evaluation of §3.6 step 3 loses `m` to one fused
    /// multiply-add; the binary64 one gives the same bits fused or not.
    #[test]
    fn a_fused_multiply_add_leaves_the_rotation_unchanged() {
        let (a, b, c) = (0.577_296_9_f32, 0.577_369_15_f32, 0.577_384_7_f32);
        let m32 = |t: f32| if t > 0.0 { t.sqrt() } else { 0.0 };
        let plain32 = m32(1.0 - ((a * a + b * b) + c * c));
        let fused32 = m32(1.0 - c.mul_add(c, a.mul_add(a, b * b)));
        assert!(
            (plain32 - fused32).abs() > 1e-4,
            "binary32: {plain32} unfused, {fused32} fused"
        );
        let m = quaternion([a, b, c], 0)[0];
        let (a, b, c) = (f64::from(a), f64::from(b), f64::from(c));
        for t in [
            1.0 - c.mul_add(c, a.mul_add(a, b * b)),
            1.0 - c.mul_add(c, b.mul_add(b, a * a)),
            1.0 - (c * c + (a * a + b * b)),
        ] {
            let fused = if t > 0.0 { t.sqrt() as f32 } else { 0.0 };
            assert_eq!(fused.to_bits(), m.to_bits(), "t = {t:e}");
        }
    }
}
