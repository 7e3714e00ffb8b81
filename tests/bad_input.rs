//! Every decoder error class of the container (spec §1, §9.2), each from a stream broken in
//! exactly one way (payload-level errors and the panic sweeps are in `bad_payload.rs`).

mod common;

use common::*;
use salvq::{decode, Error, Limits};
use salvq_bitstream::container::chunk::ChunkTag;
use salvq_bitstream::error::{Field, Structure};
use salvq_bitstream::limits::LimitKind;

fn err(stream: &[u8]) -> Error {
    decode(stream)
        .and_then(salvq::Scene::try_into_anchors)
        .expect_err("stream must be rejected")
}

#[test]
fn valid_stream_decodes() {
    assert_eq!(
        decode(&small_stream())
            .and_then(salvq::Scene::try_into_anchors)
            .unwrap(),
        small_expected()
    );
}

#[test]
fn signature_mismatch() {
    let mut s = small_stream();
    s[1] = b'P';
    assert!(matches!(err(&s), Error::SignatureMismatch { .. }));
    assert!(matches!(err(b"GIF89a"), Error::SignatureMismatch { .. }));
}

#[test]
fn truncated_signature_chunk_header_and_crc() {
    let s = small_stream();
    assert!(matches!(
        err(&s[..5]),
        Error::Truncated {
            structure: Structure::Signature,
            needed: 12,
            available: 5
        }
    ));
    // Cut at a chunk boundary: the stream ends before SEND.
    let send = chunk_offset(&s, ChunkTag::SEND);
    assert!(matches!(
        err(&s[..send]),
        Error::Truncated {
            structure: Structure::ChunkHeader,
            ..
        }
    ));
    // Cut inside a chunk header.
    assert!(matches!(
        err(&s[..send + 3]),
        Error::Truncated {
            structure: Structure::ChunkHeader,
            needed: 8,
            available: 3
        }
    ));
    // Cut inside the CRC of SEND.
    assert!(matches!(
        err(&s[..s.len() - 2]),
        Error::Truncated {
            structure: Structure::ChunkCrc,
            needed: 4,
            available: 2
        }
    ));
}

#[test]
fn truncated_head_payload() {
    let s = edit_payload(&small_stream(), ChunkTag::HEAD, |p| p.truncate(20));
    assert!(matches!(
        err(&s),
        Error::Truncated {
            structure: Structure::Payload(ChunkTag::HEAD),
            ..
        }
    ));
}

#[test]
fn unsupported_major_version() {
    let mut s = small_stream();
    s[8] = 1;
    assert_eq!(
        err(&s),
        Error::UnsupportedMajorVersion {
            found: 1,
            supported: 0
        }
    );
}

#[test]
fn unsupported_minor_version_in_draft_series() {
    let current = salvq_bitstream::container::FORMAT_MINOR;
    for minor in [current - 1, current + 1] {
        let mut s = small_stream();
        s[9] = minor;
        assert_eq!(
            err(&s),
            Error::UnsupportedMinorVersion {
                major: 0,
                found: minor,
                supported: salvq_bitstream::container::FORMAT_MINOR
            }
        );
    }
}

#[test]
fn reserved_file_flag() {
    let mut s = small_stream();
    s[11] = 0x80;
    assert_eq!(
        err(&s),
        Error::ReservedBitsSet {
            field: Field::FileFlags,
            value: 0x8000
        }
    );
}

#[test]
fn reserved_head_flag() {
    // head_flags is byte 12 of the HEAD payload (Table 1-4).
    let s = edit_payload(&small_stream(), ChunkTag::HEAD, |p| p[12] |= 0x80);
    assert!(matches!(
        err(&s),
        Error::ReservedBitsSet {
            field: Field::HeadFlags,
            ..
        }
    ));
}

