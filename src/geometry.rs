//! Anchor geometry (spec §8): voxel coordinates as an octree of occupancy events under
//! adaptive contexts, then a count per voxel. One traversal serves the encoder and the
//! decoder: it asks a callback for each event's bit (the encoder knows it and records the
//! event, the decoder reads it), so both evolve the contexts identically.

use rustc_hash::{FxHashMap, FxHashSet};

use crate::container::chunk::ChunkTag;
use crate::entropy::{GaussianTables, SymbolReader, SymbolWriter};
use crate::error::{Error, Result};
use crate::model::morton3;

/// §8.3: occupancy contexts (8 child indices × 8 neighbour counts × 4 × 4).
pub const OCCUPANCY_CONTEXTS: usize = 1024;
/// §8.4: voxel-count contexts.
pub const COUNT_CONTEXTS: usize = 4;
/// §8.3: counts are halved once their sum exceeds this.
pub const ADAPT_LIMIT: u32 = 256;

/// One adaptive binary context (§8.3): counts of 0s and 1s, both starting at 1, packed as
/// `c0 | c1 << 16` (both ≤ 256) so that an event reads and writes it whole.
#[derive(Debug, Clone, Copy)]
struct Counts(u32);

impl Counts {
    const START: Counts = Counts::new(1, 1);

    const fn new(c0: u32, c1: u32) -> Counts {
        Counts(c0 | c1 << 16)
    }

    /// P(1) in units of 2^−p, clamped to 1 … 2^p − 1: ⌊c1 · 2^p / (c0 + c1)⌋, computed as
    /// a product with a reciprocal (exact, see [`RECIPROCAL`]) rather than a division, which
    /// costs more than the rest of an event.
    #[inline]
    fn freq_one(self, p: u32) -> u32 {
        let (c0, c1) = (self.0 & 0xffff, self.0 >> 16);
        let sum = ((c0 + c1) as usize).min(ADAPT_LIMIT as usize);
        let f = (u64::from(c1) * RECIPROCAL[sum]) >> (RECIPROCAL_BITS - p);
        (f as u32).clamp(1, (1 << p) - 1)
    }

    #[inline]
    fn update(&mut self, bit: bool) {
        let v = self.0 + (1 << (16 * u32::from(bit)));
        let (c0, c1) = (v & 0xffff, v >> 16);
        *self = if c0 + c1 > ADAPT_LIMIT {
            Counts::new((c0 + 1) >> 1, (c1 + 1) >> 1)
        } else {
            Counts(v)
        };
    }
}

/// Bits of [`RECIPROCAL`]'s fixed point.
const RECIPROCAL_BITS: u32 = 48;

/// `⌈2^48 / s⌉` for every count sum `s` (2 … 256; the rest unused): for `c1 < s ≤ 256` and
/// `p ≤ 24`, `(c1 · ⌈2^48 / s⌉) >> (48 − p)` equals `⌊c1 · 2^p / s⌋` exactly. The product
/// exceeds `c1 · 2^p / s` by less than `c1 / 2^(48 − p) ≤ 2^−16`, and a quotient that is not
/// an integer is at least `1 / s ≥ 2^−8` below the next one. `c1 · ⌈2^48 / s⌉ < 2^56`.
const RECIPROCAL: [u64; ADAPT_LIMIT as usize + 1] = {
    let mut out = [0u64; ADAPT_LIMIT as usize + 1];
    let mut s = 1;
    while s <= ADAPT_LIMIT as usize {
        out[s] = (1u64 << RECIPROCAL_BITS).div_ceil(s as u64);
        s += 1;
    }
    out
};

/// Why a geometry payload is invalid (spec §8.2, §8.4).
pub const MORE_NODES_THAN_ANCHORS: &str = "more nodes than anchors";
pub const COUNTS_ABOVE: &str = "counts above the anchor count";
pub const COUNTS_BELOW: &str = "counts below the anchor count";

/// Index of offset `d ∈ {−1, 0, 1}³` in a node's 27-cell neighbourhood.
const fn nb(d: [i64; 3]) -> usize {
    ((d[0] + 1) + 3 * (d[1] + 1) + 9 * (d[2] + 1)) as usize
}

