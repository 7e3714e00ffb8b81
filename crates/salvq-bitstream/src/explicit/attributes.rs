//! `GATT` (spec §3.5): the attribute symbols of one layer, one ANS body per tile, under the
//! layer's causal prior. One traversal serves the encoder and the decoder (as
//! [`crate::geometry::walk`] does): it asks an [`Events`] for each event, so both compute
//! the same references, size classes, predictions and scale indices.

use crate::entropy::SCALE_INDEX_COUNT;
use crate::error::{Error, Result};
use crate::explicit::groups::{Group, GroupKind};
use crate::explicit::layer::{rest_count_bits, Layer, CONTEXT_CLASSES, SIZE_CLASSES};

/// §3.5: the largest magnitude of a lattice coordinate (so that `float32(u)` is exact).
pub const MAX_COORDINATE: i64 = 1 << 24;

/// §3.5: the probability of a position refinement bit, ½ in units of 2^−16.
pub const REFINE_FREQ: u32 = 1 << 15;

/// Which binary event the traversal asks for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BitEvent {
    /// Bit `bit` (most significant first) of the position refinement of axis `axis`.
    Refine {
        /// The axis, 0 … 2 (x, y, z).
        axis: usize,
        /// The bit, counted from the most significant refinement bit.
        bit: u8,
    },
    /// The high bit of the rotation's largest-component index.
    RotationHigh,
    /// Its low bit.
    RotationLow,
    /// Bit `bit` (counted from the least significant) of the `sh_rest` count (§3.5).
    RestCount {
        /// The bit, 0 … L − 1; the count's most significant bit is read first.
        bit: u32,
    },
}

/// What the traversal asks of the coder: the encoder answers with the values it knows and
/// records the events, the decoder reads them.
pub trait Events {
    /// A binary event with `freq_one` (units of 2^−16) of tile-local Gaussian `gaussian`.
    fn bit(&mut self, freq_one: u32, gaussian: usize, what: BitEvent) -> Result<bool>;
    /// The symbol (the residual `u − pred`) of coded value `value` of tile-local Gaussian
    /// `gaussian` under scale index `k`.
    fn symbol(&mut self, k: u8, gaussian: usize, value: usize, pred: i64) -> Result<i64>;
    /// Called before the `RestCount` bits of tile-local Gaussian `gaussian`: value `j` of
    /// its `sh_rest` group (coded value `first + j`) is predicted as `pred(j)`. The encoder
    /// takes its count from them (the values after the last nonzero symbol are not coded);
    /// the decoder has nothing to do.
    #[inline(always)]
    fn rest_predictions(&mut self, gaussian: usize, first: usize, pred: impl Fn(usize) -> i64) {
        let _ = (gaussian, first, pred);
    }
}

/// The decoded symbols of one tile.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct TileSymbols {
    /// Lattice coordinates, `values` per Gaussian, groups in order.
    pub coords: Vec<i32>,
    /// Index (0 … 3, w x y z) of each Gaussian's largest rotation component.
    pub rotation_index: Vec<u8>,
    /// Each Gaussian's size class.
    pub size_class: Vec<u8>,
    /// Each Gaussian's position refinement per axis (`refine[class]` bits).
    pub refinement: Vec<[u32; 3]>,
}

impl TileSymbols {
    /// The symbols of `n` Gaussians of `values` coded values each, all 0, to be written in
    /// place ([`TileSymbols::as_mut`]).
    pub fn zeroed(n: usize, values: usize) -> TileSymbols {
        TileSymbols {
            coords: vec![0; n * values],
            rotation_index: vec![0; n],
            size_class: vec![0; n],
            refinement: vec![[0; 3]; n],
        }
    }

