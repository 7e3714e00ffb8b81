//! Hash-grid interpolation in integer arithmetic (spec §5.1) and the marking of the grid
//! entries an anchor touches (§5.2; the set of all anchors' is built in `touched`).

use crate::model::{level_entries, Dims, HashGrid};

/// Bits of each per-axis interpolation weight (spec §5.1): weights are in units of 2^-10.
pub const WEIGHT_BITS: u32 = 10;
/// MLP input precision: grid features are in units of 2^-8 (|x| <= 256).
pub const INPUT_FRAC_BITS: u32 = 8;

/// The hash multipliers of spec §2.4 for the second and third coordinate.
pub(crate) const PRIME_Y: u32 = 2_654_435_761;
pub(crate) const PRIME_Z: u32 = 805_459_861;

/// One level of a grid tensor (spec §2.4).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Level {
    /// The level's resolution `r`: r + 1 vertices per axis.
    pub res: u32,
    /// Whether the level is dense ((r + 1)^d ≤ 2^T entries, indexed directly) rather than
    /// hashed.
    pub dense: bool,
    /// 2^T - 1: the hash mask of a hashed level.
    pub mask: u32,
    /// First entry of the level in its tensor.
    pub offset: u64,
}

/// The levels of one tensor, level 0 first.
pub fn levels(res: &[u16], dim: u32, log2: u8) -> Vec<Level> {
    let mut offset = 0u64;
    res.iter()
        .map(|&r| {
            let entries = level_entries(r, dim, log2);
            let l = Level {
                res: r.into(),
                dense: entries == (u64::from(r) + 1).saturating_pow(dim),
                mask: ((1u64 << log2) - 1) as u32,
                offset,
            };
            offset += entries;
            l
        })
        .collect()
}

/// §5.1 step 1: the cell and the upper weight of one coordinate on a level of resolution r.
/// The normalized position is p = (2v + 1) / 2^(B+1); p * r splits into the cell
/// floor(p r) and a fraction, truncated to WEIGHT_BITS bits.
#[inline]
pub(crate) fn axis(v: u32, r: u32, coord_bits: u32) -> (u32, u32) {
    let x = (2 * u64::from(v) + 1) * u64::from(r);
    let b = coord_bits + 1;
    let cell = (x >> b) as u32;
    let frac = x & ((1u64 << b) - 1);
    let w1 = if b >= WEIGHT_BITS {
        frac >> (b - WEIGHT_BITS)
    } else {
        frac << (WEIGHT_BITS - b)
    };
    (cell, w1 as u32)
}

/// §2.4: entry of 3D vertex (i, j, k).
#[inline]
pub fn index3(l: &Level, i: u32, j: u32, k: u32) -> u64 {
    let local = if l.dense {
        let n = u64::from(l.res) + 1;
        u64::from(i) + u64::from(j) * n + u64::from(k) * n * n
    } else {
        u64::from((i ^ j.wrapping_mul(PRIME_Y) ^ k.wrapping_mul(PRIME_Z)) & l.mask)
    };
    l.offset + local
}

/// §2.4: entry of 2D vertex (i, j).
#[inline]
pub fn index2(l: &Level, i: u32, j: u32) -> u64 {
    let local = if l.dense {
        u64::from(i) + u64::from(j) * (u64::from(l.res) + 1)
    } else {
        u64::from((i ^ j.wrapping_mul(PRIME_Y)) & l.mask)
    };
    l.offset + local
}

/// The grid layout of a model: its levels and channel count.
#[derive(Debug, Clone)]
pub struct GridLayout {
    /// The L3 levels of the 3D tensor.
    pub l3: Vec<Level>,
    /// The L2 levels shared by the xy, xz and yz plane tensors.
    pub l2: Vec<Level>,
    /// Channels per entry, C (1 … 16).
    pub channels: usize,
    /// Bits per voxel coordinate (`HEAD` `coord_bits`, 1 … 21), which normalizes positions.
    pub coord_bits: u32,
}

/// The three planes of spec §2.4: which coordinates each one takes.
pub(crate) const PLANES: [(usize, usize); 3] = [(0, 1), (0, 2), (1, 2)];

