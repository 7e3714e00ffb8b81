//! §5.1's hash-grid interpolation with AVX2, for grids of C = 4 channels (HAC's).
//!
//! A 3D level's 8 corners are the 8 lanes of one vector: their entries (§2.4's hash or dense
//! index) in a few vector operations, their 4 channels in one gather (an entry's 4 i8 values
//! are one i32), their weights in two multiplications. A 2D level's 4 corners are the 4 lanes
//! of a 128-bit vector, the same way.
//!
//! The sums: grid values are −1 or +1 (§2.4; `read_grid` and the model's validation give
//! nothing else), and a level's corner weights add up to exactly 2^30 (3D) or 2^20 (2D), so
//! `Σ w · g = 2^30 − 2 · Σ_{g < 0} w`: the sum of the weights whose value is negative, taken
//! with a sign mask per channel, gives the same integer as the products, bit for bit.
//!
//! Why: the scalar loop spent most of its time on the 144 corners' index and weight
//! arithmetic, one corner at a time (about 14 % of a generated 100 k-anchor decode on one
//! thread, in a profile).

use std::arch::x86_64::{
    __m128i, __m256i, _mm256_add_epi32, _mm256_and_si256, _mm256_blend_epi32,
    _mm256_castsi256_si128, _mm256_extracti128_si256, _mm256_hadd_epi32, _mm256_i32gather_epi32,
    _mm256_min_epu32, _mm256_mullo_epi32, _mm256_set1_epi32, _mm256_setr_epi32, _mm256_slli_epi32,
    _mm256_srai_epi32, _mm256_srli_epi32, _mm256_srlv_epi32, _mm256_storeu_si256, _mm256_xor_si256,
    _mm_add_epi32, _mm_and_si128, _mm_blend_epi32, _mm_hadd_epi32, _mm_i32gather_epi32,
    _mm_min_epu32, _mm_mullo_epi32, _mm_packs_epi32, _mm_set1_epi32, _mm_setr_epi32,
    _mm_slli_epi32, _mm_srai_epi32, _mm_srli_epi32, _mm_srlv_epi32, _mm_storel_epi64,
    _mm_storeu_si128, _mm_sub_epi32, _mm_xor_si128,
};

use crate::hyperprior::grid::{
    axis, GridLayout, GridSigns, Level, PLANES, PRIME_Y, PRIME_Z, WEIGHT_BITS,
};
use crate::model::HashGrid;

/// Channels per entry the kernel handles (one i32 per entry).
const CHANNELS: usize = 4;

/// The kernel. Only [`Avx2Grid::new`] makes one: on a CPU with AVX2, for a layout of 4
/// channels whose entries i32 indices reach.
#[derive(Debug, Clone)]
pub struct Avx2Grid {
    _private: (),
}

/// Entries of a level (§2.4): (res + 1)^dim when dense, 2^T when hashed.
fn entries(l: &Level, dim: u32) -> u64 {
    if l.dense {
        (u64::from(l.res) + 1).saturating_pow(dim)
    } else {
        u64::from(l.mask) + 1
    }
}

impl Avx2Grid {
    /// The kernel for `layout`, or `None` (the scalar loop then runs).
    pub fn new(layout: &GridLayout) -> Option<Avx2Grid> {
        if !std::arch::is_x86_feature_detected!("avx2") || layout.channels != CHANNELS {
            return None;
        }
        // Every entry index of every tensor fits a non-negative i32 (the gathers' indices).
        let fits = |levels: &[Level], dim: u32| {
            levels
                .iter()
                .all(|l| l.offset + entries(l, dim) <= i32::MAX as u64)
        };
        (fits(&layout.l3, 3) && fits(&layout.l2, 2)).then_some(Avx2Grid { _private: () })
    }

    /// §5.2: marks in `flags` (the 3D, xy, xz and yz tensors' entries) every entry a corner
    /// of some voxel in `voxels` has, as [`GridLayout::mark_touched`] does.
    pub fn mark_touched(
        &self,
        layout: &GridLayout,
        voxels: &[[u32; 3]],
        flags: &mut [Vec<bool>; 4],
    ) {
        if flags
            .iter()
            .any(|f| f.is_empty() || f.len() > i32::MAX as usize)
        {
            return layout.mark_touched(voxels, flags);
        }
        // SAFETY: `mark_avx2`'s contract is AVX2 alone, which `new` detected before making
        // this kernel. (The lengths checked above make its clamped lanes index every flag
        // vector in bounds; its indexing is checked regardless.)
        unsafe { mark_avx2(layout, voxels, flags) }
    }

