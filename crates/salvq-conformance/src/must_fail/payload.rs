//! Must-fail vectors inside payloads: `MLPS`, `QUAN`, `TILS`, `APOS`, `GRID`, `AMSK` and the
//! layer chunks (§1.6, §6, §8, §10).

use super::{edit, encode, payload_of, small_scene, vector, MustFailVector};
use crate::reference_coder as reference;
use salvq::decode;
use salvq_bitstream::container::chunk::ChunkTag;
use salvq_bitstream::container::payload::{context_bytes, read_mlps, read_quan, ContextPrecision};
use salvq_bitstream::entropy::GaussianTables;
use salvq_bitstream::hyperprior::prior::{Group, Prior};
use salvq_bitstream::hyperprior::GridLayout;
use salvq_bitstream::model::morton3;
use salvq_encoder::EncodeOptions;

/// Bytes of one `TILS` entry (§10.1): count, cell level, cell, box.
const TILE_ENTRY: usize = 41;

/// Every must-fail vector inside a payload, in decoding order: `MLPS`, `QUAN`, `TILS`, `APOS`,
/// then `GRID`, `AMSK` and the layer chunks.
pub(super) fn payload_vectors(base: &[u8]) -> Vec<MustFailVector> {
    let mut out = mlps_vectors(base);
    out.extend(quan_vectors(base));
    out.extend(tile_vectors(base));
    out.extend(octree_vectors(base));
    out.extend(layer_vectors(base));
    out
}

/// An unknown coding method (§1.6), and `MLPS`'s vectors (§1.6.2): a weight not finite, the
/// precisions out of range or not matching the body.
fn mlps_vectors(base: &[u8]) -> Vec<MustFailVector> {
    let d = super::head_of(base).dims;
    // MLPS: method byte, `context_precision`, the integer context MLP (§1.6.2),
    // `scaffold_precision`, then the Scaffold-GS MLPs (binary32 in the base stream).
    let context = match payload_of(base, ChunkTag::MLPS).get(1) {
        Some(0) => ContextPrecision::I16,
        _ => ContextPrecision::I8,
    };
    let precision_at = (1 + context_bytes(&d, context)) as usize;
    let scaffold = precision_at + 1;
    vec![
        vector(
            "x-unknown-coding-method",
            "UnknownCodingMethod",
            &["§1.6"],
            "GRID coding_method = 7",
            edit(base, ChunkTag::GRID, |p| p[0] = 7),
        ),
        vector(
            "x-mlps-not-finite",
            "NonFiniteValue",
            &["§1.6.2"],
            "MLPS mlp_opacity.0.weight[0, 0] = +infinity",
            edit(base, ChunkTag::MLPS, |p| {
                p[scaffold..scaffold + 4].copy_from_slice(&f32::INFINITY.to_le_bytes())
            }),
        ),
        vector(
            "x-context-precision",
            "FieldOutOfRange",
            &["§1.6.2"],
            "MLPS context_precision = 2 (Table 1-7 defines 0 and 1)",
            edit(base, ChunkTag::MLPS, |p| p[1] = 2),
        ),
        vector(
            "x-scaffold-precision",
            "FieldOutOfRange",
            &["§1.6.2"],
            "MLPS scaffold_precision = 2 (Table 1-6 defines 0 and 1)",
            edit(base, ChunkTag::MLPS, |p| p[precision_at] = 2),
        ),
        vector(
            "x-scaffold-precision-length",
            "ChunkSizeMismatch",
            &["§1.6", "§1.6.2"],
            "MLPS scaffold_precision = 1 (binary16) with binary32 values: the body is too long",
            edit(base, ChunkTag::MLPS, |p| p[precision_at] = 1),
        ),
        vector(
            "x-scaffold-f16-not-finite",
            "NonFiniteValue",
            &["§1.6.2"],
            "MLPS in binary16 with mlp_opacity.0.weight[0, 0] = binary16 +infinity (0x7C00)",
            edit(base, ChunkTag::MLPS, |p| {
                let halves: Vec<u8> = p[scaffold..]
                    .chunks_exact(4)
                    .flat_map(|c| {
                        let v = f32::from_le_bytes([c[0], c[1], c[2], c[3]]);
                        half::f16::from_f32(v).to_le_bytes()
                    })
                    .collect();
                p.truncate(scaffold);
                p[precision_at] = 1;
                p.extend_from_slice(&halves);
                p[scaffold..scaffold + 2].copy_from_slice(&0x7C00u16.to_le_bytes());
            }),
        ),
    ]
}

