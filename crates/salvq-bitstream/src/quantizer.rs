//! Quantizers (spec §7): the lattice of each attribute group, its reconstruction matrix in
//! binary32, and the reconstruction `x = μ + Δ·(B u)` in a fixed order of binary32 operations.
//!
//! Decoding never searches a lattice: it multiplies the decoded integer coordinates `u` by the
//! group's matrix B (§7.3). Which `u` an encoder picks is its own choice (the reference encoder's lattice search).

pub use crate::model::lattice_kind::LatticeKind;
use crate::model::{Basis, GroupQuantizer};

/// Lanes a dense column is padded to (8 binary32: one AVX2 vector, two SSE2 or WebAssembly
/// ones).
pub(crate) const COLUMN_LANES: usize = 8;

/// The reconstruction matrix B of one group in binary32 (§7.2, §7.3 step 1).
///
/// A learned basis is dense; the fixed generators of D_n and E8 products are stored by their
/// non-zero entries only (column by column), so a decoder's memory and work for them grow
/// with d, not d² — F = 1 024 on E8 would otherwise take a 4 MiB matrix and a million
/// multiplications per anchor. Skipping zero entries changes no result (§7.3: a zero term
/// adds nothing to a sum that is never −0).
#[derive(Debug, Clone, PartialEq)]
pub struct LatticeMatrix {
    /// The group's lattice (Table 7-1).
    pub kind: LatticeKind,
    /// The group's dimension d: the number of coordinates `u` and of values B u.
    pub dim: usize,
    /// Dense, column-major: `b[j * stride + i]` is component i of basis vector j (so `B u`
    /// runs over contiguous columns and vectorises; each `z_i` still sums in increasing j),
    /// 0 for `d <= i < stride`. Empty unless the lattice is general.
    b: Vec<f32>,
    /// A dense column's length: `d` rounded up to whole vectors of [`COLUMN_LANES`], so
    /// that the product has no scalar remainder (45 values: 48).
    stride: usize,
    /// Sparse, column-major (fixed generators): column j's entries are
    /// `sparse_rows/vals[sparse_start[j] .. sparse_start[j + 1]]`. Empty otherwise.
    sparse_start: Vec<u32>,
    sparse_rows: Vec<u32>,
    sparse_vals: Vec<f32>,
    /// Every entry of the dense `b` is finite (so a zero coordinate's terms are ±0).
    dense_finite: bool,
}

impl LatticeMatrix {
    /// §7.3 step 1. `basis` is used (and required) for [`LatticeKind::General`] only; a
    /// general lattice without factors is treated as the identity (callers validate first).
    pub fn new(kind: LatticeKind, dim: usize, basis: Option<&Basis>) -> LatticeMatrix {
        let mut m = LatticeMatrix {
            kind,
            dim,
            b: Vec::new(),
            stride: dim.div_ceil(COLUMN_LANES) * COLUMN_LANES,
            sparse_start: Vec::new(),
            sparse_rows: Vec::new(),
            sparse_vals: Vec::new(),
            dense_finite: false,
        };
        // §7.2: the generators have integer and half-integer entries, exact in binary32.
        let mut column = |entries: &mut dyn Iterator<Item = (usize, f32)>| {
            if m.sparse_start.is_empty() {
                m.sparse_start.push(0);
            }
            for (i, v) in entries {
                m.sparse_rows.push(i as u32);
                m.sparse_vals.push(v);
            }
            m.sparse_start.push(m.sparse_rows.len() as u32);
        };
        match (kind, basis) {
            (LatticeKind::Dn, _) if dim >= 1 => {
                // Columns e_j − e_{d−1} (j < d − 1), then 2·e_{d−1}.
                let last = dim - 1;
                for j in 0..last {
                    column(&mut [(j, 1.0), (last, -1.0)].into_iter());
                }
                column(&mut std::iter::once((last, 2.0)));
            }
            (LatticeKind::E8Product, _) => {
                for j in 0..dim - dim % 8 {
                    let (block, jj) = (j / 8 * 8, j % 8);
                    column(
                        &mut (0..8)
                            .map(|ii| (block + ii, f32::from(E8_BASIS_TWICE[ii * 8 + jj]) / 2.0))
                            .filter(|&(_, v)| v != 0.0),
                    );
                }
            }
            (LatticeKind::General, Some(f)) => {
                // Column-major with each column padded to `stride` (nested loops: a
                // division per entry cost more than the rest for SH 3's 45 × 45).
                let row_major = general_matrix(dim, f);
                let stride = m.stride;
                m.b = vec![0.0; dim * stride];
                for (j, column) in m.b.chunks_exact_mut(stride).enumerate() {
                    for (i, bij) in column[..dim].iter_mut().enumerate() {
                        *bij = row_major[i * dim + j];
                    }
                }
            }
            _ => {}
        }
        if m.b.is_empty() && m.sparse_start.is_empty() {
            m.kind = LatticeKind::Identity;
        }
        m.dense_finite = !m.b.is_empty() && m.b.iter().all(|v| v.is_finite());
        m
    }

