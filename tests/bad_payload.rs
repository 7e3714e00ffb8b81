//! Decoder errors inside payloads (spec §1.6, §2, §5, §6), and exhaustive truncation and
//! bit-flip sweeps that must never panic.

mod common;

use common::*;
use salvq::{decode, Error, Limits};
use salvq_bitstream::container::chunk::ChunkTag;
use salvq_bitstream::container::payload::{context_bytes, ContextPrecision, ScaffoldPrecision};
use salvq_bitstream::error::Field;

fn err(stream: &[u8]) -> Error {
    decode(stream)
        .and_then(salvq::Scene::try_into_anchors)
        .expect_err("stream must be rejected")
}

#[test]
fn padding_bits_set() {
    // GRID holds C bits per touched entry: find a scene whose count leaves padding bits.
    let (model, stream) = (14..40)
        .map(|n| {
            salvq_gen::generate(&salvq_gen::GenParams {
                feat_basis: false,
                ..salvq_gen::GenParams::small(n, 1)
            })
        })
        .find_map(|m| {
            let layout = salvq_bitstream::hyperprior::GridLayout::new(&m.dims, m.coord_bits());
            let touched =
                layout.touched(&m.anchors.voxel, m.dims.entries_3d(), m.dims.entries_2d());
            let bits: usize = touched
                .iter()
                .map(|t| t.iter().filter(|&&u| u).count())
                .sum::<usize>()
                * usize::from(m.dims.grid_channels);
            (bits % 8 != 0).then(|| {
                let s = salvq_encoder::encode(&m).unwrap();
                (m, s)
            })
        })
        .expect("a scene with padding bits");
    assert!(
        decode(&stream)
            .and_then(salvq::Scene::try_into_anchors)
            .is_ok(),
        "{} anchors",
        model.n()
    );
    let s = edit_payload(&stream, ChunkTag::GRID, |p| *p.last_mut().unwrap() |= 0x80);
    assert_eq!(
        err(&s),
        Error::PaddingBitsSet {
            tag: ChunkTag::GRID
        }
    );
}

/// The small stream's one tile cell: (level, cell) from its `TILS` (§10.1).
fn tile_cell() -> (u8, [u32; 3]) {
    let tils = chunks(&small_stream())
        .into_iter()
        .find(|(t, _)| *t == ChunkTag::TILS)
        .unwrap()
        .1;
    assert_eq!(u32::from_le_bytes([tils[1], tils[2], tils[3], tils[4]]), 1);
    let c = |at: usize| u32::from_le_bytes(tils[at..at + 4].try_into().unwrap());
    (tils[9], [c(10), c(14), c(18)])
}

/// `APOS` whose one tile's octree codes `voxels` (inside the tile's cell) instead of the
/// model's (§8, §10.2): the stream's other chunks are unchanged.
fn with_voxels(voxels: &[[u32; 3]]) -> Vec<u8> {
    let (level, cell) = tile_cell();
    let local: Vec<[u32; 3]> = voxels
        .iter()
        .map(|v| [0, 1, 2].map(|a| v[a] - (cell[a] << level)))
        .collect();
    let tables = salvq_bitstream::entropy::GaussianTables::standard();
    let body = salvq_encoder::writers::encode_geometry(&local, level, tables).unwrap();
    edit_payload(&small_stream(), ChunkTag::APOS, |p| {
        p.truncate(1);
        p.extend_from_slice(&(body.len() as u32).to_le_bytes());
        p.extend_from_slice(&body);
    })
}

#[test]
fn octree_with_more_cells_than_anchors() {
    // One more voxel than anchors (in a free cell): the leaf depth has N + 1 cells.
    let model = small_model();
    let n = model.anchors.voxel.len();
    let mut voxels = model.anchors.voxel.clone();
    let (level, cell) = tile_cell();
    let free = (0..1u32 << level)
        .map(|x| [(cell[0] << level) + x, cell[1] << level, cell[2] << level])
        .find(|v| !voxels.contains(v))
        .unwrap();
    voxels.push(free);
    voxels.sort_by_key(|v| salvq_bitstream::model::morton3(*v));
    match err(&with_voxels(&voxels)) {
        Error::OctreeInvalid {
            rule,
            count,
            anchors,
            ..
        } => {
            assert_eq!(rule, salvq_bitstream::geometry::MORE_NODES_THAN_ANCHORS);
            assert_eq!((count, anchors), (n as u64 + 1, n as u32));
        }
        e => panic!("{e:?}"),
    }
}