    /// Room for exactly `n` Gaussians' symbols, as a view to write in place: the buffers are
    /// reused (their values are left as they were, to be overwritten).
    pub fn resized(&mut self, n: usize, values: usize) -> TileSymbolsMut<'_> {
        self.coords.resize(n * values, 0);
        self.rotation_index.resize(n, 0);
        self.size_class.resize(n, 0);
        self.refinement.resize(n, [0; 3]);
        self.as_mut()
    }

    /// Every Gaussian's symbols, as one view to write in place.
    pub fn as_mut(&mut self) -> TileSymbolsMut<'_> {
        TileSymbolsMut {
            coords: &mut self.coords,
            rotation_index: &mut self.rotation_index,
            size_class: &mut self.size_class,
            refinement: &mut self.refinement,
        }
    }

    /// Every Gaussian's symbols, as a view.
    pub fn as_ref(&self) -> TileSymbolsRef<'_> {
        TileSymbolsRef {
            coords: &self.coords,
            rotation_index: &self.rotation_index,
            size_class: &self.size_class,
            refinement: &self.refinement,
        }
    }
}

impl crate::par::Scratch for TileSymbols {
    fn retained_bytes(&self) -> usize {
        use std::mem::size_of;
        self.coords.capacity() * size_of::<i32>()
            + self.rotation_index.capacity()
            + self.size_class.capacity()
            + self.refinement.capacity() * size_of::<[u32; 3]>()
    }
}

/// Some Gaussians' symbols ([`TileSymbols`]'s fields) as mutable slices, so that tiles
/// decoded on different threads write straight into one output.
#[derive(Debug)]
pub struct TileSymbolsMut<'a> {
    /// [`TileSymbols::coords`].
    pub coords: &'a mut [i32],
    /// [`TileSymbols::rotation_index`].
    pub rotation_index: &'a mut [u8],
    /// [`TileSymbols::size_class`].
    pub size_class: &'a mut [u8],
    /// [`TileSymbols::refinement`].
    pub refinement: &'a mut [[u32; 3]],
}

impl<'a> TileSymbolsMut<'a> {
    /// The first `n` Gaussians' symbols and the rest, `values` coordinates per Gaussian
    /// (`n` at most the Gaussians there are).
    pub fn split_at(self, n: usize, values: usize) -> (TileSymbolsMut<'a>, TileSymbolsMut<'a>) {
        let (coords, c) = self.coords.split_at_mut(n * values);
        let (rotation_index, r) = self.rotation_index.split_at_mut(n);
        let (size_class, s) = self.size_class.split_at_mut(n);
        let (refinement, w) = self.refinement.split_at_mut(n);
        (
            TileSymbolsMut {
                coords,
                rotation_index,
                size_class,
                refinement,
            },
            TileSymbolsMut {
                coords: c,
                rotation_index: r,
                size_class: s,
                refinement: w,
            },
        )
    }

    /// The same symbols, read only.
    pub fn as_ref(&self) -> TileSymbolsRef<'_> {
        TileSymbolsRef {
            coords: self.coords,
            rotation_index: self.rotation_index,
            size_class: self.size_class,
            refinement: self.refinement,
        }
    }
}

/// Some Gaussians' symbols ([`TileSymbols`]'s fields) as slices.
#[derive(Debug, Clone, Copy)]
pub struct TileSymbolsRef<'a> {
    /// [`TileSymbols::coords`].
    pub coords: &'a [i32],
    /// [`TileSymbols::rotation_index`].
    pub rotation_index: &'a [u8],
    /// [`TileSymbols::size_class`].
    pub size_class: &'a [u8],
    /// [`TileSymbols::refinement`].
    pub refinement: &'a [[u32; 3]],
}

/// §3.5: the context class of a value whose reference's symbol was `r_prev`.
#[inline]
pub fn context_class(has_reference: bool, r_prev: i64) -> usize {
    // 1 + min(bit length of |r_prev|, 6). From a table, not `leading_zeros`: without the
    // `lzcnt` extension (not in the baseline x86-64 target) that is `bsr`, several cycles per
    // value on some CPUs.
    const CAP: usize = 1 << (CONTEXT_CLASSES - 2);
    const CLASS: [u8; CAP + 1] = {
        let mut t = [0u8; CAP + 1];
        let mut n = 0;
        while n <= CAP {
            let bits = (usize::BITS - n.leading_zeros()) as usize;
            t[n] = if bits < CONTEXT_CLASSES - 2 {
                1 + bits as u8
            } else {
                CONTEXT_CLASSES as u8 - 1
            };
            n += 1;
        }
        t
    };
    // Without a reference the class is 0: a product, not a branch, since whether a Gaussian
    // has one follows the data.
    usize::from(CLASS[r_prev.unsigned_abs().min(CAP as u64) as usize]) * usize::from(has_reference)
}