    /// B as f64 (row-major), for an encoder's lattice search: the exact values the decoder
    /// multiplies by.
    pub fn to_f64(&self) -> Vec<f64> {
        let d = self.dim;
        let mut out = vec![0.0; d * d];
        if !self.b.is_empty() {
            for (r, o) in out.iter_mut().enumerate() {
                *o = f64::from(self.b[(r % d) * self.stride + r / d]);
            }
        } else if !self.sparse_start.is_empty() {
            for j in 0..d {
                for k in self.column_range(j) {
                    out[self.sparse_rows[k] as usize * d + j] = f64::from(self.sparse_vals[k]);
                }
            }
        } else {
            for i in 0..d {
                out[i * d + i] = 1.0;
            }
        }
        out
    }

    fn column_range(&self, j: usize) -> std::ops::Range<usize> {
        match (self.sparse_start.get(j), self.sparse_start.get(j + 1)) {
            (Some(&a), Some(&b)) => a as usize..b as usize,
            _ => 0..0,
        }
    }

    /// Whether the lattice is the identity (B = I): `z_j = w_j`, §7.3 step 2.
    pub fn is_identity(&self) -> bool {
        self.kind == LatticeKind::Identity
    }

    /// [`LatticeMatrix::apply`] for a group of `D` values (`u` holds `D`), as an array.
    ///
    /// A dense, finite B of dimension `D` takes every term, zeros included, in a loop the
    /// compiler unrolls: with B finite, a zero coordinate's terms are ±0 and change nothing
    /// (see `apply`), so the sums are the same bits without a branch per coordinate.
    #[inline(always)]
    pub fn apply_fixed<const D: usize, T: Copy + Into<i64>>(&self, u: &[T]) -> [f32; D] {
        let mut z = [0.0f32; D];
        if self.is_identity() {
            for (zi, &ui) in z.iter_mut().zip(u) {
                *zi = ui.into() as f32;
            }
        } else if self.dense_finite && self.dim == D && u.len() >= D {
            for (j, &uj) in u[..D].iter().enumerate() {
                // Column j's D values (of its padded stride), a constant count to unroll.
                let start = j * self.stride;
                let Some(column) = self.b.get(start..).and_then(<[f32]>::first_chunk::<D>) else {
                    break;
                };
                let uf = uj.into() as f32;
                for (zi, &bij) in z.iter_mut().zip(column) {
                    *zi += bij * uf;
                }
            }
        } else {
            self.apply(u, &mut z);
        }
        z
    }

    /// §7.3 step 2: `z = B u` in binary32: `z_i = (((+0 + B_i0·u_0) + B_i1·u_1) + …)`, every
    /// product and sum rounded to binary32, `u_j` converted to binary32 first. A term with
    /// `u_j = 0` or `B_ij = 0` adds ±0 to a sum that is never −0, so skipping it changes
    /// nothing.
    ///
    /// `u` may hold `i64` (the anchors' coordinates) or `i32` (the explicit profile's); the
    /// conversion to binary32 is the same rounding of the same integer.
    pub fn apply<T: Copy + Into<i64>>(&self, u: &[T], z: &mut [f32]) {
        let d = self.dim;
        if self.is_identity() {
            for (zi, &ui) in z.iter_mut().zip(u) {
                *zi = ui.into() as f32;
            }
            return;
        }
        let z = &mut z[..d];
        if self.b.is_empty() {
            z.fill(0.0);
            for (j, &uj) in u.iter().enumerate().take(d) {
                let uj: i64 = uj.into();
                if uj == 0 {
                    continue;
                }
                let uf = uj as f32;
                for k in self.column_range(j) {
                    let i = self.sparse_rows[k] as usize;
                    z[i] += self.sparse_vals[k] * uf;
                }
            }
            return;
        }
        // Writes every z_i (+0 where no column adds to it).
        crate::hyperprior::simd::dense_product(&self.b, self.stride, &u[..d.min(u.len())], z);
    }
}

