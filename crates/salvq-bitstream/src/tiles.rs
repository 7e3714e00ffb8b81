//! Tiles (spec §10): runs of canonical anchors whose entropy-coded bodies are independent.
//! The tile table (`TILS`), the per-tile framing of the entropy-coded chunks, and region
//! selection.

use crate::container::bytes::{PayloadReader, PayloadWriter};
use crate::container::method::{body, expect_len, METHOD_RAW};
use crate::container::tag::ChunkTag;
use crate::error::{Error, Field, Result};
use crate::model::morton3;

/// Bytes per tile in `TILS`: count, cell level, cell, box.
pub const TILE_ENTRY_BYTES: u64 = 4 + 1 + 12 + 24;

/// The box of a region decode (§10.3.1): world coordinates, binary64, `min ≤ max` on each
/// axis (a bound may be infinite). Only [`RegionBox::new`] makes one, so a decoder never
/// sees a NaN or an inverted box.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RegionBox {
    min: [f64; 3],
    max: [f64; 3],
}

/// Why six numbers are not a region box (§10.3.1): the caller's error, not the stream's.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InvalidRegion {
    /// The axis (0 = x, 1 = y, 2 = z).
    pub axis: usize,
    /// The minimum given on it.
    pub min: f64,
    /// The maximum given on it.
    pub max: f64,
}

impl std::fmt::Display for InvalidRegion {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "region box, {} axis: min {} and max {} are not a range (a NaN, or min > max) \
             [§10.3.1]",
            ["x", "y", "z"][self.axis],
            self.min,
            self.max
        )
    }
}

impl std::error::Error for InvalidRegion {}

impl RegionBox {
    /// The box from `min` to `max`, refused when an axis has a NaN or `min > max`.
    pub fn new(min: [f64; 3], max: [f64; 3]) -> std::result::Result<RegionBox, InvalidRegion> {
        for axis in 0..3 {
            // Refused: min > max, or a NaN (no order at all).
            if !matches!(
                min[axis].partial_cmp(&max[axis]),
                Some(std::cmp::Ordering::Less | std::cmp::Ordering::Equal)
            ) {
                return Err(InvalidRegion {
                    axis,
                    min: min[axis],
                    max: max[axis],
                });
            }
        }
        Ok(RegionBox { min, max })
    }

    /// The box from six numbers: min x, y, z, then max x, y, z.
    pub fn from_array(b: [f64; 6]) -> std::result::Result<RegionBox, InvalidRegion> {
        RegionBox::new([b[0], b[1], b[2]], [b[3], b[4], b[5]])
    }

    /// Min x, y, z, then max x, y, z.
    pub fn to_array(&self) -> [f64; 6] {
        [
            self.min[0],
            self.min[1],
            self.min[2],
            self.max[0],
            self.max[1],
            self.max[2],
        ]
    }

    /// The minimum corner.
    pub fn min(&self) -> [f64; 3] {
        self.min
    }

    /// The maximum corner.
    pub fn max(&self) -> [f64; 3] {
        self.max
    }
}

/// Part `index` of `count` of a stream's tiles (§10.3.2): what one of several workers that
/// share no memory (Web Workers, processes) decodes, each part about the same number of
/// anchors (Gaussians). Only [`TilePart::new`] makes one, so `index < count`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct TilePart {
    index: u32,
    count: u32,
}

impl TilePart {
    /// Part `index` (from 0) of `count`; `None` unless `index < count`.
    pub fn new(index: u32, count: u32) -> Option<TilePart> {
        (index < count).then_some(TilePart { index, count })
    }

    /// Which part, from 0.
    pub fn index(&self) -> u32 {
        self.index
    }

    /// How many parts.
    pub fn count(&self) -> u32 {
        self.count
    }
}

