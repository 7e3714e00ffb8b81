//! The whole context MLP (spec §5.3) with AVX2, 16 i16 lanes per `vpmaddwd`.
//!
//! Layer 0 (dense inputs): eight weight rows against one input block at a time, their eight
//! sums reduced into one vector, and the bias, rounding shift and clamped ReLU done on eight
//! outputs at once.
//!
//! Layer 1 goes by pairs of hidden units (2q, 2q + 1) and skips the pairs the ReLU set to 0
//! (about a quarter of them where half the units are 0): the broadcast pair of activations
//! times the pair's interleaved columns of W1 gives 8 outputs per `vpmaddwd`, with no
//! horizontal sums. A zero unit adds nothing to any sum, and the sums are taken modulo 2^32
//! (§5.3), so leaving pairs out and changing the order of the additions changes no bit.
//!
//! The weights are re-laid once per stream ([`Avx2Mlp::new`]), as i8 where every weight of
//! the MLP fits (a stream's `i8` weights, §1.6.2 Table 1-7, always do) and as i16 otherwise:
//! the kernel streams all its weights through the cache for every anchor, and half the bytes
//! took 4 … 10 % off a generated 100 k-anchor decode. An i8
//! weight is widened to i16 as it is loaded (`vpmovsxbw`), so the products and sums are the
//! same. Layer 0: rows padded with
//! zeros to a multiple of 16 columns, row counts padded to a multiple of 8, and the eight rows
//! of a group interleaved block by block so the kernel reads them as one sequential stream.
//! Layer 1: by unit pairs, outputs padded to a multiple of 8. Zero padding adds nothing to
//! any sum, and padded hidden units have zero weights and bias, so they are 0 after the ReLU
//! and are skipped like any other zero unit.

use std::arch::x86_64::{
    __m128i, __m256i, _mm256_add_epi32, _mm256_and_si256, _mm256_castsi256_si128,
    _mm256_cvtepi8_epi16, _mm256_extracti128_si256, _mm256_hadd_epi32, _mm256_loadu_si256,
    _mm256_madd_epi16, _mm256_permute2x128_si256, _mm256_set1_epi32, _mm256_setzero_si256,
    _mm256_sra_epi32, _mm256_storeu_si256, _mm_cvtsi32_si128, _mm_loadu_si128, _mm_max_epi16,
    _mm_packs_epi32, _mm_setzero_si128, _mm_storeu_si128,
};

use crate::hyperprior::mlp::IntMlp;

/// Input lanes per `vpmaddwd` block.
const LANES: usize = 16;
/// Weight rows evaluated together.
pub(super) const ROWS: usize = 8;

pub(super) fn round_up(n: usize, m: usize) -> usize {
    n.div_ceil(m) * m
}

/// How the kernel stores a weight: i16, or i8 where every weight of the MLP fits.
pub(super) trait Weight: Copy + Default {
    /// Whether [`load16`] widens 16 bytes (i8) rather than loading 32 (i16).
    const NARROW: bool;
    /// `w`, which the caller has checked fits.
    fn from_i16(w: i16) -> Self;
}

impl Weight for i16 {
    const NARROW: bool = false;
    fn from_i16(w: i16) -> i16 {
        w
    }
}

impl Weight for i8 {
    const NARROW: bool = true;
    fn from_i16(w: i16) -> i8 {
        w as i8
    }
}

/// The 16 weights at `p` as 16 i16 lanes (i8 weights sign-extended: the same values).
///
/// # Safety
/// The CPU has AVX2, and `p` is valid for reads of 16 consecutive `W` (16 bytes for `i8`,
/// 32 for `i16`; no alignment needed).
#[inline]
#[target_feature(enable = "avx2")]
pub(super) unsafe fn load16<W: Weight>(p: *const W) -> __m256i {
    // SAFETY: AVX2 is the caller's guarantee (# Safety), and so are the 16 `W` at `p`, the
    // bytes either unaligned load reads (16 for i8, 32 for i16).
    unsafe {
        if W::NARROW {
            _mm256_cvtepi8_epi16(_mm_loadu_si128(p.cast()))
        } else {
            _mm256_loadu_si256(p.cast())
        }
    }
}