    /// [`GridLayout::interpolate`] for a grid of ±1 values: the same features.
    pub fn interpolate(&self, layout: &GridLayout, g: &HashGrid, v: [u32; 3], out: &mut [i16]) {
        let tensors = [&g.grid_3d, &g.grid_xy, &g.grid_xz, &g.grid_yz];
        let features = CHANNELS * (layout.l3.len() + PLANES.len() * layout.l2.len());
        if out.len() < features
            || tensors
                .iter()
                .any(|t| t.len() < CHANNELS || t.len() / CHANNELS > i32::MAX as usize)
        {
            // Not a grid for this layout: the scalar loop reports it as it does.
            return layout.interpolate(g, v, out);
        }
        // SAFETY: `interpolate_avx2`'s contract: `new` made this kernel only after detecting
        // AVX2, and each tensor holds at least one entry (4 values) and at most `i32::MAX`
        // entries (checked just above). (`out` holding every feature spares a panic in its
        // checked stores.)
        unsafe { interpolate_avx2(layout, tensors, v, out) }
    }

    /// [`GridLayout::prefetch`] with the corners' entries computed as
    /// [`Avx2Grid::interpolate`] computes them (a hint: it changes no result).
    pub fn prefetch(&self, layout: &GridLayout, g: &HashGrid, v: [u32; 3]) {
        let tensors = [&g.grid_3d, &g.grid_xy, &g.grid_xz, &g.grid_yz];
        if tensors
            .iter()
            .any(|t| t.len() < CHANNELS || t.len() / CHANNELS > i32::MAX as usize)
        {
            return;
        }
        // SAFETY: `prefetch_avx2`'s contract: `new` made this kernel only after detecting
        // AVX2, and each tensor holds at least one entry and at most `i32::MAX` entries
        // (checked just above), so the lanes, clamped to its last entry, address it.
        unsafe { prefetch_avx2(layout, tensors, v) }
    }

    /// [`Avx2Grid::interpolate`] reading `signs`, the signs of `g`'s values
    /// ([`GridSigns::new`]): the same features, from an eighth of the bytes.
    pub fn interpolate_signs(
        &self,
        layout: &GridLayout,
        g: &HashGrid,
        signs: &GridSigns,
        v: [u32; 3],
        out: &mut [i16],
    ) {
        let features = CHANNELS * (layout.l3.len() + PLANES.len() * layout.l2.len());
        if out.len() < features || !signs_fit(g, signs) {
            return self.interpolate(layout, g, v, out);
        }
        // SAFETY: `interpolate_signs_avx2`'s contract: `new` made this kernel only after
        // detecting AVX2, and `signs_fit` checked that each tensor has at least one and at
        // most `i32::MAX` entries and a word for every 8 of them. (`out` holding every
        // feature spares a panic in its checked stores.)
        unsafe { interpolate_signs_avx2(layout, signs, v, out) }
    }
}

/// Whether `signs` are those of a grid shaped as `g` is (each tensor's entries, and a word
/// for every 8 of them), every tensor with at least one entry and at most `i32::MAX`.
fn signs_fit(g: &HashGrid, signs: &GridSigns) -> bool {
    let tensors = [&g.grid_3d, &g.grid_xy, &g.grid_xz, &g.grid_yz];
    tensors
        .iter()
        .zip(&signs.entries)
        .zip(&signs.words)
        .all(|((t, &e), w)| {
            e == t.len() / CHANNELS && e >= 1 && e <= i32::MAX as usize && w.len() >= e.div_ceil(8)
        })
}