#[test]
fn flipped_bit_is_a_crc_mismatch() {
    let mut s = small_stream();
    let at = chunk_offset(&s, ChunkTag::AFEA) + 8 + 5;
    s[at] ^= 0x10;
    assert!(matches!(
        err(&s),
        Error::ChunkCrcMismatch {
            tag: ChunkTag::AFEA,
            ..
        }
    ));
}

#[test]
fn flipped_case_bit_of_a_tag_is_caught_by_the_crc() {
    // `AFEA` -> `aFEA` would be an ancillary chunk; the CRC covers the tag, so it is caught.
    let mut s = small_stream();
    let at = chunk_offset(&s, ChunkTag::AFEA) + 4;
    s[at] ^= 0x20;
    assert!(matches!(err(&s), Error::ChunkCrcMismatch { .. }));
}

#[test]
fn chunk_length_past_end() {
    let mut s = small_stream();
    let at = chunk_offset(&s, ChunkTag::AOFF);
    s[at..at + 4].copy_from_slice(&1_000_000u32.to_le_bytes());
    assert!(matches!(
        err(&s),
        Error::ChunkLengthPastEnd {
            tag: ChunkTag::AOFF,
            length: 1_000_000,
            ..
        }
    ));
}

#[test]
fn chunk_tag_invalid() {
    let mut s = small_stream();
    let at = chunk_offset(&s, ChunkTag::GRID) + 4 + 1;
    s[at] = b'#';
    assert_eq!(err(&s), Error::ChunkTagInvalid { tag: *b"G#ID" });
}

#[test]
fn unknown_critical_chunk() {
    let s = small_stream();
    let mut cs = chunks(&s);
    cs.insert(1, (ChunkTag(*b"ABCD"), vec![1, 2, 3]));
    assert_eq!(
        err(&assemble(&s, &cs)),
        Error::UnknownCriticalChunk {
            tag: ChunkTag(*b"ABCD")
        }
    );
}

#[test]
fn unknown_critical_chunk_first_is_unknown_not_out_of_order() {
    // §1.5 rule 0 comes before rule 1.
    let s = small_stream();
    let mut cs = chunks(&s);
    cs.insert(0, (ChunkTag(*b"XXXX"), vec![]));
    assert_eq!(
        err(&assemble(&s, &cs)),
        Error::UnknownCriticalChunk {
            tag: ChunkTag(*b"XXXX")
        }
    );
}

#[test]
fn unknown_ancillary_chunks_are_skipped() {
    let s = small_stream();
    let mut cs = chunks(&s);
    cs.insert(1, (ChunkTag(*b"abcd"), vec![0xff; 100]));
    cs.insert(5, (ChunkTag(*b"zz99"), vec![]));
    cs.insert(cs.len() - 1, (ChunkTag::ENCD, b"hello".to_vec()));
    assert_eq!(
        decode(&assemble(&s, &cs))
            .and_then(salvq::Scene::try_into_anchors)
            .unwrap(),
        small_expected()
    );
}

#[test]
fn chunk_order() {
    let s = small_stream();
    let mut cs = chunks(&s);
    cs.swap(1, 2); // QUAN before MLPS
    assert_eq!(
        err(&assemble(&s, &cs)),
        Error::ChunkOrder {
            found: ChunkTag::QUAN,
            expected: ChunkTag::MLPS
        }
    );
    let mut cs = chunks(&s);
    let mlps = cs[1].clone();
    cs.insert(2, mlps); // MLPS twice
    assert_eq!(
        err(&assemble(&s, &cs)),
        Error::ChunkOrder {
            found: ChunkTag::MLPS,
            expected: ChunkTag::QUAN
        }
    );
    let mut cs = chunks(&s);
    cs.insert(0, (ChunkTag::ENCD, b"too early".to_vec())); // ancillary before HEAD
    assert_eq!(
        err(&assemble(&s, &cs)),
        Error::ChunkOrder {
            found: ChunkTag::ENCD,
            expected: ChunkTag::HEAD
        }
    );
}

