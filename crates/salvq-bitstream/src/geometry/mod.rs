//! Anchor geometry (spec §8): voxel coordinates as an octree of occupancy events under
//! adaptive contexts and direct nodes, then a count per voxel. One traversal serves the
//! encoder and the decoder: it asks an [`Events`] for each event (the encoder knows the
//! answer and records it, the decoder reads it), so both evolve the contexts identically.

mod contexts;
mod neighbours;
use contexts::Contexts;
use neighbours::{
    child_neighbours, face_neighbour_counts, nb, side_neighbour_counts, Neighbours, LATER_SIBLINGS,
};

use crate::container::chunk::ChunkTag;
use crate::entropy::ans::{clamp_freq_one, AnsReader, BinaryModel, UniformModel};
use crate::entropy::{GaussianTables, SymbolReader, PRECISION};
use crate::error::{AnsFault, Error, Result};

/// §8.3: occupancy contexts (8 child indices × 8 neighbour counts × 4 × 4).
pub const OCCUPANCY_CONTEXTS: usize = 1024;
/// §8.4: voxel-count contexts.
pub const COUNT_CONTEXTS: usize = 4;
/// §8.2: direct-flag contexts, by the levels left below the node (1, 2, 3, 4 or more).
pub const DIRECT_CONTEXTS: usize = 4;
/// §8.3: counts are halved once their sum exceeds this.
pub const ADAPT_LIMIT: u32 = 256;

/// Why a geometry payload is invalid (spec §8.2, §8.4).
pub const MORE_NODES_THAN_ANCHORS: &str = "more nodes than anchors";
/// §8.4: an **OctreeInvalid** rule: the voxel counts would exceed the tile's anchor count.
pub const COUNTS_ABOVE: &str = "counts above the anchor count";
/// §8.4: an **OctreeInvalid** rule: the voxel counts end below the tile's anchor count.
pub const COUNTS_BELOW: &str = "counts below the anchor count";

/// The cell of child `i` (octant bits x, y, z) of the node at cell `p`, one level down.
#[inline]
fn child_cell(p: [u32; 3], i: usize) -> [u32; 3] {
    [
        2 * p[0] + (i & 1) as u32,
        2 * p[1] + ((i >> 1) & 1) as u32,
        2 * p[2] + ((i >> 2) & 1) as u32,
    ]
}

/// What [`walk`] asks for: the encoder knows each answer and records it, the decoder reads it,
/// so both evolve the contexts identically.
pub trait Events {
    /// A binary event (§6.2.1 kind 3) with P(1) = `freq_one` / 2^P.
    fn bit(&mut self, freq_one: u32, what: Event) -> Result<bool>;
    /// A direct node's octant at one depth (§8.2): a uniform 3-bit value (§6.2.1 kind 4).
    fn octant(&mut self, what: DirectOctant) -> Result<u32>;
}

/// What a binary event of [`walk`] decides.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Event {
    /// Whether depth-`depth` cell `cell` is occupied (§8.2).
    Occupancy {
        /// The cell's depth, 1 … D (its parent's depth + 1).
        depth: u32,
        /// The cell's coordinates at that depth.
        cell: [u32; 3],
    },
    /// Whether the isolated depth-`depth` node `cell` holds a single voxel (§8.2).
    Direct {
        /// The isolated node's depth, 0 … D − 1.
        depth: u32,
        /// The node's cell coordinates at that depth.
        cell: [u32; 3],
    },
    /// Whether leaf `leaf` holds more than `extra + 1` anchors (§8.4).
    Count {
        /// Index of the leaf in the tile's leaf order.
        leaf: usize,
        /// `m` of §8.4: the anchors already known beyond the leaf's first.
        extra: usize,
    },
}

/// A direct node's octant (§8.2): the child index, at depth `level`, of the cell that holds
/// the single voxel below the depth-`depth` node `cell`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DirectOctant {
    /// Depth of the flagged node.
    pub depth: u32,
    /// The flagged node's cell coordinates at `depth`.
    pub cell: [u32; 3],
    /// The depth whose octant this is, `depth + 1` … D.
    pub level: u32,
}