/// One layer's weights in the kernel's layout: for row group `r` and input block `b`, the
/// 8 rows' 16 weights are contiguous at `((r * blocks + b) * ROWS + i) * LANES`.
#[derive(Debug, Clone)]
struct Layer<W> {
    weights: Vec<W>,
    /// Biases padded with zeros to a multiple of 8.
    bias: Vec<i32>,
    /// Input blocks of 16 per row.
    blocks: usize,
    /// Row groups of 8.
    groups: usize,
}

impl<W: Weight> Layer<W> {
    fn new(w: &[i16], bias: &[i32], rows: usize, cols: usize, rows_pad: usize) -> Layer<W> {
        let blocks = round_up(cols, LANES) / LANES;
        let groups = rows_pad / ROWS;
        let mut weights = vec![W::default(); groups * blocks * ROWS * LANES];
        for r in 0..rows {
            for c in 0..cols {
                let (g, i, b, l) = (r / ROWS, r % ROWS, c / LANES, c % LANES);
                weights[((g * blocks + b) * ROWS + i) * LANES + l] = W::from_i16(w[r * cols + c]);
            }
        }
        let mut padded = vec![0i32; rows_pad];
        padded[..rows].copy_from_slice(&bias[..rows]);
        Layer {
            weights,
            bias: padded,
            blocks,
            groups,
        }
    }
}

/// Layer 1 by unit pairs: for the pair of hidden units (2q, 2q + 1) and a group of 8
/// outputs, the 16 weights `W1[o][2q], W1[o][2q + 1]` of the 8 outputs o in turn are
/// contiguous at `(q * outputs + 8 g) * 2`: one `vpmaddwd` with the broadcast pair of
/// activations adds both units' products to the group's 8 sums. (The AVX-512 kernel's
/// copy pads the outputs to 16 and reads groups of 16 the same way.)
#[derive(Debug, Clone)]
pub(super) struct Pairs<W> {
    pub(super) weights: Vec<W>,
    /// Biases padded with zeros to `outputs`.
    pub(super) bias: Vec<i32>,
    /// Outputs padded to a multiple of 8.
    pub(super) outputs: usize,
}

impl<W: Weight> Pairs<W> {
    /// `rows` outputs of `cols` inputs (row-major `w`), the inputs padded to `cols_pad` and
    /// the outputs to a multiple of `group`.
    pub(super) fn new(
        w: &[i16],
        bias: &[i32],
        (rows, cols): (usize, usize),
        cols_pad: usize,
        group: usize,
    ) -> Pairs<W> {
        let outputs = round_up(rows, group);
        let mut weights = vec![W::default(); cols_pad * outputs];
        for r in 0..rows {
            for c in 0..cols {
                weights[((c / 2) * outputs + r) * 2 + c % 2] = W::from_i16(w[r * cols + c]);
            }
        }
        let mut padded = vec![0i32; outputs];
        padded[..rows].copy_from_slice(&bias[..rows]);
        Pairs {
            weights,
            bias: padded,
            outputs,
        }
    }
}

/// Output groups of 8 that one pass over the nonzero unit pairs accumulates in registers.
const PASS_GROUPS: usize = 11;

/// Both layers of `mlp` in the kernel's layouts, each weight stored as a `W`: layer 0 by
/// row groups (one anchor) and by input pairs (a batch, `super::avx2_batch`), layer 1 by
/// unit pairs (both).
#[derive(Debug, Clone)]
pub(super) struct Laid<W> {
    l0: Layer<W>,
    pub(super) l0_pairs: Pairs<W>,
    pub(super) l1: Pairs<W>,
}

impl<W: Weight> Laid<W> {
    fn new(mlp: &IntMlp, hidden_pad: usize) -> Laid<W> {
        let (cin, hidden, cout) = (mlp.cin, mlp.hidden, mlp.cout);
        Laid {
            l0: Layer::new(&mlp.w0, &mlp.b0, hidden, cin, hidden_pad),
            l0_pairs: Pairs::new(&mlp.w0, &mlp.b0, (hidden, cin), round_up(cin, 2), ROWS),
            l1: Pairs::new(&mlp.w1, &mlp.b1, (cout, hidden), hidden_pad, ROWS),
        }
    }
}

/// The weights, stored one way.
#[derive(Debug, Clone)]
pub(super) enum Weights {
    Wide(Laid<i16>),
    Narrow(Laid<i8>),
}