/// `QUAN`'s vectors (§1.6.3, §2.6): a wrong length, a zero step, the order gains and steps
/// are checked in, a singular basis.
fn quan_vectors(base: &[u8]) -> Vec<MustFailVector> {
    let d = super::head_of(base).dims;
    let salvq = encode(&small_scene(13, true), &EncodeOptions::default());
    let rates = usize::from(d.rates);
    let f = usize::from(d.feat_dim);
    // QUAN of the SALVQ stream: method, feat step, M gains, basis_u (F x F), basis_s (F).
    let basis_s = 1 + 4 + 4 * rates + 4 * f * f;
    vec![
        vector(
            "x-quan-size-mismatch",
            "ChunkSizeMismatch",
            &["§1.6", "§1.6.3"],
            "QUAN payload one byte shorter than HEAD implies",
            edit(base, ChunkTag::QUAN, |p| {
                p.pop();
            }),
        ),
        vector(
            "x-quan-step-zero",
            "ValueNotPositive",
            &["§1.6.3"],
            "QUAN quant.feat.step = 0",
            edit(base, ChunkTag::QUAN, |p| {
                p[1..5].copy_from_slice(&0f32.to_le_bytes())
            }),
        ),
        vector(
            "x-quan-gain-zero-then-nan",
            "NonFiniteValue",
            &["§1.6.3"],
            "QUAN quant.feat.gains = [0, NaN]: the whole tensor's finiteness is checked before any sign",
            edit(base, ChunkTag::QUAN, |p| {
                p[5..9].copy_from_slice(&0f32.to_le_bytes());
                p[9..13].copy_from_slice(&f32::NAN.to_le_bytes());
            }),
        ),
        vector(
            "x-quan-step-zero-gain-nan",
            "ValueNotPositive",
            &["§1.6.3"],
            "QUAN quant.feat.step = 0 and gains[0] = NaN: the step is checked whole before the gains are read",
            edit(base, ChunkTag::QUAN, |p| {
                p[1..5].copy_from_slice(&0f32.to_le_bytes());
                p[5..9].copy_from_slice(&f32::NAN.to_le_bytes());
            }),
        ),
        vector(
            "x-basis-singular",
            "BasisSingular",
            &["§1.6.3", "§2.6"],
            "general feature lattice: QUAN quant.feat.basis_s[2] = 0",
            edit(&salvq, ChunkTag::QUAN, |p| {
                p[basis_s + 8..basis_s + 12].copy_from_slice(&0f32.to_le_bytes())
            }),
        ),
    ]
}

/// The tiles' vectors (§10.1, §10.2): a box not the smallest, tiles out of Morton order, tile
/// lengths cut short.
fn tile_vectors(base: &[u8]) -> Vec<MustFailVector> {
    vec![
        vector(
            "x-tile-box-mismatch",
            "TileBoxMismatch",
            &["§10.1"],
            "TILS: the one tile's stated max x is one more than its anchors' max x",
            edit(base, ChunkTag::TILS, |p| {
                let at = 5 + 17 + 12;
                let x = u32::from_le_bytes([p[at], p[at + 1], p[at + 2], p[at + 3]]) + 1;
                p[at..at + 4].copy_from_slice(&x.to_le_bytes());
            }),
        ),
        vector(
            "x-tile-order",
            "TileOrder",
            &["§10.1", "§1.6.4"],
            "tiled stream: tiles 0 and 1 swapped (TILS entries, APOS bodies), out of Morton order",
            swapped_tiles(),
        ),
        vector(
            "x-truncated-tile-lengths",
            "Truncated",
            &["§10.2"],
            "tiled stream: the APOS payload ends inside its last tile_bytes field",
            truncated_tile_lengths(),
        ),
    ]
}

