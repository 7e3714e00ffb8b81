//! §5.4 step 3's scale indices of 8 values at once with AVX-512: the bucket table of
//! `threshold_search` read with gathers, the same integers as its one-value count.
//!
//! Why: the count took 9 % of a generated 100 k-anchor decode on one thread (a profile),
//! some 30 instructions a value, one value at a time. Here a value's bit length is one
//! `vplzcntq`, and its bucket's count and the two thresholds after it are three gathers for 8
//! values.
//!
//! For `v = max(y, 1) << lift` (below 2^61, so its bit length is at most 61):
//! - below 2^low the count is 0, from 2^(low + 10) on it is 63 (every threshold);
//! - otherwise bucket b = ((bits − low) << 4) | (the 4 bits after v's leading one), with
//!   bits = 63 − lzcnt(v), and the count is `c + (T[c] <= v) + (T[c + 1] <= v)` for the
//!   bucket's count c ≤ 62 (`T[63]` is the sentinel u64::MAX).

use std::arch::x86_64::{
    _mm256_maskz_loadu_epi32, _mm256_max_epi32, _mm256_set1_epi32, _mm512_add_epi64,
    _mm512_and_si512, _mm512_cmple_epu64_mask, _mm512_cmplt_epi64_mask, _mm512_cvtepi64_epi8,
    _mm512_cvtepu32_epi64, _mm512_i64gather_epi32, _mm512_i64gather_epi64, _mm512_lzcnt_epi64,
    _mm512_mask_add_epi64, _mm512_mask_blend_epi64, _mm512_max_epi64, _mm512_min_epi64,
    _mm512_or_si512, _mm512_set1_epi64, _mm512_setzero_si512, _mm512_slli_epi64, _mm512_sllv_epi64,
    _mm512_srlv_epi64, _mm512_sub_epi64, _mm_mask_storeu_epi8,
};

use crate::hyperprior::threshold_search::BucketTable;

/// Values per vector.
const LANES: usize = 8;

/// Whether this CPU has the instructions the kernel uses (AVX-512 F, CD, VL and BW).
pub fn available() -> bool {
    std::arch::is_x86_feature_detected!("avx512f")
        && std::arch::is_x86_feature_detected!("avx512cd")
        && std::arch::is_x86_feature_detected!("avx512vl")
        && std::arch::is_x86_feature_detected!("avx512bw")
}

/// The kernel. Only [`Avx512Scales::new`] makes one, on a CPU with the instructions:
/// detected once per threshold set, not once per call.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Avx512Scales {
    _private: (),
}

impl Avx512Scales {
    /// The kernel, or `None` where the CPU lacks its instructions.
    pub fn new() -> Option<Avx512Scales> {
        available().then_some(Avx512Scales { _private: () })
    }

    /// `out[i]` = the count of `table`'s thresholds <= `max(ys[i], 1) << lifts[i]`, for
    /// lifted values below 2^61. Returns false, writing nothing, where the slices' lengths
    /// differ (the caller then counts value by value). `table` is a `ThresholdSearch`'s
    /// (`counts_into` makes the only ones): the gathers rely on its bucket counts being at
    /// most 62.
    #[inline]
    pub fn counts(self, table: BucketTable<'_>, ys: &[i32], lifts: &[u32], out: &mut [u8]) -> bool {
        if ys.len() != out.len() || lifts.len() != out.len() {
            return false;
        }
        // SAFETY: `counts_avx512`'s contract: `new` made this kernel only after detecting
        // its instructions; the lengths are equal (checked just above); and `table` comes
        // from `ThresholdSearch::counts_into`, whose bucket counts `ThresholdSearch::new`
        // wrote as at most `THRESHOLDS - 1` = 62.
        unsafe { counts_avx512(table, ys, lifts, out) };
        true
    }
}