/// For child `i`, the mask of the 7 neighbourhood cells on its side (§8.3's `n7`).
const fn side_mask(i: usize) -> u32 {
    let s = [
        if i & 1 == 1 { 1 } else { -1 },
        if i & 2 == 2 { 1 } else { -1 },
        if i & 4 == 4 { 1 } else { -1 },
    ];
    (1 << nb([s[0], 0, 0]))
        | (1 << nb([0, s[1], 0]))
        | (1 << nb([0, 0, s[2]]))
        | (1 << nb([s[0], s[1], 0]))
        | (1 << nb([s[0], 0, s[2]]))
        | (1 << nb([0, s[1], s[2]]))
        | (1 << nb([s[0], s[1], s[2]]))
}

const SIDE_MASKS: [u32; 8] = [
    side_mask(0),
    side_mask(1),
    side_mask(2),
    side_mask(3),
    side_mask(4),
    side_mask(5),
    side_mask(6),
    side_mask(7),
];

/// A node's neighbours at one level: the index of the node at offset `d` in slot `nb(d)`
/// (slot 13, the node itself, unused), `u32::MAX` where there is none; bit `nb(d)` of
/// `present` set where there is one.
#[derive(Clone, Copy)]
struct Neighbours {
    index: [u32; 27],
    present: u32,
}

impl Neighbours {
    const NONE: Neighbours = Neighbours {
        index: [u32::MAX; 27],
        present: 0,
    };
}

/// For child `i` of a node and neighbour slot `nb(d)`: the slot of the node's neighbour (13:
/// the node itself) that holds the child's neighbour at `d`, and which child of it that is.
/// A child's neighbours are children of its parent's neighbours, so no lookup is needed.
const CHILD_NEIGHBOUR: [[(u8, u8); 27]; 8] = {
    let mut out = [[(0u8, 0u8); 27]; 8];
    let mut i = 0;
    while i < 8 {
        let mut slot = 0;
        while slot < 27 {
            let d = [
                (slot % 3) as i64 - 1,
                ((slot / 3) % 3) as i64 - 1,
                (slot / 9) as i64 - 1,
            ];
            let (mut parent_slot, mut child) = (0usize, 0usize);
            let mut a = 0;
            let mut weight = 1;
            while a < 3 {
                let t = ((i >> a) & 1) as i64 + d[a];
                parent_slot += (t.div_euclid(2) + 1) as usize * weight;
                child |= (t.rem_euclid(2) as usize) << a;
                weight *= 3;
                a += 1;
            }
            out[i][slot] = (parent_slot as u8, child as u8);
            slot += 1;
        }
        i += 1;
    }
    out
};

/// Set bits of every byte value: a table, since the portable x86-64 baseline has no
/// `popcnt` instruction and this is on the octree's hot path.
const POPCOUNT: [u8; 256] = {
    let mut out = [0u8; 256];
    let mut b = 0;
    while b < 256 {
        out[b] = (b as u8).count_ones() as u8;
        b += 1;
    }
    out
};

/// For child `i` and a slot `ps` of its parent's neighbourhood: the child's neighbour slots
/// that fall in the node at `ps`, each with its child index there (the inverse of
/// [`CHILD_NEIGHBOUR`], the child itself left out). Only the parent itself and the 7
/// neighbours on the child's side ([`SIDE_MASKS`]) have entries.
#[derive(Clone, Copy)]
struct FromParent {
    len: u8,
    cells: [(u8, u8); 8],
}

const FROM_PARENT: [[FromParent; 27]; 8] = {
    let empty = FromParent {
        len: 0,
        cells: [(0, 0); 8],
    };
    let mut out = [[empty; 27]; 8];
    let mut i = 0;
    while i < 8 {
        let mut slot = 0;
        while slot < 27 {
            if slot != 13 {
                // Indexing, not a `&mut` binding: the decoder's minimum Rust (1.80) allows
                // no mutable references in constants.
                let (ps, child) = CHILD_NEIGHBOUR[i][slot];
                let at = out[i][ps as usize].len as usize;
                out[i][ps as usize].cells[at] = (slot as u8, child);
                out[i][ps as usize].len += 1;
            }
            slot += 1;
        }
        i += 1;
    }
    out
};