#[test]
fn trailing_data() {
    let mut s = small_stream();
    s.extend_from_slice(b"junk");
    assert_eq!(err(&s), Error::TrailingData { bytes: 4 });
}

#[test]
fn chunk_size_mismatch() {
    let s = edit_payload(&small_stream(), ChunkTag::QUAN, |p| {
        p.pop();
    });
    assert!(matches!(
        err(&s),
        Error::ChunkSizeMismatch {
            tag: ChunkTag::QUAN,
            ..
        }
    ));
    let s = edit_payload(&small_stream(), ChunkTag::SEND, |p| p.push(0));
    assert_eq!(
        err(&s),
        Error::ChunkSizeMismatch {
            tag: ChunkTag::SEND,
            expected: 0,
            found: 1
        }
    );
    let s = edit_payload(&small_stream(), ChunkTag::HEAD, |p| p.push(0));
    assert!(matches!(
        err(&s),
        Error::ChunkSizeMismatch {
            tag: ChunkTag::HEAD,
            ..
        }
    ));
}

#[test]
fn unknown_coding_method() {
    let s = edit_payload(&small_stream(), ChunkTag::GRID, |p| p[0] = 7);
    assert_eq!(
        err(&s),
        Error::UnknownCodingMethod {
            tag: ChunkTag::GRID,
            method: 7
        }
    );
}

#[test]
fn field_out_of_range() {
    // feat_dim (HEAD bytes 4..6) = 0.
    let s = edit_payload(&small_stream(), ChunkTag::HEAD, |p| {
        p[4..6].copy_from_slice(&0u16.to_le_bytes())
    });
    assert_eq!(
        err(&s),
        Error::FieldOutOfRange {
            field: Field::FeatDim,
            value: 0,
            min: 1,
            max: 1024
        }
    );
    // coord_bits (HEAD byte 11) = 22.
    let s = edit_payload(&small_stream(), ChunkTag::HEAD, |p| p[11] = 22);
    assert!(matches!(
        err(&s),
        Error::FieldOutOfRange {
            field: Field::CoordBits,
            value: 22,
            ..
        }
    ));
}

#[test]
fn decoded_size_mismatch() {
    let s = edit_payload(&small_stream(), ChunkTag::HEAD, |p| {
        let n = p.len();
        p[n - 8] ^= 1;
    });
    assert!(matches!(err(&s), Error::DecodedSizeMismatch { .. }));
}

#[test]
fn anchor_count_over_limits() {
    let limits = Limits::default().with_max_anchors(12);
    assert_eq!(
        salvq::Decoder::builder()
            .limits(limits)
            .build()
            .decode(&small_stream())
            .and_then(salvq::Scene::try_into_anchors)
            .unwrap_err(),
        Error::LimitExceeded {
            limit: LimitKind::Anchors,
            requested: 13,
            allowed: 12
        }
    );
}

#[test]
fn huge_anchor_count_is_refused_before_allocating() {
    // A HEAD claiming 4 billion anchors with a consistent decoded size: the limit check
    // fires from the preflight alone, long before any payload is read.
    let s = small_stream();
    let model = small_model();
    let mut dims = model.dims.clone();
    dims.anchors = u32::MAX;
    let stated = salvq_bitstream::model::decoded_bytes(&dims);
    let s = edit_payload(&s, ChunkTag::HEAD, |p| {
        p[0..4].copy_from_slice(&u32::MAX.to_le_bytes());
        let n = p.len();
        p[n - 8..].copy_from_slice(&stated.to_le_bytes());
    });
    assert!(matches!(
        decode(&s)
            .and_then(salvq::Scene::try_into_anchors)
            .unwrap_err(),
        Error::LimitExceeded {
            limit: LimitKind::Anchors,
            ..
        }
    ));
    let limits = Limits::default().with_max_anchors(u64::MAX);
    assert!(matches!(
        salvq::Decoder::builder()
            .limits(limits)
            .build()
            .decode(&s)
            .and_then(salvq::Scene::try_into_anchors)
            .unwrap_err(),
        Error::LimitExceeded {
            limit: LimitKind::AllocationBytes,
            ..
        }
    ));
}