/// `APOS`'s vectors (§8.2, §8.4, §6.2.6): octrees coding too many or too few voxels, a zero
/// top word.
fn octree_vectors(base: &[u8]) -> Vec<MustFailVector> {
    vec![
        vector(
            "x-octree-too-many-nodes",
            "OctreeInvalid",
            &["§8.2"],
            "APOS codes one voxel more than the tile's anchor count (N + 1 occupied leaves)",
            with_voxels(base, |v, cell, level| {
                let free = (0..1u32 << level)
                    .map(|x| [cell[0] + x, cell[1], cell[2]])
                    .find(|c| !v.contains(c))
                    .expect("a free voxel");
                v.push(free);
            }),
        ),
        vector(
            "x-octree-direct-too-many-nodes",
            "OctreeInvalid",
            &["§8.2", "§6.2.1"],
            "APOS codes one voxel more than the anchor count, the extra one last in Morton order and isolated: the bound is broken by a direct node's child, after its octants",
            {
                let stream = with_voxels(base, |v, cell, level| {
                    let corner = cell.map(|c| c + (1 << level) - 1);
                    assert!(!v.contains(&corner), "the cell's last voxel is free");
                    v.push(corner);
                });
                last_event_is_an_octant(&stream);
                stream
            },
        ),
        vector(
            "x-octree-counts-above",
            "OctreeInvalid",
            &["§8.4"],
            "APOS codes anchor 3's voxel twice: the voxel counts exceed the anchor count",
            with_voxels(base, |v, _, _| v.insert(3, v[3])),
        ),
        vector(
            "x-octree-counts-below",
            "OctreeInvalid",
            &["§8.4"],
            "APOS codes N − 1 anchors: the voxel counts fall short of the anchor count",
            with_voxels(base, |v, _, _| {
                v.remove(5);
            }),
        ),
        vector(
            "x-ans-zero-top-word-apos",
            "AnsStreamInvalid",
            &["§6.2.6", "§8.1"],
            "APOS: the tile body's state_high word is 0",
            edit(base, ChunkTag::APOS, |p| p[5..9].fill(0)),
        ),
    ]
}

/// `GRID`'s padding (§1.6.1), `AMSK` (§6.6.1) and the layer chunks' bodies (§6.2, §6.4,
/// §10.2, §10.3): ANS streams out of words or with a zero top word, tile lengths that do not
/// match, an escape too long.
fn layer_vectors(base: &[u8]) -> Vec<MustFailVector> {
    vec![
        vector(
            "x-padding-bits-set",
            "PaddingBitsSet",
            &["§1.6.1", "§0.3"],
            "GRID: the last padding bit of the touched-entry bits is 1",
            padding_stream(),
        ),
        vector(
            "x-amsk-p-one-zero",
            "ValueInvalid",
            &["§6.6.1"],
            "AMSK p_one[0] = 0",
            edit(base, ChunkTag::AMSK, |p| p[1..3].fill(0)),
        ),
        vector(
            "x-ans-out-of-words-afea",
            "AnsStreamInvalid",
            &["§6.2.4", "§6.2.6", "§6.6.2"],
            "AFEA: the tile body's last word dropped, tile_bytes adjusted: out of words",
            edit(base, ChunkTag::AFEA, |p| {
                p.truncate(p.len() - 4);
                let len = u32::from_le_bytes([p[1], p[2], p[3], p[4]]) - 4;
                p[1..5].copy_from_slice(&len.to_le_bytes());
            }),
        ),
        vector(
            "x-tile-lengths-mismatch",
            "ChunkSizeMismatch",
            &["§10.2"],
            "AFEA: tile_bytes 4 more than the body that follows",
            edit(base, ChunkTag::AFEA, |p| {
                let len = u32::from_le_bytes([p[1], p[2], p[3], p[4]]) + 4;
                p[1..5].copy_from_slice(&len.to_le_bytes());
            }),
        ),
        vector(
            "x-ans-lowest-tile-reported",
            "AnsStreamInvalid",
            &["§10.3", "§6.2.6"],
            "tiled stream: zero top word in tile 1's AOFF body and the last tile's AFEA body",
            lowest_tile_error(),
        ),
        vector(
            "x-escape-overflow",
            "EscapeOverflow",
            &["§6.4", "§6.6.2"],
            "AFEA: the first symbol is ESCAPE followed by 31 zero prefix bits",
            escape_overflow(base),
        ),
    ]
}

