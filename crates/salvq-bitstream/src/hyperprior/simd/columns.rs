//! §7.3 step 2's `z = B u` for a dense B: the non-zero coordinates' columns added in
//! increasing j, every row's sum kept in registers across them.
//!
//! One portable loop, compiled twice on x86-64: as it is (SSE2, the baseline) and inside a
//! function built for AVX2, chosen when the CPU has it. Each lane does the same binary32
//! operations in the same order either way (Rust never fuses a product into a sum), so both
//! give §7.3's bits. Columns are padded to whole vectors (`LatticeMatrix`'s stride), so no
//! scalar remainder is left: 45 values are 6 AVX2 vectors.
//!
//! Why: the KLT product of the explicit profile's 45 `sh_rest` values went through memory
//! once per four columns, and took 18 % of fruit_drops' decode instructions.

/// Rows summed in one pass over the columns: 8 AVX2 vectors.
const ROWS: usize = 64;

/// `z = B u` for the dense, column-major `b` whose columns are `stride` long (a multiple of
/// 8, zero below the matrix): `z_i = (((+0 + b_i0·u_0) + b_i1·u_1) + …)` over the `j` with
/// `u_j ≠ 0`, each product and sum rounded to binary32. `z` holds the `d` outputs and `u`
/// the `d` coordinates.
pub fn dense_product<T: Copy + Into<i64>>(b: &[f32], stride: usize, u: &[T], z: &mut [f32]) {
    #[cfg(all(feature = "simd", target_arch = "x86_64"))]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: `dense_product_avx2`'s contract is AVX2 alone, detected just now.
        return unsafe { dense_product_avx2(b, stride, u, z) };
    }
    dense_product_portable(b, stride, u, z);
}

/// [`dense_product_portable`] built for AVX2.
///
/// # Safety
/// The CPU has AVX2. (The body is safe code, bounds-checked: the compiler may use AVX2
/// instructions in it, which is all that needs the promise.)
#[cfg(all(feature = "simd", target_arch = "x86_64"))]
#[target_feature(enable = "avx2")]
unsafe fn dense_product_avx2<T: Copy + Into<i64>>(
    b: &[f32],
    stride: usize,
    u: &[T],
    z: &mut [f32],
) {
    dense_product_portable(b, stride, u, z);
}

#[inline(always)]
fn dense_product_portable<T: Copy + Into<i64>>(b: &[f32], stride: usize, u: &[T], z: &mut [f32]) {
    let d = z.len();
    let mut first = 0;
    while first < d {
        // Whole vectors: `stride` and `first` are multiples of 8.
        let rows = stride.saturating_sub(first).min(ROWS);
        let out = &mut z[first..d.min(first + rows)];
        match rows / 8 {
            1 => rows_of::<8, T>(b, stride, first, u, out),
            2 => rows_of::<16, T>(b, stride, first, u, out),
            3 => rows_of::<24, T>(b, stride, first, u, out),
            4 => rows_of::<32, T>(b, stride, first, u, out),
            5 => rows_of::<40, T>(b, stride, first, u, out),
            6 => rows_of::<48, T>(b, stride, first, u, out),
            7 => rows_of::<56, T>(b, stride, first, u, out),
            8 => rows_of::<64, T>(b, stride, first, u, out),
            // Not a stride of whole vectors (or none left): nothing to add.
            _ => return out.fill(0.0),
        }
        first += rows;
    }
}

/// Rows `first .. first + R` of `B u` into `out` (the ones below `d`).
#[inline(always)]
fn rows_of<const R: usize, T: Copy + Into<i64>>(
    b: &[f32],
    stride: usize,
    first: usize,
    u: &[T],
    out: &mut [f32],
) {
    let mut sums = [0.0f32; R];
    // Most coordinates of a fine rate are 0, at no pattern a branch predicts: the non-zero
    // ones of each run of 64 are marked in a mask first (no branch), then their columns
    // added in increasing j.
    for (run, us) in u.chunks(64).enumerate() {
        let mut nonzero = 0u64;
        for (j, &uj) in us.iter().enumerate() {
            nonzero |= u64::from(uj.into() != 0) << j;
        }
        while nonzero != 0 {
            let j = nonzero.trailing_zeros() as usize;
            nonzero &= nonzero - 1;
            let Some(&uj) = us.get(j) else { break };
            let start = (run * 64 + j) * stride + first;
            let Some(column) = b.get(start..start + R) else {
                break;
            };
            let uj = uj.into() as f32;
            for (sum, &bij) in sums.iter_mut().zip(column) {
                *sum += bij * uj;
            }
        }
    }
    for (zi, &sum) in out.iter_mut().zip(&sums) {
        *zi = sum;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The AVX2 build and the portable one give the same bits, and both are the sums in
    /// order, for dimensions around the row blocks, infinite entries, and zero coordinates
    /// (whose columns, infinite or not, are left out).
    #[test]
    fn both_builds_are_the_sums_in_order() {
        let mut x = 0x2545_f491_4f6c_dd1du64;
        let mut next = move || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x
        };
        for d in [1usize, 3, 7, 8, 9, 45, 50, 63, 64, 65, 72, 130] {
            let stride = d.div_ceil(8) * 8;
            for round in 0..6 {
                let mut b = vec![0.0f32; d * stride];
                for j in 0..d {
                    for i in 0..d {
                        b[j * stride + i] = match next() % 50 {
                            0 if round > 2 => f32::INFINITY,
                            1 if round > 2 => -3.0e38,
                            _ => (next() % 2001) as f32 / 1000.0 - 1.0,
                        };
                    }
                }
                let u: Vec<i64> = (0..d)
                    .map(|_| match next() % 3 {
                        0 => 0,
                        _ => (next() % (1 << 24)) as i64 - (1 << 23),
                    })
                    .collect();
                let want: Vec<u32> = (0..d)
                    .map(|i| {
                        let terms = (0..d).filter(|&j| u[j] != 0);
                        terms
                            .fold(0.0f32, |s, j| s + b[j * stride + i] * u[j] as f32)
                            .to_bits()
                    })
                    .collect();
                let (mut portable, mut chosen) = (vec![f32::NAN; d], vec![f32::NAN; d]);
                dense_product_portable(&b, stride, &u, &mut portable);
                dense_product(&b, stride, &u, &mut chosen);
                let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(&portable), want, "portable, d {d}, round {round}");
                assert_eq!(bits(&chosen), want, "dispatched, d {d}, round {round}");
            }
        }
    }
}
