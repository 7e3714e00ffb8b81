//! The explicit profile's must-fail vectors that break a rule inside a tile (spec §6.2.6,
//! §6.4, §8.4, §10.1): tiles out of order or sharing a voxel, a box that is not the smallest,
//! octrees coding too many or too few voxels, bodies with words left over, a final state
//! not reached, an escape prefix too long. Each re-codes the base stream's tile 0 (or swaps
//! tiles) with the format's own writers, everything decoded before the broken rule intact.

use salvq_bitstream::container::chunk::ChunkTag;
use salvq_bitstream::entropy::{GaussianTables, SymbolReader};
use salvq_encoder::writers::surgery;
use salvq_encoder::writers::SymbolWriter;

use super::explicit_edited::{EscapeAt, LayerEdit};
use super::must_fail::{vector as must_fail, MustFailVector};

fn edit(stream: &[u8], tag: ChunkTag, f: impl FnOnce(&mut Vec<u8>)) -> Vec<u8> {
    surgery::edit_payload(stream, tag, f).expect("the chunk is in the base stream")
}

fn chunks(stream: &[u8]) -> Vec<(ChunkTag, Vec<u8>)> {
    surgery::chunks(stream).expect("the base stream frames")
}

/// Each tile's body of a tiled chunk's `payload` (§10.2), in a stream of `tiles` tiles
/// (its `TILS` payload).
fn tile_bodies(tag: ChunkTag, payload: &[u8], tiles: &[u8]) -> Vec<Vec<u8>> {
    let t = u32::from_le_bytes([tiles[1], tiles[2], tiles[3], tiles[4]]);
    salvq_bitstream::tiles::split_bodies(tag, 1, &payload[1..], t as usize)
        .expect("the chunk's tiles frame")
        .into_iter()
        .map(<[u8]>::to_vec)
        .collect()
}

/// The payload of the first chunk tagged `tag`.
fn payload_of(stream: &[u8], tag: ChunkTag) -> Vec<u8> {
    chunks(stream)
        .into_iter()
        .find(|(t, _)| *t == tag)
        .map(|(_, p)| p)
        .expect("the chunk is in the base stream")
}

/// The base stream with tiles 0 and 1 of layer 0 swapped: their `TILS` entries (41 bytes
/// each after the 5 of `coding_method` and `tile_count`, §10.1) and their bodies of `APOS`
/// and `GATT`. Each tile is valid on its own; only their order is not.
fn tiles_swapped(base: &[u8]) -> Vec<u8> {
    let mut cs = chunks(base);
    let tils = payload_of(base, ChunkTag::TILS);
    for (tag, p) in cs.iter_mut().filter(|(t, _)| *t != ChunkTag::GHED) {
        match *tag {
            ChunkTag::TILS => {
                let (t0, t1) = (p[5..46].to_vec(), p[46..87].to_vec());
                p[5..46].copy_from_slice(&t1);
                p[46..87].copy_from_slice(&t0);
            }
            ChunkTag::APOS | ChunkTag::GATT => {
                let mut bodies = tile_bodies(*tag, p, &tils);
                bodies.swap(0, 1);
                p.truncate(1);
                p.extend(salvq_bitstream::tiles::join_bodies(&bodies));
            }
            _ => continue,
        }
        if *tag == ChunkTag::GATT {
            break; // layer 0's chunks only
        }
    }
    surgery::assemble(base, &cs)
}

/// Layer 0 with tile 1's first Gaussian moved onto tile 0's last voxel: tile 1's cell and
/// box follow (so §10.1's box check passes) and its bodies are coded again, so only the
/// strict order of §10.1 is broken (equal Morton keys).
fn tiles_sharing_a_voxel(base: &[u8]) -> Vec<u8> {
    let mut e = LayerEdit::new(base.to_vec());
    let start = e.tiles.range(1).start;
    e.voxels[start] = e.voxels[start - 1];
    let voxels = &e.voxels[e.tiles.range(1)];
    let level = (0..=e.layer.coord_bits)
        .find(|&l| {
            voxels
                .iter()
                .all(|v| v.map(|c| c >> l) == voxels[0].map(|c| c >> l))
        })
        .expect("the whole grid holds the tile");
    e.tiles.cells[1] = (level, voxels[0].map(|c| c >> level));
    let mut b = [u32::MAX, u32::MAX, u32::MAX, 0, 0, 0];
    for v in voxels {
        for a in 0..3 {
            b[a] = b[a].min(v[a]);
            b[3 + a] = b[3 + a].max(v[a]);
        }
    }
    e.tiles.boxes[1] = b;
    e.encode()
}

