//! The whole context MLP (spec §5.3) with WebAssembly SIMD (`simd128`): 8 i16 lanes per
//! `i32x4.dot_i16x8_s`, the instruction `pmaddwd` is on x86 (two i16 × i16 products added
//! into each i32 lane).
//!
//! The same plan as [`super::avx2`] at half the width. Layer 0: four weight rows against one
//! input block at a time, their four sums reduced into one vector, then the bias, rounding
//! shift and clamped ReLU on four outputs at once. Layer 1 by pairs of hidden units, skipping
//! the pairs the ReLU set to 0: the broadcast pair of activations times the pair's interleaved
//! weights gives 4 outputs per `dot`. §5.3 takes the sums modulo 2^32, so the order of the
//! additions and the pairs left out change no bit (see the module above for the one pair of
//! products that exceeds i32).
//!
//! The weights are re-laid once per stream ([`WasmMlp::new`]) as vectors, so the kernel reads
//! them with plain indexing (no pointer loads). Zero padding adds nothing to any sum.
//!
//! Why: the portable loop, which the compiler vectorizes one row at a time, made the context
//! MLP a third of an anchors stream's decode in WebAssembly (30 000 generated anchors, Node).

#[cfg(target_arch = "wasm32")]
use core::arch::wasm32::{
    i16x8, i32x4, i32x4_add, i32x4_dot_i16x8, i32x4_extract_lane, i32x4_max, i32x4_min, i32x4_shr,
    i32x4_shuffle, i32x4_splat, v128, v128_and,
};
#[cfg(not(target_arch = "wasm32"))]
use emulated::{
    i16x8, i32x4, i32x4_add, i32x4_dot_i16x8, i32x4_extract_lane, i32x4_max, i32x4_min, i32x4_shr,
    i32x4_shuffle, i32x4_splat, v128, v128_and,
};

use crate::hyperprior::mlp::IntMlp;

/// Input lanes per `dot`.
const LANES: usize = 8;
/// Weight rows (layer 0) or outputs (layer 1) per vector of sums.
const ROWS: usize = 4;
/// Input blocks the kernel keeps as vectors on the stack: inputs up to 512.
const MAX_BLOCKS: usize = 64;
/// Output groups of 4 that one pass over the nonzero unit pairs accumulates.
const PASS_GROUPS: usize = 8;

fn round_up(n: usize, m: usize) -> usize {
    n.div_ceil(m) * m
}

/// The context MLP in this kernel's layout; [`WasmMlp::new`] makes one.
#[derive(Debug, Clone)]
pub struct WasmMlp {
    /// Layer 0: for row group `g` and input block `b`, the 4 rows' vectors at
    /// `(g · blocks + b) · 4 + i`.
    w0: Vec<v128>,
    /// Layer 0 biases padded with zeros to `hidden_pad`.
    b0: Vec<i32>,
    /// Input blocks of 8.
    blocks: usize,
    /// Layer 1: for unit pair `q` and output group `o`, the vector `(W1[4o + i][2q],
    /// W1[4o + i][2q + 1])` for i = 0 … 3, at `q · out_groups + o`.
    w1: Vec<v128>,
    /// Layer 1 biases padded with zeros to `out_groups · 4`.
    b1: Vec<i32>,
    out_groups: usize,
    shift0: u8,
    cin: usize,
    /// Hidden units padded to a multiple of 8 (padding units are always 0).
    hidden_pad: usize,
    cout: usize,
}

/// 8 i16 as one vector.
#[inline(always)]
fn vector(v: &[i16]) -> v128 {
    let a: [i16; LANES] = core::array::from_fn(|i| v.get(i).copied().unwrap_or(0));
    i16x8(a[0], a[1], a[2], a[3], a[4], a[5], a[6], a[7])
}

