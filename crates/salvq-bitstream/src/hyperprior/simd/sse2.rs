//! The context MLP's dot product with SSE2's `pmaddwd`: the baseline x86-64 path, used when
//! AVX2 is absent (SSE2 is part of every x86-64 CPU, so no feature detection is needed).
//!
//! Same result: `pmaddwd` adds two i16 x i16 products into an i32; the only case that exceeds
//! i32, (-32768)^2 + (-32768)^2 = 2^31, comes out as 0x8000_0000, which is 2^31 modulo 2^32.
//! All further additions wrap. The sum modulo 2^32 is therefore exactly the one spec §5.3
//! defines, in any order; `tests::matches_the_portable_sum` checks it, extreme values included.

/// Wrapping i32 dot product of two i16 slices of equal length.
#[cfg(target_arch = "x86_64")]
#[allow(unsafe_code)]
pub fn dot(w: &[i16], x: &[i16]) -> i32 {
    use std::arch::x86_64::{
        __m128i, _mm_add_epi32, _mm_loadu_si128, _mm_madd_epi16, _mm_setzero_si128,
        _mm_storeu_si128,
    };
    let n = w.len().min(x.len());
    let blocks = n / 8;
    // SAFETY: SSE2 is always available on x86_64. Every load reads 8 i16 (16 bytes) starting
    // at index 8 * i with i < n / 8, so it stays inside both slices; unaligned loads are used.
    let lanes = unsafe {
        let mut acc0 = _mm_setzero_si128();
        let mut acc1 = _mm_setzero_si128();
        let (wp, xp) = (w.as_ptr(), x.as_ptr());
        let mut i = 0;
        while i + 1 < blocks {
            let a = _mm_loadu_si128(wp.add(8 * i) as *const __m128i);
            let b = _mm_loadu_si128(xp.add(8 * i) as *const __m128i);
            acc0 = _mm_add_epi32(acc0, _mm_madd_epi16(a, b));
            let a = _mm_loadu_si128(wp.add(8 * i + 8) as *const __m128i);
            let b = _mm_loadu_si128(xp.add(8 * i + 8) as *const __m128i);
            acc1 = _mm_add_epi32(acc1, _mm_madd_epi16(a, b));
            i += 2;
        }
        if i < blocks {
            let a = _mm_loadu_si128(wp.add(8 * i) as *const __m128i);
            let b = _mm_loadu_si128(xp.add(8 * i) as *const __m128i);
            acc0 = _mm_add_epi32(acc0, _mm_madd_epi16(a, b));
        }
        let mut out = [0i32; 4];
        _mm_storeu_si128(out.as_mut_ptr() as *mut __m128i, _mm_add_epi32(acc0, acc1));
        out
    };
    let tail = w[8 * blocks..n]
        .iter()
        .zip(&x[8 * blocks..n])
        .fold(0i32, |a, (&w, &x)| {
            a.wrapping_add(i32::from(w) * i32::from(x))
        });
    lanes.iter().fold(tail, |a, &l| a.wrapping_add(l))
}

#[cfg(test)]
mod tests {
    /// The definition: products in i32, every addition modulo 2^32.
    fn portable(w: &[i16], x: &[i16]) -> i32 {
        w.iter().zip(x).fold(0i32, |a, (&w, &x)| {
            a.wrapping_add(i32::from(w) * i32::from(x))
        })
    }

    #[test]
    #[cfg(target_arch = "x86_64")]
    fn matches_the_portable_sum() {
        let mut seed = 0x1234_5678_9abc_def0u64;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            seed
        };
        for n in [0usize, 1, 7, 8, 9, 15, 16, 17, 96, 100, 175, 2048] {
            for trial in 0..50 {
                let pick = |r: u64| match (trial + (r % 5) as usize) % 5 {
                    0 => i16::MIN,
                    1 => i16::MAX,
                    _ => r as i16,
                };
                let w: Vec<i16> = (0..n).map(|_| pick(next())).collect();
                let x: Vec<i16> = (0..n).map(|_| pick(next())).collect();
                assert_eq!(super::dot(&w, &x), portable(&w, &x), "n {n} trial {trial}");
            }
        }
        let all_min = vec![i16::MIN; 64];
        assert_eq!(super::dot(&all_min, &all_min), portable(&all_min, &all_min));
    }
}