/// §10.3.2: which part each of the tiles `kept` goes to. Largest tile first (ties by index),
/// each to the part with the fewest anchors so far (ties by the lowest part): the greedy
/// plan that evens out the parts' work, the same for every decoder.
pub fn part_plan(counts: &[u32], kept: &[bool], parts: u32) -> Vec<Option<u32>> {
    use std::cmp::Reverse;
    let mut order: Vec<usize> = (0..counts.len()).filter(|&t| kept[t]).collect();
    order.sort_by_key(|&t| (Reverse(counts[t]), t));
    // Only the first `order.len()` parts can receive a tile: all start empty, and a tie goes
    // to the lowest part.
    let live = parts.min(u32::try_from(order.len()).unwrap_or(u32::MAX));
    let mut load: std::collections::BinaryHeap<Reverse<(u64, u32)>> =
        (0..live).map(|p| Reverse((0, p))).collect();
    let mut plan = vec![None; counts.len()];
    for t in order {
        if let Some(Reverse((sum, p))) = load.pop() {
            plan[t] = Some(p);
            load.push(Reverse((sum + u64::from(counts[t]), p)));
        }
    }
    plan
}

/// The tile table of a stream (§10.1).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TileTable {
    /// First anchor of each tile; `starts[0] = 0`.
    pub starts: Vec<u32>,
    /// Per tile: the aligned octree cell its geometry is coded in (§8 per tile): side
    /// `2^level`, covering voxels `cell · 2^level …`.
    pub cells: Vec<(u8, [u32; 3])>,
    /// Per tile: min x, y, z, then max x, y, z of its anchors' voxels.
    pub boxes: Vec<[u32; 6]>,
    /// N.
    pub anchors: u32,
}

/// The smallest aligned cell holding every voxel of a Morton run from `first` to `last`.
pub fn enclosing_cell(first: [u32; 3], last: [u32; 3]) -> (u8, [u32; 3]) {
    let (a, b) = (morton3(first), morton3(last));
    let differing = 64 - (a ^ b).leading_zeros();
    let level = differing.div_ceil(3);
    (level as u8, first.map(|c| c >> level))
}

/// The smallest box holding `voxels` (which is not empty).
pub fn bounding_box(voxels: &[[u32; 3]]) -> [u32; 6] {
    let mut b = [u32::MAX, u32::MAX, u32::MAX, 0, 0, 0];
    for v in voxels {
        for a in 0..3 {
            b[a] = b[a].min(v[a]);
            b[3 + a] = b[3 + a].max(v[a]);
        }
    }
    b
}

impl TileTable {
    /// Anchors of tile `t`.
    pub fn count(&self, t: usize) -> u32 {
        self.range(t).len() as u32
    }

    /// T.
    pub fn len(&self) -> usize {
        self.starts.len()
    }

    /// Whether the table has no tile (T = 0).
    pub fn is_empty(&self) -> bool {
        self.starts.is_empty()
    }

    /// Anchor indices of tile `t`.
    pub fn range(&self, t: usize) -> std::ops::Range<usize> {
        let end = self.starts.get(t + 1).copied().unwrap_or(self.anchors);
        self.starts[t] as usize..end as usize
    }

    /// §10.1: the `TILS` payload.
    pub fn to_payload(&self) -> Vec<u8> {
        let mut w = PayloadWriter::default();
        w.u8(METHOD_RAW);
        w.u32(self.len() as u32);
        for t in 0..self.len() {
            w.u32(self.count(t));
            let (level, cell) = self.cells[t];
            w.u8(level);
            for c in cell {
                w.u32(c);
            }
            for c in self.boxes[t] {
                w.u32(c);
            }
        }
        w.buf
    }