/// The nibbles (entry `e`'s 4 sign bits at bits 0 … 3) of the 8 entries in `entry`, from the
/// words at `base` (8 entries a word).
///
/// # Safety
/// The CPU has AVX2, and for every lane `e` of `entry` (as u32) `base` is valid for reading
/// the i32 at index `e / 8` (no alignment needed).
#[inline]
#[target_feature(enable = "avx2")]
unsafe fn nibbles8(base: *const i32, entry: __m256i) -> __m256i {
    // SAFETY: the gather reads the word at index e / 8 (a logical shift: never negative) of
    // each lane, which the caller guarantees readable, as it does AVX2 (# Safety).
    unsafe {
        let words = _mm256_i32gather_epi32::<4>(base, _mm256_srli_epi32::<3>(entry));
        let shift = _mm256_slli_epi32::<2>(_mm256_and_si256(entry, _mm256_set1_epi32(7)));
        _mm256_srlv_epi32(words, shift)
    }
}

/// [`nibbles8`] for 4 entries.
///
/// # Safety
/// As [`nibbles8`]'s, for the 4 lanes of `entry`.
#[inline]
#[target_feature(enable = "avx2")]
unsafe fn nibbles4(base: *const i32, entry: __m128i) -> __m128i {
    // SAFETY: as in `nibbles8`: the words the gather reads and AVX2 are the caller's
    // guarantee (# Safety).
    unsafe {
        let words = _mm_i32gather_epi32::<4>(base, _mm_srli_epi32::<3>(entry));
        let shift = _mm_slli_epi32::<2>(_mm_and_si128(entry, _mm_set1_epi32(7)));
        _mm_srlv_epi32(words, shift)
    }
}

/// Prefetches the lines of the corners with dx = 0 (3D) or di = 0 (2D): the corner one step
/// along x is almost always the next entry or one in the same 64-byte line (§2.4: `i` is the
/// hash's low bits, and the dense index's step), so requesting it too mostly repeats a
/// request.
///
/// # Safety
/// The CPU has AVX2, and every tensor holds at least one entry (4 values) and at most
/// `i32::MAX` entries, so that [`last_entry`] bounds its lanes to its entries.
#[target_feature(enable = "avx2")]
unsafe fn prefetch_avx2(layout: &GridLayout, tensors: [&Vec<i8>; 4], v: [u32; 3]) {
    use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
    // SAFETY: every operation relies on this function's contract (# Safety). The
    // intrinsics and `entries3` / `entries2` need AVX2 (the prefetch SSE): the caller's
    // guarantee. The stores write 8 (or 4) u32 into `lanes`, 8 long. Every lane is at
    // most its tensor's last entry, `last_entry` (0 ..= i32::MAX - 1 for a tensor of 1 ..=
    // i32::MAX entries), so `base.add(e)`, 4e bytes on, stays inside the tensor; the
    // prefetch itself reads nothing the program sees and cannot fault.
    unsafe {
        let bits = layout.coord_bits;
        let mut lanes = [0u32; 8];
        let base = tensors[0].as_ptr().cast::<i32>();
        let top = _mm256_set1_epi32(last_entry(tensors[0]));
        for l in &layout.l3 {
            let (cx, _) = axis(v[0], l.res, bits);
            let (cy, _) = axis(v[1], l.res, bits);
            let (cz, _) = axis(v[2], l.res, bits);
            _mm256_storeu_si256(lanes.as_mut_ptr().cast(), entries3(l, cx, cy, cz, top));
            for e in lanes.iter().step_by(2) {
                _mm_prefetch::<_MM_HINT_T0>(base.add(*e as usize).cast());
            }
        }
        for (&(pa, pb), tensor) in PLANES.iter().zip(&tensors[1..]) {
            let base = tensor.as_ptr().cast::<i32>();
            let top = _mm_set1_epi32(last_entry(tensor));
            for l in &layout.l2 {
                let (ci, _) = axis(v[pa], l.res, bits);
                let (cj, _) = axis(v[pb], l.res, bits);
                _mm_storeu_si128(lanes.as_mut_ptr().cast(), entries2(l, ci, cj, top));
                for e in lanes[..4].iter().step_by(2) {
                    _mm_prefetch::<_MM_HINT_T0>(base.add(*e as usize).cast());
                }
            }
        }
    }
}

/// The last entry of a tensor of at least one entry (as an unsigned lane bound).
fn last_entry(t: &[i8]) -> i32 {
    (t.len() / CHANNELS - 1) as i32
}