#[test]
fn chunk_over_limit() {
    let limits = Limits::default().with_max_chunk_bytes(16);
    assert!(matches!(
        salvq::Decoder::builder()
            .limits(limits)
            .build()
            .decode(&small_stream())
            .and_then(salvq::Scene::try_into_anchors)
            .unwrap_err(),
        Error::LimitExceeded {
            limit: LimitKind::ChunkBytes,
            allowed: 16,
            ..
        }
    ));
}

#[test]
fn display_names_rule_and_section() {
    let e = Error::ChunkCrcMismatch {
        tag: ChunkTag::AFEA,
        stored: 0x1234abcd,
        computed: 0x0badf00d,
    };
    assert_eq!(
        e.to_string(),
        "chunk AFEA: CRC-32C mismatch (stored 0x1234abcd, computed 0x0badf00d) [§1.3]"
    );
    assert_eq!(e.class(), "ChunkCrcMismatch");
}

/// §1.4 step 4 checks `coord_bits` before the lattice codes and their fit: a HEAD with both
/// broken reports `coord_bits`, the class every decoder written from the spec alone reports
/// (the Python decoder found the order).
#[test]
fn head_checks_follow_the_spec_order() {
    use salvq_bitstream::error::Field;
    let s = small_stream();
    for scaling_lattice in [2u8, 9] {
        let bad = edit_payload(&s, ChunkTag::HEAD, |p| {
            p[11] = 0; // coord_bits: below its range
            p[14] = scaling_lattice; // E8 on S = 6 (does not fit), or no such code
        });
        match err(&bad) {
            Error::FieldOutOfRange { field, .. } => assert_eq!(field, Field::CoordBits),
            other => panic!("expected coord_bits out of range, got {other:?}"),
        }
    }
    // With coord_bits valid, the lattice's fit is reported.
    let bad = edit_payload(&s, ChunkTag::HEAD, |p| p[14] = 2);
    assert!(matches!(err(&bad), Error::LatticeDimension { .. }));
}

/// §9.1: a stream of a few bytes whose header claims 2^24 Gaussians of SH degree 3 in one
/// voxel asks for 3.96 GB of output, within the reference default 4 GiB
/// ([`Limits::desktop`]), but a decode that keeps the
/// symbols would hold 4.13 GB more: the allocation limit refuses it at `GHED`, before anything
/// is allocated. Decoding Gaussians only it holds 0.2 GB more and passes that check.
#[test]
fn the_allocation_limit_counts_what_an_explicit_decode_holds() {
    let h = salvq_bitstream::explicit::header::GaussianHeader {
        count: 1 << 24,
        sh_degree: 3,
        rate_count: 1,
        rate_mask: 1,
        origin: [0.0; 3],
        progressive: false,
    };
    let limit = Limits::desktop().max_alloc_bytes;
    assert!(h.decoded_bytes() <= limit);
    let stream = salvq_encoder::writers::surgery::assemble(
        &salvq_bitstream::container::signature::Signature::current().to_bytes(),
        &[(ChunkTag::GHED, h.to_payload()), (ChunkTag::SEND, vec![])],
    );
    let decode = |gaussians_only: bool| {
        (salvq::Decoder::builder()
            .limits(Limits::desktop())
            .gaussians_only(gaussians_only))
        .build()
        .decode(&stream)
        .err()
    };
    match decode(false) {
        Some(Error::LimitExceeded {
            limit: LimitKind::AllocationBytes,
            requested,
            ..
        }) => assert!(requested > limit, "{requested}"),
        other => panic!("keeping the symbols: {other:?}"),
    }
    assert!(
        !matches!(decode(true), Some(Error::LimitExceeded { .. })),
        "Gaussians only: {:?}",
        decode(true)
    );
}