impl WasmMlp {
    /// The kernel for `mlp`, or `None` where its tensors do not have the lengths its
    /// dimensions give, it has more inputs than the kernel keeps (512), or more hidden units
    /// than the 16-bit pair indices reach (the portable path then handles it).
    pub fn new(mlp: &IntMlp) -> Option<WasmMlp> {
        let (cin, hidden, cout) = (mlp.cin, mlp.hidden, mlp.cout);
        if mlp.w0.len() != hidden * cin
            || mlp.b0.len() != hidden
            || mlp.w1.len() != cout * hidden
            || mlp.b1.len() != cout
        {
            return None;
        }
        let blocks = cin.div_ceil(LANES);
        let hidden_pad = round_up(hidden, LANES);
        if blocks > MAX_BLOCKS || hidden_pad > usize::from(u16::MAX) {
            return None;
        }
        let groups0 = hidden_pad / ROWS;
        let mut w0 = Vec::with_capacity(groups0 * blocks * ROWS);
        for g in 0..groups0 {
            for b in 0..blocks {
                for i in 0..ROWS {
                    let r = g * ROWS + i;
                    let row = mlp.w0.get(r * cin..(r + 1) * cin).unwrap_or(&[]);
                    w0.push(vector(row.get(b * LANES..).unwrap_or(&[])));
                }
            }
        }
        let mut b0 = mlp.b0.clone();
        b0.resize(hidden_pad, 0);
        let out_groups = cout.div_ceil(ROWS);
        let mut w1 = Vec::with_capacity(hidden_pad / 2 * out_groups);
        let weight = |o: usize, j: usize| {
            if o < cout && j < hidden {
                mlp.w1[o * hidden + j]
            } else {
                0
            }
        };
        for q in 0..hidden_pad / 2 {
            for o in 0..out_groups {
                let lanes: [i16; LANES] =
                    core::array::from_fn(|l| weight(o * ROWS + l / 2, 2 * q + l % 2));
                w1.push(vector(&lanes));
            }
        }
        let mut b1 = mlp.b1.clone();
        b1.resize(out_groups * ROWS, 0);
        Some(WasmMlp {
            w0,
            b0,
            blocks,
            w1,
            b1,
            out_groups,
            shift0: mlp.shift0,
            cin,
            hidden_pad,
            cout,
        })
    }

    /// Length of the zero-padded input the kernel reads.
    pub fn input_len(&self) -> usize {
        self.blocks * LANES
    }

    /// Length of the hidden scratch the kernel writes: the activations, then the list of
    /// unit pairs with a nonzero unit.
    pub fn hidden_len(&self) -> usize {
        self.hidden_pad + self.hidden_pad / 2
    }

    /// Length of the hidden scratch [`Self::eval_batch`] needs: each anchor's in turn.
    pub fn batch_hidden_len(&self, anchors: usize) -> usize {
        anchors * self.hidden_len()
    }

    /// [`Self::eval`] of `A` anchors in turn (the AVX2 kernel's batch, which shares each
    /// weight's load between anchors, is not written for this one): `x` holds their inputs,
    /// [`Self::input_len`] each, `h` their scratch, `y` their outputs, `cout` each.
    pub fn eval_batch<const A: usize>(&self, x: &[i16], h: &mut [i16], y: &mut [i32]) {
        let anchors = x
            .chunks_exact(self.input_len())
            .zip(h.chunks_exact_mut(self.hidden_len()))
            .zip(y.chunks_exact_mut(self.cout));
        for ((xa, ha), ya) in anchors.take(A) {
            self.eval(xa, ha, ya);
        }
    }