/// The entries of the 8 corners of 3D level `l` whose cell is `(cx, cy, cz)`, corner `c`
/// at (c & 1, c >> 1 & 1, c >> 2) from it, each at most `top` (compared as u32).
///
/// # Safety
/// The CPU has AVX2.
#[inline]
#[target_feature(enable = "avx2")]
// Register intrinsics only: unsafe functions for Rust 1.80 (see the module `simd`), safe
// inside this function for compilers from 1.87 on, which find the block unneeded.
#[allow(unused_unsafe)]
unsafe fn entries3(l: &Level, cx: u32, cy: u32, cz: u32, top: __m256i) -> __m256i {
    // SAFETY: register operations only, which need AVX2: the caller's guarantee
    // (# Safety).
    unsafe {
        let i = _mm256_add_epi32(
            _mm256_set1_epi32(cx as i32),
            _mm256_setr_epi32(0, 1, 0, 1, 0, 1, 0, 1),
        );
        let j = _mm256_add_epi32(
            _mm256_set1_epi32(cy as i32),
            _mm256_setr_epi32(0, 0, 1, 1, 0, 0, 1, 1),
        );
        let k = _mm256_add_epi32(
            _mm256_set1_epi32(cz as i32),
            _mm256_setr_epi32(0, 0, 0, 0, 1, 1, 1, 1),
        );
        // §2.4, modulo 2^32 like the scalar index (exact where dense: the level's entries fit
        // i32, checked in `new`).
        let local = if l.dense {
            let n = l.res.wrapping_add(1);
            _mm256_add_epi32(
                i,
                _mm256_add_epi32(
                    _mm256_mullo_epi32(j, _mm256_set1_epi32(n as i32)),
                    _mm256_mullo_epi32(k, _mm256_set1_epi32(n.wrapping_mul(n) as i32)),
                ),
            )
        } else {
            _mm256_and_si256(
                _mm256_xor_si256(
                    i,
                    _mm256_xor_si256(
                        _mm256_mullo_epi32(j, _mm256_set1_epi32(PRIME_Y as i32)),
                        _mm256_mullo_epi32(k, _mm256_set1_epi32(PRIME_Z as i32)),
                    ),
                ),
                _mm256_set1_epi32(l.mask as i32),
            )
        };
        // Clamped into the tensor (a no-op for a grid of this layout: memory safety alone).
        _mm256_min_epu32(
            _mm256_add_epi32(local, _mm256_set1_epi32(l.offset as i32)),
            top,
        )
    }
}

/// The entries of the 4 corners of 2D level `l` whose cell is `(ci, cj)`, corner `c` at
/// (c & 1, c >> 1) from it, each at most `top` (compared as u32).
///
/// # Safety
/// The CPU has AVX2.
#[inline]
#[target_feature(enable = "avx2")]
// Register intrinsics only: unsafe functions for Rust 1.80 (see the module `simd`), safe
// inside this function for compilers from 1.87 on, which find the block unneeded.
#[allow(unused_unsafe)]
unsafe fn entries2(l: &Level, ci: u32, cj: u32, top: __m128i) -> __m128i {
    // SAFETY: register operations only, which need AVX2: the caller's guarantee
    // (# Safety).
    unsafe {
        let i = _mm_add_epi32(_mm_set1_epi32(ci as i32), _mm_setr_epi32(0, 1, 0, 1));
        let j = _mm_add_epi32(_mm_set1_epi32(cj as i32), _mm_setr_epi32(0, 0, 1, 1));
        let local = if l.dense {
            let n = l.res.wrapping_add(1);
            _mm_add_epi32(i, _mm_mullo_epi32(j, _mm_set1_epi32(n as i32)))
        } else {
            _mm_and_si128(
                _mm_xor_si128(i, _mm_mullo_epi32(j, _mm_set1_epi32(PRIME_Y as i32))),
                _mm_set1_epi32(l.mask as i32),
            )
        };
        _mm_min_epu32(_mm_add_epi32(local, _mm_set1_epi32(l.offset as i32)), top)
    }
}