/// The context MLP in the AVX2 kernel's layout. Only [`Avx2Mlp::new`] makes one, and only
/// on a CPU with AVX2.
#[derive(Debug, Clone)]
pub struct Avx2Mlp {
    pub(super) weights: Weights,
    /// Layer 0's input blocks of 16.
    blocks: usize,
    pub(super) shift0: u8,
    pub(super) cin: usize,
    /// Hidden units padded to a multiple of 8 (padding units are always 0).
    pub(super) hidden_pad: usize,
    pub(super) cout: usize,
    /// The input pairs 0, 1, … of layer 0 (every one), as the batch kernel's list.
    pub(super) input_pairs: Vec<i16>,
    /// The batch kernel with AVX-512, where the CPU has it (`super::avx512_batch`).
    #[cfg(salvq_avx512)]
    pub(super) avx512: Option<super::avx512_batch::Avx512Weights>,
}

impl Avx2Mlp {
    /// The kernel for `mlp`, or `None` where the CPU lacks AVX2, the MLP's tensors do not
    /// have the lengths its dimensions give, or it has more inputs or hidden units than the
    /// kernel's 16-bit pair indices reach (the portable path then handles it).
    pub fn new(mlp: &IntMlp) -> Option<Avx2Mlp> {
        if !std::arch::is_x86_feature_detected!("avx2") {
            return None;
        }
        let (cin, hidden, cout) = (mlp.cin, mlp.hidden, mlp.cout);
        if mlp.w0.len() != hidden * cin
            || mlp.b0.len() != hidden
            || mlp.w1.len() != cout * hidden
            || mlp.b1.len() != cout
        {
            return None;
        }
        // The passes over a layer point into its weights before reading any, which needs at
        // least one input pair's column in each layer: an MLP without inputs or hidden units
        // (no valid stream has one) takes the portable path.
        if cin == 0 || hidden == 0 {
            return None;
        }
        // Layer 0 writes the hidden activations 8 at a time (and layer 1 reads them in
        // pairs): padding to 8, not to a whole 16-lane vector, spares HAC's 100 units a
        // group of 8 rows of zeros.
        let hidden_pad = round_up(hidden, ROWS);
        // The batch kernel lists layer 0's input pairs with the same 16-bit indices.
        if hidden_pad > usize::from(u16::MAX) || cin.div_ceil(2) > usize::from(u16::MAX) {
            return None;
        }
        let fits = |w: &[i16]| w.iter().all(|&v| i8::try_from(v).is_ok());
        let narrow = fits(&mlp.w0) && fits(&mlp.w1);
        let weights = if narrow {
            Weights::Narrow(Laid::new(mlp, hidden_pad))
        } else {
            Weights::Wide(Laid::new(mlp, hidden_pad))
        };
        Some(Avx2Mlp {
            weights,
            blocks: round_up(cin, LANES) / LANES,
            shift0: mlp.shift0,
            cin,
            hidden_pad,
            cout,
            input_pairs: (0..cin.div_ceil(2)).map(|q| q as u16 as i16).collect(),
            #[cfg(salvq_avx512)]
            avx512: super::avx512_batch::Avx512Weights::new(mlp, narrow),
        })
    }

    /// Length of the zero-padded input the kernel reads.
    pub fn input_len(&self) -> usize {
        self.blocks * LANES
    }

    /// The same kernel without its AVX-512 batch (to test the AVX2 batch on any CPU).
    #[cfg(test)]
    pub(super) fn without_avx512(self) -> Avx2Mlp {
        Avx2Mlp {
            #[cfg(salvq_avx512)]
            avx512: None,
            ..self
        }
    }

    /// Whether the weights are stored as i8 (every weight fits).
    #[cfg(test)]
    pub(super) fn narrow(&self) -> bool {
        matches!(self.weights, Weights::Narrow(..))
    }

    /// Length of the hidden scratch the kernel writes: the activations, then the list of
    /// unit pairs with a nonzero unit.
    pub fn hidden_len(&self) -> usize {
        self.hidden_pad + self.hidden_pad / 2
    }