/// The stream with its one tile's `APOS` body re-coded from the model's voxels changed by
/// `f` (given the voxels, the tile cell's first voxel and its level), kept in Morton order.
fn with_voxels(base: &[u8], f: impl FnOnce(&mut Vec<[u32; 3]>, [u32; 3], u8)) -> Vec<u8> {
    let tils = payload_of(base, ChunkTag::TILS);
    assert_eq!(
        tils[1..5],
        1u32.to_le_bytes(),
        "the small stream has one tile"
    );
    let level = tils[9];
    let word = |at: usize| u32::from_le_bytes([tils[at], tils[at + 1], tils[at + 2], tils[at + 3]]);
    let cell = [word(10), word(14), word(18)].map(|c| c << level);
    let mut voxels = decode(base)
        .and_then(salvq::Scene::try_into_anchors)
        .expect("the base stream decodes")
        .anchors
        .voxel;
    f(&mut voxels, cell, level);
    voxels.sort_by_key(|v| morton3(*v));
    let local: Vec<[u32; 3]> = voxels
        .iter()
        .map(|v| [0, 1, 2].map(|a| v[a] - cell[a]))
        .collect();
    let body = salvq_encoder::writers::encode_geometry(&local, level, GaussianTables::standard())
        .expect("voxels inside the cell code");
    edit(base, ChunkTag::APOS, |p| {
        p.truncate(1);
        p.extend_from_slice(&(body.len() as u32).to_le_bytes());
        p.extend_from_slice(&body);
    })
}

/// A tiled stream (13 anchors, at most 4 per tile) and its tile count.
fn tiled() -> (Vec<u8>, usize) {
    let s = encode(
        &small_scene(13, false),
        &EncodeOptions {
            tile_anchors: 4,
            ..Default::default()
        },
    );
    let tils = payload_of(&s, ChunkTag::TILS);
    let nt = u32::from_le_bytes([tils[1], tils[2], tils[3], tils[4]]) as usize;
    assert!(nt >= 3, "{nt} tiles");
    (s, nt)
}

/// The tile bodies of a tiled chunk's payload (§10.2): `prefix` bytes, `nt` lengths, bodies.
fn split_tiles(p: &[u8], prefix: usize, nt: usize) -> Vec<Vec<u8>> {
    let mut at = prefix + 4 * nt;
    (0..nt)
        .map(|t| {
            let l = &p[prefix + 4 * t..prefix + 4 * t + 4];
            let len = u32::from_le_bytes([l[0], l[1], l[2], l[3]]) as usize;
            at += len;
            p[at - len..at].to_vec()
        })
        .collect()
}

/// A tiled chunk's payload from its `prefix` bytes and tile bodies (§10.2).
fn join_tiles(prefix: &[u8], bodies: &[Vec<u8>]) -> Vec<u8> {
    let mut out = prefix.to_vec();
    out.extend(bodies.iter().flat_map(|b| (b.len() as u32).to_le_bytes()));
    out.extend(bodies.concat());
    out
}

/// The tiled stream with tiles 0 and 1 swapped: their `TILS` entries and `APOS` bodies.
fn swapped_tiles() -> Vec<u8> {
    let (s, nt) = tiled();
    let s = edit(&s, ChunkTag::TILS, |p| {
        let first = p[5..5 + TILE_ENTRY].to_vec();
        p.copy_within(5 + TILE_ENTRY..5 + 2 * TILE_ENTRY, 5);
        p[5 + TILE_ENTRY..5 + 2 * TILE_ENTRY].copy_from_slice(&first);
    });
    edit(&s, ChunkTag::APOS, |p| {
        let mut bodies = split_tiles(p, 1, nt);
        bodies.swap(0, 1);
        *p = join_tiles(&p[..1], &bodies);
    })
}

/// The tiled stream with a zero top word (§6.2.6 step 2) in tile 1's `AOFF` body and in the
/// last tile's `AFEA` body: tile 1's error is the one reported (§10.3).
fn lowest_tile_error() -> Vec<u8> {
    let (s, nt) = tiled();
    let zero_top = |tile: usize| {
        move |p: &mut Vec<u8>| {
            let mut bodies = split_tiles(p, 1, nt);
            bodies[tile][..4].fill(0);
            *p = join_tiles(&p[..1], &bodies);
        }
    };
    let s = edit(&s, ChunkTag::AOFF, zero_top(1));
    edit(&s, ChunkTag::AFEA, zero_top(nt - 1))
}

/// The tiled stream with `APOS` cut inside its last tile length (§10.2).
fn truncated_tile_lengths() -> Vec<u8> {
    let (s, nt) = tiled();
    edit(&s, ChunkTag::APOS, |p| p.truncate(1 + 4 * nt - 2))
}