/// A group's lattice matrices, one per spatial region (§7.6; one region unless Sp-SALVQ).
#[derive(Debug, Clone)]
pub struct GroupLattices {
    /// First canonical anchor of each region, ascending, region 0 at 0.
    starts: Vec<u32>,
    matrices: Vec<LatticeMatrix>,
}

impl GroupLattices {
    /// §7.2 for every region of `q` (a group of lattice `kind` and dimension `dim`).
    pub fn new(kind: LatticeKind, dim: usize, q: &GroupQuantizer) -> GroupLattices {
        let bases = q.bases();
        if bases.is_empty() {
            return GroupLattices {
                starts: vec![0],
                matrices: vec![LatticeMatrix::new(kind, dim, None)],
            };
        }
        GroupLattices {
            starts: q.region_starts(),
            matrices: bases
                .into_iter()
                .map(|b| LatticeMatrix::new(kind, dim, Some(b)))
                .collect(),
        }
    }

    /// The matrix of the region holding canonical anchor `anchor`.
    pub fn for_anchor(&self, anchor: u32) -> &LatticeMatrix {
        let k = self.starts.partition_point(|&s| s <= anchor).max(1);
        &self.matrices[k - 1]
    }

    /// Every region's matrix, region 0 first.
    pub fn matrices(&self) -> &[LatticeMatrix] {
        &self.matrices
    }

    /// First anchor of each region.
    pub fn starts(&self) -> &[u32] {
        &self.starts
    }
}

/// §7.3 step 1 for a general basis: `B_ij = Σ_k (U_ik · s_k) · V_jk`, k ascending, each
/// product and sum in binary32, starting from +0.
fn general_matrix(d: usize, f: &Basis) -> Vec<f32> {
    let mut b = vec![0f32; d * d];
    let finite_products = || {
        f.u.chunks_exact(d.max(1))
            .all(|row| row.iter().zip(&f.s).all(|(u, s)| (u * s).is_finite()))
    };
    if is_identity(d, &f.v) && finite_products() {
        // V = I (the explicit profile's bases, §3.3): every term but k = j is (U_ik·s_k)·0,
        // a ±0 (the products are finite) that leaves a sum started at +0 as it is, so
        // B_ij = +0 + U_ij·s_j: the same bits as the sum, in d² operations rather than d³.
        for (i, row) in b.chunks_exact_mut(d).enumerate() {
            for (j, bij) in row.iter_mut().enumerate() {
                *bij = 0.0 + f.u[i * d + j] * f.s[j];
            }
        }
        return b;
    }
    for i in 0..d {
        for j in 0..d {
            let mut acc = 0f32;
            for k in 0..d {
                acc += (f.u[i * d + k] * f.s[k]) * f.v[j * d + k];
            }
            b[i * d + j] = acc;
        }
    }
    b
}

/// Whether `v` (row-major d × d) is exactly the identity.
fn is_identity(d: usize, v: &[f32]) -> bool {
    v.len() == d * d
        && v.chunks_exact(d.max(1)).enumerate().all(|(i, row)| {
            row.iter().enumerate().all(|(j, &x)| {
                let one = if i == j { 1.0f32 } else { 0.0 };
                x.to_bits() == one.to_bits()
            })
        })
}

/// §7.3 step 3: one reconstructed value, `μ + Δ·z` in binary32 (the §5.5 rule with z in
/// place of u).
#[inline]
pub fn reconstruct_value(mu: f32, delta: f32, z: f32) -> f32 {
    crate::hyperprior::step::canonical_nan(mu + delta * z)
}

/// §1.6.3: the first entry `(i, j)` of a general matrix (§7.2) that is not finite, if any
/// (finite factors can still overflow).
pub fn general_matrix_non_finite(d: usize, f: &Basis) -> Option<(usize, usize)> {
    general_matrix(d, f)
        .iter()
        .position(|v| !v.is_finite())
        .map(|p| (p / d, p % d))
}