    /// §10.1: reads and checks `TILS` against the preflight (N anchors, coordinates below
    /// `2^coord_bits`). The boxes are checked later, against the decoded geometry
    /// ([`TileTable::check_geometry`]).
    pub fn parse(payload: &[u8], anchors: u32, coord_bits: u8) -> Result<TileTable> {
        let tag = ChunkTag::TILS;
        let b = body(tag, payload, METHOD_RAW)?;
        let n = u64::from(anchors);
        if b.len() < 4 {
            return Err(Error::ChunkSizeMismatch {
                tag,
                expected: 5,
                found: b.len() as u64 + 1,
            });
        }
        let mut r = PayloadReader::new(tag, b);
        let t = u64::from(r.u32()?);
        if t == 0 || t > n {
            return Err(Error::FieldOutOfRange {
                field: Field::TileCount,
                value: t,
                min: 1,
                max: n,
            });
        }
        expect_len(tag, b, 4 + TILE_ENTRY_BYTES * t)?;
        let mut table = TileTable {
            starts: Vec::with_capacity(t as usize),
            cells: Vec::with_capacity(t as usize),
            boxes: Vec::with_capacity(t as usize),
            anchors,
        };
        let mut start = 0u64;
        for tile in 0..t {
            // §10.1: every later tile needs at least one anchor, and the last one makes it N
            // exactly (its bounds are that one value).
            let max = n - start - (t - 1 - tile);
            let min = if tile + 1 == t { max } else { 1 };
            let count = u64::from(r.u32()?);
            if count < min || count > max {
                return Err(Error::FieldOutOfRange {
                    field: Field::TileAnchors,
                    value: count,
                    min,
                    max,
                });
            }
            table.starts.push(start as u32);
            start += count;
            let level = r.u8()?;
            if level > coord_bits {
                return Err(Error::FieldOutOfRange {
                    field: Field::TileCellLevel,
                    value: level.into(),
                    min: 0,
                    max: coord_bits.into(),
                });
            }
            let side_cells = 1u64 << (coord_bits - level);
            let mut cell = [0u32; 3];
            for c in &mut cell {
                *c = r.u32()?;
                if u64::from(*c) >= side_cells {
                    return Err(Error::FieldOutOfRange {
                        field: Field::TileCell,
                        value: (*c).into(),
                        min: 0,
                        max: side_cells - 1,
                    });
                }
            }
            table.cells.push((level, cell));
            let mut stated = [0u32; 6];
            for c in &mut stated {
                *c = r.u32()?;
            }
            table.boxes.push(stated);
        }
        r.finish()?;
        Ok(table)
    }

    /// §10.1: after the geometry, each tile's box must be its anchors' box, and the tiles'
    /// voxels must follow each other in Morton order (no voxel shared between tiles).
    pub fn check_geometry(&self, voxels: &[[u32; 3]]) -> Result<()> {
        self.check_geometry_of(voxels, None)
    }

    /// [`TileTable::check_geometry`] for the tiles `decoded` marks (all without it): an
    /// explicit-profile part decode's (§10.3.2), which checks each of its tiles' box, and its
    /// order where the tile before it is decoded too.
    pub fn check_geometry_of(&self, voxels: &[[u32; 3]], decoded: Option<&[bool]>) -> Result<()> {
        let is_decoded = |t: usize| decoded.map_or(true, |d| d.get(t).copied().unwrap_or(false));
        for t in (0..self.len()).filter(|&t| is_decoded(t)) {
            let r = self.range(t);
            let actual = bounding_box(&voxels[r.clone()]);
            if actual != self.boxes[t] {
                return Err(Error::TileBoxMismatch {
                    tile: t as u32,
                    stated: self.boxes[t],
                    actual,
                });
            }
            if t > 0
                && is_decoded(t - 1)
                && morton3(voxels[r.start]) <= morton3(voxels[r.start - 1])
            {
                return Err(Error::TileOrder { tile: t as u32 });
            }
        }
        Ok(())
    }

    /// §10.3.1 step 1: tile `t`'s world box (min x, y, z, max x, y, z), for voxels of edge
    /// `voxel_size` whose voxel (0, 0, 0) has its corner at `origin`.
    pub fn world_box(&self, t: usize, origin: [f32; 3], voxel_size: f32) -> [f64; 6] {
        let b = self.boxes[t];
        let vs = f64::from(voxel_size);
        let mut w = [0f64; 6];
        for a in 0..3 {
            // Exact conversions and an exact product (≤ 22 × 24 bits); one rounding.
            let o = f64::from(origin[a]);
            w[a] = o + f64::from(b[a]) * vs;
            w[3 + a] = o + (f64::from(b[3 + a]) + 1.0) * vs;
        }
        w
    }