    /// §5.3 steps 1-3, bit-identical to [`IntMlp::eval`]: `x` holds the `cin` inputs followed
    /// by zeros up to [`Self::input_len`]; `h` is scratch of [`Self::hidden_len`] whose first
    /// `hidden` values are the hidden activations afterwards; `y` gets the `cout` outputs.
    pub fn eval(&self, x: &[i16], h: &mut [i16], y: &mut [i32]) {
        assert!(
            x.len() >= self.input_len()
                && x[self.cin..self.input_len()].iter().all(|&v| v == 0)
                && h.len() >= self.hidden_len()
                && y.len() == self.cout,
            "Avx2Mlp::eval: scratch of the wrong shape"
        );
        // SAFETY: `eval_avx2`'s contract: `new` returned this kernel only after detecting
        // AVX2 on this CPU; `l0` and `l1` are the two layers of `self.weights`, laid by `new`
        // for this MLP; the assertion above gives `x.len() >= self.input_len()` and
        // `h.len() >= self.hidden_len()`.
        unsafe {
            match &self.weights {
                Weights::Wide(w) => self.eval_avx2(&w.l0, &w.l1, x, h, y),
                Weights::Narrow(w) => self.eval_avx2(&w.l0, &w.l1, x, h, y),
            }
        }
    }

    /// [`Self::eval`] after its checks.
    ///
    /// # Safety
    /// - The CPU has AVX2.
    /// - `l0` and `l1` are layer 0 (by row groups) and layer 1 of one `Laid` of
    ///   `self.weights`: `l0` has `self.hidden_pad / 8` row groups of `self.input_len() / 16`
    ///   blocks, and `l1` the columns of `self.hidden_pad / 2` unit pairs.
    /// - `x.len() >= self.input_len()` (the rows read `l0.blocks · 16` inputs).
    /// - `h.len() >= self.hidden_len()`: `self.hidden_pad` activations, then the list of up
    ///   to `self.hidden_pad / 2` unit pairs, written without bounds checks.
    #[target_feature(enable = "avx2")]
    unsafe fn eval_avx2<W: Weight>(
        &self,
        l0: &Layer<W>,
        l1: &Pairs<W>,
        x: &[i16],
        h: &mut [i16],
        y: &mut [i32],
    ) {
        // Layer 0: s_h = b0[h] + W0[h] . x, then a_h = min(max(rshr(s_h, shift0), 0), 32767).
        // SAFETY: AVX2 is the caller's guarantee (# Safety), which `rows8` and `store_hidden`
        // also need. `rows8`: g < `l0.groups`, and `x` holds `self.input_len()` =
        // `l0.blocks · 16` values (# Safety). The bias load reads 8 i32 at g · 8, inside
        // `l0.bias`, which `Layer::new` padded to `l0.groups · 8`. `store_hidden` checks its
        // slice itself (and `h[g * ROWS..]` is a checked slice).
        unsafe {
            for g in 0..l0.groups {
                let s = rows8(l0, g, x.as_ptr());
                let bias = _mm256_loadu_si256(l0.bias.as_ptr().add(g * ROWS).cast());
                let acc = _mm256_add_epi32(s, bias);
                store_hidden(acc, self.shift0, &mut h[g * ROWS..]);
            }
        }
        // The unit pairs with a nonzero unit, in order. Written without branches: each pair
        // is stored and the count advances only past nonzero ones (a branch per pair would be
        // mispredicted often).
        let (act, list) = h.split_at_mut(self.hidden_pad);
        let mut n = 0;
        for (q, pair) in act.chunks_exact(2).enumerate() {
            // SAFETY: the store for pair q is at n <= q < hidden_pad / 2, and `list`, the
            // rest of `h`, holds at least hidden_pad / 2 values: `h.len() >=
            // self.hidden_len()` (# Safety).
            unsafe { *list.get_unchecked_mut(n) = q as u16 as i16 };
            n += usize::from((pair[0] | pair[1]) != 0);
        }
        let (act, list) = (&*act, &list[..n]);
        // Layer 1: y_o = b1[o] + Σ_j W1[o][j] a_j over the pairs, PASS_GROUPS output groups
        // of 8 at a time.
        let groups = l1.outputs / ROWS;
        let mut first = 0;
        while first < groups {
            // SAFETY: `layer1_pass`'s contract. AVX2: the caller's guarantee (# Safety). Each
            // pass has first + B <= `groups` = `l1.outputs / 8` (B is at most the groups left).
            // `l1` is laid by `Pairs::new` with its inputs padded to `self.hidden_pad`, at least
            // 8 (`new` refuses an MLP without hidden units): `l1.weights` holds `hidden_pad ·
            // l1.outputs` values and `l1.bias` `l1.outputs`. Every listed q < hidden_pad / 2
            // (the loop above lists each pair of `act` once), so 2q + 1 < `act.len()` =
            // hidden_pad and (q + 1) · 2 · `l1.outputs` <= `l1.weights.len()`.
            unsafe {
                match groups - first {
                    1 => self.layer1_pass::<W, 1>(l1, act, list, first, y),
                    2 => self.layer1_pass::<W, 2>(l1, act, list, first, y),
                    3 => self.layer1_pass::<W, 3>(l1, act, list, first, y),
                    4 => self.layer1_pass::<W, 4>(l1, act, list, first, y),
                    5 => self.layer1_pass::<W, 5>(l1, act, list, first, y),
                    6 => self.layer1_pass::<W, 6>(l1, act, list, first, y),
                    7 => self.layer1_pass::<W, 7>(l1, act, list, first, y),
                    8 => self.layer1_pass::<W, 8>(l1, act, list, first, y),
                    9 => self.layer1_pass::<W, 9>(l1, act, list, first, y),
                    10 => self.layer1_pass::<W, 10>(l1, act, list, first, y),
                    _ => self.layer1_pass::<W, PASS_GROUPS>(l1, act, list, first, y),
                }
            }
            first += PASS_GROUPS;
        }
    }