/// The next level's neighbours from this level's: `bytes[p]` is node `p`'s occupancy byte
/// and its children are numbered in order (node by node, octant by octant).
///
/// A child's neighbours lie in its parent and the parent's 7 neighbours on the child's side,
/// so only the neighbours the parent has are visited: deep in a sparse octree most nodes
/// have none or few.
fn child_neighbours(nbr: &[Neighbours], bytes: &[u8]) -> Vec<Neighbours> {
    let mut first = Vec::with_capacity(bytes.len());
    let mut count = 0u32;
    for &b in bytes {
        first.push(count);
        count += u32::from(POPCOUNT[usize::from(b)]);
    }
    let mut out = Vec::with_capacity(count as usize);
    for (p, &byte) in bytes.iter().enumerate() {
        if byte == 0 {
            continue;
        }
        // The occupancy byte and first child of the node (slot 13) and of each neighbour it
        // has; 32 entries so that a 5-bit index needs no bounds check.
        let present = nbr[p].present;
        let (mut near_bytes, mut near_first) = ([0u8; 32], [0u32; 32]);
        near_bytes[13] = byte;
        near_first[13] = first[p];
        let mut rest = present;
        while rest != 0 {
            let slot = rest.trailing_zeros() as usize & 31;
            rest &= rest - 1;
            let q = nbr[p].index[slot] as usize;
            near_bytes[slot] = bytes[q];
            near_first[slot] = first[q];
        }
        for (i, (&side, from)) in SIDE_MASKS.iter().zip(&FROM_PARENT).enumerate() {
            if byte >> i & 1 == 0 {
                continue;
            }
            let mut row = Neighbours::NONE;
            let mut sources = (present & side) | (1 << 13);
            while sources != 0 {
                let ps = sources.trailing_zeros() as usize & 31;
                sources &= sources - 1;
                let (b, base) = (near_bytes[ps], near_first[ps]);
                let f = &from[ps.min(26)];
                for &(slot, child) in &f.cells[..usize::from(f.len).min(8)] {
                    let child = child & 7;
                    if b >> child & 1 == 1 {
                        let below = POPCOUNT[usize::from(b & LOW[usize::from(child)])];
                        row.index[usize::from(slot).min(26)] = base + u32::from(below);
                        row.present |= 1 << slot;
                    }
                }
            }
            out.push(row);
        }
    }
    out
}

/// The cell of child `i` (octant bits x, y, z) of the node at cell `p`, one level down.
#[inline]
fn child_cell(p: [u32; 3], i: usize) -> [u32; 3] {
    [
        2 * p[0] + (i & 1) as u32,
        2 * p[1] + ((i >> 1) & 1) as u32,
        2 * p[2] + ((i >> 2) & 1) as u32,
    ]
}

/// `LOW[j]`: the bits below bit `j` of an occupancy byte.
const LOW: [u8; 8] = [0x00, 0x01, 0x03, 0x07, 0x0f, 0x1f, 0x3f, 0x7f];