/// [`Avx2Grid::interpolate`] after its checks.
///
/// # Safety
/// The CPU has AVX2, and every tensor holds at least one entry (4 values) and at most
/// `i32::MAX` entries.
#[target_feature(enable = "avx2")]
unsafe fn interpolate_avx2(
    layout: &GridLayout,
    tensors: [&Vec<i8>; 4],
    v: [u32; 3],
    out: &mut [i16],
) {
    let bases = tensors.map(|t| t.as_ptr().cast::<i32>());
    let tops = tensors.map(|t| last_entry(t));
    // SAFETY: `interpolate_from`'s contract: AVX2 is the caller's guarantee (# Safety), and
    // each tensor of 1 ..= i32::MAX entries has `last_entry` = entries − 1, in 0 ..
    // i32::MAX, and a readable i32 (its entry's 4 values) at every index up to it.
    unsafe { interpolate_from::<false>(layout, bases, tops, v, out) };
}

/// [`Avx2Grid::interpolate_signs`] after its checks.
///
/// # Safety
/// The CPU has AVX2, and for every tensor t, `signs.entries[t]` is in 1 ..= `i32::MAX` and
/// `signs.words[t]` holds at least `signs.entries[t].div_ceil(8)` words.
#[target_feature(enable = "avx2")]
unsafe fn interpolate_signs_avx2(
    layout: &GridLayout,
    signs: &GridSigns,
    v: [u32; 3],
    out: &mut [i16],
) {
    let bases = [0, 1, 2, 3].map(|t| signs.words[t].as_ptr().cast::<i32>());
    let tops = signs.entries.map(|e| e as i32 - 1);
    // SAFETY: `interpolate_from`'s contract: AVX2 is the caller's guarantee (# Safety), and
    // each tensor's top, entries − 1, is in 0 .. i32::MAX, with the word of every entry up
    // to it, at index top / 8 < entries.div_ceil(8), inside its words.
    unsafe { interpolate_from::<true>(layout, bases, tops, v, out) };
}

/// §5.1 for the tensors at `bases` (3D, xy, xz, yz), entries clamped to `tops`: an entry's 4
/// values as one i32 each (`SIGNS` false), or its 4 sign bits in a word of 8 entries
/// ([`GridSigns`], `SIGNS` true).
///
/// # Safety
/// The CPU has AVX2, and for every tensor t, `tops[t] >= 0` and `bases[t]` is valid for
/// reading the i32 (no alignment needed) at every index `0 ..= tops[t]` (`SIGNS` false) or
/// `0 ..= tops[t] / 8` (`SIGNS` true). (`out` too short for the features panics.)
#[inline]
#[target_feature(enable = "avx2")]
unsafe fn interpolate_from<const SIGNS: bool>(
    layout: &GridLayout,
    bases: [*const i32; 4],
    tops: [i32; 4],
    v: [u32; 3],
    out: &mut [i16],
) {
    // SAFETY: every operation relies on this function's contract (# Safety). The intrinsics
    // and the functions called need AVX2: the caller's guarantee. `entries3` / `entries2`
    // clamp every lane to its tensor's top (as u32; a top is not negative), so each gather
    // (or `nibbles8` / `nibbles4`, which read the word of entry / 8) reads an i32 the caller
    // guarantees readable. `store4` writes through a checked slice of `out`.
    unsafe {
        let one = 1i32 << WEIGHT_BITS;
        let bits = layout.coord_bits;
        let mut at = 0;
        let top = _mm256_set1_epi32(tops[0]);
        for l in &layout.l3 {
            let (cx, wx) = axis(v[0], l.res, bits);
            let (cy, wy) = axis(v[1], l.res, bits);
            let (cz, wz) = axis(v[2], l.res, bits);
            let entry = entries3(l, cx, cy, cz, top);
            let values = if SIGNS {
                nibbles8(bases[0], entry)
            } else {
                _mm256_i32gather_epi32::<4>(bases[0], entry)
            };
            let w = _mm256_mullo_epi32(
                _mm256_mullo_epi32(
                    _mm256_blend_epi32::<0b1010_1010>(
                        _mm256_set1_epi32(one - wx as i32),
                        _mm256_set1_epi32(wx as i32),
                    ),
                    _mm256_blend_epi32::<0b1100_1100>(
                        _mm256_set1_epi32(one - wy as i32),
                        _mm256_set1_epi32(wy as i32),
                    ),
                ),
                _mm256_blend_epi32::<0b1111_0000>(
                    _mm256_set1_epi32(one - wz as i32),
                    _mm256_set1_epi32(wz as i32),
                ),
            );
            let negative = negative_sums8::<SIGNS>(w, values);
            // §5.1 step 3: A = 2^30 − 2 S, rounded to units of 2^-8 (shift 3 · 10 − 8 = 22).
            let a = _mm_sub_epi32(_mm_set1_epi32(1 << 30), _mm_slli_epi32::<1>(negative));
            let q = _mm_srai_epi32::<22>(_mm_add_epi32(a, _mm_set1_epi32(1 << 21)));
            store4(out, at, q);
            at += CHANNELS;
        }
        for (p, &(pa, pb)) in PLANES.iter().enumerate() {
            let (base, top) = (bases[p + 1], _mm_set1_epi32(tops[p + 1]));
            for l in &layout.l2 {
                let (ci, wi) = axis(v[pa], l.res, bits);
                let (cj, wj) = axis(v[pb], l.res, bits);
                let entry = entries2(l, ci, cj, top);
                let values = if SIGNS {
                    nibbles4(base, entry)
                } else {
                    _mm_i32gather_epi32::<4>(base, entry)
                };
                let w = _mm_mullo_epi32(
                    _mm_blend_epi32::<0b1010>(
                        _mm_set1_epi32(one - wi as i32),
                        _mm_set1_epi32(wi as i32),
                    ),
                    _mm_blend_epi32::<0b1100>(
                        _mm_set1_epi32(one - wj as i32),
                        _mm_set1_epi32(wj as i32),
                    ),
                );
                let negative = negative_sums4::<SIGNS>(w, values);
                // A = 2^20 − 2 S, rounded to units of 2^-8 (shift 2 · 10 − 8 = 12).
                let a = _mm_sub_epi32(_mm_set1_epi32(1 << 20), _mm_slli_epi32::<1>(negative));
                let q = _mm_srai_epi32::<12>(_mm_add_epi32(a, _mm_set1_epi32(1 << 11)));
                store4(out, at, q);
                at += CHANNELS;
            }
        }
    }
}