    /// Layer 1's outputs `8 * first .. 8 * (first + B)` from the unit pairs in `list`.
    ///
    /// # Safety
    /// - The CPU has AVX2.
    /// - `first + B <= l1.outputs / 8`; `l1` is laid by [`Pairs::new`] (`l1.bias` holds
    ///   `l1.outputs` values) and holds at least one pair's column: `2 · l1.outputs <=
    ///   l1.weights.len()`.
    /// - Every `q` in `list` (read as u16) has `2q + 1 < act.len()` and its column in `l1`:
    ///   `(q + 1) · 2 · l1.outputs <= l1.weights.len()`.
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn layer1_pass<W: Weight, const B: usize>(
        &self,
        l1: &Pairs<W>,
        act: &[i16],
        list: &[i16],
        first: usize,
        y: &mut [i32],
    ) {
        // SAFETY: every operation relies on this function's contract (# Safety). The
        // intrinsics, `load16` and `store_outputs` need AVX2: the caller's guarantee. `base`,
        // at first · 16 < 2 · `l1.outputs`, is inside `l1.weights`. For a listed q, units 2q
        // and 2q + 1 are in `act`, and `col` (q · 2 · `l1.outputs` on from the weights)
        // and its B groups' 16 weights, up to (q + 1) · 2 · `l1.outputs`, are in
        // `l1.weights`. The bias loads read 8 i32 at o < o + 8 <= `l1.outputs`.
        // `store_outputs` leaves out the outputs past `y`'s end itself.
        unsafe {
            let mut acc = [_mm256_setzero_si256(); B];
            let base = l1.weights.as_ptr().add(first * ROWS * 2);
            for &q in list {
                let q = usize::from(q as u16);
                let both = u32::from(*act.get_unchecked(2 * q) as u16)
                    | u32::from(*act.get_unchecked(2 * q + 1) as u16) << 16;
                let hv = _mm256_set1_epi32(both as i32);
                let col = base.add(q * l1.outputs * 2);
                for (i, a) in acc.iter_mut().enumerate() {
                    let w = load16(col.add(i * 2 * ROWS));
                    *a = _mm256_add_epi32(*a, _mm256_madd_epi16(w, hv));
                }
            }
            for (i, a) in acc.into_iter().enumerate() {
                let o = (first + i) * ROWS;
                let v = _mm256_add_epi32(a, _mm256_loadu_si256(l1.bias.as_ptr().add(o).cast()));
                store_outputs(v, o, y);
            }
        }
    }
}