/// §3.5: whether Gaussian `i` of a tile (voxels in tile order) has a reference: the previous
/// Gaussian of the tile, when their voxels agree above the `pred_level` low bits.
#[inline]
pub fn has_reference(voxels: &[[u32; 3]], i: usize, pred_level: u8) -> bool {
    i > 0 && (0..3).all(|a| voxels[i - 1][a] >> pred_level == voxels[i][a] >> pred_level)
}

/// §3.5: a reference coordinate `u` coded with shift `from` as a prediction for shift `to`:
/// `u · 2^(from − to)` when that is ≥ 1 (clamped to ±2^24), else rounded:
/// `rshr(u, to − from)`.
#[inline]
pub fn rescale(u: i64, from: i8, to: i8) -> i64 {
    debug_assert!((-32..=32).contains(&(i32::from(from) - i32::from(to))));
    let d = i32::from(from) - i32::from(to);
    if d >= 0 {
        // §3.5 clamps the exact product. A symbol reaches 2^31 + 127, so for d ≤ 24 the
        // product stays below 2^56 in i64; from d = 25 on, any u ≠ 0 is past 2^24.
        if d > 24 {
            u.signum() * MAX_COORDINATE
        } else {
            (u << d).clamp(-MAX_COORDINATE, MAX_COORDINATE)
        }
    } else {
        let s = -d;
        (u + (1 << (s - 1))) >> s
    }
}

/// §3.5: the scale index of table entry `k` with its size class's offset:
/// `clamp(k + offset, 0, 127)` (a table scale or a wide one, §6.3.6).
#[inline]
pub fn offset_scale(k: u8, offset: i8) -> u8 {
    (i32::from(k) + i32::from(offset)).clamp(0, SCALE_INDEX_COUNT as i32 - 1) as u8
}

/// §3.5: walks the events of one tile whose Gaussians sit at `voxels` (tile order).
pub fn walk(
    layer: &Layer,
    groups: &[Group],
    voxels: &[[u32; 3]],
    events: &mut impl Events,
) -> Result<TileSymbols> {
    let values: usize = groups.iter().map(|g| g.dim).sum();
    let mut out = TileSymbols::zeroed(voxels.len(), values);
    walk_into(layer, groups, voxels, events, &mut out.as_mut())?;
    Ok(out)
}

/// [`walk`], writing the symbols into `out` (room for exactly the tile's Gaussians).
pub fn walk_into(
    layer: &Layer,
    groups: &[Group],
    voxels: &[[u32; 3]],
    events: &mut impl Events,
    out: &mut TileSymbolsMut,
) -> Result<()> {
    let values: usize = groups.iter().map(|g| g.dim).sum();
    let n = voxels.len();
    debug_assert_eq!(out.coords.len(), n * values);
    let scale_indices = ScaleIndices::new(layer, groups, values);
    let rest_bits = rest_count_bits(
        groups
            .iter()
            .find(|g| g.kind == GroupKind::Rest)
            .map_or(0, |g| g.dim),
    );
    let mut prev_r = vec![0i64; values];
    let mut prev_u = vec![0i64; values];
    let mut prev_shift = vec![0i8; groups.len()];
    let rows = out.coords.chunks_exact_mut(values.max(1));
    for (i, row) in rows.enumerate().take(n) {
        let reference = has_reference(voxels, i, layer.pred_level);
        let mut class = 0usize;
        let mut v = 0usize;
        for (gi, g) in groups.iter().enumerate() {
            if gi == 1 {
                // After the scale group: the size class, then the position refinement.
                let scale = &row[..groups[0].dim];
                let largest = scale.iter().map(|&u| i64::from(u)).max().unwrap_or(0);
                class = layer.size_class(largest);
                let e = layer.refine[class];
                let mut w = [0u32; 3];
                for (axis, wa) in w.iter_mut().enumerate() {
                    for bit in (0..e).rev() {
                        let b = events.bit(REFINE_FREQ, i, BitEvent::Refine { axis, bit })?;
                        *wa = 2 * *wa + u32::from(b);
                    }
                }
                out.size_class[i] = class as u8;
                out.refinement[i] = w;
            }
            if g.kind == GroupKind::Rotation {
                let f = &layer.rotation_freq;
                let high = events.bit(u32::from(f[0]), i, BitEvent::RotationHigh)?;
                let low = events.bit(
                    u32::from(f[1 + usize::from(high)]),
                    i,
                    BitEvent::RotationLow,
                )?;
                out.rotation_index[i] = 2 * u8::from(high) + u8::from(low);
            }
            let (from, to) = (prev_shift[gi], layer.group_shift(gi, class));
            let group = Values {
                gaussian: i,
                first: v,
                reference,
                predicted: reference & layer.predict[gi],
                from,
                to,
            };
            let range = v..v + g.dim;
            let (prev_r, prev_u) = (&mut prev_r[range.clone()], &mut prev_u[range.clone()]);
            let (k_rows, row) = (&scale_indices.of(class)[range.clone()], &mut row[range]);
            if g.kind == GroupKind::Rest {
                rest_values(
                    layer, events, &group, rest_bits, prev_r, prev_u, k_rows, row,
                )?;
            } else {
                group.decode(events, prev_r, prev_u, k_rows, row)?;
            }
            v += g.dim;
            prev_shift[gi] = to;
        }
    }
    Ok(())
}