/// The octant (child index) of voxel `v` at the depth where `shift` more levels remain.
#[inline]
pub fn octant_of(v: [u32; 3], shift: u32) -> usize {
    ((v[0] >> shift & 1) | (v[1] >> shift & 1) << 1 | (v[2] >> shift & 1) << 2) as usize
}

/// §8.2's bound: a depth holds at most `N_t` cells.
#[inline]
fn check_room(children: usize, k: u32, anchors: u32) -> Result<()> {
    if children == anchors as usize {
        return Err(Error::OctreeInvalid {
            rule: MORE_NODES_THAN_ANCHORS,
            depth: (k + 1) as u8,
            count: u64::from(anchors) + 1,
            anchors,
        });
    }
    Ok(())
}

/// What a node's occupancy events depend on besides the events themselves (§8.3): the
/// node, and its children's `n7` and across-face `kf`, 4 bits per child.
#[derive(Clone, Copy)]
struct NodeContext {
    depth: u32,
    cell: [u32; 3],
    side_counts: u32,
    face_counts: u32,
    /// The nodes of the next depth before this node's children, and the bound on them.
    nodes_before: usize,
    anchors: u32,
}

/// §8.2, §8.3: a node's eight occupancy events (the last implied when the first seven are 0),
/// as its occupancy byte. §8.2's bound on the nodes of a depth is checked as each occupied
/// child is decided, before the next event.
///
/// Not inlined into [`walk`]: on its own, the coder's state stays in registers across the
/// eight events instead of going through the stack; the children are unrolled so that each
/// one's shifts and sibling counts are constants.
#[inline(never)]
fn occupancy_byte<E: Events>(
    events: &mut E,
    occ: &mut Contexts<OCCUPANCY_CONTEXTS>,
    node: NodeContext,
) -> Result<u8> {
    let mut decided = Decided {
        face_counts: node.face_counts,
        byte: 0,
        occupied: 0,
    };
    child_event::<E, 0>(events, occ, &node, &mut decided)?;
    child_event::<E, 1>(events, occ, &node, &mut decided)?;
    child_event::<E, 2>(events, occ, &node, &mut decided)?;
    child_event::<E, 3>(events, occ, &node, &mut decided)?;
    child_event::<E, 4>(events, occ, &node, &mut decided)?;
    child_event::<E, 5>(events, occ, &node, &mut decided)?;
    child_event::<E, 6>(events, occ, &node, &mut decided)?;
    child_event::<E, 7>(events, occ, &node, &mut decided)?;
    Ok(decided.byte)
}

/// A node's children decided so far: the occupancy byte, how many are occupied, and the
/// `kf` counts with the occupied siblings added.
struct Decided {
    face_counts: u32,
    byte: u8,
    occupied: usize,
}

/// Child `I`'s occupancy event (§8.3's context) and what it changes.
#[inline(always)]
fn child_event<E: Events, const I: usize>(
    events: &mut E,
    occ: &mut Contexts<OCCUPANCY_CONTEXTS>,
    node: &NodeContext,
    decided: &mut Decided,
) -> Result<()> {
    let bit = if I == 7 && decided.occupied == 0 {
        true
    } else {
        let n7 = (node.side_counts >> (4 * I) & 0xf) as usize;
        let kf = (decided.face_counts >> (4 * I) & 0xf) as usize;
        let ctx = ((I * 8 + n7) * 4 + kf.min(3)) * 4 + decided.occupied.min(3);
        let what = Event::Occupancy {
            depth: node.depth + 1,
            cell: child_cell(node.cell, I),
        };
        let bit = events.bit(occ.freq_one(ctx), what)?;
        occ.update(ctx, bit);
        bit
    };
    // An occupied child's updates as products with the bit, not under a branch: whether a
    // child is occupied follows the data.
    if bit & (node.nodes_before + decided.occupied == node.anchors as usize) {
        check_room(node.anchors as usize, node.depth, node.anchors)?;
    }
    decided.byte |= u8::from(bit) << I;
    decided.occupied += usize::from(bit);
    decided.face_counts += LATER_SIBLINGS[I] * u32::from(bit);
    Ok(())
}

