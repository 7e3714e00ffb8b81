//! The context MLP (spec §5.3) of several anchors at once with AVX2: each weight loaded (and
//! widened from i8) once for all of them.
//!
//! Why: one anchor's evaluation ([`Avx2Mlp::eval`]) loads and widens every weight it
//! multiplies. Two anchors share those loads; the passes over the weights then run about
//! 5 200 instructions an anchor, a `vpmaddwd`, a `vpaddd` and half a load for each 16
//! products. In `perf record` profiles of the decode the MLP's time fell by 12 … 14 % against
//! the unchanged grid interpolation's. Four anchors leave too few registers for the sums and
//! ran slower than two.
//!
//! Both layers go by pairs of inputs (c, c + 1), as [`Avx2Mlp::eval`]'s layer 1 does: the
//! broadcast pair of one anchor's inputs times the pair's interleaved weights gives 8 sums
//! per `vpmaddwd`, and the same weight vector serves every anchor of the batch. Layer 0 takes
//! every input pair; layer 1 the unit pairs with a nonzero unit in any anchor of the batch
//! (a pair that is zero in one anchor adds nothing to its sums). §5.3 takes the sums modulo
//! 2^32, so the order of the additions and the pairs left out change no bit: the outputs are
//! [`Avx2Mlp::eval`]'s, anchor by anchor.

use std::arch::x86_64::{
    __m128i, __m256i, _mm256_add_epi32, _mm256_castsi256_si128, _mm256_extracti128_si256,
    _mm256_loadu_si256, _mm256_madd_epi16, _mm256_set1_epi32, _mm256_setzero_si256, _mm_max_epi16,
    _mm_packs_epi32, _mm_setzero_si128, _mm_storeu_si128,
};

use super::avx2::{
    load16, nonzero_pairs, round_shift, store_outputs, Avx2Mlp, Pairs, Weight, Weights, ROWS,
};

/// Output groups of 8 that one pass keeps in registers for a batch of `a` anchors: `a` sums
/// per group, `a` broadcast inputs and the weight vector within AVX2's 16 registers.
const fn pass_groups(a: usize) -> usize {
    match a {
        1 => 13,
        2 => 6,
        3 => 4,
        _ => 3,
    }
}

/// The most groups [`pass`] is built for.
const MAX_PASS_GROUPS: usize = 13;

impl Avx2Mlp {
    /// Length of the hidden scratch [`Self::eval_batch`] writes for `a` anchors: their
    /// activations, then the list of unit pairs with a nonzero unit.
    pub fn batch_hidden_len(&self, a: usize) -> usize {
        let avx2 = a * self.hidden_pad + self.hidden_pad / 2;
        #[cfg(salvq_avx512)]
        if let Some(w) = &self.avx512 {
            return avx2.max(w.batch_hidden_len(a));
        }
        avx2
    }

    /// [`Self::eval`] of `A` anchors (1 ≤ A ≤ 8): `x` holds their inputs one after the
    /// other, each `cin` values followed by zeros up to [`Self::input_len`]; `h` is scratch
    /// of [`Self::batch_hidden_len`]`(A)`; `y` gets their outputs, `cout` each.
    pub fn eval_batch<const A: usize>(&self, x: &[i16], h: &mut [i16], y: &mut [i32]) {
        let stride = self.input_len();
        assert!(
            (1..=8).contains(&A)
                && x.len() >= A * stride
                && x[..A * stride]
                    .chunks_exact(stride)
                    .all(|xa| xa[self.cin..].iter().all(|&v| v == 0))
                && h.len() >= self.batch_hidden_len(A)
                && y.len() == A * self.cout,
            "Avx2Mlp::eval_batch: scratch of the wrong shape"
        );
        #[cfg(salvq_avx512)]
        if let Some(w) = &self.avx512 {
            // SAFETY: `Avx512Weights::eval_batch`'s contract: `new` made these weights for
            // this kernel, and the assertion above gives `x.len() >= A ·
            // self.input_len()` and `h.len() >= self.batch_hidden_len(A)`, which is at least
            // `w.batch_hidden_len(A)`. (Only `Avx512Weights::new` makes the weights, after
            // detecting the instructions.)
            unsafe { w.eval_batch::<A>(self, x, h, y) };
            return;
        }
        // SAFETY: `batch_avx2`'s contract: `new` returned this kernel only after detecting
        // AVX2 on this CPU; `l0` and `l1` are the layers of one `Laid` of `self.weights`,
        // laid by `new` for this MLP; the assertion above gives `x.len() >= A ·
        // self.input_len()` and `h.len() >= self.batch_hidden_len(A)`, which is at least
        // `A · self.hidden_pad + self.hidden_pad / 2`.
        unsafe {
            match &self.weights {
                Weights::Wide(w) => self.batch_avx2::<_, A>(&w.l0_pairs, &w.l1, x, h, y),
                Weights::Narrow(w) => self.batch_avx2::<_, A>(&w.l0_pairs, &w.l1, x, h, y),
            }
        }
    }