impl GridLayout {
    /// The layout of a model of dimensions `d` whose voxel coordinates are below
    /// 2^`coord_bits` (§2.4).
    pub fn new(d: &Dims, coord_bits: u8) -> Self {
        GridLayout {
            l3: levels(&d.res_3d, 3, d.log2_size_3d),
            l2: levels(&d.res_2d, 2, d.log2_size_2d),
            channels: d.grid_channels.into(),
            coord_bits: coord_bits.into(),
        }
    }

    /// Width of the feature vector: C (L3 + 3 L2).
    pub fn features(&self) -> usize {
        self.channels * (self.l3.len() + 3 * self.l2.len())
    }

    /// Starts loading the grid entries [`GridLayout::interpolate`] will read for voxel `v`
    /// (a hint: it changes no result). Called for the next anchor while this one is
    /// computed, it overlaps the waits for scattered table entries with work.
    #[cfg(feature = "simd")]
    pub fn prefetch(&self, g: &HashGrid, v: [u32; 3]) {
        use crate::hyperprior::simd::prefetch;
        let c = self.channels;
        let tensors = [&g.grid_3d, &g.grid_xy, &g.grid_xz, &g.grid_yz];
        self.levels_of(
            v,
            |_: &mut (), t, e, _| prefetch(tensors[t], e * c),
            |_, _| {},
        );
    }

    /// Without the `simd` feature there is no prefetch hint: nothing to do.
    #[cfg(not(feature = "simd"))]
    pub fn prefetch(&self, _: &HashGrid, _: [u32; 3]) {}

    /// §5.1: the integer grid features of voxel `v` (units of 2^-8), written to `out`
    /// (length [`GridLayout::features`]) in the order 3D levels, xy, xz, yz levels, C each.
    pub fn interpolate(&self, g: &HashGrid, v: [u32; 3], out: &mut [i16]) {
        // Common channel counts get a copy of the loop with the count a constant, which the
        // compiler unrolls and vectorises (HAC uses C = 4).
        match self.channels {
            2 => self.interpolate_c(2, g, v, out),
            4 => self.interpolate_c(4, g, v, out),
            8 => self.interpolate_c(8, g, v, out),
            c => self.interpolate_c(c, g, v, out),
        }
    }

    #[inline(always)]
    fn interpolate_c(&self, c: usize, g: &HashGrid, v: [u32; 3], out: &mut [i16]) {
        let tensors = [&g.grid_3d, &g.grid_xy, &g.grid_xz, &g.grid_yz];
        let mut at = 0;
        self.levels_of(
            v,
            |acc: &mut [i32; 16], t, e, w| {
                let e = e * c;
                for (a, &s) in acc.iter_mut().zip(&tensors[t][e..e + c]) {
                    *a += w * i32::from(s);
                }
            },
            |acc, dims| {
                // §5.1 step 3: round to units of 2^-8 (add half, arithmetic shift). The sums
                // fit i32: a level's corner weights add up to 2^30 (3D) or 2^20 (2D) and
                // values are ±1.
                let shift = dims * WEIGHT_BITS - INPUT_FRAC_BITS;
                for (o, a) in out[at..at + c].iter_mut().zip(&acc) {
                    *o = ((a + (1 << (shift - 1))) >> shift) as i16;
                }
                at += c;
            },
        );
    }

    /// [`GridLayout::interpolate`] of a grid of ±1 values read through their signs (§5.1
    /// for `C` = [`SIGN_CHANNELS`]), for targets without an interpolation kernel (WebAssembly,
    /// aarch64). A level's weights sum to one (2^30 or 2^20), so a channel's sum is that one
    /// less twice the weights of its corners whose value is −1. Why: the signs take an
    /// eighth of the bytes' memory, and the corners are scattered over all of it. A layout
    /// whose entries lie outside `signs` reads those as +1 (the grids the decoder builds
    /// `signs` from have every entry).
    pub fn interpolate_signs(&self, signs: &GridSigns, v: [u32; 3], out: &mut [i16]) {
        const C: usize = SIGN_CHANNELS;
        let mut at = 0;
        self.levels_of(
            v,
            |negative: &mut [i32; C], t, e, w| {
                add_negative(negative, nibble(&signs.words[t], e), w);
            },
            |negative, dims| {
                let shift = dims * WEIGHT_BITS - INPUT_FRAC_BITS;
                write_features(
                    &mut out[at..at + C],
                    negative,
                    1 << (dims * WEIGHT_BITS),
                    shift,
                );
                at += C;
            },
        );
    }

