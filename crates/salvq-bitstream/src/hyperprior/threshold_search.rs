//! §5.4 step 3's count of thresholds, found without a search: a table per threshold set,
//! indexed by the value's bit length and next four bits, gives the count at the start of the
//! value's bucket, and at most two comparisons finish it. The same integers as the binary
//! search (the count is defined by comparisons of integers); only the way to it differs.
//!
//! Why: every coded value needs its scale index, and a 6-step binary search is a chain of
//! dependent loads and comparisons per value.

use super::step::THRESHOLDS;

/// Sub-buckets per power of two: 2^SUB_BITS. A bucket spans at most 1/16 of its values'
/// magnitude, and neighbouring thresholds are about 2^(1/8) apart (Table 6-1), so a bucket
/// holds at most one of them except where rounding to integers crowds them (checked).
const SUB_BITS: u32 = 4;
/// Powers of two a table covers from the first threshold's: the thresholds span 2^7.75.
const OCTAVES: u32 = 10;
const BUCKETS: usize = (OCTAVES as usize) << SUB_BITS;
/// The bucket table's length: three zero bytes after the last bucket, so that a 4-byte
/// read at any bucket stays inside it (the AVX-512 kernel gathers the counts that way).
pub(crate) const COUNTS_LEN: usize = BUCKETS + 3;

/// One increasing threshold set (63 thresholds and the sentinel `u64::MAX`) with its bucket
/// table, or with none where the set does not fit the scheme (then the count is searched).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ThresholdSearch {
    thresholds: [u64; THRESHOLDS + 1],
    /// floor(log2 `T[0]`): values below 2^low are below every threshold.
    low: u32,
    /// Per bucket: the count of thresholds <= the bucket's smallest value, at most 62 (then
    /// the padding of [`COUNTS_LEN`]).
    counts: Option<Box<[u8; COUNTS_LEN]>>,
    /// The vector kernel for the table, where there is a table and the CPU has the kernel's
    /// instructions.
    #[cfg(all(feature = "simd", target_arch = "x86_64", salvq_avx512))]
    kernel: Option<crate::hyperprior::simd::scale_avx512::Avx512Scales>,
}

/// A threshold set's bucket table, as the vector kernels read it: the count of the
/// thresholds <= `v` (for `v` >= 1) is 0 below 2^`low`, 63 from 2^(`low` + 10) on, and
/// otherwise `c + (thresholds[c] <= v) + (thresholds[c + 1] <= v)` with `c` the count of
/// bucket `((bit length of v − 1 − low) << 4) | (the 4 bits after v's leading one)`.
#[cfg(all(feature = "simd", target_arch = "x86_64", salvq_avx512))]
#[derive(Debug, Clone, Copy)]
pub(crate) struct BucketTable<'a> {
    pub thresholds: &'a [u64; THRESHOLDS + 1],
    pub low: u32,
    pub counts: &'a [u8; COUNTS_LEN],
}

/// The number of `thresholds` <= `v` (the thresholds increase; the last is the sentinel).
fn count_searched(thresholds: &[u64; THRESHOLDS + 1], v: u64) -> usize {
    // A branch-free binary search over the 63 thresholds and the sentinel (the comparisons
    // become conditional moves; `& 63` keeps every probe in bounds without a check).
    let mut c = 0usize;
    for half in [32usize, 16, 8, 4, 2, 1] {
        c += half * usize::from(thresholds[(c + half - 1) & 63] <= v);
    }
    c
}

/// The bucket of `v` >= 1 whose bit length is `bits` = floor(log2 v), `low <= bits <
/// low + OCTAVES`: its bit length above `low`, then the four bits after the leading one.
#[inline(always)]
fn bucket(v: u64, bits: u32, low: u32) -> usize {
    let next = if bits >= SUB_BITS {
        (v >> (bits - SUB_BITS)) & ((1 << SUB_BITS) - 1)
    } else {
        (v << (SUB_BITS - bits)) & ((1 << SUB_BITS) - 1)
    };
    (((bits - low) as usize) << SUB_BITS) | next as usize
}

