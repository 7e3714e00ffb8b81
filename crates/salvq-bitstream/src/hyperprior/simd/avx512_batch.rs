//! The context MLP (spec §5.3) of several anchors at once with AVX-512 and its VNNI
//! instructions: [`super::avx2_batch`]'s plan with 16 sums a vector, each multiply-add one
//! `vpdpwssd`.
//!
//! Why: the AVX2 batch spends a `vpmaddwd` and a `vpaddd` on every 16 products. `vpdpwssd`
//! on a 512-bit vector does 32 products and their additions in one instruction, and 32
//! vector registers hold a batch of two anchors' 176 output sums at once, so layer 1 is one
//! pass over the unit pairs. Only CPUs with AVX-512 F, BW and VNNI run it (detected once per
//! stream); the AVX2 batch serves the others.
//!
//! The same bits as the AVX2 batch: `vpdpwssd` adds the two i16 x i16 products of each lane
//! to the lane's i32 sum modulo 2^32, as `vpmaddwd` then `vpaddd` do (the one pair product
//! beyond i32, 2 · (−32768)², wraps the same way), and §5.3 takes the sums modulo 2^32.
//!
//! Its own copy of the weights: the same layout as [`Pairs`] with the outputs (and so the
//! hidden units) padded to 16 rather than 8, so that every group is one full vector.

use std::arch::x86_64::{
    __m512i, _mm256_loadu_si256, _mm256_max_epi16, _mm256_setzero_si256, _mm256_storeu_si256,
    _mm512_add_epi32, _mm512_and_si512, _mm512_cvtepi8_epi16, _mm512_cvtsepi32_epi16,
    _mm512_dpwssd_epi32, _mm512_loadu_si512, _mm512_mask_storeu_epi32, _mm512_set1_epi32,
    _mm512_setzero_si512, _mm512_sra_epi32, _mm_cvtsi32_si128,
};

use super::avx2::{nonzero_pairs, round_up, Avx2Mlp, Pairs, Weight};
use crate::hyperprior::mlp::IntMlp;

/// Sums (outputs) per vector.
const LANES: usize = 16;

/// Output groups of 16 one pass keeps in registers for a batch of `a` anchors: `a` sums per
/// group, `a` broadcast inputs and the weight vector within AVX-512's 32 registers.
const fn pass_groups(a: usize) -> usize {
    match a {
        1 | 2 => 12,
        3 => 8,
        4 => 6,
        5 | 6 => 4,
        7 => 3,
        _ => 2,
    }
}

/// Both layers by pairs of inputs, outputs padded to 16.
#[derive(Debug, Clone)]
pub(super) struct Layers<W> {
    l0: Pairs<W>,
    l1: Pairs<W>,
}

#[derive(Debug, Clone)]
enum Stored {
    Wide(Layers<i16>),
    Narrow(Layers<i8>),
}

/// The weights in this kernel's layout. Only [`Avx512Weights::new`] makes them, and only on
/// a CPU with AVX-512 F, BW and VNNI.
#[derive(Debug, Clone)]
pub struct Avx512Weights {
    stored: Stored,
    /// Hidden units padded to a multiple of 16 (padding units are always 0).
    hidden_pad: usize,
}

impl Avx512Weights {
    /// The kernel's weights for `mlp` (whose tensor lengths [`Avx2Mlp::new`] has checked),
    /// stored as i8 when `narrow`; `None` where the CPU lacks the instructions or the
    /// padded hidden units pass the 16-bit pair indices.
    pub(super) fn new(mlp: &IntMlp, narrow: bool) -> Option<Avx512Weights> {
        let detected = std::arch::is_x86_feature_detected!("avx512f")
            && std::arch::is_x86_feature_detected!("avx512bw")
            && std::arch::is_x86_feature_detected!("avx512vnni");
        let hidden_pad = round_up(mlp.hidden, LANES);
        if !detected || hidden_pad > usize::from(u16::MAX) {
            return None;
        }
        fn layers<W: Weight>(mlp: &IntMlp, hidden_pad: usize) -> Layers<W> {
            let (cin, hidden, cout) = (mlp.cin, mlp.hidden, mlp.cout);
            Layers {
                l0: Pairs::new(&mlp.w0, &mlp.b0, (hidden, cin), round_up(cin, 2), LANES),
                l1: Pairs::new(&mlp.w1, &mlp.b1, (cout, hidden), hidden_pad, LANES),
            }
        }
        let stored = if narrow {
            Stored::Narrow(layers(mlp, hidden_pad))
        } else {
            Stored::Wide(layers(mlp, hidden_pad))
        };
        Some(Avx512Weights { stored, hidden_pad })
    }