/// [`Avx2Grid::mark_touched`] after its checks.
///
/// # Safety
/// The CPU has AVX2. (Flags of 1 ..= `i32::MAX` entries keep every lane inside them; other
/// lengths make the checked indexing panic.)
#[target_feature(enable = "avx2")]
unsafe fn mark_avx2(layout: &GridLayout, voxels: &[[u32; 3]], flags: &mut [Vec<bool>; 4]) {
    // SAFETY: AVX2, which the intrinsics and `entries3` / `entries2` need, is the caller's
    // guarantee (# Safety); the stores write 8 (or 4) u32 into `lanes`, 8 long. The flags
    // are indexed with checks.
    unsafe {
        let bits = layout.coord_bits;
        let mut lanes = [0u32; 8];
        // The lanes are clamped to the last flag, so the indexing below never fails.
        let top3 = _mm256_set1_epi32(flags[0].len() as i32 - 1);
        let top2 = [1, 2, 3].map(|p| _mm_set1_epi32(flags[p].len() as i32 - 1));
        for &v in voxels {
            for l in &layout.l3 {
                let (cx, _) = axis(v[0], l.res, bits);
                let (cy, _) = axis(v[1], l.res, bits);
                let (cz, _) = axis(v[2], l.res, bits);
                _mm256_storeu_si256(lanes.as_mut_ptr().cast(), entries3(l, cx, cy, cz, top3));
                for &e in &lanes {
                    flags[0][e as usize] = true;
                }
            }
            for (p, &(pa, pb)) in PLANES.iter().enumerate() {
                for l in &layout.l2 {
                    let (ci, _) = axis(v[pa], l.res, bits);
                    let (cj, _) = axis(v[pb], l.res, bits);
                    _mm_storeu_si128(lanes.as_mut_ptr().cast(), entries2(l, ci, cj, top2[p]));
                    for &e in &lanes[..4] {
                        flags[p + 1][e as usize] = true;
                    }
                }
            }
        }
    }
}