/// §8.2–§8.4: walks the octree of depth `depth` for `anchors` anchors, asking `events` for
/// each event in coding order (occupancy, direct flags and octants in traversal order, then
/// the counts). Returns the anchors' voxels in canonical order.
///
/// Per node, the 26 neighbours at its depth are looked up once: none present makes the node
/// isolated (a direct-flag candidate); otherwise their occupancy gives `n7` for every child,
/// and the occupancy bytes of the face neighbours already walked give the children's face
/// neighbours across the node's faces (`kf`); neighbours inside the node are the siblings
/// decoded so far.
pub fn walk<E: Events>(
    depth: u8,
    anchors: u32,
    precision: u32,
    events: &mut E,
) -> Result<Vec<[u32; 3]>> {
    walk_with(
        depth,
        anchors,
        precision,
        events,
        &mut WalkScratch::default(),
    )
}

/// The buffers of one octree walk's levels, kept from level to level and, by a caller that
/// walks several tiles in turn, from tile to tile. A tile's deeper levels take megabytes of
/// neighbour rows (112 bytes a node); allocated afresh for every level of every tile, the
/// allocator handed them back to the kernel and the decoder page-faulted them in again.
#[derive(Default)]
pub struct WalkScratch {
    nodes: Vec<[u32; 3]>,
    direct: Vec<bool>,
    children: Vec<[u32; 3]>,
    child_direct: Vec<bool>,
    bytes: Vec<u8>,
    nbr: Vec<Neighbours>,
    child_nbr: Vec<Neighbours>,
    first_child: Vec<u32>,
}

impl crate::par::Scratch for WalkScratch {
    fn retained_bytes(&self) -> usize {
        use std::mem::size_of;
        (self.nodes.capacity() + self.children.capacity()) * size_of::<[u32; 3]>()
            + self.direct.capacity()
            + self.child_direct.capacity()
            + self.bytes.capacity()
            + (self.nbr.capacity() + self.child_nbr.capacity()) * size_of::<Neighbours>()
            + self.first_child.capacity() * size_of::<u32>()
    }
}