    /// §5.1's corners of voxel `v`, level by level in the features' order (3D levels, then
    /// the xy, xz and yz planes' levels): `corner(sums, tensor, entry, weight)` for each
    /// corner of a level (tensor 0 the 3D one, 1 … 3 the planes; the weight in units of
    /// 2^−10 per axis), then `level(sums, dims)` with the level's sums (from
    /// `S::default()`) and its dimensions, 3 or 2.
    #[inline(always)]
    fn levels_of<S: Default>(
        &self,
        v: [u32; 3],
        mut corner: impl FnMut(&mut S, usize, usize, i32),
        mut level: impl FnMut(S, u32),
    ) {
        let one = 1i32 << WEIGHT_BITS;
        let weights = |w: u32| [one - w as i32, w as i32];
        for l in &self.l3 {
            let (cx, wx) = axis(v[0], l.res, self.coord_bits);
            let (cy, wy) = axis(v[1], l.res, self.coord_bits);
            let (cz, wz) = axis(v[2], l.res, self.coord_bits);
            let (ax, ay, az) = (weights(wx), weights(wy), weights(wz));
            let mut sums = S::default();
            for c in 0..8u32 {
                let (dx, dy, dz) = (c & 1, (c >> 1) & 1, (c >> 2) & 1);
                let e = index3(l, cx + dx, cy + dy, cz + dz) as usize;
                corner(
                    &mut sums,
                    0,
                    e,
                    ax[dx as usize] * ay[dy as usize] * az[dz as usize],
                );
            }
            level(sums, 3);
        }
        for (p, &(pa, pb)) in PLANES.iter().enumerate() {
            for l in &self.l2 {
                let (ci, wi) = axis(v[pa], l.res, self.coord_bits);
                let (cj, wj) = axis(v[pb], l.res, self.coord_bits);
                let (ai, aj) = (weights(wi), weights(wj));
                let mut sums = S::default();
                for c in 0..4u32 {
                    let (di, dj) = (c & 1, c >> 1);
                    let e = index2(l, ci + di, cj + dj) as usize;
                    corner(&mut sums, p + 1, e, ai[di as usize] * aj[dj as usize]);
                }
                level(sums, 2);
            }
        }
    }

    /// §5.2: marks in `flags` (the 3D, xy, xz and yz tensors' entries) every entry a corner
    /// of some voxel in `voxels` has.
    pub fn mark_touched(&self, voxels: &[[u32; 3]], flags: &mut [Vec<bool>; 4]) {
        for &v in voxels {
            self.levels_of(v, |_: &mut (), t, e, _| flags[t][e] = true, |_, _| {});
        }
    }
}

/// A binary grid's values as sign bits, for the interpolation kernel (§2.4: every value is
/// −1 or +1, so one bit holds it): in each tensor, bit `c` of nibble `e` is set where channel
/// `c` of entry `e` is −1, eight entries (C = 4) to a word. Why: the kernel gathers scattered
/// entries, and a HAC-size grid (12 3D levels of 2^13 entries, 3 × 4 2D levels of 2^15) takes
/// 1.77 MB as bytes, which the L2 cache (2 MB on this machine) cannot hold beside the rest of
/// a decode; as signs it takes 222 KB. A 100 k-anchor decode spent 7 … 10 % less time
/// (`perf record` profiles, and the two builds' decodes timed in turn).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct GridSigns {
    /// The 3D, xy, xz and yz tensors' words.
    pub(crate) words: [Vec<u32>; 4],
    /// Each tensor's entries.
    pub(crate) entries: [usize; 4],
}

/// Channels per entry that [`GridSigns`] packs (HAC's C).
pub const SIGN_CHANNELS: usize = 4;

impl GridSigns {
    /// The signs of `grid`, whose entries have `channels` values each: `None` unless
    /// `channels` is [`SIGN_CHANNELS`]. A value's bit says only whether it is negative, so
    /// the kernel that reads them gives §5.1's features for ±1 values, which every decoded
    /// and every validated grid holds.
    pub fn new(grid: &HashGrid, channels: usize) -> Option<GridSigns> {
        if channels != SIGN_CHANNELS {
            return None;
        }
        let tensors = [&grid.grid_3d, &grid.grid_xy, &grid.grid_xz, &grid.grid_yz];
        Some(GridSigns {
            words: tensors.map(|t| pack_signs(t)),
            entries: tensors.map(|t| t.len() / SIGN_CHANNELS),
        })
    }
}