    /// [`Self::eval_batch`] with AVX2, after its checks.
    ///
    /// # Safety
    /// - The CPU has AVX2.
    /// - `l0` and `l1` are layer 0 by input pairs (`l0_pairs`) and layer 1 of one `Laid` of
    ///   `self.weights`: `l0` has the columns of `self.cin.div_ceil(2)` input pairs and
    ///   `l1` those of `self.hidden_pad / 2` unit pairs, each for `self.hidden_pad` and
    ///   `round_up(self.cout, 8)` outputs.
    /// - `x.len() >= A · self.input_len()` (the A anchors' inputs are read through a
    ///   pointer).
    /// - `h.len() >= A · self.hidden_pad + self.hidden_pad / 2`: the A anchors'
    ///   activations, then the list of unit pairs, both written without bounds checks.
    #[target_feature(enable = "avx2")]
    unsafe fn batch_avx2<W: Weight, const A: usize>(
        &self,
        l0: &Pairs<W>,
        l1: &Pairs<W>,
        x: &[i16],
        h: &mut [i16],
        y: &mut [i32],
    ) {
        let (stride, hp) = (self.input_len(), self.hidden_pad);
        let (act, list) = h.split_at_mut(A * hp);
        // SAFETY: every operation relies on this function's contract (# Safety). AVX2, which
        // the intrinsics and the functions called need: the caller's guarantee.
        // - `pass_in` for layer 0: b <= `pass_groups(A)` <= 13 and first + b <= `groups` =
        //   `hp / 8` = `l0.outputs / 8`; `l0` (laid by `Pairs::new`, inputs padded to
        //   `round_up(cin, 2)` >= 2, as `new` refuses an MLP without inputs) holds
        //   `round_up(cin, 2) · l0.outputs` weights, so one pair's column at least and that
        //   of every listed q < cin.div_ceil(2) (`input_pairs`); anchor a's pair q reads
        //   inputs a · stride + 2q and + 1 < A · stride <= `x.len()` (stride =
        //   `input_len()` >= `round_up(cin, 2)`; the last pair of an odd `cin` reads the
        //   first zero of the padding).
        // - The bias loads read 8 i32 at o < o + 8 <= `l0.outputs` (or `l1.outputs`), the
        //   length `Pairs::new` padded the biases to.
        // - The activation store writes 8 i16 at a · hp + o with a < A and o + 8 <= hp:
        //   inside `act`, A · hp long.
        // - `nonzero_pairs`: `act` holds A · hp values and `list`, the rest of `h`, at least
        //   hp / 2 (`h.len()` in # Safety).
        // - `pass_in` for layer 1: first + b <= `l1.outputs / 8`; `l1` holds `hp ·
        //   l1.outputs` weights (hp >= 8: `new` refuses an MLP without hidden units); every
        //   listed q < hp / 2, so its column is in `l1` and anchor a's units a · hp + 2q
        //   and + 1 are inside `act`.
        // - `store_outputs` leaves out the outputs past each anchor's slice itself.
        unsafe {
            // Layer 0: s_h = b0[h] + W0[h] . x, then
            // a_h = min(max(rshr(s_h, shift0), 0), 32767).
            let mut sums = [[_mm256_setzero_si256(); A]; MAX_PASS_GROUPS];
            let groups = hp / ROWS;
            let mut first = 0;
            while first < groups {
                let b = (groups - first).min(pass_groups(A));
                pass_in::<W, A>(
                    b,
                    l0,
                    first,
                    x.as_ptr(),
                    stride,
                    &self.input_pairs,
                    &mut sums,
                );
                for (i, group) in sums[..b].iter().enumerate() {
                    let o = (first + i) * ROWS;
                    let bias = _mm256_loadu_si256(l0.bias.as_ptr().add(o).cast());
                    // `avx2::store_hidden` written out: called here, it made the compiler's
                    // code for the passes 6 % longer (callgrind, 100 k anchors).
                    for (a, &s) in group.iter().enumerate() {
                        let q = round_shift(_mm256_add_epi32(s, bias), self.shift0);
                        // Signed saturation to i16 then max with 0 is the clamp to
                        // 0 ..= 32767.
                        let packed = _mm_packs_epi32(
                            _mm256_castsi256_si128(q),
                            _mm256_extracti128_si256(q, 1),
                        );
                        let relu = _mm_max_epi16(packed, _mm_setzero_si128());
                        let at = act.as_mut_ptr().add(a * hp + o);
                        _mm_storeu_si128(at.cast::<__m128i>(), relu);
                    }
                }
                first += b;
            }
            let n = nonzero_pairs::<A>(act, hp, list);
            let list = &list[..n];
            // Layer 1: y_o = b1[o] + Σ_j W1[o][j] a_j over the listed pairs.
            let groups = l1.outputs / ROWS;
            let mut first = 0;
            while first < groups {
                let b = (groups - first).min(pass_groups(A));
                pass_in::<W, A>(b, l1, first, act.as_ptr(), hp, list, &mut sums);
                for (i, group) in sums[..b].iter().enumerate() {
                    let o = (first + i) * ROWS;
                    let bias = _mm256_loadu_si256(l1.bias.as_ptr().add(o).cast());
                    for (&s, ya) in group.iter().zip(y.chunks_exact_mut(self.cout)) {
                        store_outputs(_mm256_add_epi32(s, bias), o, ya);
                    }
                }
                first += b;
            }
        }
    }
}