#[test]
fn octree_counts_that_do_not_add_up() {
    let model = small_model();
    let n = model.anchors.voxel.len() as u32;
    // A voxel repeated: the counts reach N + 1.
    let mut more = model.anchors.voxel.clone();
    more.insert(3, more[3]);
    match err(&with_voxels(&more)) {
        Error::OctreeInvalid { rule, anchors, .. } => {
            assert_eq!(rule, salvq_bitstream::geometry::COUNTS_ABOVE);
            assert_eq!(anchors, n);
        }
        e => panic!("{e:?}"),
    }
    // A voxel missing: N − 1 leaves of count 1.
    let mut fewer = model.anchors.voxel.clone();
    fewer.remove(5);
    assert_eq!(
        err(&with_voxels(&fewer)),
        Error::OctreeInvalid {
            rule: salvq_bitstream::geometry::COUNTS_BELOW,
            depth: tile_cell().0,
            count: u64::from(n) - 1,
            anchors: n
        }
    );
}

#[test]
fn non_finite_values() {
    // MLPS: method byte, `context_precision`, the integer context MLP, `scaffold_precision`,
    // then the Scaffold-GS MLPs, binary32 or binary16 (§1.6.2): an infinity in each.
    let d = small_model().dims;
    let stored = [
        (ScaffoldPrecision::F32, f32::INFINITY.to_le_bytes().to_vec()),
        (ScaffoldPrecision::F16, vec![0x00, 0x7c]),
    ];
    for (precision, infinity) in stored {
        let options = salvq_encoder::EncodeOptions {
            scaffold_precision: Some(precision),
            ..Default::default()
        };
        let stream = salvq_encoder::encode_with_options(&small_model(), &options).unwrap();
        let mlps = salvq_encoder::writers::surgery::chunks(&stream)
            .unwrap()
            .into_iter()
            .find(|(t, _)| *t == ChunkTag::MLPS)
            .unwrap()
            .1;
        let context = match mlps[1] {
            0 => ContextPrecision::I16,
            _ => ContextPrecision::I8,
        };
        let scaffold = (1 + context_bytes(&d, context)) as usize + 1;
        let w = infinity.len();
        let s = edit_payload(&stream, ChunkTag::MLPS, |p| {
            assert_eq!(p[scaffold - 1], precision.code(), "{precision:?}");
            p[scaffold + w..scaffold + 2 * w].copy_from_slice(&infinity);
        });
        assert_eq!(
            err(&s),
            Error::NonFiniteValue {
                tensor: "mlp_opacity.0.weight",
                index: vec![0, 1]
            },
            "{precision:?}"
        );
    }
    // origin.x is HEAD bytes 37..41.
    let s = edit_payload(&small_stream(), ChunkTag::HEAD, |p| {
        p[37..41].copy_from_slice(&f32::NAN.to_le_bytes());
    });
    assert_eq!(
        err(&s),
        Error::NonFiniteValue {
            tensor: "geometry.origin",
            index: vec![0]
        }
    );
}

#[test]
fn values_not_positive() {
    // QUAN: method byte, then quant.feat.step.
    let s = edit_payload(&small_stream(), ChunkTag::QUAN, |p| {
        p[1..5].copy_from_slice(&0f32.to_le_bytes());
    });
    assert!(matches!(
        err(&s),
        Error::ValueNotPositive {
            tensor: "quant.feat.step",
            ..
        }
    ));
    let s = edit_payload(&small_stream(), ChunkTag::QUAN, |p| {
        p[9..13].copy_from_slice(&(-1f32).to_le_bytes());
    });
    assert_eq!(
        err(&s),
        Error::ValueNotPositive {
            tensor: "quant.feat.gains",
            index: vec![1],
            value: -1.0
        }
    );
    // voxel_size is HEAD bytes 49..53.
    let s = edit_payload(&small_stream(), ChunkTag::HEAD, |p| {
        p[49..53].copy_from_slice(&0f32.to_le_bytes());
    });
    assert!(matches!(
        err(&s),
        Error::ValueNotPositive {
            tensor: "geometry.voxel_size",
            ..
        }
    ));
}