/// The sign bits of `values`, 32 to a word (value `j` of a word's 32 at bit `j`).
fn pack_signs(values: &[i8]) -> Vec<u32> {
    // The sign bits of 8 bytes x in one multiplication: (x & 0x80…80) holds them at bits
    // 8j + 7, and the product with Σ_k 2^(7k) puts byte j's at bit 56 + j (k = 7 − j), every
    // term a distinct power of two, so nothing carries.
    const SIGNS: u64 = 0x8080_8080_8080_8080;
    const GATHER: u64 = 0x0002_0408_1020_4081;
    values
        .chunks(32)
        .map(|chunk| {
            let mut word = 0u32;
            for (j, bytes) in chunk.chunks(8).enumerate() {
                let mut b = [0u8; 8];
                for (o, &v) in b.iter_mut().zip(bytes) {
                    *o = v as u8;
                }
                let x = u64::from_le_bytes(b) & SIGNS;
                word |= ((x.wrapping_mul(GATHER) >> 56) as u32) << (8 * j);
            }
            word
        })
        .collect()
}

/// Entry `e`'s sign bits (channel `c` at bit `c`), +1 values where `words` has no word for it.
#[inline(always)]
fn nibble(words: &[u32], e: usize) -> u32 {
    words.get(e / 8).map_or(0, |w| w >> (4 * (e % 8)) & 0xf)
}

/// For each nibble, the mask of each channel whose bit it sets (all ones) or not (zero).
const NIBBLE_MASKS: [[i32; SIGN_CHANNELS]; 16] = {
    let mut masks = [[0; SIGN_CHANNELS]; 16];
    let mut n = 0;
    while n < 16 {
        let mut c = 0;
        while c < SIGN_CHANNELS {
            masks[n][c] = -((n >> c & 1) as i32);
            c += 1;
        }
        n += 1;
    }
    masks
};

/// Adds corner weight `w` to the channels whose bit in `bits` (a nibble) is set: one
/// table row and four lanes, which the compiler makes one vector `and` and `add`.
#[inline(always)]
fn add_negative(negative: &mut [i32; SIGN_CHANNELS], bits: u32, w: i32) {
    let mask = &NIBBLE_MASKS[(bits & 0xf) as usize];
    for (n, &m) in negative.iter_mut().zip(mask) {
        *n += w & m;
    }
}

/// §5.1 step 3 for one level: each channel's sum `one − 2 · negative` (no overflow: both
/// parts lie in 0 … `one`), rounded to units of 2^−8.
#[inline(always)]
fn write_features(out: &mut [i16], negative: [i32; SIGN_CHANNELS], one: i32, shift: u32) {
    for (o, n) in out.iter_mut().zip(negative) {
        let sum = one - n - n;
        *o = ((sum + (1 << (shift - 1))) >> shift) as i16;
    }
}

/// The grid a prior reads: its values, and their signs where the caller made them (the
/// kernel then reads those).
#[derive(Debug, Clone, Copy)]
pub struct GridRef<'a> {
    /// The grid's values, −1 or +1 per entry and channel.
    pub values: &'a HashGrid,
    /// The same values packed as sign bits, when the caller built them.
    pub signs: Option<&'a GridSigns>,
}

impl<'a> GridRef<'a> {
    /// `values`, read through `signs` where there are some.
    pub fn new(values: &'a HashGrid, signs: Option<&'a GridSigns>) -> GridRef<'a> {
        GridRef { values, signs }
    }
}