/// The first small scene (13 anchors and up) whose `GRID` bits leave padding in their last
/// byte (§1.6.1), encoded, with the last byte's top (padding) bit set.
fn padding_stream() -> Vec<u8> {
    let m = (13..64)
        .map(|n| small_scene(n, false))
        .find(|m| {
            let layout = GridLayout::new(&m.dims, m.coord_bits());
            let touched =
                layout.touched(&m.anchors.voxel, m.dims.entries_3d(), m.dims.entries_2d());
            let entries: usize = touched
                .iter()
                .map(|t| t.iter().filter(|&&u| u).count())
                .sum();
            !(entries * usize::from(m.dims.grid_channels)).is_multiple_of(8)
        })
        .expect("a small scene with padding bits");
    let s = encode(&m, &EncodeOptions::default());
    edit(&s, ChunkTag::GRID, |p| {
        *p.last_mut().expect("GRID has bits") |= 0x80
    })
}

/// `AFEA` whose first symbol (anchor 0, feature 0, §6.6.2) decodes as ESCAPE with a 31-bit
/// zero prefix (§6.4). Its scale index comes from the stream's own prior (§5.4).
fn escape_overflow(base: &[u8]) -> Vec<u8> {
    let head = super::head_of(base);
    let d = &head.dims;
    let (int_mlp, _) = read_mlps(&payload_of(base, ChunkTag::MLPS), d).expect("valid MLPS");
    let quant = read_quan(&payload_of(base, ChunkTag::QUAN), d).expect("valid QUAN");
    let model = decode(base)
        .and_then(salvq::Scene::try_into_anchors)
        .expect("the base stream decodes");
    let prior = Prior::new(
        d,
        head.coord_bits,
        int_mlp,
        [&quant[0], &quant[1], &quant[2]],
        0,
    );
    let mut ctx = prior.context();
    prior.eval(&model.grid, model.anchors.voxel[0], &mut ctx);
    let step = prior.step(&ctx.y, Group::Feature);
    let k = prior.scale_index(&ctx.y, Group::Feature, 0, &step);
    let tables = GaussianTables::standard();
    let t = tables.scale(k);
    let (c, e) = (t.cumulative(), t.escape_index());
    let half = 1u32 << (tables.precision() - 1);
    let mut enc = reference::Encoder::new(tables.precision());
    enc.push(c[e], c[e + 1] - c[e]);
    for _ in 0..31 {
        enc.push(0, half);
    }
    let body = enc.finish();
    edit(base, ChunkTag::AFEA, |p| {
        p.truncate(1);
        p.extend_from_slice(&(body.len() as u32).to_le_bytes());
        p.extend_from_slice(&body);
    })
}

/// Checks that the `APOS` body of a one-tile stream fails on a direct node's child: the last
/// event read before the error is a direct octant (§8.2), not an occupancy event.
fn last_event_is_an_octant(stream: &[u8]) {
    use salvq_bitstream::entropy::SymbolReader;
    use salvq_bitstream::geometry::{self, DirectOctant, Event, Events};
    struct Last<'a> {
        reader: SymbolReader<'a>,
        octant_last: bool,
    }
    impl Events for Last<'_> {
        fn bit(&mut self, freq_one: u32, _: Event) -> salvq::Result<bool> {
            self.octant_last = false;
            self.reader.bit(freq_one)
        }
        fn octant(&mut self, _: DirectOctant) -> salvq::Result<u32> {
            self.octant_last = true;
            self.reader.uniform(3)
        }
    }
    let tils = payload_of(stream, ChunkTag::TILS);
    let anchors = u32::from_le_bytes([tils[5], tils[6], tils[7], tils[8]]);
    let level = tils[9];
    let apos = payload_of(stream, ChunkTag::APOS);
    let tables = GaussianTables::standard();
    let mut last = Last {
        reader: SymbolReader::new(ChunkTag::APOS, &apos[5..], tables).expect("a framed body"),
        octant_last: false,
    };
    let err = geometry::walk(level, anchors, tables.precision(), &mut last)
        .expect_err("one voxel too many");
    assert!(
        matches!(err, salvq::Error::OctreeInvalid { rule, .. } if rule == geometry::MORE_NODES_THAN_ANCHORS),
        "{err}"
    );
    assert!(last.octant_last, "the bound broke on an occupancy event");
}