/// The smallest and largest value of bucket `b` (for a table whose first power is `low`).
fn bucket_range(b: usize, low: u32) -> (u64, u64) {
    let bits = low + (b >> SUB_BITS) as u32;
    let next = (b & ((1 << SUB_BITS) - 1)) as u64;
    if bits >= SUB_BITS {
        let width = 1u64 << (bits - SUB_BITS);
        let lo = (1u64 << bits) | (next * width);
        (lo, lo + width - 1)
    } else {
        // Fewer bits than the sub-bucket index: each value has a bucket of its own (and the
        // buckets in between hold none, so their count is never read).
        let lo = (1u64 << bits) | (next >> (SUB_BITS - bits));
        (lo, lo)
    }
}

impl ThresholdSearch {
    /// The search over `thresholds` (increasing, the last `u64::MAX`).
    pub fn new(thresholds: [u64; THRESHOLDS + 1]) -> ThresholdSearch {
        let first = thresholds[0];
        let low = 63 - first.max(1).leading_zeros();
        let mut search = ThresholdSearch {
            thresholds,
            low,
            counts: None,
            #[cfg(all(feature = "simd", target_arch = "x86_64", salvq_avx512))]
            kernel: None,
        };
        // Values of OCTAVES powers above `low` and more must be above every threshold, and
        // the table's values must stay below 2^64.
        let top = low + OCTAVES;
        if first == 0 || top >= 64 || thresholds[THRESHOLDS - 1] > 1u64 << top {
            return search;
        }
        let mut counts = Box::new([0u8; COUNTS_LEN]);
        for (b, count) in counts.iter_mut().take(BUCKETS).enumerate() {
            let (lo, hi) = bucket_range(b, low);
            let at_lo = count_searched(&thresholds, lo);
            // Two comparisons finish the count only if the bucket holds at most two
            // thresholds above its smallest value.
            if count_searched(&thresholds, hi) > at_lo + 2 {
                return search;
            }
            *count = at_lo.min(THRESHOLDS - 1) as u8;
        }
        search.counts = Some(counts);
        #[cfg(all(feature = "simd", target_arch = "x86_64", salvq_avx512))]
        {
            search.kernel = crate::hyperprior::simd::scale_avx512::Avx512Scales::new();
        }
        search
    }

    /// Whether [`ThresholdSearch::counts_into`] runs a vector kernel for this set (it has a
    /// bucket table, and the CPU the kernel's instructions); then counting a few values
    /// more costs next to nothing.
    #[inline]
    pub fn vectorized(&self) -> bool {
        #[cfg(all(feature = "simd", target_arch = "x86_64", salvq_avx512))]
        return self.kernel.is_some();
        #[cfg(not(all(feature = "simd", target_arch = "x86_64", salvq_avx512)))]
        false
    }

    /// `out[i]` = the count of thresholds <= `max(ys[i], 1) << lifts[i]` (§5.4 step 3), for
    /// values whose lifted form stays below 2^61; with AVX-512 where the CPU has it, else
    /// value by value. The three slices have the same length.
    #[inline]
    pub fn counts_into(&self, ys: &[i32], lifts: &[u32], out: &mut [u8]) {
        #[cfg(all(feature = "simd", target_arch = "x86_64", salvq_avx512))]
        if let (Some(kernel), Some(counts)) = (self.kernel, &self.counts) {
            let table = BucketTable {
                thresholds: &self.thresholds,
                low: self.low,
                counts,
            };
            if kernel.counts(table, ys, lifts, out) {
                return;
            }
        }
        for ((k, &yv), &lift) in out.iter_mut().zip(ys).zip(lifts) {
            *k = self.count((yv.max(1) as u64) << lift) as u8;
        }
    }