    /// Length of the hidden scratch a batch of `a` anchors writes: their activations, then
    /// the list of unit pairs with a nonzero unit.
    pub(super) fn batch_hidden_len(&self, a: usize) -> usize {
        a * self.hidden_pad + self.hidden_pad / 2
    }

    /// [`Avx2Mlp::eval_batch`] with this kernel.
    ///
    /// # Safety
    /// `k` is the kernel these weights were made with (by [`Avx2Mlp::new`], for the same
    /// MLP), `x.len() >= A · k.input_len()` and `h.len() >=`
    /// [`Self::batch_hidden_len`]`(A)`. (The CPU's instructions need no promise: only
    /// [`Self::new`] makes these weights, after detecting them.)
    pub(super) unsafe fn eval_batch<const A: usize>(
        &self,
        k: &Avx2Mlp,
        x: &[i16],
        h: &mut [i16],
        y: &mut [i32],
    ) {
        // SAFETY: `batch`'s contract: `new` made these weights only after detecting AVX-512
        // F, BW and VNNI; `w` is their own layers; `k`, `x` and `h` are as the caller
        // guarantees (# Safety).
        unsafe {
            match &self.stored {
                Stored::Wide(w) => self.batch::<_, A>(w, k, x, h, y),
                Stored::Narrow(w) => self.batch::<_, A>(w, k, x, h, y),
            }
        }
    }

    /// [`Self::eval_batch`] for the weights `w`.
    ///
    /// # Safety
    /// - The CPU has AVX-512 F, BW and VNNI.
    /// - `w` is the layers of `self.stored`, and `k` the kernel [`Avx2Mlp::new`] made for
    ///   the same MLP (its `input_pairs` list the `k.cin.div_ceil(2)` input pairs `w.l0`
    ///   has columns for, and `k.cin` and the hidden units are at least 1).
    /// - `x.len() >= A · k.input_len()` and `h.len() >= self.batch_hidden_len(A)`.
    #[target_feature(enable = "avx512f,avx512bw,avx512vnni")]
    unsafe fn batch<W: Weight, const A: usize>(
        &self,
        w: &Layers<W>,
        k: &Avx2Mlp,
        x: &[i16],
        h: &mut [i16],
        y: &mut [i32],
    ) {
        let (stride, hp) = (k.input_len(), self.hidden_pad);
        let (act, list) = h.split_at_mut(A * hp);
        // Layer 0: s_h = b0[h] + W0[h] . x, then a_h = min(max(rshr(s_h, shift0), 0), 32767).
        // The last pair of an odd `cin` reads the first zero of the padding.
        let hidden = Sink::Hidden {
            act: act.as_mut_ptr(),
            hp,
            shift0: k.shift0,
        };
        // SAFETY: `passes`' contract. The CPU features: the caller's guarantee (# Safety).
        // `w.l0`, laid by `Pairs::new` with its inputs padded to `round_up(cin, 2)` >= 2 and
        // its outputs to `hp`, holds `round_up(cin, 2) · hp` weights: one pair's column,
        // and that of every listed q < cin.div_ceil(2) (`k.input_pairs`). Anchor a's pair q
        // reads inputs a · stride + 2q and + 1 < A · stride <= `x.len()` (stride =
        // `k.input_len()` >= `round_up(cin, 2)`). The sink writes `act`, A · hp values,
        // which nothing else uses during the call, for `w.l0.outputs` = hp outputs.
        unsafe { passes::<W, A>(&w.l0, x.as_ptr(), stride, &k.input_pairs, hidden) };
        // SAFETY: `nonzero_pairs`' contract: `act` holds A · hp values and `list`, the rest
        // of `h`, at least hp / 2 (`h.len() >= self.batch_hidden_len(A)`, # Safety).
        let n = unsafe { nonzero_pairs::<A>(act, hp, list) };
        let list = &list[..n];
        // Layer 1: y_o = b1[o] + Σ_j W1[o][j] a_j over the listed pairs.
        let outputs = Sink::Outputs { y, cout: k.cout };
        // SAFETY: `passes`' contract. The CPU features: the caller's guarantee (# Safety).
        // `w.l1`, laid by `Pairs::new` with its inputs padded to `hp` >= 16, holds `hp ·
        // w.l1.outputs` weights: one pair's column, and that of every listed q < hp / 2,
        // whose units a · hp + 2q and + 1 are inside `act` (A · hp). The sink writes `y`
        // through `store_outputs`, which leaves out what is past its end.
        unsafe { passes::<W, A>(&w.l1, act.as_ptr(), hp, list, outputs) };
    }
}