/// §8.2–§8.4: walks the octree of depth `depth` for `anchors` anchors. `event(freq_one,
/// what)` returns each event's bit (occupancy events first, in traversal order, then count
/// events). Returns the anchors' voxels in canonical order.
///
/// Per node, the 26 neighbours at its depth are looked up once: their occupancy gives `n7`
/// for every child, and the occupancy bytes of the face neighbours already walked give the
/// children's face neighbours across the node's faces (`kf`); neighbours inside the node are
/// the siblings decoded so far.
pub fn walk(
    depth: u8,
    anchors: u32,
    precision: u32,
    mut event: impl FnMut(u32, Event) -> Result<bool>,
) -> Result<Vec<[u32; 3]>> {
    let n = anchors as usize;
    let mut occ = [Counts::START; OCCUPANCY_CONTEXTS];
    let mut nodes: Vec<[u32; 3]> = vec![[0, 0, 0]];
    // The root has no neighbours; each level's follow from its parents' (§8.3's contexts
    // need them), without a lookup by position.
    let mut nbr: Vec<Neighbours> = vec![Neighbours::NONE];
    for k in 0..u32::from(depth) {
        let mut bytes = vec![0u8; nodes.len()];
        let mut children: Vec<[u32; 3]> = Vec::with_capacity((nodes.len() * 2).min(n));
        for (pi, &p) in nodes.iter().enumerate() {
            let (row, present) = (&nbr[pi].index, nbr[pi].present);
            // The occupancy bytes of the face neighbours −x, +x, −y, +y, −z, +z (0 where there
            // is none or it is not walked yet: `bytes` is filled in walking order). They do
            // not change while this node's children are decided.
            let last = bytes.len() - 1;
            let face = |slot: usize| {
                let q = row[slot];
                bytes[(q as usize).min(last)] & 0u8.wrapping_sub(u8::from(q != u32::MAX))
            };
            let face_bytes = [
                face(nb([-1, 0, 0])),
                face(nb([1, 0, 0])),
                face(nb([0, -1, 0])),
                face(nb([0, 1, 0])),
                face(nb([0, 0, -1])),
                face(nb([0, 0, 1])),
            ];
            let (mut byte, mut occupied) = (0u8, 0usize);
            for (i, &side) in SIDE_MASKS.iter().enumerate() {
                let bit = if i == 7 && occupied == 0 {
                    true
                } else {
                    let n7 = (present & side).count_ones() as usize;
                    let mut kf = 0usize;
                    for a in 0..3 {
                        let j = i ^ (1 << a);
                        let high = (i >> a) & 1;
                        // Inside the node: the sibling across this face, if decoded (j < i,
                        // which is when bit a of i is set).
                        kf += high & usize::from(byte >> j & 1);
                        // Across the node's face on the child's side: child j of that
                        // neighbour, if the neighbour has been walked.
                        kf += usize::from(face_bytes[2 * a + high] >> j & 1);
                    }
                    let ctx = ((i * 8 + n7) * 4 + kf.min(3)) * 4 + occupied.min(3);
                    let what = Event::Occupancy {
                        depth: k + 1,
                        cell: child_cell(p, i),
                    };
                    let bit = event(occ[ctx].freq_one(precision), what)?;
                    occ[ctx].update(bit);
                    bit
                };
                if bit {
                    if children.len() == n {
                        return Err(Error::OctreeInvalid {
                            rule: MORE_NODES_THAN_ANCHORS,
                            depth: (k + 1) as u8,
                            count: n as u64 + 1,
                            anchors,
                        });
                    }
                    children.push(child_cell(p, i));
                    byte |= 1 << i;
                    occupied += 1;
                }
            }
            bytes[pi] = byte;
        }
        if k + 1 < u32::from(depth) {
            nbr = child_neighbours(&nbr, &bytes);
        }
        nodes = children;
    }
    // §8.4: counts.
    let mut counts = [Counts::START; COUNT_CONTEXTS];
    let mut out = Vec::with_capacity(n);
    for (j, &leaf) in nodes.iter().enumerate() {
        let mut extra = 0usize;
        loop {
            if out.len() + 1 + extra > n {
                return Err(Error::OctreeInvalid {
                    rule: COUNTS_ABOVE,
                    depth,
                    count: (out.len() + 1 + extra) as u64,
                    anchors,
                });
            }
            let ctx = extra.min(COUNT_CONTEXTS - 1);
            let more = event(
                counts[ctx].freq_one(precision),
                Event::Count { leaf: j, extra },
            )?;
            counts[ctx].update(more);
            if !more {
                break;
            }
            extra += 1;
        }
        out.extend(std::iter::repeat(leaf).take(1 + extra));
    }
    if out.len() < n {
        return Err(Error::OctreeInvalid {
            rule: COUNTS_BELOW,
            depth,
            count: out.len() as u64,
            anchors,
        });
    }
    Ok(out)
}

/// What an event of [`walk`] decides.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Event {
    /// Whether depth-`depth` cell `cell` is occupied (§8.2).
    Occupancy { depth: u32, cell: [u32; 3] },
    /// Whether leaf `leaf` holds more than `extra + 1` anchors (§8.4).
    Count { leaf: usize, extra: usize },
}