    /// §5.3 steps 1-3, bit-identical to [`IntMlp::eval`]: `x` holds the `cin` inputs followed
    /// by zeros up to [`Self::input_len`]; `h` is scratch of [`Self::hidden_len`] whose first
    /// `hidden` values are the hidden activations afterwards; `y` gets the `cout` outputs.
    /// Scratch of another shape leaves `y` as it is (the caller sizes it from this kernel).
    pub fn eval(&self, x: &[i16], h: &mut [i16], y: &mut [i32]) {
        if x.len() < self.input_len()
            || x[self.cin..self.input_len()].iter().any(|&v| v != 0)
            || h.len() < self.hidden_len()
            || y.len() != self.cout
        {
            return;
        }
        let mut xv = [i32x4_splat(0); MAX_BLOCKS];
        for (b, v) in xv.iter_mut().enumerate().take(self.blocks) {
            *v = vector(&x[b * LANES..(b + 1) * LANES]);
        }
        let xv = &xv[..self.blocks];
        // Layer 0: s_h = b0[h] + W0[h] . x, then a_h = min(max(rshr(s_h, shift0), 0), 32767).
        let (act, list) = h.split_at_mut(self.hidden_pad);
        let group_len = self.blocks * ROWS;
        for (g, (bias, out)) in self
            .b0
            .chunks_exact(ROWS)
            .zip(act.chunks_exact_mut(ROWS))
            .enumerate()
        {
            let rows = &self.w0[g * group_len..(g + 1) * group_len];
            let mut acc = [i32x4_splat(0); ROWS];
            for (w, &x) in rows.chunks_exact(ROWS).zip(xv) {
                for (a, &w) in acc.iter_mut().zip(w) {
                    *a = i32x4_add(*a, i32x4_dot_i16x8(w, x));
                }
            }
            let s = i32x4_add(reduce4(acc), lanes(bias));
            let q = i32x4_min(
                i32x4_max(round_shift(s, self.shift0), i32x4_splat(0)),
                i32x4_splat(i32::from(i16::MAX)),
            );
            out[0] = i32x4_extract_lane::<0>(q) as i16;
            out[1] = i32x4_extract_lane::<1>(q) as i16;
            out[2] = i32x4_extract_lane::<2>(q) as i16;
            out[3] = i32x4_extract_lane::<3>(q) as i16;
        }
        // The unit pairs with a nonzero unit, in order (a count that advances past nonzero
        // pairs only, rather than a branch per pair).
        let mut n = 0;
        for (q, pair) in act.chunks_exact(2).enumerate() {
            if let Some(slot) = list.get_mut(n) {
                *slot = q as u16 as i16;
            }
            n += usize::from((pair[0] | pair[1]) != 0);
        }
        let (act, list) = (&*act, &list[..n.min(list.len())]);
        // Layer 1: y_o = b1[o] + Σ_j W1[o][j] a_j over the pairs, PASS_GROUPS output groups
        // of 4 at a time.
        let mut first = 0;
        while first < self.out_groups {
            match self.out_groups - first {
                1 => self.layer1_pass::<1>(act, list, first, y),
                2 => self.layer1_pass::<2>(act, list, first, y),
                3 => self.layer1_pass::<3>(act, list, first, y),
                4 => self.layer1_pass::<4>(act, list, first, y),
                5 => self.layer1_pass::<5>(act, list, first, y),
                6 => self.layer1_pass::<6>(act, list, first, y),
                7 => self.layer1_pass::<7>(act, list, first, y),
                _ => self.layer1_pass::<PASS_GROUPS>(act, list, first, y),
            }
            first += PASS_GROUPS;
        }
    }

    /// Layer 1's outputs `4 · first .. 4 · (first + B)` from the unit pairs in `list`.
    #[inline(always)]
    fn layer1_pass<const B: usize>(&self, act: &[i16], list: &[i16], first: usize, y: &mut [i32]) {
        let mut acc = [i32x4_splat(0); B];
        for &q in list {
            let q = usize::from(q as u16);
            let both = u32::from(act[2 * q] as u16) | u32::from(act[2 * q + 1] as u16) << 16;
            let hv = i32x4_splat(both as i32);
            let at = q * self.out_groups + first;
            for (a, &w) in acc.iter_mut().zip(&self.w1[at..at + B]) {
                *a = i32x4_add(*a, i32x4_dot_i16x8(w, hv));
            }
        }
        for (i, a) in acc.into_iter().enumerate() {
            let o = (first + i) * ROWS;
            let v = i32x4_add(a, lanes(&self.b1[o..o + ROWS]));
            let lanes = [
                i32x4_extract_lane::<0>(v),
                i32x4_extract_lane::<1>(v),
                i32x4_extract_lane::<2>(v),
                i32x4_extract_lane::<3>(v),
            ];
            let end = (o + ROWS).min(self.cout);
            y[o..end].copy_from_slice(&lanes[..end - o]);
        }
    }
}

/// 4 i32 as one vector.
#[inline(always)]
fn lanes(v: &[i32]) -> v128 {
    i32x4(v[0], v[1], v[2], v[3])
}

/// The lane sums of four vectors, `[Σ a0, Σ a1, Σ a2, Σ a3]`.
#[inline(always)]
fn reduce4([a0, a1, a2, a3]: [v128; ROWS]) -> v128 {
    // Interleave, add, interleave again: each step halves the partial sums per row.
    let u0 = i32x4_add(
        i32x4_shuffle::<0, 4, 1, 5>(a0, a1),
        i32x4_shuffle::<2, 6, 3, 7>(a0, a1),
    );
    let u1 = i32x4_add(
        i32x4_shuffle::<0, 4, 1, 5>(a2, a3),
        i32x4_shuffle::<2, 6, 3, 7>(a2, a3),
    );
    i32x4_add(
        i32x4_shuffle::<0, 1, 4, 5>(u0, u1),
        i32x4_shuffle::<2, 3, 6, 7>(u0, u1),
    )
}

/// §0.5 `rshr(acc, s)` on 4 lanes without the 64-bit sum: `(acc >> s) + bit (s - 1) of acc`,
/// which equals `(acc + 2^(s-1)) >> s` for every i32 and 1 <= s <= 31.
#[inline(always)]
fn round_shift(acc: v128, s: u8) -> v128 {
    if s == 0 {
        return acc;
    }
    let shifted = i32x4_shr(acc, u32::from(s));
    let half = i32x4_shr(acc, u32::from(s) - 1);
    i32x4_add(shifted, v128_and(half, i32x4_splat(1)))
}