/// Where a pass's sums go, with the layer's bias added.
enum Sink<'a> {
    /// Layer 0: `min(max(rshr(s, shift0), 0), 32767)`, anchor a's at `act + a · hp`.
    Hidden {
        act: *mut i16,
        hp: usize,
        shift0: u8,
    },
    /// Layer 1: anchor a's `cout` outputs at `y[a · cout ..]`.
    Outputs { y: &'a mut [i32], cout: usize },
}

impl Sink<'_> {
    /// Stores the `A` anchors' sums `s` of outputs `o .. o + 16`, `bias` added.
    ///
    /// # Safety
    /// The CPU has AVX-512 F and BW. For `Sink::Hidden { act, hp, .. }`: `o + 16 <= hp`,
    /// and `act` is valid for writes of `A · hp` i16 that nothing else uses during the
    /// call. (`Sink::Outputs` needs nothing more.)
    #[inline]
    #[target_feature(enable = "avx512f,avx512bw")]
    unsafe fn put<const A: usize>(&mut self, o: usize, s: &[__m512i; A], bias: __m512i) {
        match self {
            Sink::Hidden { act, hp, shift0 } => {
                for (a, &s) in s.iter().enumerate() {
                    // SAFETY: `round_shift` needs AVX-512 F: the caller's guarantee.
                    let q = unsafe { round_shift(_mm512_add_epi32(s, bias), *shift0) };
                    // Signed saturation to i16 then max with 0 is the clamp to 0 ..= 32767.
                    let relu = _mm256_max_epi16(_mm512_cvtsepi32_epi16(q), _mm256_setzero_si256());
                    // SAFETY: the store writes 16 i16 at a · hp + o, with a < A and o + 16 <=
                    // hp: inside the A · hp the caller guarantees writable (# Safety).
                    unsafe { _mm256_storeu_si256(act.add(a * *hp + o).cast(), relu) };
                }
            }
            Sink::Outputs { y, cout } => {
                for (&s, ya) in s.iter().zip(y.chunks_exact_mut(*cout)) {
                    // SAFETY: `store_outputs` needs AVX-512 F alone (it leaves out what is
                    // past `ya`'s end): the caller's guarantee.
                    unsafe { store_outputs(_mm512_add_epi32(s, bias), o, ya) };
                }
            }
        }
    }
}

/// Every output group of `layer` in passes of at most [`pass_groups`]`(A)` groups, over the
/// input pairs in `list` of the `A` vectors at `act`, `stride` values apart, into `sink`.
///
/// # Safety
/// [`pass`]'s contract for every pass, that is:
/// - The CPU has AVX-512 F, BW and VNNI.
/// - `layer` is laid by [`Pairs::new`] with outputs padded to 16 and holds at least one
///   pair's column: `2 · layer.outputs <= layer.weights.len()`.
/// - Every `q` in `list` (read as u16) has its column in `layer`: `(q + 1) · 2 ·
///   layer.outputs <= layer.weights.len()`; and `act` is valid for reads of `a · stride +
///   2q + 2` i16 for every a < A.
/// - For `Sink::Hidden { act: out, hp, .. }`: `layer.outputs <= hp`, and `out` is valid for
///   writes of `A · hp` i16 that nothing else uses during the call.
#[inline]
#[target_feature(enable = "avx512f,avx512bw,avx512vnni")]
unsafe fn passes<W: Weight, const A: usize>(
    layer: &Pairs<W>,
    act: *const i16,
    stride: usize,
    list: &[i16],
    mut sink: Sink<'_>,
) {
    let groups = layer.outputs / LANES;
    let mut first = 0;
    while first < groups {
        let b = (groups - first).min(pass_groups(A));
        // SAFETY: `pass_in`'s contract: 1 <= b <= `pass_groups(A)` <= 12 and first + b <=
        // `layer.outputs / 16`; the rest is this function's own (# Safety), passed on.
        unsafe { pass_in::<W, A>(b, layer, first, act, stride, list, &mut sink) };
        first += b;
    }
}