impl<'a> From<&'a HashGrid> for GridRef<'a> {
    fn from(values: &'a HashGrid) -> GridRef<'a> {
        GridRef::new(values, None)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each value's bit is its sign, at 4e + c of its tensor (the word e / 8, bits from
    /// 4 (e mod 8)), for values ±1 and others, in full words and a last partial one.
    #[test]
    fn signs_are_packed_value_by_value() {
        let mut rng = crate::hyperprior::test_scene::Rng::new(7);
        let values = |n: usize, rng: &mut crate::hyperprior::test_scene::Rng| -> Vec<i8> {
            (0..n).map(|_| rng.next() as i8).collect()
        };
        let grid = HashGrid {
            grid_3d: values(4 * 37, &mut rng),
            grid_xy: values(4 * 8, &mut rng),
            grid_xz: vec![-1; 4 * 3],
            grid_yz: vec![1; 4],
        };
        let signs = GridSigns::new(&grid, 4).expect("C = 4");
        let tensors = [&grid.grid_3d, &grid.grid_xy, &grid.grid_xz, &grid.grid_yz];
        for (t, values) in tensors.into_iter().enumerate() {
            assert_eq!(signs.entries[t], values.len() / 4);
            assert_eq!(signs.words[t].len(), values.len().div_ceil(32));
            for (i, &v) in values.iter().enumerate() {
                let bit = signs.words[t][i / 32] >> (i % 32) & 1;
                assert_eq!(bit == 1, v < 0, "tensor {t}, value {i}");
            }
        }
        assert_eq!(GridSigns::new(&grid, 2), None);
    }

    /// The scalar loop through the signs gives the bytes' features, voxel by voxel, on
    /// HAC-shaped random ±1 grids (C = 4): hashed and dense levels, 2D and 3D, voxels at
    /// both ends of the range and between.
    #[test]
    fn signs_give_the_bytes_features() {
        use crate::hyperprior::test_scene::{dims, random_grid, Rng};
        let mut rng = Rng::new(0x5851_f42d_4c95_7f2d);
        let res_3d = vec![18, 24, 33, 44, 59, 80, 108, 148, 201, 275, 376, 514];
        for (coord_bits, log2_3d, log2_2d) in [(9u8, 13u8, 15u8), (1, 4, 4), (21, 19, 19)] {
            let d = dims(
                1,
                4,
                res_3d.clone(),
                vec![130, 258, 514, 1026],
                (log2_3d, log2_2d),
            );
            let layout = GridLayout::new(&d, coord_bits);
            let grid = random_grid(&mut rng, &d);
            let signs = GridSigns::new(&grid, layout.channels).expect("C = 4");
            let mut bytes = vec![0i16; layout.features()];
            let mut through_signs = bytes.clone();
            let top = (1u64 << coord_bits) - 1;
            for i in 0..300 {
                let v = match i % 4 {
                    0 => [0; 3],
                    1 => [top as u32; 3],
                    _ => [0; 3].map(|_| (rng.next() % (top + 1)) as u32),
                };
                layout.interpolate(&grid, v, &mut bytes);
                layout.interpolate_signs(&signs, v, &mut through_signs);
                assert_eq!(bytes, through_signs, "voxel {v:?}, coord_bits {coord_bits}");
            }
        }
    }

    #[test]
    fn axis_splits_position_into_cell_and_weight() {
        // coord_bits 1: voxels 0 and 1 sit at p = 1/4 and 3/4.
        assert_eq!(axis(0, 2, 1), (0, 512)); // p r = 0.5
        assert_eq!(axis(1, 2, 1), (1, 512)); // p r = 1.5
        assert_eq!(axis(1, 4, 1), (3, 0)); // p r = 3.0
                                           // Deep coordinates: weight truncated to 10 bits.
        let (cell, w) = axis((1 << 20) - 1, 514, 20);
        assert!(cell < 514 && w < 1024);
    }

    #[test]
    fn weights_sum_to_one_and_features_stay_in_range() {
        let scene = crate::hyperprior::test_scene::TestScene::new(50, 3);
        let layout = GridLayout::new(&scene.dims, scene.coord_bits);
        let mut out = vec![0i16; layout.features()];
        for &v in &scene.voxels {
            let mut levels = 0;
            layout.levels_of(
                v,
                |sum: &mut i64, _, _, w| *sum += i64::from(w),
                |sum, dims| {
                    assert_eq!(sum, 1 << (dims * WEIGHT_BITS), "voxel {v:?}");
                    levels += 1;
                },
            );
            assert_eq!(levels, layout.l3.len() + 3 * layout.l2.len());
            layout.interpolate(&scene.grid, v, &mut out);
            assert!(out.iter().all(|&x| (-256..=256).contains(&x)));
        }
    }
}