/// For each channel c, the sum of the 8 lanes' weights whose value is negative:
/// `[S0, S1, S2, S3]`. A lane holds its entry's 4 values as bytes (`SIGNS` false: channel
/// c's sign at bit 8c + 7) or as sign bits (`SIGNS` true: at bit c).
///
/// # Safety
/// The CPU has AVX2.
#[inline]
#[target_feature(enable = "avx2")]
// Register intrinsics only: unsafe functions for Rust 1.80 (see the module `simd`), safe
// inside this function for compilers from 1.87 on, which find the block unneeded.
#[allow(unused_unsafe)]
unsafe fn negative_sums8<const SIGNS: bool>(w: __m256i, values: __m256i) -> __m128i {
    // SAFETY: register operations only, which need AVX2: the caller's guarantee
    // (# Safety).
    unsafe {
        // A channel's sign bit moved to the top, then spread over the lane.
        let [m0, m1, m2, m3] = if SIGNS {
            [
                _mm256_slli_epi32::<31>(values),
                _mm256_slli_epi32::<30>(values),
                _mm256_slli_epi32::<29>(values),
                _mm256_slli_epi32::<28>(values),
            ]
        } else {
            [
                _mm256_slli_epi32::<24>(values),
                _mm256_slli_epi32::<16>(values),
                _mm256_slli_epi32::<8>(values),
                values,
            ]
        }
        .map(|x| _mm256_srai_epi32::<31>(x));
        let s01 = _mm256_hadd_epi32(_mm256_and_si256(w, m0), _mm256_and_si256(w, m1));
        let s23 = _mm256_hadd_epi32(_mm256_and_si256(w, m2), _mm256_and_si256(w, m3));
        // Each 128-bit half now holds the channels' sums over its 4 lanes.
        let s = _mm256_hadd_epi32(s01, s23);
        _mm_add_epi32(_mm256_castsi256_si128(s), _mm256_extracti128_si256::<1>(s))
    }
}

/// [`negative_sums8`] over 4 lanes.
///
/// # Safety
/// The CPU has AVX2.
#[inline]
#[target_feature(enable = "avx2")]
// Register intrinsics only: unsafe functions for Rust 1.80 (see the module `simd`), safe
// inside this function for compilers from 1.87 on, which find the block unneeded.
#[allow(unused_unsafe)]
unsafe fn negative_sums4<const SIGNS: bool>(w: __m128i, values: __m128i) -> __m128i {
    // SAFETY: register operations only, which need AVX2: the caller's guarantee
    // (# Safety).
    unsafe {
        let [m0, m1, m2, m3] = if SIGNS {
            [
                _mm_slli_epi32::<31>(values),
                _mm_slli_epi32::<30>(values),
                _mm_slli_epi32::<29>(values),
                _mm_slli_epi32::<28>(values),
            ]
        } else {
            [
                _mm_slli_epi32::<24>(values),
                _mm_slli_epi32::<16>(values),
                _mm_slli_epi32::<8>(values),
                values,
            ]
        }
        .map(|x| _mm_srai_epi32::<31>(x));
        let s01 = _mm_hadd_epi32(_mm_and_si128(w, m0), _mm_and_si128(w, m1));
        let s23 = _mm_hadd_epi32(_mm_and_si128(w, m2), _mm_and_si128(w, m3));
        _mm_hadd_epi32(s01, s23)
    }
}