/// §5.3 step 2 on 8 layer-0 sums (biases added): `min(max(rshr(s, shift0), 0), 32767)`,
/// stored at the front of `h` (which it asserts holds 8 values).
///
/// # Safety
/// The CPU has AVX2.
#[inline]
#[target_feature(enable = "avx2")]
pub(super) unsafe fn store_hidden(sums: __m256i, shift0: u8, h: &mut [i16]) {
    // SAFETY: register operations only (`round_shift` included), which need AVX2: the
    // caller's guarantee (# Safety).
    let relu = unsafe {
        let q = round_shift(sums, shift0);
        // Signed saturation to i16 then max with 0 is exactly the clamp to 0 ..= 32767.
        let packed = _mm_packs_epi32(_mm256_castsi256_si128(q), _mm256_extracti128_si256(q, 1));
        _mm_max_epi16(packed, _mm_setzero_si128())
    };
    assert!(h.len() >= ROWS, "store_hidden: fewer than 8 units");
    // SAFETY: the store writes 8 i16 (unaligned) to the front of `h`, which holds at least
    // 8 (asserted just above); AVX2 (SSE2 suffices) is the caller's guarantee.
    unsafe { _mm_storeu_si128(h.as_mut_ptr().cast::<__m128i>(), relu) };
}

/// The unit pairs with a nonzero unit in any of the `A` activation vectors in `act` (each
/// `hp` units), in order, written to the front of `list`; returns how many. Written without
/// branches (see `Avx2Mlp::eval`): each pair is stored and the count advances only past
/// nonzero ones. (Bounds-checked indexing here cost 1.6 % of a 100 k-anchor decode.)
///
/// # Safety
/// `act` holds at least `A · hp` values and `list` at least `hp / 2` (no CPU feature is
/// needed).
#[inline(always)]
pub(super) unsafe fn nonzero_pairs<const A: usize>(
    act: &[i16],
    hp: usize,
    list: &mut [i16],
) -> usize {
    let mut n = 0;
    for q in 0..hp / 2 {
        let mut any = 0u32;
        for a in 0..A {
            // SAFETY: units a · hp + 2q and + 1, with a < A and 2q + 2 <= hp, are inside
            // the A · hp values of `act` (# Safety); the read is unaligned.
            any |= unsafe {
                act.as_ptr()
                    .add(a * hp + 2 * q)
                    .cast::<u32>()
                    .read_unaligned()
            };
        }
        // SAFETY: the store for pair q is at n <= q < hp / 2, inside `list`, which holds at
        // least hp / 2 values (# Safety).
        unsafe { *list.get_unchecked_mut(n) = q as u16 as i16 };
        n += usize::from(any != 0);
    }
    n
}

/// Stores the 8 sums `v` of outputs `o .. o + 8` into `y`, leaving out those past its end.
///
/// # Safety
/// The CPU has AVX2 (any `o` and `y` will do).
#[inline]
#[target_feature(enable = "avx2")]
pub(super) unsafe fn store_outputs(v: __m256i, o: usize, y: &mut [i32]) {
    if o + ROWS <= y.len() {
        // SAFETY: the store writes `y[o .. o + 8]`, inside `y` (checked just above), and
        // needs AVX2: the caller's guarantee (# Safety).
        unsafe { _mm256_storeu_si256(y.as_mut_ptr().add(o).cast::<__m256i>(), v) };
    } else {
        let mut last = [0i32; ROWS];
        // SAFETY: the store writes the 8 i32 of `last`; AVX2 is the caller's guarantee.
        unsafe { _mm256_storeu_si256(last.as_mut_ptr().cast::<__m256i>(), v) };
        let at = o.min(y.len());
        let n = y.len() - at;
        y[at..].copy_from_slice(&last[..n.min(ROWS)]);
    }
}