/// [`pass`] for `b` output groups (1 ..= 13; it panics on others), its sums written to the
/// front of `sums`.
///
/// # Safety
/// [`pass`]'s contract with B = `b`.
#[inline]
#[target_feature(enable = "avx2")]
unsafe fn pass_in<W: Weight, const A: usize>(
    b: usize,
    layer: &Pairs<W>,
    first: usize,
    act: *const i16,
    stride: usize,
    list: &[i16],
    sums: &mut [[__m256i; A]; MAX_PASS_GROUPS],
) {
    macro_rules! by_groups {
        ($($n:literal)*) => {
            match b {
                $($n => pass::<W, A, $n>(layer, first, act, stride, list, &mut sums[..$n]),)*
                _ => unreachable!("pass_groups gives 1 ..= 13"),
            }
        };
    }
    // SAFETY: the arm taken calls `pass` with B = `b`, whose contract the caller meets
    // (# Safety).
    unsafe { by_groups!(1 2 3 4 5 6 7 8 9 10 11 12 13) };
}

/// The sums of output groups `first .. first + B` of `layer` over the input pairs in `list`,
/// for the `A` activation vectors at `act`, `stride` values apart, into `sums` (B long).
///
/// # Safety
/// - The CPU has AVX2.
/// - `first + B <= layer.outputs / 8`, and `layer` (laid by [`Pairs::new`]) holds at least
///   one pair's column: `2 · layer.outputs <= layer.weights.len()`.
/// - Every `q` in `list` (read as u16) has its column in `layer`: `(q + 1) · 2 ·
///   layer.outputs <= layer.weights.len()`; and `act` is valid for reads of `a · stride +
///   2q + 2` i16 for every a < A.
#[inline]
#[target_feature(enable = "avx2")]
unsafe fn pass<W: Weight, const A: usize, const B: usize>(
    layer: &Pairs<W>,
    first: usize,
    act: *const i16,
    stride: usize,
    list: &[i16],
    sums: &mut [[__m256i; A]],
) {
    // SAFETY: every operation relies on this function's contract (# Safety). The intrinsics
    // and `load16` need AVX2: the caller's guarantee. `base`, at first · 16 < 2 ·
    // `layer.outputs`, is inside `layer.weights`. For a listed q, anchor a reads the two i16
    // (one unaligned i32) at a · stride + 2q from `act`, and `col` (q · 2 · `layer.outputs`
    // on from the weights) and its B groups' 16 weights, up to (q + 1) · 2 ·
    // `layer.outputs`, are inside `layer.weights`.
    unsafe {
        let mut acc = [[_mm256_setzero_si256(); A]; B];
        let base = layer.weights.as_ptr().add(first * ROWS * 2);
        for &q in list {
            let q = usize::from(q as u16);
            let mut both = [_mm256_setzero_si256(); A];
            for (a, v) in both.iter_mut().enumerate() {
                let pair = act.add(a * stride + 2 * q).cast::<i32>().read_unaligned();
                *v = _mm256_set1_epi32(pair);
            }
            let col = base.add(q * layer.outputs * 2);
            for (i, group) in acc.iter_mut().enumerate() {
                let w = load16(col.add(i * 2 * ROWS));
                for (s, v) in group.iter_mut().zip(&both) {
                    *s = _mm256_add_epi32(*s, _mm256_madd_epi16(w, *v));
                }
            }
        }
        sums.copy_from_slice(&acc);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn batches_match_the_portable_mlp() {
        if !super::super::avx2_or_skip(
            "hyperprior::simd::avx2_batch::tests::batches_match_the_portable_mlp",
        ) {
            return;
        }
        super::super::kernel_tests::batches_match_the_portable_mlp(|m| {
            Avx2Mlp::new(m).expect("AVX2 present").without_avx512()
        });
    }
}