#[test]
fn corrupt_entropy_coded_words() {
    // A flipped bit inside AFEA's words (CRC recomputed): decoding goes astray and the end
    // checks of §6.2 catch it (or an escape overflows); never a panic.
    for byte in [5usize, 9, 17] {
        let s = edit_payload(&small_stream(), ChunkTag::AFEA, |p| {
            let at = byte.min(p.len() - 1);
            p[at] ^= 0x40
        });
        assert!(
            matches!(
                err(&s),
                Error::AnsStreamInvalid { .. } | Error::EscapeOverflow { .. }
            ),
            "byte {byte}: {}",
            err(&s)
        );
    }
    // The small stream has one tile: bytes 1..5 of a layer chunk are its body's length
    // (§10.2). Words dropped from the end with the length kept: the lengths no longer add up.
    let s = edit_payload(&small_stream(), ChunkTag::AOFF, |p| p.truncate(p.len() - 4));
    assert!(matches!(
        err(&s),
        Error::ChunkSizeMismatch {
            tag: ChunkTag::AOFF,
            ..
        }
    ));
    // With the length fixed too: the coder runs out or ends in the wrong state.
    let shorten = |p: &mut Vec<u8>, by: usize| {
        p.truncate(p.len() - by);
        let len = u32::from_le_bytes([p[1], p[2], p[3], p[4]]) - by as u32;
        p[1..5].copy_from_slice(&len.to_le_bytes());
    };
    let s = edit_payload(&small_stream(), ChunkTag::AOFF, |p| shorten(p, 4));
    assert!(matches!(
        err(&s),
        Error::AnsStreamInvalid {
            tag: ChunkTag::AOFF,
            ..
        }
    ));
    // A body that is not whole words.
    let s = edit_payload(&small_stream(), ChunkTag::ASCL, |p| shorten(p, 1));
    assert!(matches!(
        err(&s),
        Error::AnsStreamInvalid {
            tag: ChunkTag::ASCL,
            fault: salvq_bitstream::error::AnsFault::Framing
        }
    ));
}

/// `AMSK` is decoded alongside `GRID` where it follows it (the decoder looks ahead), but its
/// outcome still comes at its own position (§1.5): a broken `GRID` is reported before a
/// broken `AMSK`, an ancillary chunk between them changes nothing, and a damaged `AMSK`
/// frame is reported as the reader finds it.
#[test]
fn grid_and_mask_errors_come_in_stream_order() {
    let s = small_stream();
    let good = decode(&s)
        .and_then(salvq::Scene::try_into_anchors)
        .expect("valid");
    let bad_mask = |p: &mut Vec<u8>| p[1..3].fill(0);
    let mask_error = Error::ValueInvalid {
        tensor: "AMSK.p_one",
        index: vec![0],
        value: 0,
        allowed: "1..=65535",
    };
    assert_eq!(err(&edit_payload(&s, ChunkTag::AMSK, bad_mask)), mask_error);
    // GRID one byte short as well: GRID's error, not AMSK's.
    let grid_short = edit_payload(&s, ChunkTag::GRID, |p| {
        p.pop();
    });
    let grid_error = err(&grid_short);
    assert!(
        !matches!(grid_error, Error::ValueInvalid { .. }),
        "{grid_error}"
    );
    let both = edit_payload(&grid_short, ChunkTag::AMSK, bad_mask);
    assert_eq!(err(&both), grid_error);
    // An ancillary chunk between GRID and AMSK: the same decode, the same AMSK error.
    let with_ancillary = |stream: &[u8]| {
        let mut cs = chunks(stream);
        let at = cs.iter().position(|(t, _)| *t == ChunkTag::AMSK).unwrap();
        cs.insert(at, (ChunkTag::ENCD, b"between GRID and AMSK".to_vec()));
        assemble(stream, &cs)
    };
    assert_eq!(
        decode(&with_ancillary(&s))
            .and_then(salvq::Scene::try_into_anchors)
            .expect("valid"),
        good
    );
    let masked = edit_payload(&s, ChunkTag::AMSK, bad_mask);
    assert_eq!(err(&with_ancillary(&masked)), mask_error);
    // AMSK's CRC wrong: not looked ahead at, and reported as a CRC mismatch at its position.
    let mut crc_bad = s.clone();
    let cs = chunks(&s);
    let mut at = 12;
    for (tag, payload) in &cs {
        if *tag == ChunkTag::AMSK {
            let crc = at + 8 + payload.len();
            crc_bad[crc] ^= 1;
            break;
        }
        at += 12 + payload.len();
    }
    assert!(matches!(
        err(&crc_bad),
        Error::ChunkCrcMismatch {
            tag: ChunkTag::AMSK,
            ..
        }
    ));
}