/// The 4 lanes of `q` (each within ±256) as i16 at `out[at..at + 4]` (a checked slice: it
/// panics where `out` is shorter).
///
/// # Safety
/// The CPU has AVX2.
#[inline]
#[target_feature(enable = "avx2")]
unsafe fn store4(out: &mut [i16], at: usize, q: __m128i) {
    let dst = &mut out[at..at + CHANNELS];
    // SAFETY: the store writes 8 bytes, the 4 i16 of `dst`; AVX2 (SSE2 suffices) is the
    // caller's guarantee (# Safety).
    unsafe { _mm_storel_epi64(dst.as_mut_ptr().cast::<__m128i>(), _mm_packs_epi32(q, q)) };
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hyperprior::test_scene::{dims, random_grid, Rng};
    use crate::model::Dims;

    /// HAC's grid levels (C = 4) with the given table sizes.
    fn hac_dims(log2_3d: u8, log2_2d: u8) -> Dims {
        let res_3d = vec![18, 24, 33, 44, 59, 80, 108, 148, 201, 275, 376, 514];
        dims(1, 4, res_3d, vec![130, 258, 514, 1026], (log2_3d, log2_2d))
    }

    /// Voxels in a 2^coord_bits cube: every fourth at the origin, every fourth at the far
    /// corner, the rest random.
    fn voxels(rng: &mut Rng, coord_bits: u8, n: usize) -> Vec<[u32; 3]> {
        let top = (1u64 << coord_bits) - 1;
        (0..n)
            .map(|i| match i % 4 {
                0 => [0; 3],
                1 => [top as u32; 3],
                _ => [0; 3].map(|_| (rng.next() % (top + 1)) as u32),
            })
            .collect()
    }

    /// The kernel, from the values and from their signs, against the scalar loop on random
    /// ±1 grids, voxels over the whole range (both ends included), hashed and dense levels,
    /// 2D and 3D.
    #[test]
    fn matches_the_scalar_interpolation() {
        if !super::super::avx2_or_skip(
            "hyperprior::simd::grid_avx2::tests::matches_the_scalar_interpolation",
        ) {
            return;
        }
        let mut rng = Rng::new(0x2545_f491_4f6c_dd1d);
        let (mut dense, mut hashed) = (0, 0);
        for (coord_bits, log2_3d, log2_2d) in
            [(9u8, 13u8, 15u8), (1, 4, 4), (16, 10, 12), (21, 19, 19)]
        {
            let d = hac_dims(log2_3d, log2_2d);
            let layout = GridLayout::new(&d, coord_bits);
            let k = Avx2Grid::new(&layout).expect("4 channels, AVX2");
            for l in layout.l3.iter().chain(&layout.l2) {
                if l.dense {
                    dense += 1;
                } else {
                    hashed += 1;
                }
            }
            let grid = random_grid(&mut rng, &d);
            let signs = GridSigns::new(&grid, 4).expect("4 channels");
            let mut want = vec![0i16; layout.features()];
            let (mut got, mut from_signs) = (want.clone(), want.clone());
            for v in voxels(&mut rng, coord_bits, 400) {
                layout.interpolate(&grid, v, &mut want);
                k.interpolate(&layout, &grid, v, &mut got);
                assert_eq!(got, want, "voxel {v:?}, coord_bits {coord_bits}");
                k.interpolate_signs(&layout, &grid, &signs, v, &mut from_signs);
                assert_eq!(
                    from_signs, want,
                    "signs: voxel {v:?}, coord_bits {coord_bits}"
                );
            }
        }
        assert!(
            dense > 0 && hashed > 0,
            "levels: {dense} dense, {hashed} hashed"
        );
    }

    /// The kernel's touched entries (§5.2) against the scalar marking, on the same layouts.
    #[test]
    fn marks_the_scalar_touched_entries() {
        if !super::super::avx2_or_skip(
            "hyperprior::simd::grid_avx2::tests::marks_the_scalar_touched_entries",
        ) {
            return;
        }
        let mut rng = Rng::new(0x9e37_79b9_7f4a_7c15);
        for (coord_bits, log2_3d, log2_2d) in [(9u8, 13u8, 15u8), (1, 4, 4), (16, 10, 12)] {
            let d = hac_dims(log2_3d, log2_2d);
            let layout = GridLayout::new(&d, coord_bits);
            let k = Avx2Grid::new(&layout).expect("4 channels, AVX2");
            let voxels = voxels(&mut rng, coord_bits, 300);
            let empty = || {
                [
                    d.entries_3d(),
                    d.entries_2d(),
                    d.entries_2d(),
                    d.entries_2d(),
                ]
                .map(|n| vec![false; n as usize])
            };
            let (mut want, mut got) = (empty(), empty());
            layout.mark_touched(&voxels, &mut want);
            k.mark_touched(&layout, &voxels, &mut got);
            assert!(
                want.iter().all(|f| f.contains(&true)),
                "some entries marked"
            );
            assert_eq!(got, want, "coord_bits {coord_bits}");
        }
    }
}