/// [`walk`], in `scratch`'s buffers.
pub fn walk_with<E: Events>(
    depth: u8,
    anchors: u32,
    precision: u32,
    events: &mut E,
    scratch: &mut WalkScratch,
) -> Result<Vec<[u32; 3]>> {
    let d = u32::from(depth);
    let n = anchors as usize;
    let mut occ = Contexts::<OCCUPANCY_CONTEXTS>::new(precision);
    let mut single = Contexts::<DIRECT_CONTEXTS>::new(precision);
    let WalkScratch {
        nodes,
        direct,
        children,
        child_direct,
        bytes,
        nbr,
        child_nbr,
        first_child,
    } = scratch;
    // A node is a cell of the current depth, or, once coded directly, the voxel it holds
    // (marked in `direct`): its one child at every later depth holds the same voxel.
    nodes.clear();
    nodes.push([0, 0, 0]);
    direct.clear();
    direct.push(false);
    // The root has no neighbours; each level's follow from its parents' (§8.3's contexts
    // need them), without a lookup by position.
    nbr.clear();
    nbr.push(Neighbours::NONE);
    for k in 0..d {
        // Levels below depth k + 1: the shift from a voxel to its depth-(k + 1) cell.
        let below = d - k - 1;
        bytes.clear();
        bytes.resize(nodes.len(), 0);
        children.clear();
        child_direct.clear();
        let capacity = (nodes.len() * 2).min(n);
        children.reserve(capacity);
        child_direct.reserve(capacity);
        for (pi, &p) in nodes.iter().enumerate() {
            if direct[pi] {
                // §8.2: no events below a direct node.
                check_room(children.len(), k, anchors)?;
                bytes[pi] = 1 << octant_of(p, below);
                children.push(p);
                child_direct.push(true);
                continue;
            }
            if nbr[pi].present == 0 {
                // §8.2: an isolated node says whether it holds a single voxel; if so, that
                // voxel's octant at every depth below follows at once.
                let ctx = (d - k).min(DIRECT_CONTEXTS as u32) as usize - 1;
                let what = Event::Direct { depth: k, cell: p };
                let is_single = events.bit(single.freq_one(ctx), what)?;
                single.update(ctx, is_single);
                if is_single {
                    let v = direct_voxel(events, p, k, d)?;
                    check_room(children.len(), k, anchors)?;
                    bytes[pi] = 1 << octant_of(v, below);
                    children.push(v);
                    child_direct.push(true);
                    continue;
                }
            }
            let (side_counts, face_counts) = neighbour_counts(&nbr[pi], bytes);
            let node = NodeContext {
                depth: k,
                cell: p,
                side_counts,
                face_counts,
                nodes_before: children.len(),
                anchors,
            };
            let byte = occupancy_byte(events, &mut occ, node)?;
            push_children(children, child_direct, p, byte);
            bytes[pi] = byte;
        }
        if k + 1 < d {
            child_neighbours(nbr, bytes, first_child, child_nbr);
            std::mem::swap(nbr, child_nbr);
        }
        std::mem::swap(nodes, children);
        std::mem::swap(direct, child_direct);
    }
    leaf_counts(nodes, depth, anchors, precision, events)
}

/// §8.3's `kf` of every child of a node with neighbours `nbr`, 4 bits each, as (side,
/// face) counts.
#[inline(always)]
fn neighbour_counts(nbr: &Neighbours, bytes: &[u8]) -> (u32, u32) {
    let (row, present) = (&nbr.index, nbr.present);
    // The occupancy bytes of the face neighbours −x, +x, −y, +y, −z, +z (0 where there
    // is none or it is not walked yet: `bytes` is filled in walking order). They do
    // not change while this node's children are decided.
    let last = bytes.len() - 1;
    let face = |slot: usize| {
        let has = (present >> slot & 1) as u8;
        bytes[(row[slot] as usize).min(last)] & 0u8.wrapping_sub(has)
    };
    let face_bytes = [
        face(nb([-1, 0, 0])),
        face(nb([1, 0, 0])),
        face(nb([0, -1, 0])),
        face(nb([0, 1, 0])),
        face(nb([0, 0, -1])),
        face(nb([0, 0, 1])),
    ];
    // §8.3's `kf` of every child, 4 bits each (at most 3 + 3): first the neighbours
    // across the node's faces, then, as children are decided, the siblings.
    let face_counts = face_neighbour_counts(face_bytes);
    let side_counts = side_neighbour_counts(present);
    (side_counts, face_counts)
}

/// Appends the children that `byte` marks occupied to the next depth's nodes.
///
/// Every child's cell written, the occupied ones kept: no branch per child. All eight are
/// appended and the rest cut off again, so that the copy has a constant size (a variable
/// one is a call to `memcpy`).
#[inline(always)]
fn push_children(
    children: &mut Vec<[u32; 3]>,
    child_direct: &mut Vec<bool>,
    p: [u32; 3],
    byte: u8,
) {
    let (mut cells, mut occupied) = ([[0u32; 3]; 8], 0usize);
    for i in 0..8 {
        cells[occupied & 7] = child_cell(p, i);
        occupied += usize::from(byte >> i & 1);
    }
    let before = children.len();
    children.extend_from_slice(&cells);
    children.truncate(before + occupied);
    child_direct.extend_from_slice(&[false; 8]);
    child_direct.truncate(before + occupied);
}