/// The 32 weights at `p` as 32 i16 lanes (i8 weights sign-extended: the same values).
///
/// # Safety
/// The CPU has AVX-512 F and BW, and `p` is valid for reads of 32 consecutive `W` (32 bytes
/// for `i8`, 64 for `i16`; no alignment needed).
#[inline]
#[target_feature(enable = "avx512f,avx512bw")]
unsafe fn load32<W: Weight>(p: *const W) -> __m512i {
    if W::NARROW {
        // SAFETY: the unaligned load reads the 32 bytes of 32 i8 at `p`: the caller's
        // guarantee, as are the CPU features (# Safety).
        _mm512_cvtepi8_epi16(unsafe { _mm256_loadu_si256(p.cast()) })
    } else {
        // SAFETY: the unaligned load reads the 64 bytes of 32 i16 at `p`: the caller's
        // guarantee, as are the CPU features (# Safety).
        unsafe { _mm512_loadu_si512(p.cast()) }
    }
}

/// [`pass`] for `b` output groups (1 ..= 12; it panics on others).
///
/// # Safety
/// [`pass`]'s contract with B = `b`.
#[inline]
#[target_feature(enable = "avx512f,avx512bw,avx512vnni")]
unsafe fn pass_in<W: Weight, const A: usize>(
    b: usize,
    layer: &Pairs<W>,
    first: usize,
    act: *const i16,
    stride: usize,
    list: &[i16],
    sink: &mut Sink<'_>,
) {
    macro_rules! by_groups {
        ($($n:literal)*) => {
            match b {
                $($n => pass::<W, A, $n>(layer, first, act, stride, list, sink),)*
                _ => unreachable!("pass_groups gives 1 ..= 12"),
            }
        };
    }
    // SAFETY: the arm taken calls `pass` with B = `b`, whose contract the caller meets
    // (# Safety).
    unsafe { by_groups!(1 2 3 4 5 6 7 8 9 10 11 12) };
}

/// The sums of output groups `first .. first + B` (of 16) of `layer` over the input pairs in
/// `list`, for the `A` activation vectors at `act`, `stride` values apart, into `sink`
/// straight from the registers.
///
/// # Safety
/// - The CPU has AVX-512 F, BW and VNNI.
/// - `first + B <= layer.outputs / 16`; `layer` is laid by [`Pairs::new`] (`layer.bias`
///   holds `layer.outputs` values) and holds at least one pair's column: `2 ·
///   layer.outputs <= layer.weights.len()`.
/// - Every `q` in `list` (read as u16) has its column in `layer`: `(q + 1) · 2 ·
///   layer.outputs <= layer.weights.len()`; and `act` is valid for reads of `a · stride +
///   2q + 2` i16 for every a < A.
/// - For `Sink::Hidden { act: out, hp, .. }`: `layer.outputs <= hp`, and `out` is valid for
///   writes of `A · hp` i16 that nothing else uses during the call.
#[inline]
#[target_feature(enable = "avx512f,avx512bw,avx512vnni")]
unsafe fn pass<W: Weight, const A: usize, const B: usize>(
    layer: &Pairs<W>,
    first: usize,
    act: *const i16,
    stride: usize,
    list: &[i16],
    sink: &mut Sink<'_>,
) {
    let mut acc = [[_mm512_setzero_si512(); A]; B];
    // SAFETY: first · 32 < 2 · `layer.outputs` <= `layer.weights.len()` (# Safety): the
    // offset stays inside the weights.
    let base = unsafe { layer.weights.as_ptr().add(first * LANES * 2) };
    for &q in list {
        let q = usize::from(q as u16);
        let mut both = [_mm512_setzero_si512(); A];
        for (a, v) in both.iter_mut().enumerate() {
            // SAFETY: for a listed q, the two i16 at a · stride + 2q are readable through
            // `act` (# Safety); the read is unaligned.
            let pair = unsafe { act.add(a * stride + 2 * q).cast::<i32>().read_unaligned() };
            *v = _mm512_set1_epi32(pair);
        }
        // SAFETY: q's column starts q · 2 · `layer.outputs` on from the weights, inside them
        // as (q + 1) · 2 · `layer.outputs` <= `layer.weights.len()` (# Safety).
        let col = unsafe { base.add(q * layer.outputs * 2) };
        for (i, group) in acc.iter_mut().enumerate() {
            // SAFETY: `load32`'s contract: the CPU features are the caller's guarantee; the
            // 32 weights of group first + i end at q · 2 · outputs + (first + i + 1) · 32
            // <= (q + 1) · 2 · outputs, inside the weights.
            let w = unsafe { load32(col.add(i * 2 * LANES)) };
            for (s, v) in group.iter_mut().zip(&both) {
                *s = _mm512_dpwssd_epi32(*s, *v, w);
            }
        }
    }
    for (i, group) in acc.iter().enumerate() {
        let o = (first + i) * LANES;
        // SAFETY: the load reads 16 i32 at o < o + 16 <= `layer.outputs`, inside
        // `layer.bias`. `put`'s contract: the CPU features, and for a `Sink::Hidden` o + 16
        // <= `layer.outputs` <= hp with its A · hp values writable, are the caller's
        // guarantee (# Safety).
        unsafe {
            let bias = _mm512_loadu_si512(layer.bias.as_ptr().add(o).cast());
            sink.put(o, group, bias);
        }
    }
}