    /// The tiles a decode keeps: those whose world box meets `region` (§10.3.1 step 2,
    /// closed on both sides; every tile without a region), and of those, the ones `part`
    /// takes (§10.3.2; all of them without a part).
    pub fn select(
        &self,
        origin: [f32; 3],
        voxel_size: f32,
        region: Option<RegionBox>,
        part: Option<TilePart>,
    ) -> Vec<bool> {
        let kept: Vec<bool> = match region {
            None => vec![true; self.len()],
            Some(r) => (0..self.len())
                .map(|t| {
                    let w = self.world_box(t, origin, voxel_size);
                    (0..3).all(|a| w[a] <= r.max[a] && r.min[a] <= w[3 + a])
                })
                .collect(),
        };
        let Some(part) = part else {
            return kept;
        };
        let counts: Vec<u32> = (0..self.len()).map(|t| self.count(t)).collect();
        part_plan(&counts, &kept, part.count)
            .into_iter()
            .map(|p| p == Some(part.index))
            .collect()
    }
}

/// §10.2: splits the words of a tiled chunk into its T tile bodies; `prefix` is the number
/// of payload bytes before the words (for the lengths errors report).
pub fn split_bodies(
    tag: ChunkTag,
    prefix: usize,
    words: &[u8],
    tiles: usize,
) -> Result<Vec<&[u8]>> {
    let mut r = PayloadReader::new(tag, words);
    let mut lens = Vec::with_capacity(tiles.min(words.len() / 4 + 1));
    let mut total = 0u64;
    for _ in 0..tiles {
        let l = r.u32()?;
        total += u64::from(l);
        lens.push(l as usize);
    }
    let rest = &words[r.consumed()..];
    if rest.len() as u64 != total {
        return Err(Error::ChunkSizeMismatch {
            tag,
            expected: (prefix + words.len() - rest.len()) as u64 + total,
            found: (prefix + words.len()) as u64,
        });
    }
    let mut out = Vec::with_capacity(tiles);
    let mut at = 0usize;
    for l in lens {
        out.push(&rest[at..at + l]);
        at += l;
    }
    Ok(out)
}

/// §10.2: the words of a tiled chunk from its tile bodies.
pub fn join_bodies(bodies: &[Vec<u8>]) -> Vec<u8> {
    let mut out = Vec::with_capacity(4 * bodies.len() + bodies.iter().map(Vec::len).sum::<usize>());
    for b in bodies {
        out.extend_from_slice(&(b.len() as u32).to_le_bytes());
    }
    for b in bodies {
        out.extend_from_slice(b);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn part_plan_gives_each_tile_to_the_least_loaded_part() {
        // Largest first: 9 (tile 1) to part 0, 9 (tile 4) to part 1, 5 (tile 5) to part 2,
        // then 3 (tile 0) to part 2 (load 5), 3 (tile 2) to part 2 (8 < 9), 1 (tile 3) to
        // part 0 (9, tie with part 1, lowest part).
        let counts = [3, 9, 3, 1, 9, 5];
        let plan = part_plan(&counts, &[true; 6], 3);
        assert_eq!(plan, [Some(2), Some(0), Some(2), Some(0), Some(1), Some(2)]);
        // Tiles a region dropped take no part; more parts than tiles leave parts empty.
        let kept = [true, false, true, false, false, true];
        let plan = part_plan(&counts, &kept, 5);
        assert_eq!(plan, [Some(1), None, Some(2), None, None, Some(0)]);
        assert_eq!(part_plan(&counts, &[true; 6], u32::MAX).len(), 6);
    }

    #[test]
    fn parts_split_the_kept_tiles() {
        let counts: Vec<u32> = (0..41).map(|i| (i * 7919 % 97) + 1).collect();
        let kept: Vec<bool> = (0..41).map(|i| i % 5 != 3).collect();
        for parts in 1..=6u32 {
            let plan = part_plan(&counts, &kept, parts);
            let mut load = vec![0u32; parts as usize];
            for t in 0..41 {
                // Every kept tile in exactly one part, no other tile in any.
                assert_eq!(plan[t].is_some(), kept[t], "tile {t} of {parts} parts");
                if let Some(p) = plan[t] {
                    load[p as usize] += counts[t];
                }
            }
            // Greedy largest-first: no part exceeds another by more than the largest tile.
            let (lo, hi) = (load.iter().min(), load.iter().max());
            assert!(hi.unwrap() - lo.unwrap() <= *counts.iter().max().unwrap());
        }
        assert!(TilePart::new(2, 2).is_none() && TilePart::new(0, 0).is_none());
        assert_eq!(
            TilePart::new(1, 2).map(|p| (p.index(), p.count())),
            Some((1, 2))
        );
    }
}