/// §8.1: the `APOS` body of canonical-order voxels (coordinates below `2^depth`).
pub fn encode(voxels: &[[u32; 3]], depth: u8, tables: &GaussianTables) -> Result<Vec<u8>> {
    // The occupied cells of every depth, and each voxel's anchor count (voxels are sorted,
    // so equal ones are adjacent).
    let occupied: Vec<FxHashSet<u64>> = (0..=u32::from(depth))
        .map(|k| {
            let shift = u32::from(depth) - k;
            voxels
                .iter()
                .map(|v| morton3(v.map(|c| c >> shift)))
                .collect()
        })
        .collect();
    let mut runs: Vec<usize> = Vec::new();
    for (i, v) in voxels.iter().enumerate() {
        match runs.last_mut() {
            Some(r) if voxels[i - 1] == *v => *r += 1,
            _ => runs.push(1),
        }
    }
    let mut writer = SymbolWriter::new(ChunkTag::APOS, tables);
    let decoded = walk(
        depth,
        voxels.len() as u32,
        tables.precision(),
        |freq, what| {
            let bit = match what {
                Event::Occupancy { depth, cell } => {
                    occupied[depth as usize].contains(&morton3(cell))
                }
                Event::Count { leaf, extra } => extra + 1 < runs.get(leaf).copied().unwrap_or(1),
            };
            writer.bit(bit, freq);
            Ok(bit)
        },
    )?;
    debug_assert_eq!(decoded, voxels);
    Ok(writer.finish())
}

/// §8.1: decodes an `APOS` body into canonical-order voxels.
pub fn decode(
    body: &[u8],
    depth: u8,
    anchors: u32,
    tables: &GaussianTables,
) -> Result<Vec<[u32; 3]>> {
    let mut reader = SymbolReader::new(ChunkTag::APOS, body, tables)?;
    let voxels = walk(depth, anchors, tables.precision(), |freq, _| {
        reader.bit(freq)
    })?;
    reader.finish()?;
    Ok(voxels)
}

/// The order-0 entropy, in bits, of the octree's occupancy bytes over distinct `voxels`
/// (coordinates below `2^depth`), each depth with its own byte histogram: the baseline the
/// contexts of §8.3 are measured against (informative; benches and tests).
pub fn order0_occupancy_bits(voxels: &[[u32; 3]], depth: u8) -> f64 {
    let mut total = 0.0;
    for k in 0..u32::from(depth) {
        let shift = u32::from(depth) - k - 1;
        let mut bytes: FxHashMap<u64, u8> = FxHashMap::default();
        for v in voxels {
            let c = v.map(|x| x >> shift);
            let i = (c[0] & 1) | ((c[1] & 1) << 1) | ((c[2] & 1) << 2);
            *bytes.entry(morton3(c.map(|x| x >> 1))).or_default() |= 1 << i;
        }
        let mut hist = [0u64; 256];
        for b in bytes.values() {
            hist[usize::from(*b)] += 1;
        }
        let n = bytes.len() as f64;
        total += hist
            .iter()
            .filter(|&&h| h > 0)
            .map(|&h| -(h as f64) * (h as f64 / n).log2())
            .sum::<f64>();
    }
    total
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::entropy::ans::{MAX_PRECISION, MIN_PRECISION};

    /// The reciprocal product is the §8.3 quotient for every reachable count pair and every
    /// precision the tables allow.
    #[test]
    fn reciprocal_product_is_the_exact_quotient() {
        for p in MIN_PRECISION..=MAX_PRECISION {
            for sum in 2..=ADAPT_LIMIT {
                for c1 in 1..sum {
                    let counts = Counts::new(sum - c1, c1);
                    let exact = ((u64::from(c1) << p) / u64::from(sum)) as u32;
                    assert_eq!(
                        counts.freq_one(p),
                        exact.clamp(1, (1 << p) - 1),
                        "c1 {c1}, sum {sum}, P {p}"
                    );
                }
            }
        }
    }
}