#[test]
fn mlp_shift_out_of_range() {
    // MLPS: method byte, context_precision, then w0_frac_bits (§1.6.2).
    let s = edit_payload(&small_stream(), ChunkTag::MLPS, |p| p[2] = 31);
    assert!(matches!(
        err(&s),
        Error::FieldOutOfRange {
            field: Field::W0FracBits,
            value: 31,
            ..
        }
    ));
}

#[test]
fn context_precision_out_of_range_and_i8_weights_decode() {
    // context_precision is the body's first byte (§1.6.2 Table 1-7): 2 is undefined.
    let s = edit_payload(&small_stream(), ChunkTag::MLPS, |p| p[1] = 2);
    assert_eq!(
        err(&s),
        Error::FieldOutOfRange {
            field: Field::ContextPrecision,
            value: 2,
            min: 0,
            max: 1
        }
    );
    // Both storages decode to what the encoder predicts; i8 is the smaller.
    let m = small_model();
    let mut sizes = Vec::new();
    for p in [ContextPrecision::I16, ContextPrecision::I8] {
        let options = salvq_encoder::EncodeOptions {
            context_precision: Some(p),
            ..Default::default()
        };
        let e = salvq_encoder::encode_full(&m, &options).unwrap();
        assert_eq!(
            &decode(&e.stream)
                .and_then(salvq::Scene::try_into_anchors)
                .unwrap(),
            e.expected()
        );
        sizes.push(e.stream.len());
    }
    let d = &m.dims;
    let weights = d.context_input() * u64::from(d.context_hidden)
        + d.context_output() * u64::from(d.context_hidden);
    assert_eq!((sizes[0] - sizes[1]) as u64, weights);
}

#[test]
fn rate_mask_out_of_range() {
    // rate_mask is HEAD bytes 29..37; the small model has 2 rates, so only bits 0-1 exist.
    for mask in [0u64, 4, 1 << 63] {
        let s = edit_payload(&small_stream(), ChunkTag::HEAD, |p| {
            p[29..37].copy_from_slice(&mask.to_le_bytes())
        });
        assert_eq!(
            err(&s),
            Error::FieldOutOfRange {
                field: Field::RateMask,
                value: mask,
                min: 1,
                max: 3
            }
        );
    }
}

#[test]
fn lattice_codes_and_dimensions() {
    // feat_lattice is HEAD byte 13: code 4 is undefined.
    let s = edit_payload(&small_stream(), ChunkTag::HEAD, |p| p[13] = 4);
    assert_eq!(
        err(&s),
        Error::FieldOutOfRange {
            field: Field::FeatLattice,
            value: 4,
            min: 0,
            max: 3
        }
    );
    // scaling_lattice (byte 14) = E8 product on the 6 scaling dimensions.
    let s = edit_payload(&small_stream(), ChunkTag::HEAD, |p| p[14] = 2);
    assert!(matches!(
        err(&s),
        Error::LatticeDimension {
            field: Field::ScalingLattice,
            lattice: "e8",
            dim: 6,
            ..
        }
    ));
}

#[test]
fn every_truncation_is_an_error_not_a_panic() {
    let s = small_stream();
    for len in 0..s.len() {
        assert!(
            decode(&s[..len])
                .and_then(salvq::Scene::try_into_anchors)
                .is_err(),
            "prefix of {len} bytes decoded"
        );
    }
}

#[test]
fn every_single_bit_flip_is_rejected_without_panic() {
    let s = small_stream();
    let mut accepted = 0;
    for i in 0..s.len() * 8 {
        let mut t = s.clone();
        t[i / 8] ^= 1 << (i % 8);
        if salvq::Decoder::builder()
            .limits(Limits::tight())
            .build()
            .decode(&t)
            .and_then(salvq::Scene::try_into_anchors)
            .is_ok()
        {
            accepted += 1;
        }
    }
    // Every byte is covered by the signature checks, a CRC, or a length whose change breaks
    // framing; only flips of the case bit in an ancillary tag could pass, and there is none.
    assert_eq!(accepted, 0);
}