/// The `sh_rest` count an encoder writes for coordinates `row` predicted as `pred(j)`
/// (§3.5): the values up to the last whose symbol `row[j] − pred(j)` is not 0.
pub fn rest_count_of(row: &[i32], pred: impl Fn(usize) -> i64) -> usize {
    row.iter()
        .enumerate()
        .rposition(|(j, &u)| i64::from(u) != pred(j))
        .map_or(0, |j| j + 1)
}

/// §3.5: the `sh_rest` count of tile-local Gaussian `i`, `bits` binary events down the
/// tree whose node probabilities are `freq` (most significant bit first).
pub fn read_rest_count(
    events: &mut impl Events,
    freq: &[u16],
    bits: u32,
    i: usize,
) -> Result<usize> {
    let mut node = 1usize;
    for bit in (0..bits).rev() {
        let f = freq.get(node - 1).copied().unwrap_or(1);
        let b = events.bit(u32::from(f), i, BitEvent::RestCount { bit })?;
        node = 2 * node + usize::from(b);
    }
    Ok(node - (1 << bits))
}

/// One group of one Gaussian's values as §3.5 reads them.
struct Values {
    /// The tile-local Gaussian.
    gaussian: usize,
    /// The coded value the group starts at.
    first: usize,
    /// Whether the Gaussian has a reference, and whether the group is predicted from it.
    reference: bool,
    predicted: bool,
    /// The reference's step shift of the group, and this Gaussian's.
    from: i8,
    to: i8,
}

impl Values {
    /// Reads one symbol per value: `prev_r`, `prev_u` hold the reference's symbols and
    /// coordinates and become this Gaussian's; `row` gets its coordinates.
    #[inline(always)]
    fn decode(
        &self,
        events: &mut impl Events,
        prev_r: &mut [i64],
        prev_u: &mut [i64],
        k_rows: &[[u8; CONTEXT_CLASSES]],
        row: &mut [i32],
    ) -> Result<()> {
        // The reference's symbols and coordinates in this Gaussian's step units: the same
        // units where the shifts agree (the rescaling is the identity there, as the clamp to
        // ±2^24 is for a coordinate and for the context class). Decided once per group, not
        // per value: an `sh_rest` group's 45 values then take no rescaling at all.
        let (from, to) = (self.from, self.to);
        if from == to {
            self.decode_with(events, prev_r, prev_u, k_rows, row, |v| v)
        } else {
            self.decode_with(events, prev_r, prev_u, k_rows, row, |v| {
                rescale(v, from, to)
            })
        }
    }