/// [`Avx512Scales::counts`] after its checks.
///
/// # Safety
/// - The CPU has AVX-512 F, CD, VL and BW.
/// - `ys.len() >= out.len()` and `lifts.len() >= out.len()`.
/// - Every bucket's count in `table.counts` (its first `COUNTS_LEN - 3` bytes) is at most
///   62, so that the thresholds read at the count and the one after it are inside
///   `table.thresholds` (64).
#[target_feature(enable = "avx512f,avx512cd,avx512vl,avx512bw")]
unsafe fn counts_avx512(table: BucketTable<'_>, ys: &[i32], lifts: &[u32], out: &mut [u8]) {
    let low = _mm512_set1_epi64(i64::from(table.low));
    let top = _mm512_set1_epi64(i64::from(table.low) + 10);
    let (one, four) = (_mm512_set1_epi64(1), _mm512_set1_epi64(4));
    let last_bucket = _mm512_set1_epi64((table.counts.len() - 4) as i64);
    let counts = table.counts.as_ptr().cast::<i32>();
    let thresholds = table.thresholds.as_ptr().cast::<i64>();
    let mut at = 0;
    while at < out.len() {
        // The lanes left: a mask for the last, short vector (masked lanes are neither read
        // nor written).
        let n = (out.len() - at).min(LANES);
        let k = ((1u32 << n) - 1) as u8;
        // SAFETY: at < `out.len()` <= `ys.len()` and `lifts.len()` (# Safety), so both
        // pointers are inside their slices, and the mask enables the n lanes at .. at + n <=
        // `out.len()`, the only ones read. The CPU features are the caller's guarantee.
        let (y, lift) = unsafe {
            (
                _mm256_maskz_loadu_epi32(k, ys.as_ptr().add(at)),
                _mm256_maskz_loadu_epi32(k, lifts.as_ptr().add(at).cast()),
            )
        };
        let y = _mm256_max_epi32(y, _mm256_set1_epi32(1));
        let v = _mm512_sllv_epi64(_mm512_cvtepu32_epi64(y), _mm512_cvtepu32_epi64(lift));
        // Bit length − 1, and the 4 bits after the leading one.
        let bits = _mm512_sub_epi64(_mm512_set1_epi64(63), _mm512_lzcnt_epi64(v));
        let right = _mm512_max_epi64(_mm512_sub_epi64(bits, four), _mm512_setzero_si512());
        let left = _mm512_max_epi64(_mm512_sub_epi64(four, bits), _mm512_setzero_si512());
        let next = _mm512_and_si512(
            _mm512_sllv_epi64(_mm512_srlv_epi64(v, right), left),
            _mm512_set1_epi64(15),
        );
        // The bucket, kept inside the table for the lanes below 2^low or from 2^(low + 10)
        // on (their counts are set below).
        let bucket = _mm512_or_si512(_mm512_slli_epi64::<4>(_mm512_sub_epi64(bits, low)), next);
        let bucket = _mm512_min_epi64(
            _mm512_max_epi64(bucket, _mm512_setzero_si512()),
            last_bucket,
        );
        // The bucket's count: the first of the 4 bytes read there (`COUNTS_LEN` pads them).
        // SAFETY: every lane's bucket is clamped to 0 ..= `COUNTS_LEN - 4` just above, and
        // the gather reads the 4 bytes there, inside `table.counts` (`COUNTS_LEN` long).
        let c = unsafe { _mm512_i64gather_epi32::<1>(bucket, counts) };
        let c = _mm512_and_si512(_mm512_cvtepu32_epi64(c), _mm512_set1_epi64(0xFF));
        // SAFETY: c is a bucket's count, at most 62 (# Safety), so the gathers read the u64
        // at c and c + 1 <= 63, inside `table.thresholds` (64).
        let (t0, t1) = unsafe {
            (
                _mm512_i64gather_epi64::<8>(c, thresholds),
                _mm512_i64gather_epi64::<8>(_mm512_add_epi64(c, one), thresholds),
            )
        };
        let count = _mm512_mask_add_epi64(c, _mm512_cmple_epu64_mask(t0, v), c, one);
        let count = _mm512_mask_add_epi64(count, _mm512_cmple_epu64_mask(t1, v), count, one);
        let below = _mm512_cmplt_epi64_mask(bits, low);
        let above = !_mm512_cmplt_epi64_mask(bits, top);
        let count = _mm512_mask_blend_epi64(below, count, _mm512_setzero_si512());
        let count = _mm512_mask_blend_epi64(above, count, _mm512_set1_epi64(63));
        // SAFETY: at < `out.len()` keeps the pointer inside `out`, and the mask enables the
        // n bytes at .. at + n <= `out.len()`, the only ones written.
        unsafe {
            _mm_mask_storeu_epi8(
                out.as_mut_ptr().add(at).cast(),
                u16::from(k),
                _mm512_cvtepi64_epi8(count),
            )
        };
        at += n;
    }
}

/// [`super::detected_or_skip`] for this kernel.
#[cfg(test)]
pub(crate) fn or_skip(test: &str) -> bool {
    super::detected_or_skip(
        test,
        available(),
        "AVX-512 CD/VL/BW",
        "SALVQ_REQUIRE_AVX512",
    )
}
