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

/// One adaptive binary context (§8.3): counts of 0s and 1s, both starting at 1.
#[derive(Debug, Clone, Copy)]
struct Counts {
    c0: u32,
    c1: u32,
}

impl Counts {
    const START: Counts = Counts { c0: 1, c1: 1 };

    /// P(1) in units of 2^−p, clamped to 1 … 2^p − 1.
    fn freq_one(self, p: u32) -> u32 {
        let f = (u64::from(self.c1) << p) / u64::from(self.c0 + self.c1);
        (f as u32).clamp(1, (1 << p) - 1)
    }

    fn update(&mut self, bit: bool) {
        if bit {
            self.c1 += 1;
        } else {
            self.c0 += 1;
        }
        if self.c0 + self.c1 > ADAPT_LIMIT {
            self.c0 = (self.c0 + 1) >> 1;
            self.c1 = (self.c1 + 1) >> 1;
        }
    }
}

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

/// Morton code of `c + d` if it lies in `[0, 2^bits)^3`.
#[inline]
fn shifted(c: [u32; 3], d: [i64; 3], bits: u32) -> Option<u64> {
    let mut out = [0u32; 3];
    for a in 0..3 {
        let v = i64::from(c[a]) + d[a];
        if v < 0 || v >= 1i64 << bits {
            return None;
        }
        out[a] = v as u32;
    }
    Some(morton3(out))
}

/// The 13 neighbour offsets whose first non-zero component (z, then y, then x) is positive:
/// with their opposites, the 26 of §8.3's neighbourhood.
const HALF_NEIGHBOURHOOD: [[i64; 3]; 13] = {
    let mut out = [[0i64; 3]; 13];
    let mut n = 0;
    let mut i = 0;
    while i < 27 {
        let d = [
            (i % 3) as i64 - 1,
            ((i / 3) % 3) as i64 - 1,
            (i / 9) as i64 - 1,
        ];
        let first = if d[2] != 0 {
            d[2]
        } else if d[1] != 0 {
            d[1]
        } else {
            d[0]
        };
        if first > 0 {
            out[n] = d;
            n += 1;
        }
        i += 1;
    }
    out
};

/// For every node of a level (coordinates below `2^bits`): which of its 26 neighbours are
/// nodes (bit `nb(d)`), and the index of its face neighbours (−x, +x, −y, +y, −z, +z;
/// `u32::MAX` for none). Each pair of neighbours is looked up once, from the node whose
/// offset to the other is in [`HALF_NEIGHBOURHOOD`].
fn neighbourhoods(
    nodes: &[[u32; 3]],
    index: &FxHashMap<u64, u32>,
    bits: u32,
) -> (Vec<u32>, Vec<[u32; 6]>) {
    let mut present = vec![0u32; nodes.len()];
    let mut faces = vec![[u32::MAX; 6]; nodes.len()];
    for (pi, &p) in nodes.iter().enumerate() {
        for d in HALF_NEIGHBOURHOOD {
            let Some(&q) = shifted(p, d, bits).and_then(|m| index.get(&m)) else {
                continue;
            };
            let back = d.map(|v| -v);
            present[pi] |= 1 << nb(d);
            present[q as usize] |= 1 << nb(back);
            if d.iter().filter(|&&v| v != 0).count() == 1 {
                let a = d.iter().position(|&v| v != 0).unwrap_or(0);
                // `d` points up its axis (its only component is positive).
                faces[pi][2 * a + 1] = q;
                faces[q as usize][2 * a] = pi as u32;
            }
        }
    }
    (present, faces)
}

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
    for k in 0..u32::from(depth) {
        let index: FxHashMap<u64, u32> = nodes
            .iter()
            .enumerate()
            .map(|(i, &p)| (morton3(p), i as u32))
            .collect();
        let (present, faces) = neighbourhoods(&nodes, &index, k);
        let mut bytes = vec![0u8; nodes.len()];
        let mut children: Vec<[u32; 3]> = Vec::with_capacity((nodes.len() * 2).min(n));
        for (pi, &p) in nodes.iter().enumerate() {
            let (present, face) = (present[pi], faces[pi]);
            let mut byte = 0u8;
            for (i, &side) in SIDE_MASKS.iter().enumerate() {
                let c = [
                    2 * p[0] + (i & 1) as u32,
                    2 * p[1] + ((i >> 1) & 1) as u32,
                    2 * p[2] + ((i >> 2) & 1) as u32,
                ];
                let occupied = byte.count_ones();
                let bit = if i == 7 && occupied == 0 {
                    true
                } else {
                    let n7 = (present & side).count_ones() as usize;
                    let mut kf = 0usize;
                    for a in 0..3 {
                        let j = i ^ (1 << a);
                        let high = (i >> a) & 1 == 1;
                        // Inside the node: the sibling across this face, if decoded (j < i).
                        if j < i && byte >> j & 1 == 1 {
                            kf += 1;
                        }
                        // Across the node's face on the child's side: child j of that
                        // neighbour, if the neighbour has been walked.
                        let q = face[2 * a + usize::from(high)];
                        if q != u32::MAX && bytes[q as usize] >> j & 1 == 1 {
                            kf += 1;
                        }
                    }
                    let ctx = ((i * 8 + n7) * 4 + kf.min(3)) * 4 + (occupied as usize).min(3);
                    let what = Event::Occupancy {
                        depth: k + 1,
                        cell: c,
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
                    children.push(c);
                    byte |= 1 << i;
                }
            }
            bytes[pi] = byte;
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