/// Stores the 16 sums `v` of outputs `o .. o + 16` into `y`, leaving out those past its end
/// (a masked store: the lanes left out are neither written nor touched).
///
/// # Safety
/// The CPU has AVX-512 F (any `o` and `y` will do).
#[inline]
#[target_feature(enable = "avx512f")]
unsafe fn store_outputs(v: __m512i, o: usize, y: &mut [i32]) {
    let at = o.min(y.len());
    let n = (y.len() - at).min(LANES);
    let mask = ((1u32 << n) - 1) as u16;
    // SAFETY: `at <= y.len()` keeps the pointer inside `y` (or at its end), and the mask
    // enables n <= y.len() − at lanes: the store writes `y[at .. at + n]` alone. AVX-512 F
    // is the caller's guarantee (# Safety).
    unsafe { _mm512_mask_storeu_epi32(y.as_mut_ptr().add(at).cast(), mask, v) };
}

/// §0.5 `rshr(acc, s)` on 16 lanes, as `avx2::round_shift` on 8.
///
/// # Safety
/// The CPU has AVX-512 F.
#[inline]
#[target_feature(enable = "avx512f")]
unsafe fn round_shift(acc: __m512i, s: u8) -> __m512i {
    if s == 0 {
        return acc;
    }
    let shifted = _mm512_sra_epi32(acc, _mm_cvtsi32_si128(i32::from(s)));
    let half = _mm512_sra_epi32(acc, _mm_cvtsi32_si128(i32::from(s) - 1));
    _mm512_add_epi32(shifted, _mm512_and_si512(half, _mm512_set1_epi32(1)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn batches_match_the_portable_mlp() {
        if !super::super::avx512_or_skip(
            "hyperprior::simd::avx512_batch::tests::batches_match_the_portable_mlp",
        ) {
            return;
        }
        super::super::kernel_tests::batches_match_the_portable_mlp(|m| {
            let k = Avx2Mlp::new(m).expect("AVX2 present");
            assert!(k.avx512.is_some(), "AVX-512 kernel chosen where detected");
            k
        });
    }

    #[test]
    fn round_shift_matches_the_definition_at_the_edges() {
        if !super::super::avx512_or_skip(
            "hyperprior::simd::avx512_batch::tests::round_shift_matches_the_definition_at_the_edges",
        ) {
            return;
        }
        let values = super::super::kernel_tests::ROUND_SHIFT_EDGES;
        for s in 0..=31u8 {
            let mut lanes = [0i32; LANES];
            lanes[..values.len()].copy_from_slice(&values);
            let mut out = [0i32; LANES];
            // SAFETY: AVX-512 F detected above, which is all that `load_lanes`,
            // `round_shift` and `store_outputs` need.
            unsafe { store_outputs(round_shift(load_lanes(&lanes), s), 0, &mut out) };
            for (a, b) in lanes.iter().zip(out) {
                assert_eq!(crate::hyperprior::mlp::round_shift(*a, s), b, "{a} >> {s}");
            }
        }
    }

    /// The 16 lanes of `lanes` as one vector.
    ///
    /// # Safety
    /// The CPU has AVX-512 F.
    #[target_feature(enable = "avx512f")]
    unsafe fn load_lanes(lanes: &[i32; LANES]) -> __m512i {
        // SAFETY: the unaligned load reads the 16 i32 of `lanes`; AVX-512 F is the caller's
        // guarantee (# Safety).
        unsafe { _mm512_loadu_si512(lanes.as_ptr().cast()) }
    }
}