/// Table 7-2 times 2 (row-major): twice the E8 generator block.
pub const E8_BASIS_TWICE: [i8; 64] = [
    2, 2, 2, 2, 2, 1, 1, 0, //
    0, 2, 2, 2, 2, 1, 1, 0, //
    0, 0, 2, 2, 2, 1, 1, 0, //
    0, 0, 0, 2, 2, 1, 1, 0, //
    0, 0, 0, 0, 2, 1, 1, 0, //
    0, 0, 0, 0, 0, 1, 1, 0, //
    0, 0, 0, 0, 0, -1, 1, 0, //
    -2, -4, -6, -8, -10, -5, -7, 4, //
];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn codes_and_names_round_trip() {
        for k in LatticeKind::ALL {
            assert_eq!(LatticeKind::from_code(k.code()), Some(k));
            assert_eq!(LatticeKind::from_name(k.name()), Some(k));
        }
        assert_eq!(LatticeKind::from_code(4), None);
    }

    #[test]
    fn dimension_rules() {
        assert!(LatticeKind::E8Product.check_dim(48).is_ok());
        assert!(LatticeKind::E8Product.check_dim(50).is_err());
        assert!(LatticeKind::Dn.check_dim(1).is_err());
        assert!(LatticeKind::Identity.check_dim(1).is_ok());
    }

    #[test]
    fn e8_points_are_exact_and_skipping_zeros_changes_nothing() {
        let m = LatticeMatrix::new(LatticeKind::E8Product, 16, None);
        let u: Vec<i64> = (0..16).map(|j| [0, 3, -1, 0, 7][j % 5]).collect();
        let mut z = vec![0f32; 16];
        m.apply(&u, &mut z);
        let b = m.to_f64();
        for (i, zi) in z.iter().enumerate() {
            let exact: f64 = (0..16).map(|j| b[i * 16 + j] * u[j] as f64).sum();
            assert_eq!(f64::from(*zi), exact);
        }
    }

    /// §7.3: a NaN reconstruction is output as 0x7FC00000 whatever NaN the arithmetic made.
    /// A general basis's `B u` is §7.3's sums, term by term in increasing j in binary32,
    /// whatever the dimension's remainder by the kernel's row blocks and wherever `u` is 0.
    /// A seeded xorshift64 sequence for the tests' random bases and coordinates.
    fn xorshift(mut seed: u64) -> impl FnMut() -> u64 {
        move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            seed
        }
    }

    #[test]
    fn general_products_are_section_7_3_sums_in_order() {
        let mut next = xorshift(0x2545_f491_4f6c_dd1du64);
        // 64 and past it: the non-zero columns are listed 64 at a time.
        for d in [1usize, 2, 7, 8, 9, 16, 45, 50, 63, 64, 65, 130] {
            let mut value = |scale: f32| (next() % 2001) as f32 / 1000.0 * scale - scale;
            let basis = Basis {
                u: (0..d * d).map(|_| value(1.0)).collect(),
                s: (0..d).map(|_| 0.5 + value(0.25).abs()).collect(),
                v: (0..d * d).map(|_| value(1.0)).collect(),
            };
            let m = LatticeMatrix::new(LatticeKind::General, d, Some(&basis));
            let b = m.to_f64();
            assert_eq!(
                b,
                general_matrix(d, &basis)
                    .iter()
                    .map(|&x| f64::from(x))
                    .collect::<Vec<_>>()
            );
            for round in 0..4 {
                let u: Vec<i64> = (0..d)
                    .map(|_| match next() % 4 {
                        0 => 0,
                        1 if round > 1 => (next() % (1 << 24)) as i64 - (1 << 23),
                        _ => (next() % 15) as i64 - 7,
                    })
                    .collect();
                let mut z = vec![f32::NAN; d];
                m.apply(&u, &mut z);
                for (i, zi) in z.iter().enumerate() {
                    let sum = (0..d).fold(0.0f32, |acc, j| acc + b[i * d + j] as f32 * u[j] as f32);
                    assert_eq!(zi.to_bits(), sum.to_bits(), "d {d}, row {i}");
                }
                // The explicit profile's i32 coordinates give the same bits.
                let u32s: Vec<i32> = u.iter().map(|&x| x as i32).collect();
                let mut z32 = vec![f32::NAN; d];
                m.apply(&u32s, &mut z32);
                assert_eq!(
                    z.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
                    z32.iter().map(|x| x.to_bits()).collect::<Vec<_>>()
                );
            }
        }
    }

    /// `apply_fixed` takes every term of a finite dense B, zeros included: the same bits as
    /// `apply`, which skips them; a B with a non-finite entry goes through `apply`.
    #[test]
    fn fixed_size_products_are_the_same_bits() {
        fn check<const D: usize>(m: &LatticeMatrix, u: &[i32]) {
            let mut z = vec![f32::NAN; D];
            m.apply(u, &mut z);
            let fixed: [f32; D] = m.apply_fixed(u);
            let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&z), bits(&fixed), "u {u:?}");
        }
        let identity = |d: usize| {
            let mut v = vec![0.0f32; d * d];
            for i in 0..d {
                v[i * d + i] = 1.0;
            }
            v
        };
        let mut next = xorshift(0x9e37_79b9_7f4a_7c15u64);
        for round in 0..200 {
            let mut value = || (next() % 2001) as f32 / 1000.0 - 1.0;
            let mut basis3 = Basis {
                u: (0..9).map(|_| value()).collect(),
                s: (0..3).map(|_| 0.5 + value().abs()).collect(),
                v: identity(3),
            };
            if round < 20 {
                // U_00 times s_0 overflows binary32: B has one infinity, taken only where u_0
                // is not 0.
                basis3.u[0] = 3.0e38;
                basis3.s[0] = 2.0;
            }
            let basis1 = Basis {
                u: vec![value()],
                s: vec![0.5 + value().abs()],
                v: identity(1),
            };
            let mut u: Vec<i32> = (0..3)
                .map(|_| match next() % 3 {
                    0 => 0,
                    _ => (next() % 4001) as i32 - 2000,
                })
                .collect();
            if round % 4 == 0 {
                // Only u_0: the infinity's row takes none of its NaN entries.
                u[1..].fill(0);
            }
            check::<3>(
                &LatticeMatrix::new(LatticeKind::General, 3, Some(&basis3)),
                &u,
            );
            check::<1>(
                &LatticeMatrix::new(LatticeKind::General, 1, Some(&basis1)),
                &u[..1],
            );
            check::<3>(&LatticeMatrix::new(LatticeKind::Identity, 3, None), &u);
            check::<3>(&LatticeMatrix::new(LatticeKind::Dn, 3, None), &u);
        }
    }

    /// With V = I, B is computed in d² operations; it must be the d³ sum of §7.3 step 1 bit
    /// for bit, −0 entries of U and products that overflow included.
    #[test]
    fn identity_v_takes_the_short_way_to_the_same_bits() {
        let full = |d: usize, f: &Basis| -> Vec<u32> {
            let mut b = vec![0u32; d * d];
            for i in 0..d {
                for j in 0..d {
                    let mut acc = 0f32;
                    for k in 0..d {
                        acc += (f.u[i * d + k] * f.s[k]) * f.v[j * d + k];
                    }
                    b[i * d + j] = acc.to_bits();
                }
            }
            b
        };
        let d = 5;
        let identity: Vec<f32> = (0..d * d).map(|at| f32::from(at / d == at % d)).collect();
        let mut u: Vec<f32> = (0..d * d).map(|at| at as f32 * 0.37 - 4.0).collect();
        u[3] = -0.0;
        u[7] = 0.0;
        u[12] = -1e-30;
        let s = vec![0.5, 2.0, 1e-10, 3.0, 7.5];
        let mut basis = Basis { u, s, v: identity };
        let bits = |m: Vec<f32>| m.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(general_matrix(d, &basis)), full(d, &basis));
        // A product that overflows: the long way (its NaNs), not the short one.
        basis.u[6] = 3e38;
        basis.s[1] = 4.0;
        assert_eq!(bits(general_matrix(d, &basis)), full(d, &basis));
        // Not quite the identity.
        basis.u[6] = 1.0;
        basis.v[1] = -0.0;
        assert_eq!(bits(general_matrix(d, &basis)), full(d, &basis));
    }

    #[test]
    fn nan_reconstructions_are_canonical() {
        let x = reconstruct_value(f32::INFINITY, 1.0, f32::NEG_INFINITY);
        assert_eq!(x.to_bits(), 0x7FC0_0000);
        let y = reconstruct_value(f32::from_bits(0xFFC0_0001), 1.0, 0.0);
        assert_eq!(y.to_bits(), 0x7FC0_0000);
        assert_eq!(reconstruct_value(1.0, 2.0, 3.0), 7.0);
    }

    #[test]
    fn identity_reconstruction_is_section_5_5() {
        let m = LatticeMatrix::new(LatticeKind::Identity, 3, None);
        let mut z = [0f32; 3];
        m.apply(&[5, -2, 0], &mut z);
        assert_eq!(z, [5.0, -2.0, 0.0]);
        assert_eq!(reconstruct_value(0.25, 0.5, z[0]), 2.75);
    }
}
