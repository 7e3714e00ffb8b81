//! Tiles (spec §10): any number of threads gives the same model; a region decode is the
//! full decode's selected tiles; broken tile tables and tile framing are typed errors, and the
//! lowest tile's error is the one reported.

mod common;

use common::*;
use salvq::{decode, extract_rate, DecoderBuilder, Error, Limits};
use salvq_bitstream::container::chunk::ChunkTag;
use salvq_bitstream::error::Field;
use salvq_encoder::{encode_full, EncodeOptions};
use salvq_gen::{generate, GenParams};

fn model(n: u32) -> salvq::SceneModel {
    generate(&GenParams {
        feat_dim: 16,
        ..GenParams::small(n, 5)
    })
}

fn tiled(m: &salvq::SceneModel, per_tile: u32) -> salvq_encoder::Encoded {
    encode_full(
        m,
        &EncodeOptions {
            tile_anchors: per_tile,
            rates: vec![0, 1],
            ..Default::default()
        },
    )
    .unwrap()
}

fn with(threads: Option<usize>, region: Option<[f64; 6]>) -> DecoderBuilder {
    salvq::Decoder::builder()
        .threads(threads)
        .region(region.map(|r| salvq::RegionBox::from_array(r).unwrap()))
}

#[test]
fn every_thread_count_decodes_the_same_model() {
    let m = model(1000);
    let e = tiled(&m, 97);
    assert_eq!(
        &decode(&e.stream)
            .and_then(salvq::Scene::try_into_anchors)
            .unwrap(),
        e.expected()
    );
    for threads in [1, 2, 3, 8] {
        let d = (with(Some(threads), None))
            .build()
            .decode(&e.stream)
            .and_then(salvq::Scene::try_into_anchors)
            .unwrap();
        assert_eq!(&d, e.expected(), "{threads} threads");
    }
    // Extraction of a tiled multi-rate stream is still byte-identical.
    let alone = encode_full(
        &m,
        &EncodeOptions {
            tile_anchors: 97,
            rates: vec![1],
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(
        extract_rate(&e.stream, 1, &Limits::default()).unwrap(),
        alone.stream
    );
}

#[test]
fn a_region_decodes_the_intersecting_tiles_only() {
    let m = model(1200);
    let e = tiled(&m, 100);
    let full = e.expected();
    let tiles = salvq_encoder::writers::cut(&full.anchors.voxel, 100);
    let nt = tiles.len();
    assert!(nt >= 12, "{nt} tiles");
    assert!((0..nt).all(|t| tiles.range(t).len() <= 100));
    // A box inside tile `pick`'s box, in world coordinates.
    let pick = nt / 3;
    let b = tiles.boxes[pick];
    let vs = f64::from(full.voxel_size);
    let o = full.origin.map(f64::from);
    let region = [
        o[0] + f64::from(b[0]) * vs + 0.25 * vs,
        o[1] + f64::from(b[1]) * vs + 0.25 * vs,
        o[2] + f64::from(b[2]) * vs + 0.25 * vs,
        o[0] + f64::from(b[3]) * vs + 0.75 * vs,
        o[1] + f64::from(b[4]) * vs + 0.75 * vs,
        o[2] + f64::from(b[5]) * vs + 0.75 * vs,
    ];
    let selected = tiles.select(
        full.origin,
        full.voxel_size,
        Some(salvq::RegionBox::from_array(region).unwrap()),
        None,
    );
    assert!(selected[pick]);
    assert!(selected.iter().filter(|&&s| s).count() < nt / 2);
    let part = (with(Some(2), Some(region)))
        .build()
        .decode(&e.stream)
        .and_then(salvq::Scene::try_into_anchors)
        .unwrap();
    let kept: Vec<usize> = (0..nt)
        .filter(|&t| selected[t])
        .flat_map(|t| tiles.range(t))
        .collect();
    assert_eq!(part.dims.anchors as usize, kept.len());
    let (f, s, k) = (16, 6, usize::from(full.dims.offsets));
    for (j, &i) in kept.iter().enumerate() {
        assert_eq!(part.anchors.voxel[j], full.anchors.voxel[i]);
        assert_eq!(
            part.anchors.feat[j * f..(j + 1) * f],
            full.anchors.feat[i * f..(i + 1) * f]
        );
        assert_eq!(
            part.anchors.scaling[j * s..(j + 1) * s],
            full.anchors.scaling[i * s..(i + 1) * s]
        );
        assert_eq!(
            part.anchors.offsets[j * 3 * k..(j + 1) * 3 * k],
            full.anchors.offsets[i * 3 * k..(i + 1) * 3 * k]
        );
        assert_eq!(
            part.anchors.mask[j * k..(j + 1) * k],
            full.anchors.mask[i * k..(i + 1) * k]
        );
    }
    assert_eq!(part.grid, full.grid);
    // The partial model is a valid model file.
    let bytes = salvq_render::interchange::model_to_safetensors(&part);
    salvq_render::interchange::model_from_safetensors(&bytes).unwrap();
}

#[test]
fn the_parts_of_a_stream_are_its_tiles_once_each() {
    // §10.3.2: each part decodes as a region decode of its tiles; together they are the
    // full decode, every tile in exactly one part, and the parts about equal in anchors.
    let m = model(1200);
    let e = tiled(&m, 100);
    let full = e.expected();
    let tiles = salvq_encoder::writers::cut(&full.anchors.voxel, 100);
    let (f, k) = (16, usize::from(full.dims.offsets));
    for count in [1, 2, 3, 5] {
        let mut owner = vec![None; tiles.len()];
        let mut sizes = Vec::new();
        for index in 0..count {
            let part = salvq::TilePart::new(index, count).unwrap();
            let options = with(Some(2), None).part(Some(part));
            let d = options
                .build()
                .decode(&e.stream)
                .and_then(salvq::Scene::try_into_anchors)
                .unwrap();
            let mine = tiles.select(full.origin, full.voxel_size, None, Some(part));
            let rows: Vec<usize> = (0..tiles.len())
                .filter(|&t| mine[t])
                .inspect(|&t| {
                    assert_eq!(owner[t], None, "tile {t} in two parts");
                    owner[t] = Some(index);
                })
                .flat_map(|t| tiles.range(t))
                .collect();
            assert_eq!(d.anchors.voxel.len(), rows.len());
            for (j, &i) in rows.iter().enumerate() {
                assert_eq!(d.anchors.voxel[j], full.anchors.voxel[i]);
                assert_eq!(
                    d.anchors.feat[j * f..][..f],
                    full.anchors.feat[i * f..][..f]
                );
                assert_eq!(
                    d.anchors.offsets[j * 3 * k..][..3 * k],
                    full.anchors.offsets[i * 3 * k..][..3 * k]
                );
            }
            assert_eq!(d.grid, full.grid);
            sizes.push(rows.len());
        }
        assert!(
            owner.iter().all(Option::is_some),
            "{count} parts miss a tile"
        );
        let (lo, hi) = (sizes.iter().min().unwrap(), sizes.iter().max().unwrap());
        assert!(hi - lo <= 100, "{count} parts: {sizes:?}");
    }
}

/// 900 anchors with three spatial feature regions (§7.6), in tiles of 100.
fn three_regions_in_tiles_of_100() -> salvq_encoder::Encoded {
    encode_full(
        &model(900),
        &EncodeOptions {
            fit_basis: true,
            feat_regions: 3,
            tile_anchors: 100,
            ..Default::default()
        },
    )
    .unwrap()
}

#[test]
fn region_decodes_rebase_spatial_quantizer_regions() {
    let e = three_regions_in_tiles_of_100();
    let full = e.expected();
    let tiles = salvq_encoder::writers::cut(&full.anchors.voxel, 100);
    // Tiles 2 and 3 (anchors 200..400) straddle region boundary 300.
    let b2 = tiles.boxes[2];
    let vs = f64::from(full.voxel_size);
    let o = full.origin.map(f64::from);
    let region = [0, 1, 2, 3, 4, 5].map(|c| o[c % 3] + (f64::from(b2[c]) + 0.5) * vs);
    let part = (with(None, Some(region)))
        .build()
        .decode(&e.stream)
        .and_then(salvq::Scene::try_into_anchors)
        .unwrap();
    let bytes = salvq_render::interchange::model_to_safetensors(&part);
    let back = salvq_render::interchange::model_from_safetensors(&bytes).unwrap();
    assert_eq!(back, part);
    assert!(part.dims.anchors < 900);
}

#[test]
fn a_region_meeting_no_tile_outputs_no_anchors_and_keeps_region_0() {
    let e = three_regions_in_tiles_of_100();
    let full = e.expected();
    let far = full.origin.map(|x| f64::from(x) - 1.0e3);
    let part = (with(None, Some([far[0], far[1], far[2], far[0], far[1], far[2]])))
        .build()
        .decode(&e.stream)
        .and_then(salvq::Scene::try_into_anchors)
        .unwrap();
    // §10.3.1 step 6: no anchors, every shared tensor; step 5: region 0 kept alone.
    assert_eq!(part.dims.anchors, 0);
    assert!(part.anchors.voxel.is_empty() && part.anchors.feat.is_empty());
    assert_eq!(part.dims.feat_regions, 1);
    assert!(part.quant_feat.regions.is_empty());
    assert_eq!(part.quant_feat.basis, full.quant_feat.basis);
    assert_eq!(part.grid, full.grid);
}

#[test]
fn region_boxes_refuse_nan_and_inverted_axes() {
    use salvq::RegionBox;
    assert!(RegionBox::from_array([0.0, 0.0, 0.0, 1.0, 1.0, 1.0]).is_ok());
    // A point and infinite bounds are boxes.
    assert!(RegionBox::from_array([1.0, 1.0, 1.0, 1.0, 1.0, 1.0]).is_ok());
    let inf = f64::INFINITY;
    assert!(RegionBox::from_array([-inf, -inf, -inf, inf, inf, inf]).is_ok());
    let e = RegionBox::from_array([0.0, 2.0, 0.0, 1.0, 1.0, 1.0]).unwrap_err();
    assert_eq!((e.axis, e.min, e.max), (1, 2.0, 1.0));
    assert!(e.to_string().contains("y axis") && e.to_string().contains("§10.3.1"));
    let e = RegionBox::from_array([0.0, 0.0, f64::NAN, 1.0, 1.0, 1.0]).unwrap_err();
    assert_eq!(e.axis, 2);
}

/// TILS entries: count (4), cell level (1), cell (12), box (24), after method and T.
const ENTRY: usize = 41;

fn tils_of(stream: &[u8]) -> Vec<u8> {
    chunks(stream)
        .into_iter()
        .find(|(t, _)| *t == ChunkTag::TILS)
        .unwrap()
        .1
}

/// Where tile `t`'s TILS entry, its anchor count first, starts (after method and T).
fn count_at(t: usize) -> usize {
    5 + ENTRY * t
}

#[test]
fn broken_tile_tables_are_typed_errors() {
    let m = model(500);
    let e = tiled(&m, 100);
    let s = &e.stream;
    let tils = tils_of(s);
    let nt = u32::from_le_bytes([tils[1], tils[2], tils[3], tils[4]]) as usize;
    assert!(nt >= 3);
    let count0 = u32::from_le_bytes(tils[5..9].try_into().unwrap());
    broken_tile_count(s);
    broken_tile_anchor_counts(s, nt, count0);
    broken_tile_cells(s, e.expected().coord_bits());
    // A box that is not its anchors'.
    let bad = edit_payload(s, ChunkTag::TILS, |p| p[count_at(2) + 17] ^= 1);
    assert!(matches!(
        decode(&bad)
            .and_then(salvq::Scene::try_into_anchors)
            .unwrap_err(),
        Error::TileBoxMismatch { tile: 2, .. }
    ));
    // Tile lengths that do not add up to the chunk.
    let bad = edit_payload(s, ChunkTag::AFEA, |p| {
        let l = u32::from_le_bytes([p[5], p[6], p[7], p[8]]) + 4;
        p[5..9].copy_from_slice(&l.to_le_bytes());
    });
    assert!(matches!(
        decode(&bad)
            .and_then(salvq::Scene::try_into_anchors)
            .unwrap_err(),
        Error::ChunkSizeMismatch {
            tag: ChunkTag::AFEA,
            ..
        }
    ));
}

/// A TILS tile count T of 0 or above N (= 500 anchors in `s`) is out of its range.
fn broken_tile_count(s: &[u8]) {
    let bad = edit_payload(s, ChunkTag::TILS, |p| {
        p[1..5].copy_from_slice(&0u32.to_le_bytes())
    });
    assert_eq!(
        decode(&bad)
            .and_then(salvq::Scene::try_into_anchors)
            .unwrap_err(),
        Error::FieldOutOfRange {
            field: Field::TileCount,
            value: 0,
            min: 1,
            max: 500
        }
    );
    let bad = edit_payload(s, ChunkTag::TILS, |p| {
        p[1..5].copy_from_slice(&501u32.to_le_bytes())
    });
    assert!(matches!(
        decode(&bad)
            .and_then(salvq::Scene::try_into_anchors)
            .unwrap_err(),
        Error::FieldOutOfRange {
            field: Field::TileCount,
            ..
        }
    ));
}

/// Tile anchor counts that do not share out N (= 500 in `s`, `nt` tiles, tile 0 with
/// `count0`) are out of their range.
fn broken_tile_anchor_counts(s: &[u8], nt: usize, count0: u32) {
    // Counts: tile 0 taking every anchor leaves none for the others; counts that fall
    // short of N at the last tile.
    let bad = edit_payload(s, ChunkTag::TILS, |p| {
        p[count_at(0)..count_at(0) + 4].copy_from_slice(&500u32.to_le_bytes())
    });
    assert_eq!(
        decode(&bad)
            .and_then(salvq::Scene::try_into_anchors)
            .unwrap_err(),
        Error::FieldOutOfRange {
            field: Field::TileAnchors,
            value: 500,
            min: 1,
            max: 500 - (nt as u64 - 1)
        }
    );
    let bad = edit_payload(s, ChunkTag::TILS, |p| {
        p[count_at(0)..count_at(0) + 4].copy_from_slice(&(count0 - 1).to_le_bytes())
    });
    assert!(matches!(
        decode(&bad)
            .and_then(salvq::Scene::try_into_anchors)
            .unwrap_err(),
        Error::FieldOutOfRange {
            field: Field::TileAnchors,
            ..
        }
    ));
}

/// A tile's cell level above `coord_bits` (`bits`), and a cell outside the cube, are out of
/// their ranges.
fn broken_tile_cells(s: &[u8], bits: u8) {
    let bad = edit_payload(s, ChunkTag::TILS, |p| p[count_at(0) + 4] = bits + 1);
    assert!(matches!(
        decode(&bad)
            .and_then(salvq::Scene::try_into_anchors)
            .unwrap_err(),
        Error::FieldOutOfRange {
            field: Field::TileCellLevel,
            ..
        }
    ));
    let bad = edit_payload(s, ChunkTag::TILS, |p| {
        let at = count_at(0) + 5;
        p[at..at + 4].copy_from_slice(&(1u32 << bits).to_le_bytes())
    });
    assert!(matches!(
        decode(&bad)
            .and_then(salvq::Scene::try_into_anchors)
            .unwrap_err(),
        Error::FieldOutOfRange {
            field: Field::TileCell,
            ..
        }
    ));
}

/// Tiles 0 and 1 swapped (their TILS entries and APOS bodies): each decodes, but tile 1's
/// voxels now precede tile 0's.
#[test]
fn tiles_out_of_order_are_refused() {
    let m = model(300);
    let e = tiled(&m, 100);
    let tils = tils_of(&e.stream);
    let nt = u32::from_le_bytes([tils[1], tils[2], tils[3], tils[4]]) as usize;
    assert!(nt >= 2);
    let bad = edit_payload(&e.stream, ChunkTag::TILS, |p| {
        let (a, b) = (
            p[5..5 + ENTRY].to_vec(),
            p[5 + ENTRY..5 + 2 * ENTRY].to_vec(),
        );
        p[5..5 + ENTRY].copy_from_slice(&b);
        p[5 + ENTRY..5 + 2 * ENTRY].copy_from_slice(&a);
    });
    let bad = edit_payload(&bad, ChunkTag::APOS, |p| {
        let lens: Vec<usize> = (0..nt)
            .map(|t| u32::from_le_bytes(p[1 + 4 * t..5 + 4 * t].try_into().unwrap()) as usize)
            .collect();
        let base = 1 + 4 * nt;
        let mut bodies: Vec<Vec<u8>> = (0..nt)
            .map(|t| {
                let a = base + lens[..t].iter().sum::<usize>();
                p[a..a + lens[t]].to_vec()
            })
            .collect();
        bodies.swap(0, 1);
        let mut out = p[..1].to_vec();
        for b in &bodies {
            out.extend_from_slice(&(b.len() as u32).to_le_bytes());
        }
        for b in &bodies {
            out.extend_from_slice(b);
        }
        *p = out;
    });
    assert_eq!(
        decode(&bad)
            .and_then(salvq::Scene::try_into_anchors)
            .unwrap_err(),
        Error::TileOrder { tile: 1 }
    );
}

#[test]
fn the_lowest_tile_error_is_reported() {
    let m = model(500);
    let e = tiled(&m, 100);
    // Zero the top word of tile 1's AOFF body and of tile 3's AFEA body: tile 1 comes first.
    let tils = chunks(&e.stream)
        .into_iter()
        .find(|(t, _)| *t == ChunkTag::TILS)
        .unwrap()
        .1;
    let nt = u32::from_le_bytes([tils[1], tils[2], tils[3], tils[4]]) as usize;
    assert!(nt > 3);
    let zero_top = |p: &mut Vec<u8>, tile: usize| {
        let lens: Vec<usize> = (0..nt)
            .map(|t| {
                u32::from_le_bytes([p[1 + 4 * t], p[2 + 4 * t], p[3 + 4 * t], p[4 + 4 * t]])
                    as usize
            })
            .collect();
        let at = 1 + 4 * nt + lens[..tile].iter().sum::<usize>();
        p[at..at + 4].copy_from_slice(&[0; 4]);
    };
    let bad = edit_payload(&e.stream, ChunkTag::AOFF, |p| zero_top(p, 1));
    let bad = edit_payload(&bad, ChunkTag::AFEA, |p| zero_top(p, 3));
    for threads in [1, 4] {
        assert_eq!(
            (with(Some(threads), None))
                .build()
                .decode(&bad)
                .and_then(salvq::Scene::try_into_anchors)
                .unwrap_err(),
            Error::AnsStreamInvalid {
                tag: ChunkTag::AOFF,
                fault: salvq_bitstream::error::AnsFault::ZeroTopWord
            }
        );
    }
}

/// Tiles are decoded largest first, but errors are still reported by tile order: with every
/// later tile of `AFEA` broken too, tile 1's fault is the one reported.
#[test]
fn the_lowest_tile_error_is_reported_whichever_tile_runs_first() {
    let m = model(700);
    let e = tiled(&m, 100);
    let tils = tils_of(&e.stream);
    let nt = u32::from_le_bytes([tils[1], tils[2], tils[3], tils[4]]) as usize;
    assert!(nt > 4, "{nt} tiles");
    let starts = |p: &[u8]| tile_body_starts(p, nt);
    // Tiles 2.. get a state the encoder never ends on; tile 1 gets a zero top word.
    let later = edit_payload(&e.stream, ChunkTag::AFEA, |p| {
        for &at in &starts(p)[2..] {
            p[at..at + 8].copy_from_slice(&[0xA5; 8]);
        }
    });
    let both = edit_payload(&later, ChunkTag::AFEA, |p| {
        let at = starts(p)[1];
        p[at..at + 4].copy_from_slice(&[0; 4]);
    });
    let zero_top = Error::AnsStreamInvalid {
        tag: ChunkTag::AFEA,
        fault: salvq_bitstream::error::AnsFault::ZeroTopWord,
    };
    for threads in [1, 2, 4] {
        let options = with(Some(threads), None);
        let other = options
            .build()
            .decode(&later)
            .and_then(salvq::Scene::try_into_anchors)
            .unwrap_err();
        assert_ne!(other, zero_top, "tiles 2.. alone must fail otherwise");
        assert_eq!(
            options
                .build()
                .decode(&both)
                .and_then(salvq::Scene::try_into_anchors)
                .unwrap_err(),
            zero_top
        );
    }
}

/// The encoder's default tile size (§10, informative): a scene below 8 · 16 384 anchors gets
/// about 8 tiles of at least 2 048, so that it decodes on several threads; one of at most
/// 2 048 stays whole, and a large one keeps tiles of at most 16 384.
#[test]
fn the_default_tiles_split_a_small_scene_but_not_a_tiny_one() {
    use salvq_encoder::writers::tile_cut::{
        auto_tile_anchors, DEFAULT_TILE_ANCHORS, MIN_AUTO_TILE_ANCHORS,
    };
    assert_eq!(auto_tile_anchors(0), MIN_AUTO_TILE_ANCHORS);
    assert_eq!(auto_tile_anchors(4_721), MIN_AUTO_TILE_ANCHORS);
    assert_eq!(auto_tile_anchors(22_589), 2_824);
    assert_eq!(auto_tile_anchors(8 * 16_384), DEFAULT_TILE_ANCHORS);
    assert_eq!(auto_tile_anchors(usize::MAX), DEFAULT_TILE_ANCHORS);
    let tiles_of = |n: u32| {
        let e = encode_full(&model(n), &EncodeOptions::default()).unwrap();
        salvq_encoder::info::inspect(&e.stream, &Limits::default())
            .unwrap()
            .tiles
            .unwrap()
    };
    let tiny = tiles_of(2_000);
    assert_eq!(tiny.count, 1);
    let small = tiles_of(6_000);
    assert!(small.count >= 3, "{small:?}");
    assert!(small.max_anchors <= MIN_AUTO_TILE_ANCHORS, "{small:?}");
}