/// The 8 wrapping dot products of row group `g` of `layer` with the input at `x`, as one
/// vector of 8 sums.
///
/// # Safety
/// The CPU has AVX2; `g < layer.groups`; `x` is valid for reads of `layer.blocks * 16` i16.
/// (`layer` is laid by `Layer::new`: its weights hold `groups · blocks · 8 · 16` values.)
#[inline]
#[target_feature(enable = "avx2")]
unsafe fn rows8<W: Weight>(layer: &Layer<W>, g: usize, x: *const i16) -> __m256i {
    // SAFETY: every operation relies on this function's contract (# Safety). The intrinsics
    // and `load16` need AVX2: the caller's guarantee. Block b < `layer.blocks` reads the 16
    // inputs at `x + 16 b`, inside the `layer.blocks · 16` the caller guarantees, and row
    // i < 8's 16 weights at ((g · blocks + b) · 8 + i) · 16, inside `layer.weights` since
    // g < `layer.groups`.
    unsafe {
        let mut acc = [_mm256_setzero_si256(); ROWS];
        let base = layer.weights.as_ptr().add(g * layer.blocks * ROWS * LANES);
        for b in 0..layer.blocks {
            let xv = _mm256_loadu_si256(x.add(b * LANES).cast());
            let wb = base.add(b * ROWS * LANES);
            for (i, a) in acc.iter_mut().enumerate() {
                let wv = load16(wb.add(i * LANES));
                *a = _mm256_add_epi32(*a, _mm256_madd_epi16(wv, xv));
            }
        }
        // Reduce: after two rounds of pairwise horizontal adds, each 128-bit half holds
        // partial sums of rows 0-3 (from acc 0-3) or 4-7; adding the halves completes them.
        let s01 = _mm256_hadd_epi32(acc[0], acc[1]);
        let s23 = _mm256_hadd_epi32(acc[2], acc[3]);
        let s45 = _mm256_hadd_epi32(acc[4], acc[5]);
        let s67 = _mm256_hadd_epi32(acc[6], acc[7]);
        let t0 = _mm256_hadd_epi32(s01, s23);
        let t1 = _mm256_hadd_epi32(s45, s67);
        let lo = _mm256_permute2x128_si256(t0, t1, 0x20);
        let hi = _mm256_permute2x128_si256(t0, t1, 0x31);
        _mm256_add_epi32(lo, hi)
    }
}

/// §0.5 `rshr(acc, s)` on 8 lanes without the 64-bit sum: `(acc >> s) + bit (s - 1) of acc`,
/// which equals `(acc + 2^(s-1)) >> s` for every i32 and 1 <= s <= 31.
///
/// # Safety
/// The CPU has AVX2.
#[inline]
#[target_feature(enable = "avx2")]
// Register intrinsics only: unsafe functions for Rust 1.80 (see the module `simd`), safe
// inside this function for compilers from 1.87 on, which find the block unneeded.
#[allow(unused_unsafe)]
pub(super) unsafe fn round_shift(acc: __m256i, s: u8) -> __m256i {
    if s == 0 {
        return acc;
    }
    // SAFETY: register operations only, which need AVX2: the caller's guarantee
    // (# Safety).
    unsafe {
        let shifted = _mm256_sra_epi32(acc, _mm_cvtsi32_si128(i32::from(s)));
        let half = _mm256_sra_epi32(acc, _mm_cvtsi32_si128(i32::from(s) - 1));
        _mm256_add_epi32(shifted, _mm256_and_si256(half, _mm256_set1_epi32(1)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_the_portable_mlp() {
        if !super::super::avx2_or_skip("hyperprior::simd::avx2::tests::matches_the_portable_mlp") {
            return;
        }
        super::super::kernel_tests::matches_the_portable_mlp(|m| {
            let k = Avx2Mlp::new(m).expect("AVX2 present");
            let fits = m.w0.iter().chain(&m.w1).all(|&w| i8::try_from(w).is_ok());
            assert_eq!(
                k.narrow(),
                fits,
                "i8 storage exactly where every weight fits"
            );
            k
        });
    }

    #[test]
    fn round_shift_matches_the_definition_at_the_edges() {
        if !super::super::avx2_or_skip(
            "hyperprior::simd::avx2::tests::round_shift_matches_the_definition_at_the_edges",
        ) {
            return;
        }
        let values = super::super::kernel_tests::ROUND_SHIFT_EDGES;
        for s in 0..=31u8 {
            for chunk in values.chunks(8).chain(std::iter::once(&values[3..])) {
                let mut lanes = [0i32; 8];
                lanes[..chunk.len()].copy_from_slice(chunk);
                let mut out = [0i32; 8];
                // SAFETY: AVX2 detected above (`round_shift`'s contract and the loads'); both
                // arrays hold the 8 i32 the load reads and the store writes.
                unsafe {
                    let v = _mm256_loadu_si256(lanes.as_ptr().cast());
                    _mm256_storeu_si256(out.as_mut_ptr().cast(), round_shift(v, s));
                }
                for (a, b) in lanes.iter().zip(out) {
                    assert_eq!(crate::hyperprior::mlp::round_shift(*a, s), b, "{a} >> {s}");
                }
            }
        }
    }
}