    /// The number of thresholds <= `v`, for `v` >= 1 (0 ..= 63).
    #[inline(always)]
    pub fn count(&self, v: u64) -> usize {
        let Some(counts) = &self.counts else {
            return count_searched(&self.thresholds, v);
        };
        // The bit length from a table, not `leading_zeros`: without the `lzcnt` extension
        // (not in the baseline x86-64 target) that is `bsr`, several cycles per value on
        // some CPUs.
        let above = v >> self.low;
        if above == 0 {
            return 0;
        }
        let Some(&octave) = FLOOR_LOG2.get(above as usize) else {
            return THRESHOLDS;
        };
        let bits = self.low + u32::from(octave);
        // The count at the bucket's start is at most 62, so both probes are in bounds (the
        // second may be the sentinel).
        let c = usize::from(counts[bucket(v, bits, self.low)]);
        let t = &self.thresholds;
        c + usize::from(t[c & 63] <= v) + usize::from(t[(c + 1) & 63] <= v)
    }
}

/// floor(log2 n) for n = 1 .. 2^OCTAVES (entry 0 is unused).
const FLOOR_LOG2: [u8; 1 << OCTAVES] = {
    let mut t = [0u8; 1 << OCTAVES];
    let mut n = 2;
    while n < t.len() {
        t[n] = t[n / 2] + 1;
        n += 1;
    }
    t
};

#[cfg(test)]
mod tests {
    use super::*;
    use crate::entropy::scale::THRESHOLD_Q16;
    use crate::hyperprior::step::{BaseStep, STEP_FACTOR};

    fn with_sentinel(t: [u64; THRESHOLDS]) -> [u64; THRESHOLDS + 1] {
        std::array::from_fn(|i| t.get(i).copied().unwrap_or(u64::MAX))
    }

    /// Values worth probing for one set: around every threshold and every bucket boundary,
    /// the ends of the range, and powers of two.
    fn probes(s: &ThresholdSearch) -> Vec<u64> {
        let mut v = vec![1, 2, 3, u64::MAX >> 3, (1 << 61) - 1];
        for &t in &s.thresholds[..THRESHOLDS] {
            v.extend([t.saturating_sub(1), t, t.saturating_add(1)]);
        }
        // Bucket edges exist only where the table does (its range then ends below 2^64).
        if s.counts.is_some() {
            for b in 0..BUCKETS {
                let (lo, hi) = bucket_range(b, s.low);
                v.extend([lo.saturating_sub(1), lo, hi, hi.saturating_add(1)]);
            }
        }
        for e in 0..61 {
            v.extend([(1u64 << e) - 1, 1 << e, (1 << e) + 1]);
        }
        v.retain(|&x| x >= 1);
        v
    }

    /// The table gives the searched count for the thresholds of every step factor at base
    /// steps from tiny (thresholds crowded into small integers) to large, and for every
    /// lift the scale outputs can have; most sets use the table.
    #[test]
    fn counts_equal_the_binary_search() {
        let (mut tabled, mut sets) = (0, 0);
        for step in [
            1e-30f32, 1e-9, 3.7e-5, 0.001, 0.0173, 0.5, 1.0, 7.25, 1e4, 3e9,
        ] {
            let base = BaseStep::new(step, 1.0);
            for &factor in STEP_FACTOR.iter().step_by(4) {
                for emax in [-8, 0, 9, 16, 24, 40, 60] {
                    let t = base.y_thresholds(factor, emax, &THRESHOLD_Q16);
                    if t.windows(2).any(|w| w[0] > w[1]) {
                        continue;
                    }
                    let s = ThresholdSearch::new(with_sentinel(t));
                    sets += 1;
                    tabled += usize::from(s.counts.is_some());
                    for v in probes(&s) {
                        assert_eq!(
                            s.count(v),
                            count_searched(&s.thresholds, v),
                            "step {step} factor {factor} emax {emax} value {v}"
                        );
                    }
                }
            }
        }
        assert!(tabled * 2 > sets, "{tabled} of {sets} sets use the table");
    }