/// Layer 0 with tile 0's `APOS` body coding `change` of its voxels (cell-relative, Morton
/// order) while `TILS` keeps its Gaussian count (§8.2, §8.4).
fn octree_changed(base: &[u8], change: impl FnOnce(&mut Vec<[u32; 3]>, u8)) -> Vec<u8> {
    let e = LayerEdit::new(base.to_vec());
    let (level, mut local) = e.local_voxels(0);
    change(&mut local, level);
    local.sort_by_key(|&v| salvq_bitstream::model::morton3(v));
    let tils = payload_of(base, ChunkTag::TILS);
    let mut apos = tile_bodies(ChunkTag::APOS, &payload_of(base, ChunkTag::APOS), &tils);
    apos[0] = salvq_encoder::writers::encode_geometry(&local, level, GaussianTables::standard())
        .expect("the voxels code");
    let gatt = tile_bodies(ChunkTag::GATT, &payload_of(base, ChunkTag::GATT), &tils);
    e.stream_with(&apos, &gatt)
}

/// A voxel of the cell of level `level` that `voxels` lacks (next to one of them).
fn free_voxel(voxels: &[[u32; 3]], level: u8) -> [u32; 3] {
    let side = 1u32 << level;
    voxels
        .iter()
        .flat_map(|v| (0..3).flat_map(move |a| [1i64, -1].map(move |d| (v, a, d))))
        .filter_map(|(v, a, d)| {
            let c = i64::from(v[a]) + d;
            let mut w = *v;
            w[a] = u32::try_from(c).ok().filter(|&c| c < side)?;
            Some(w)
        })
        .find(|w| !voxels.contains(w))
        .expect("the tile's cell has room")
}

/// The tile-table and octree vectors (§8, §10.1): tile 0 of layer 0 of `base` (16
/// Gaussians) or the order of its tiles changed.
pub(crate) fn tile_vectors(base: &[u8]) -> Vec<MustFailVector> {
    vec![
        must_fail(
            "x-g-tile-box",
            "TileBoxMismatch",
            &["§10.1"],
            "TILS tile 0's box one voxel wider in x than its Gaussians' (it still holds them: \
             the box must be the smallest)",
            edit(base, ChunkTag::TILS, |p| {
                // Tile 0's entry at 5: count (4), cell level (1), cell (12), box min (12), max x.
                let at = 5 + 4 + 1 + 12 + 12;
                let x = u32::from_le_bytes([p[at], p[at + 1], p[at + 2], p[at + 3]]);
                p[at..at + 4].copy_from_slice(&(x + 1).to_le_bytes());
            }),
        ),
        must_fail(
            "x-g-tile-order",
            "TileOrder",
            &["§10.1"],
            "layer 0's tiles 0 and 1 swapped (TILS entries and APOS, GATT bodies): tile 1's voxels \
             come before tile 0's in Morton order",
            tiles_swapped(base),
        ),
        must_fail(
            "x-g-tile-order-shared",
            "TileOrder",
            &["§10.1"],
            "tile 1's first Gaussian on tile 0's last voxel (tile 1's cell, box and bodies \
             coded again): equal Morton keys are not in order",
            tiles_sharing_a_voxel(base),
        ),
        must_fail(
            "x-g-octree-nodes",
            "OctreeInvalid",
            &["§8.2"],
            "tile 0's APOS body codes its 16 voxels and one more, with TILS's count 16: a depth \
             holds 17 cells",
            octree_changed(base, |v, level| {
                let w = free_voxel(v, level);
                v.push(w);
            }),
        ),
        must_fail(
            "x-g-octree-counts-below",
            "OctreeInvalid",
            &["§8.4"],
            "tile 0's APOS body codes 15 of its 16 voxels, with TILS's count 16: the counts \
             add up to 15",
            octree_changed(base, |v, _| {
                v.pop();
            }),
        ),
        must_fail(
            "x-g-octree-counts-above",
            "OctreeInvalid",
            &["§8.4"],
            "tile 0's APOS body codes its first voxel twice, with TILS's count 16: the counts \
             pass 16",
            octree_changed(base, |v, _| v.push(v[0])),
        ),
    ]
}

/// `base` with tile 0's body of `tag` (layer 0) replaced by `f` of it.
fn tile0_body(base: &[u8], tag: ChunkTag, f: impl FnOnce(&mut Vec<u8>)) -> Vec<u8> {
    let tils = payload_of(base, ChunkTag::TILS);
    edit(base, tag, |p| {
        let mut bodies = tile_bodies(tag, p, &tils);
        f(&mut bodies[0]);
        p.truncate(1);
        p.extend(salvq_bitstream::tiles::join_bodies(&bodies));
    })
}

/// Tile 0's `GATT` body of layer 0 coded again with `escape` or an extra event (§6.2.6,
/// §6.4); whether the walk ends without error must be `walks`.
fn gatt_changed(base: &[u8], escape: Option<EscapeAt>, extra_event: bool, walks: bool) -> Vec<u8> {
    let e = LayerEdit::new(base.to_vec());
    let (body, walked) = e.gatt_body(0, escape, extra_event);
    assert_eq!(walked.is_ok(), walks, "{walked:?}");
    tile0_body(base, ChunkTag::GATT, |b| *b = body)
}