/// §8.4: how many anchors each leaf voxel holds (1 + the count's unary events), the voxels
/// repeated as often, `anchors` in all.
fn leaf_counts<E: Events>(
    nodes: &[[u32; 3]],
    depth: u8,
    anchors: u32,
    precision: u32,
    events: &mut E,
) -> Result<Vec<[u32; 3]>> {
    let n = anchors as usize;
    let mut counts = Contexts::<COUNT_CONTEXTS>::new(precision);
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
            let what = Event::Count { leaf: j, extra };
            let more = events.bit(counts.freq_one(ctx), what)?;
            counts.update(ctx, more);
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
/// §8.2: the voxel a direct node at depth `k` holds, its octant at every depth below read
/// from the body.
#[inline(always)]
fn direct_voxel<E: Events>(events: &mut E, p: [u32; 3], k: u32, d: u32) -> Result<[u32; 3]> {
    let mut v = p;
    for level in k + 1..=d {
        let what = DirectOctant {
            depth: k,
            cell: p,
            level,
        };
        v = child_cell(v, (events.octant(what)? & 7) as usize);
    }
    Ok(v)
}

/// The decoder reads every event from the body.
impl Events for SymbolReader<'_> {
    #[inline(always)]
    fn bit(&mut self, freq_one: u32, _: Event) -> Result<bool> {
        SymbolReader::bit(self, freq_one)
    }

    #[inline(always)]
    fn octant(&mut self, _: DirectOctant) -> Result<u32> {
        self.uniform(3)
    }
}

/// The decoder at the format's precision: a bare coder with nothing but binary events and
/// uniform values, whose state the compiler keeps in registers across the walk (the general
/// [`SymbolReader`] serves the other precisions).
struct OctreeReader<'a> {
    ans: AnsReader<'a>,
}

impl OctreeReader<'_> {
    #[cold]
    fn fault(fault: AnsFault) -> Error {
        Error::AnsStreamInvalid {
            tag: ChunkTag::APOS,
            fault,
        }
    }
}

impl Events for OctreeReader<'_> {
    #[inline(always)]
    fn bit(&mut self, freq_one: u32, _: Event) -> Result<bool> {
        const P: usize = PRECISION as usize;
        // `walk` passes a context's P(1), which [`Counts::freq_one`] keeps in 1 … 2^P − 1.
        debug_assert_eq!(freq_one, clamp_freq_one(PRECISION, freq_one));
        let model = BinaryModel {
            freq_zero: (1 << P) - freq_one,
        };
        self.ans.decode_binary::<P>(model).map_err(Self::fault)
    }

    #[inline(always)]
    fn octant(&mut self, _: DirectOctant) -> Result<u32> {
        self.ans
            .decode_uniform::<{ PRECISION as usize }>(UniformModel { bits: 3 })
            .map_err(Self::fault)
    }
}

/// §8.1: decodes an `APOS` body into canonical-order voxels.
pub fn decode(
    body: &[u8],
    depth: u8,
    anchors: u32,
    tables: &GaussianTables,
) -> Result<Vec<[u32; 3]>> {
    decode_with(body, depth, anchors, tables, &mut WalkScratch::default())
}

/// [`decode`], in `scratch`'s buffers (a caller decoding tile after tile keeps one).
pub fn decode_with(
    body: &[u8],
    depth: u8,
    anchors: u32,
    tables: &GaussianTables,
    scratch: &mut WalkScratch,
) -> Result<Vec<[u32; 3]>> {
    if tables.precision() == PRECISION {
        let ans = AnsReader::new(body).map_err(OctreeReader::fault)?;
        let mut reader = OctreeReader { ans };
        let voxels = walk_with(depth, anchors, PRECISION, &mut reader, scratch)?;
        reader.ans.finish().map_err(OctreeReader::fault)?;
        return Ok(voxels);
    }
    let mut reader = SymbolReader::new(ChunkTag::APOS, body, tables)?;
    let voxels = walk_with(depth, anchors, tables.precision(), &mut reader, scratch)?;
    reader.finish()?;
    Ok(voxels)
}