/// The WebAssembly SIMD operations the kernel uses, on `[i32; 4]`, as the WebAssembly core
/// specification defines them, so that the kernel's tests run on any machine (the wasm build
/// uses the instructions; CI's `decode_speed` smoke compares its decode with the native one).
#[cfg(not(target_arch = "wasm32"))]
#[allow(non_camel_case_types)]
mod emulated {
    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    pub struct v128([i32; 4]);

    fn halves(v: i32) -> [i32; 2] {
        [i32::from(v as i16), i32::from((v >> 16) as i16)]
    }

    #[allow(clippy::too_many_arguments)]
    pub fn i16x8(a0: i16, a1: i16, a2: i16, a3: i16, a4: i16, a5: i16, a6: i16, a7: i16) -> v128 {
        let pair = |lo: i16, hi: i16| i32::from(lo as u16) | i32::from(hi as u16) << 16;
        v128([pair(a0, a1), pair(a2, a3), pair(a4, a5), pair(a6, a7)])
    }
    pub fn i32x4(a0: i32, a1: i32, a2: i32, a3: i32) -> v128 {
        v128([a0, a1, a2, a3])
    }
    pub fn i32x4_splat(a: i32) -> v128 {
        v128([a; 4])
    }
    fn map2(a: v128, b: v128, f: impl Fn(i32, i32) -> i32) -> v128 {
        v128(core::array::from_fn(|i| f(a.0[i], b.0[i])))
    }
    pub fn i32x4_add(a: v128, b: v128) -> v128 {
        map2(a, b, i32::wrapping_add)
    }
    /// `i32x4.dot_i16x8_s`: per lane, the two i16 × i16 products added, modulo 2^32.
    pub fn i32x4_dot_i16x8(a: v128, b: v128) -> v128 {
        map2(a, b, |a, b| {
            let ([a0, a1], [b0, b1]) = (halves(a), halves(b));
            (a0 * b0).wrapping_add(a1 * b1)
        })
    }
    pub fn i32x4_max(a: v128, b: v128) -> v128 {
        map2(a, b, i32::max)
    }
    pub fn i32x4_min(a: v128, b: v128) -> v128 {
        map2(a, b, i32::min)
    }
    pub fn v128_and(a: v128, b: v128) -> v128 {
        map2(a, b, |a, b| a & b)
    }
    /// `i32x4.shr_s`: arithmetic, the shift taken modulo 32.
    pub fn i32x4_shr(a: v128, amt: u32) -> v128 {
        v128(a.0.map(|v| v >> (amt % 32)))
    }
    pub fn i32x4_extract_lane<const N: usize>(a: v128) -> i32 {
        a.0[N]
    }
    /// Lanes 0 … 3 are `a`'s, 4 … 7 are `b`'s.
    pub fn i32x4_shuffle<const I0: usize, const I1: usize, const I2: usize, const I3: usize>(
        a: v128,
        b: v128,
    ) -> v128 {
        let lane = |i: usize| if i < 4 { a.0[i] } else { b.0[i - 4] };
        v128([lane(I0), lane(I1), lane(I2), lane(I3)])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_the_portable_mlp() {
        super::super::kernel_tests::matches_the_portable_mlp(|m| {
            WasmMlp::new(m).expect("the test's shapes fit the kernel")
        });
    }

    #[test]
    fn batches_match_the_portable_mlp() {
        super::super::kernel_tests::batches_match_the_portable_mlp(|m| {
            WasmMlp::new(m).expect("the test's shapes fit the kernel")
        });
    }

    #[test]
    fn round_shift_matches_the_definition_at_the_edges() {
        let values = super::super::kernel_tests::ROUND_SHIFT_EDGES;
        for s in 0..=31u8 {
            for &v in &values {
                let got = i32x4_extract_lane::<0>(round_shift(i32x4_splat(v), s));
                assert_eq!(crate::hyperprior::mlp::round_shift(v, s), got, "{v} >> {s}");
            }
        }
    }

    #[test]
    fn reduce4_sums_each_vector() {
        let v = |k: i32| i32x4(k, 10 * k, 100 * k, 1000 * k);
        let got = reduce4([v(1), v(2), v(3), v(4)]);
        assert_eq!(got, i32x4(1111, 2222, 3333, 4444));
    }
}
