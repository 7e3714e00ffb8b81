//! §8.3's neighbourhoods: each node's 26 neighbours at its depth, found from its parent's
//! without a lookup by position (a child's neighbours are children of its parent's).

/// Index of offset `d ∈ {−1, 0, 1}³` in a node's 27-cell neighbourhood.
pub(super) const fn nb(d: [i64; 3]) -> usize {
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

pub(super) const SIDE_MASKS: [u32; 8] = [
    side_mask(0),
    side_mask(1),
    side_mask(2),
    side_mask(3),
    side_mask(4),
    side_mask(5),
    side_mask(6),
    side_mask(7),
];

/// A node's neighbours at one level: bit `nb(d)` of `present` set where there is a node at
/// offset `d`, and then its index in slot `nb(d)` (slot 13, the node itself, unused). The
/// other slots hold nothing meaningful ([`child_neighbours`] leaves them stale).
#[derive(Clone, Copy)]
pub(super) struct Neighbours {
    pub(super) index: [u32; 27],
    pub(super) present: u32,
}

impl Neighbours {
    pub(super) const NONE: Neighbours = Neighbours {
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

/// `NEIGHBOUR_CHILDREN[i][ps]`: which children of the node at slot `ps` of child `i`'s
/// parent's neighbourhood are neighbours of child `i` (a mask over that node's occupancy
/// byte; the child itself left out). Only the parent itself and the 7 neighbours on the
/// child's side ([`SIDE_MASKS`]) have any.
const NEIGHBOUR_CHILDREN: [[u8; 27]; 8] = {
    let mut out = [[0u8; 27]; 8];
    let mut i = 0;
    while i < 8 {
        let mut slot = 0;
        while slot < 27 {
            if slot != 13 {
                let (ps, child) = CHILD_NEIGHBOUR[i][slot];
                out[i][ps as usize] |= 1 << child;
            }
            slot += 1;
        }
        i += 1;
    }
    out
};

/// For child `i` and each cell of the 2×2×2 block of its parent's neighbourhood on its side
/// (the parent and its 7 neighbours of [`SIDE_MASKS`]): that cell's parent slot, which of its
/// children are child `i`'s neighbours ([`NEIGHBOUR_CHILDREN`]), and the shift that takes
/// [`SPREAD27`] of them to their slots in child `i`'s neighbourhood, plus 13 (so that it is
/// never negative; the product is shifted back by 13).
#[derive(Clone, Copy)]
struct BlockCell {
    slot: u8,
    keep: u8,
    shift: u8,
}

const BLOCK: [[BlockCell; 8]; 8] = {
    let empty = BlockCell {
        slot: 13,
        keep: 0,
        shift: 0,
    };
    let mut out = [[empty; 8]; 8];
    let mut i = 0;
    while i < 8 {
        let mut b = 0;
        while b < 8 {
            // The cell's offset from the parent per axis: 0, or toward child `i`'s side.
            let mut e = [0i64; 3];
            let mut a = 0;
            while a < 3 {
                if (b >> a) & 1 == 1 {
                    e[a] = if (i >> a) & 1 == 1 { 1 } else { -1 };
                }
                a += 1;
            }
            // The cell's child c sits at offset 2e + c − i from child `i`: slot
            // Σ (2e_a − i_a + 1 + c_a) · 3^a, which is the base below plus SPREAD27's bit of c.
            let mut base = 0i64;
            let (mut a, mut weight) = (0, 1);
            while a < 3 {
                base += (2 * e[a] - ((i >> a) & 1) as i64 + 1) * weight;
                weight *= 3;
                a += 1;
            }
            let slot = nb(e);
            out[i][b] = BlockCell {
                slot: slot as u8,
                keep: NEIGHBOUR_CHILDREN[i][slot],
                shift: (base + 13) as u8,
            };
            b += 1;
        }
        i += 1;
    }
    out
};

/// `SPREAD27[b]`: bit `x + 3y + 9z` set for each child (octant bits x, y, z) set in `b`.
const SPREAD27: [u32; 256] = {
    let mut out = [0u32; 256];
    let mut b = 0;
    while b < 256 {
        let mut c = 0;
        while c < 8 {
            if (b >> c) & 1 == 1 {
                out[b] |= 1 << ((c & 1) + 3 * ((c >> 1) & 1) + 9 * (c >> 2));
            }
            c += 1;
        }
        b += 1;
    }
    out
};

/// The next level's neighbours from this level's, into `out`: `bytes[p]` is node `p`'s
/// occupancy byte and its children are numbered in order (node by node, octant by octant);
/// `first` is scratch (each node's first child). Only the slots a row's `present` sets are
/// written: `out`'s rows are reused from level to level, and their other slots are stale.
///
/// A child's neighbours lie in its parent and the parent's 7 neighbours on the child's side:
/// its `present` is the occupancy bytes of those 8 cells spread to its slots, without a
/// branch, and only the slots it sets are visited to find the neighbours' indices.
pub(super) fn child_neighbours(
    nbr: &[Neighbours],
    bytes: &[u8],
    first: &mut Vec<u32>,
    out: &mut Vec<Neighbours>,
) {
    first.clear();
    first.reserve(bytes.len());
    let mut count = 0u32;
    for &b in bytes {
        first.push(count);
        count += u32::from(POPCOUNT[usize::from(b)]);
    }
    let first = &first[..];
    // Rows are overwritten in place (their `present` and the slots it sets), not rebuilt: a
    // level's rows take megabytes, and most of a row is slots without a neighbour.
    out.truncate(count as usize);
    out.resize(count as usize, Neighbours::NONE);
    let mut rows = out.iter_mut();
    // The first child of the node (slot 13) and of each neighbour it has; 32 entries so that
    // a 5-bit index needs no bounds check. Only the slots whose byte is read as nonzero are
    // read, so the array is not cleared per node.
    let mut near_first = [0u32; 32];
    for (p, &byte) in bytes.iter().enumerate() {
        if byte == 0 {
            continue;
        }
        let present = nbr[p].present;
        if present == 0 && byte & (byte - 1) == 0 {
            // An only child of an isolated node (a direct node's, most often) is isolated.
            let Some(row) = rows.next() else { break };
            row.present = 0;
            continue;
        }
        // The occupancy byte of the node and of each neighbour it has, 0 elsewhere.
        let mut near_bytes = [0u8; 32];
        near_bytes[13] = byte;
        near_first[13] = first[p];
        let mut rest = present;
        while rest != 0 {
            let slot = rest.trailing_zeros() as usize & 31;
            rest &= rest - 1;
            let q = nbr[p].index[slot.min(26)] as usize;
            near_bytes[slot] = bytes[q];
            near_first[slot] = first[q];
        }
        let mut kids = byte;
        while kids != 0 {
            let i = kids.trailing_zeros() as usize & 7;
            kids &= kids - 1;
            let block = &BLOCK[i];
            let Some(row) = rows.next() else { break };
            let mut mask = 0u64;
            for cell in block {
                let b = near_bytes[usize::from(cell.slot) & 31] & cell.keep;
                mask |= u64::from(SPREAD27[usize::from(b)]) << cell.shift;
            }
            let child_present = (mask >> 13) as u32;
            row.present = child_present;
            let mut slots = child_present;
            while slots != 0 {
                let slot = slots.trailing_zeros() as usize;
                slots &= slots - 1;
                let (ps, child) = CHILD_NEIGHBOUR[i][slot.min(26)];
                let (ps, child) = (usize::from(ps) & 31, usize::from(child) & 7);
                let below = POPCOUNT[usize::from(near_bytes[ps] & LOW[child])];
                row.index[slot.min(26)] = near_first[ps] + u32::from(below);
            }
        }
    }
}

/// `LOW[j]`: the bits below bit `j` of an occupancy byte.
const LOW: [u8; 8] = [0x00, 0x01, 0x03, 0x07, 0x0f, 0x1f, 0x3f, 0x7f];

/// `x` with the bit of each child `i` spread to bit `4·i`.
const SPREAD: [u32; 256] = {
    let mut out = [0u32; 256];
    let mut b = 0;
    while b < 256 {
        let mut i = 0;
        while i < 8 {
            out[b] |= ((b as u32 >> i) & 1) << (4 * i);
            i += 1;
        }
        b += 1;
    }
    out
};

/// For child `i`: one in the 4-bit count of each later sibling it is a face neighbour of
/// (`i + 2^a` for each axis `a` where bit `a` of `i` is 0).
pub(super) const LATER_SIBLINGS: [u32; 8] = {
    let mut out = [0u32; 8];
    let mut i = 0;
    while i < 8 {
        let mut a = 0;
        while a < 3 {
            if (i >> a) & 1 == 0 {
                out[i] += 1 << (4 * (i | 1 << a));
            }
            a += 1;
        }
        i += 1;
    }
    out
};

/// For every child of a node, how many of its face neighbours across the node's faces are
/// occupied, 4 bits per child: from the occupancy bytes of the node's face neighbours
/// −x, +x, −y, +y, −z, +z (0 where absent or not walked yet). Child `i` with bit `a` of `i`
/// clear faces child `i + 2^a` of the −a neighbour; with it set, child `i − 2^a` of the +a one.
#[inline]
pub(super) fn face_neighbour_counts(f: [u8; 6]) -> u32 {
    let axis = |low: u8, high: u8, a: u32, low_children: u8| {
        let shift = 1 << a;
        SPREAD[usize::from(((low >> shift) & low_children) | ((high << shift) & !low_children))]
    };
    axis(f[0], f[1], 0, 0x55) + axis(f[2], f[3], 1, 0x33) + axis(f[4], f[5], 2, 0x0f)
}

/// For each byte `b` of a neighbourhood mask (bits `8·byte` … `8·byte + 7` of the 27 slots):
/// how many of the set slots lie on each child's side ([`SIDE_MASKS`]), 4 bits per child.
const SIDE_COUNTS: [[u32; 256]; 4] = {
    let mut out = [[0u32; 256]; 4];
    let mut byte = 0;
    while byte < 4 {
        let mut b = 0;
        while b < 256 {
            let mut i = 0;
            while i < 8 {
                let n = ((b as u32) << (8 * byte)) & SIDE_MASKS[i];
                out[byte][b] |= n.count_ones() << (4 * i);
                i += 1;
            }
            b += 1;
        }
        byte += 1;
    }
    out
};

/// §8.3's `n7` of every child of a node with neighbourhood mask `present`, 4 bits each.
#[inline]
pub(super) fn side_neighbour_counts(present: u32) -> u32 {
    let b = present.to_le_bytes();
    SIDE_COUNTS[0][usize::from(b[0])]
        + SIDE_COUNTS[1][usize::from(b[1])]
        + SIDE_COUNTS[2][usize::from(b[2])]
        + SIDE_COUNTS[3][usize::from(b[3])]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A xorshift64 generator: the tests' random levels and masks, the same on every machine.
    fn xorshift(seed: u64) -> impl FnMut() -> u64 {
        let mut x = seed;
        move || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x
        }
    }

    /// Brute force: the row of every cell of `cells`, by looking each neighbour up by position.
    fn rows_by_position(cells: &[[i64; 3]]) -> Vec<Neighbours> {
        let at: std::collections::HashMap<[i64; 3], u32> = cells
            .iter()
            .enumerate()
            .map(|(j, &c)| (c, j as u32))
            .collect();
        cells
            .iter()
            .map(|c| {
                let mut row = Neighbours::NONE;
                for slot in (0..27).filter(|&s| s != 13) {
                    let d = [
                        slot as i64 % 3 - 1,
                        slot as i64 / 3 % 3 - 1,
                        slot as i64 / 9 - 1,
                    ];
                    if let Some(&j) = at.get(&[c[0] + d[0], c[1] + d[1], c[2] + d[2]]) {
                        row.index[slot] = j;
                        row.present |= 1 << slot;
                    }
                }
                row
            })
            .collect()
    }

    /// Every child's row is the one found by looking its neighbours up by position, for
    /// sparse and dense levels, only children of isolated nodes included.
    #[test]
    fn child_rows_are_the_neighbours_by_position() {
        let mut next = xorshift(0x2545_f491_4f6c_dd1d);
        let (mut first, mut out) = (Vec::new(), Vec::new());
        for round in 0..200u64 {
            // Cell density 1/64 … 1, child density 1/8 … 1.
            let (cell_odds, child_odds) = (1 + round % 64, 1 + round / 64 % 8);
            let cells: Vec<[i64; 3]> = (0..512i64)
                .map(|m| [m % 8, m / 8 % 8, m / 64])
                .filter(|_| next() % cell_odds == 0)
                .collect();
            let bytes: Vec<u8> = cells
                .iter()
                .map(|_| {
                    (0..8)
                        .filter(|_| next() % child_odds == 0)
                        .fold(0, |b, i| b | 1 << i)
                })
                .collect();
            let children: Vec<[i64; 3]> = cells
                .iter()
                .zip(&bytes)
                .flat_map(|(c, &b)| {
                    (0..8i64).filter(move |i| b >> i & 1 == 1).map(move |i| {
                        [
                            2 * c[0] + (i & 1),
                            2 * c[1] + (i >> 1 & 1),
                            2 * c[2] + (i >> 2),
                        ]
                    })
                })
                .collect();
            child_neighbours(&rows_by_position(&cells), &bytes, &mut first, &mut out);
            let expected = rows_by_position(&children);
            assert_eq!(out.len(), expected.len(), "round {round}");
            for (j, (got, want)) in out.iter().zip(&expected).enumerate() {
                assert_eq!(got.present, want.present, "round {round}, child {j}");
                for slot in (0..27).filter(|s| want.present >> s & 1 == 1) {
                    assert_eq!(
                        got.index[slot], want.index[slot],
                        "round {round}, child {j}"
                    );
                }
            }
        }
    }

    /// The packed per-child counts are §8.3's `n7` and the across-face part of `kf`, as
    /// their definitions compute them one child at a time.
    #[test]
    fn packed_child_counts_match_the_definitions() {
        let mut next = xorshift(0x9e37_79b9_7f4a_7c15);
        for _ in 0..20_000 {
            let r = next();
            let present = (r as u32) & ((1 << 27) - 1) & !(1 << 13);
            let faces = (r >> 32).to_le_bytes();
            let faces = [faces[0], faces[1], faces[2], faces[3], faces[4], faces[5]];
            let (n7s, kfs) = (side_neighbour_counts(present), face_neighbour_counts(faces));
            for (i, side) in SIDE_MASKS.iter().enumerate() {
                let n7 = (present & side).count_ones();
                assert_eq!(n7s >> (4 * i) & 0xf, n7, "present {present:#x}, child {i}");
                let across: u32 = (0..3)
                    .map(|a| {
                        let high = (i >> a) & 1;
                        u32::from(faces[2 * a + high] >> (i ^ (1 << a)) & 1)
                    })
                    .sum();
                assert_eq!(kfs >> (4 * i) & 0xf, across, "faces {faces:?}, child {i}");
            }
        }
        // Each decided child adds one to the later siblings it touches across a face.
        for (i, later) in LATER_SIBLINGS.iter().enumerate() {
            for j in 0..8usize {
                let touches = (i ^ j).count_ones() == 1 && j > i;
                assert_eq!(later >> (4 * j) & 0xf, u32::from(touches));
            }
        }
    }
}