    /// `counts_into` (with AVX-512 where the CPU has it) gives `count` of every lifted value,
    /// in slices of every length up to 19 (the kernel's short last vector), for the tabled
    /// sets of `counts_equal_the_binary_search` and lifts across Table 5-1's range.
    #[test]
    fn counts_into_equals_the_count_of_each_value() {
        #[cfg(all(feature = "simd", target_arch = "x86_64", salvq_avx512))]
        let _ = crate::hyperprior::simd::scale_avx512::or_skip(
            "hyperprior::threshold_search::tests::counts_into_equals_the_count_of_each_value",
        );
        let mut checked = 0usize;
        for step in [1e-9f32, 0.001, 0.0173, 1.0, 7.25, 3e9] {
            let base = BaseStep::new(step, 1.0);
            for &factor in STEP_FACTOR.iter().step_by(16) {
                for emax in [-8, 0, 16, 40] {
                    let t = base.y_thresholds(factor, emax, &THRESHOLD_Q16);
                    if t.windows(2).any(|w| w[0] > w[1]) {
                        continue;
                    }
                    let s = ThresholdSearch::new(with_sentinel(t));
                    let (mut ys, mut lifts) = (vec![i32::MIN, -1, 0, i32::MAX], vec![0, 3, 30, 0]);
                    for lift in [0u32, 1, 5, 13, 30] {
                        for v in probes(&s) {
                            let y = (v >> lift).min(i32::MAX as u64) as i32;
                            for y in [y.saturating_sub(1), y, y.saturating_add(1)] {
                                ys.push(y);
                                lifts.push(lift);
                            }
                        }
                    }
                    let mut out = vec![0u8; ys.len()];
                    let mut at = 0;
                    for len in (1..20).cycle() {
                        let end = (at + len).min(ys.len());
                        s.counts_into(&ys[at..end], &lifts[at..end], &mut out[at..end]);
                        at = end;
                        if at == ys.len() {
                            break;
                        }
                    }
                    for ((&y, &lift), &k) in ys.iter().zip(&lifts).zip(&out) {
                        let v = (y.max(1) as u64) << lift;
                        assert_eq!(usize::from(k), s.count(v), "y {y} lift {lift} step {step}");
                    }
                    checked += ys.len();
                }
            }
        }
        assert!(checked > 100_000, "{checked} values checked");
        // A tabled set whose bucket [68, 71] holds two thresholds above its start (69, 70),
        // where the second comparison decides: every value up to 2^17, as y with lift 0.
        let mut t = [0u64; THRESHOLDS + 1];
        t[..5].copy_from_slice(&[64, 69, 70, 80, 96]);
        for i in 5..THRESHOLDS {
            t[i] = t[i - 1] + t[i - 1] / 11 + 1;
        }
        t[THRESHOLDS] = u64::MAX;
        let s = ThresholdSearch::new(t);
        assert!(s.counts.is_some(), "the set is tabled");
        let ys: Vec<i32> = (1..1 << 17).collect();
        let lifts = vec![0u32; ys.len()];
        let mut out = vec![0u8; ys.len()];
        s.counts_into(&ys, &lifts, &mut out);
        for (&y, &k) in ys.iter().zip(&out) {
            assert_eq!(usize::from(k), count_searched(&t, y as u64), "y {y}");
        }
    }

    /// Thresholds crowded into a few small integers do not fit two per bucket: the search is
    /// used, and counts still agree.
    #[test]
    fn crowded_thresholds_fall_back_to_the_search() {
        let mut t = [0u64; THRESHOLDS + 1];
        for (i, x) in t.iter_mut().enumerate() {
            *x = 1000 + (i as u64) / 8;
        }
        t[THRESHOLDS] = u64::MAX;
        let s = ThresholdSearch::new(t);
        assert!(s.counts.is_none());
        for v in 990..1020 {
            assert_eq!(s.count(v), count_searched(&t, v));
        }
    }
}