    /// [`Values::decode`] with the reference's values taken through `in_units`.
    #[inline(always)]
    fn decode_with(
        &self,
        events: &mut impl Events,
        prev_r: &mut [i64],
        prev_u: &mut [i64],
        k_rows: &[[u8; CONTEXT_CLASSES]],
        row: &mut [i32],
        in_units: impl Fn(i64) -> i64,
    ) -> Result<()> {
        let i = self.gaussian;
        let values = prev_r.iter_mut().zip(prev_u).zip(k_rows).zip(row);
        for (j, (((r_prev, u_prev), k_row), coord)) in values.enumerate() {
            let (r_ref, u_ref) = (in_units(*r_prev), in_units(*u_prev));
            let k = k_row[context_class(self.reference, r_ref)];
            let pred = if self.predicted { u_ref } else { 0 };
            let r = events.symbol(k, i, self.first + j, pred)?;
            let u = pred + r;
            if u.abs() > MAX_COORDINATE {
                return Err(Error::ValueInvalid {
                    tensor: "GATT.coordinate",
                    index: vec![i as u64, (self.first + j) as u64],
                    value: u,
                    allowed: "|u| ≤ 2^24 (§3.5)",
                });
            }
            *r_prev = r;
            *u_prev = u;
            *coord = u as i32;
        }
        Ok(())
    }

    /// The reference's coordinate `u` as this Gaussian's prediction (0 when not predicted).
    #[inline(always)]
    fn prediction(&self, u: i64) -> i64 {
        match (self.predicted, self.from == self.to) {
            (false, _) => 0,
            (true, true) => u,
            (true, false) => rescale(u, self.from, self.to),
        }
    }
}

/// §3.5: the `sh_rest` group of one Gaussian: its count (`bits` binary events down the tree
/// of `rest_count_freq`, most significant first; above the group's values, `ValueInvalid`),
/// the symbols of the values it counts, then the values after them, whose symbol is 0 and
/// whose coordinate is the prediction (within ±2^24: `rescale` clamps it). Out of line, so
/// that the walk of the other groups stays as it was.
#[allow(clippy::too_many_arguments)]
#[inline(never)]
fn rest_values(
    layer: &Layer,
    events: &mut impl Events,
    group: &Values,
    bits: u32,
    prev_r: &mut [i64],
    prev_u: &mut [i64],
    k_rows: &[[u8; CONTEXT_CLASSES]],
    row: &mut [i32],
) -> Result<()> {
    let i = group.gaussian;
    events.rest_predictions(i, group.first, |j| group.prediction(prev_u[j]));
    let n = read_rest_count(events, &layer.rest_count_freq, bits, i)?;
    if n > row.len() {
        return Err(Error::ValueInvalid {
            tensor: "GATT.rest_count",
            index: vec![i as u64],
            value: n as i64,
            allowed: "at most the sh_rest group's values (§3.5)",
        });
    }
    let (r_coded, r_rest) = prev_r.split_at_mut(n);
    let (u_coded, u_rest) = prev_u.split_at_mut(n);
    let (row_coded, row_rest) = row.split_at_mut(n);
    group.decode(events, r_coded, u_coded, &k_rows[..n], row_coded)?;
    r_rest.fill(0);
    for (u_prev, coord) in u_rest.iter_mut().zip(row_rest) {
        *u_prev = group.prediction(*u_prev);
        *coord = *u_prev as i32;
    }
    Ok(())
}

/// §3.5's scale index of every coded value, per size class and context class: the layer's
/// table with the class's group offset applied (`offset_scale`), computed once per walk
/// rather than once per value.
struct ScaleIndices {
    /// `[class][value][context class]`, `values` rows per size class.
    table: Vec<[u8; CONTEXT_CLASSES]>,
    values: usize,
}

impl ScaleIndices {
    fn new(layer: &Layer, groups: &[Group], values: usize) -> ScaleIndices {
        let mut table = Vec::with_capacity(SIZE_CLASSES * values);
        for class in 0..SIZE_CLASSES {
            let mut v = 0;
            for (gi, g) in groups.iter().enumerate() {
                let offset = layer.group_offset(gi, class);
                for row in &layer.scale_table[v..v + g.dim] {
                    table.push(row.map(|k| offset_scale(k, offset)));
                }
                v += g.dim;
            }
        }
        ScaleIndices { table, values }
    }

    /// The rows of size class `class`, one per coded value.
    fn of(&self, class: usize) -> &[[u8; CONTEXT_CLASSES]] {
        &self.table[class * self.values..(class + 1) * self.values]
    }
}

#[cfg(test)]
mod tests;