/// Tile 0's `APOS` body of layer 0 coded again with one more binary event after its last,
/// which no decoder reads: every word is used and the state ends above 2^32 (§6.2.6).
fn apos_extra_event(base: &[u8]) -> Vec<u8> {
    struct Transcribe<'a> {
        reader: SymbolReader<'a>,
        writer: SymbolWriter<'a>,
    }
    impl salvq_bitstream::geometry::Events for Transcribe<'_> {
        fn bit(
            &mut self,
            freq_one: u32,
            _: salvq_bitstream::geometry::Event,
        ) -> salvq::Result<bool> {
            let b = self.reader.bit(freq_one)?;
            self.writer.bit(b, freq_one);
            Ok(b)
        }
        fn octant(&mut self, _: salvq_bitstream::geometry::DirectOctant) -> salvq::Result<u32> {
            let v = self.reader.uniform(3)?;
            self.writer.uniform(v, 3);
            Ok(v)
        }
    }
    let e = LayerEdit::new(base.to_vec());
    let tables = GaussianTables::standard();
    let tils = payload_of(base, ChunkTag::TILS);
    let body = tile_bodies(ChunkTag::APOS, &payload_of(base, ChunkTag::APOS), &tils).remove(0);
    let mut copy = Transcribe {
        reader: SymbolReader::new(ChunkTag::APOS, &body, tables).expect("the body starts"),
        writer: SymbolWriter::new(ChunkTag::APOS, tables),
    };
    let (level, _) = e.local_voxels(0);
    let n = e.tiles.count(0);
    salvq_bitstream::geometry::walk(level, n, tables.precision(), &mut copy)
        .expect("the body decodes");
    copy.reader
        .finish()
        .expect("the body ends where its events do");
    copy.writer.bit(false, 1 << 15);
    let changed = copy.writer.finish();
    tile0_body(base, ChunkTag::APOS, |b| *b = changed)
}

/// The vectors of a body's end and its symbols (§3.5, §6.2.6, §6.4) on tile 0 of layer 0
/// of `base`; its first Gaussian's opacity (coded value 3) is the symbol changed.
pub(crate) fn body_vectors(base: &[u8]) -> Vec<MustFailVector> {
    let opacity = |zeros| EscapeAt {
        gaussian: 0,
        value: 3,
        zeros,
    };
    let past_limit = {
        let mut e = LayerEdit::new(base.to_vec());
        e.set_coord(0, 3, (1 << 24) + 1);
        let (body, walked) = e.gatt_body(0, None, false);
        assert!(walked.is_err(), "the walk stops at the coordinate");
        tile0_body(base, ChunkTag::GATT, |b| *b = body)
    };
    let word = |b: &mut Vec<u8>| b.extend_from_slice(&[0, 0, 0, 0]);
    vec![
        must_fail(
            "x-g-apos-words-left",
            "AnsStreamInvalid",
            &["§6.2.6", "§8.1"],
            "tile 0's APOS body with a zero word appended, which its events never read \
             (WordsLeftOver)",
            tile0_body(base, ChunkTag::APOS, word),
        ),
        must_fail(
            "x-g-apos-state",
            "AnsStreamInvalid",
            &["§6.2.6", "§8.1"],
            "tile 0's APOS body coded with one more binary event after its last: every word \
             is read, the state ends at 2^33, not 2^32 (StateNotFinal)",
            apos_extra_event(base),
        ),
        must_fail(
            "x-g-gatt-words-left",
            "AnsStreamInvalid",
            &["§3.5", "§6.2.6"],
            "tile 0's GATT body with a zero word appended, which its events never read \
             (WordsLeftOver)",
            tile0_body(base, ChunkTag::GATT, word),
        ),
        must_fail(
            "x-g-gatt-state",
            "AnsStreamInvalid",
            &["§3.5", "§6.2.6"],
            "tile 0's GATT body coded with one more binary event after its last: every word \
             is read, the state ends at 2^33, not 2^32 (StateNotFinal)",
            gatt_changed(base, None, true, true),
        ),
        must_fail(
            "x-g-escape-overflow",
            "EscapeOverflow",
            &["§3.5", "§6.4"],
            "tile 0's first Gaussian's opacity symbol is ESCAPE followed by 31 zero bits",
            gatt_changed(base, Some(opacity(31)), false, true),
        ),
        must_fail(
            "x-g-escape-prefix-30",
            "ValueInvalid",
            &["§3.5", "§6.4"],
            "tile 0's first Gaussian's opacity symbol escaped with a prefix of 30 zero bits \
             (the longest allowed): it decodes, then its coordinate passes 2^24",
            gatt_changed(base, Some(opacity(30)), false, false),
        ),
        must_fail(
            "x-g-coordinate-past-limit",
            "ValueInvalid",
            &["§3.5"],
            "tile 0's first Gaussian's opacity coordinate 2^24 + 1, one past the largest \
             allowed (valid vector g-coordinate-limit holds ±2^24)",
            past_limit,
        ),
    ]
}
