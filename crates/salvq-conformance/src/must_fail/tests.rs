//! Each must-fail vector fails, and with the rule it is named for.

use super::*;

use salvq_bitstream::error::{AnsFault, Error, Structure};
use salvq_bitstream::geometry;
use std::collections::BTreeSet;

/// Table 9-1's classes a stream decoder can report (encoder-only and model-file classes
/// left out).
const STREAM_CLASSES: [&str; 29] = [
    "SignatureMismatch",
    "Truncated",
    "UnsupportedMajorVersion",
    "UnsupportedMinorVersion",
    "ReservedBitsSet",
    "ChunkTagInvalid",
    "ChunkLengthPastEnd",
    "ChunkCrcMismatch",
    "ChunkOrder",
    "UnknownCriticalChunk",
    "TrailingData",
    "FieldOutOfRange",
    "DecodedSizeMismatch",
    "LimitExceeded",
    "ChunkSizeMismatch",
    "UnknownCodingMethod",
    "PaddingBitsSet",
    "AnsStreamInvalid",
    "EscapeOverflow",
    "ScaleIndexOutOfRange",
    "LatticeDimension",
    "RateNotCoded",
    "TileOrder",
    "TileBoxMismatch",
    "OctreeInvalid",
    "NonFiniteValue",
    "ValueNotPositive",
    "ValueInvalid",
    "BasisSingular",
];

/// Classes no stream can reach (see the module documentation).
const UNREACHABLE: [&str; 1] = ["ScaleIndexOutOfRange"];

fn decode_vector(v: &MustFailVector) -> Error {
    let options = salvq::Decoder::builder().rate(Some(v.rate));
    match options
        .build()
        .decode(&v.stream)
        .and_then(salvq::Scene::try_into_anchors)
    {
        Ok(_) => panic!("{}: decoded", v.name),
        Err(e) => e,
    }
}

#[test]
fn every_vector_fails_with_its_class() {
    let vectors = must_fail_vectors();
    let mut total = 0;
    for v in &vectors {
        let e = decode_vector(v);
        assert_eq!(e.class(), v.class, "{}: {e}", v.name);
        total += v.stream.len();
        println!("{:32} {:24} {:5} {e}", v.name, v.class, v.stream.len());
    }
    println!("{} vectors, {total} bytes", vectors.len());
    assert!(total < 100_000, "{total} bytes");
    assert!(vectors.iter().all(|v| v.stream.len() < 8_000));
}

#[test]
fn names_are_unique_and_every_class_has_a_vector() {
    let vectors = must_fail_vectors();
    let names: BTreeSet<&str> = vectors.iter().map(|v| v.name).collect();
    assert_eq!(names.len(), vectors.len(), "duplicate names");
    for v in &vectors {
        assert!(v.name.starts_with("x-"), "{}", v.name);
        assert!(
            v.name[2..]
                .bytes()
                .all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b == b'-'),
            "{}",
            v.name
        );
        assert!(STREAM_CLASSES.contains(&v.class), "{}: {}", v.name, v.class);
        assert!(!v.sections.is_empty() && !v.description.is_empty());
        assert!(v.sections.iter().all(|s| s.starts_with('§')), "{}", v.name);
    }
    let classes: BTreeSet<&str> = vectors.iter().map(|v| v.class).collect();
    for c in STREAM_CLASSES {
        assert!(
            classes.contains(c) != UNREACHABLE.contains(&c),
            "class {c}: covered {}",
            classes.contains(c)
        );
    }
}

/// Every section a vector names is a numbered heading of the spec.
#[test]
fn sections_are_spec_headings() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../spec");
    let mut headings = BTreeSet::new();
    for entry in std::fs::read_dir(dir).expect("spec folder") {
        let text = std::fs::read_to_string(entry.expect("entry").path()).unwrap_or_default();
        for line in text
            .lines()
            .filter(|l| l.starts_with("## ") || l.starts_with("### "))
        {
            if let Some(number) = line.split(' ').nth(1) {
                headings.insert(number.to_string());
            }
        }
    }
    for v in must_fail_vectors() {
        for s in v.sections {
            assert!(
                headings.contains(*s),
                "{}: {s} is not a spec heading",
                v.name
            );
        }
    }
}

#[test]
fn vectors_are_deterministic() {
    let a = must_fail_vectors();
    let b = must_fail_vectors();
    assert_eq!(a.len(), b.len());
    for (x, y) in a.iter().zip(&b) {
        assert!(x.name == y.name && x.stream == y.stream, "{}", x.name);
    }
}

fn octree_rule(e: &Error) -> Option<&'static str> {
    match e {
        salvq::Error::OctreeInvalid { rule, .. } => Some(rule),
        _ => None,
    }
}

/// The vectors with several rules behind one class reach the rule their name says.
#[test]
fn vectors_reach_the_named_rule() {
    for v in must_fail_vectors() {
        let e = decode_vector(&v);
        let ok = truncation_rule(v.name, &e)
            .or_else(|| octree_named_rule(v.name, &e))
            .or_else(|| coded_payload_rule(v.name, &e))
            .or_else(|| limit_rule(v.name, &e))
            .unwrap_or(true);
        assert!(ok, "{}: {e:?}", v.name);
    }
}

/// Whether a truncation vector fails in the structure it cuts short (`None`: not one).
fn truncation_rule(name: &str, e: &Error) -> Option<bool> {
    match name {
        "x-truncated-signature" => Some(matches!(
            e,
            salvq::Error::Truncated {
                structure: Structure::Signature,
                ..
            }
        )),
        "x-truncated-chunk-header" | "x-truncated-before-send" => Some(matches!(
            e,
            salvq::Error::Truncated {
                structure: Structure::ChunkHeader,
                ..
            }
        )),
        "x-truncated-chunk-crc" => Some(matches!(
            e,
            salvq::Error::Truncated {
                structure: Structure::ChunkCrc,
                ..
            }
        )),
        "x-truncated-head" => Some(matches!(
            e,
            salvq::Error::Truncated {
                structure: Structure::Payload(ChunkTag::HEAD),
                ..
            }
        )),
        "x-truncated-tile-lengths" => Some(matches!(
            e,
            salvq::Error::Truncated {
                structure: Structure::Payload(ChunkTag::APOS),
                ..
            }
        )),
        _ => None,
    }
}

/// Whether an octree vector breaks the geometry rule its name says (`None`: not one).
fn octree_named_rule(name: &str, e: &Error) -> Option<bool> {
    match name {
        "x-octree-too-many-nodes" | "x-octree-direct-too-many-nodes" => {
            Some(octree_rule(e) == Some(geometry::MORE_NODES_THAN_ANCHORS))
        }
        "x-octree-counts-above" => Some(octree_rule(e) == Some(geometry::COUNTS_ABOVE)),
        "x-octree-counts-below" => Some(octree_rule(e) == Some(geometry::COUNTS_BELOW)),
        _ => None,
    }
}

/// Whether a vector of broken entropy-coded payloads (ANS words, tile lengths, escapes)
/// fails in the chunk and with the fault its name says (`None`: not one).
fn coded_payload_rule(name: &str, e: &Error) -> Option<bool> {
    match name {
        "x-ans-zero-top-word-apos" => Some(matches!(
            e,
            salvq::Error::AnsStreamInvalid {
                tag: ChunkTag::APOS,
                fault: AnsFault::ZeroTopWord
            }
        )),
        "x-ans-lowest-tile-reported" => Some(matches!(
            e,
            salvq::Error::AnsStreamInvalid {
                tag: ChunkTag::AOFF,
                fault: AnsFault::ZeroTopWord
            }
        )),
        "x-tile-lengths-mismatch" => Some(matches!(
            e,
            salvq::Error::ChunkSizeMismatch {
                tag: ChunkTag::AFEA,
                ..
            }
        )),
        "x-ans-out-of-words-afea" => Some(matches!(
            e,
            salvq::Error::AnsStreamInvalid {
                tag: ChunkTag::AFEA,
                fault: AnsFault::OutOfWords
            }
        )),
        "x-escape-overflow" => Some(matches!(
            e,
            salvq::Error::EscapeOverflow {
                tag: ChunkTag::AFEA,
                symbol: 0,
                prefix_bits: 31
            }
        )),
        _ => None,
    }
}

/// Whether a limit vector exceeds the limit its name says (`None`: not one).
fn limit_rule(name: &str, e: &Error) -> Option<bool> {
    match name {
        "x-limit-chunk-length" => Some(matches!(
            e,
            salvq::Error::LimitExceeded {
                limit: salvq_bitstream::limits::LimitKind::ChunkBytes,
                ..
            }
        )),
        "x-limit-anchors" => Some(matches!(
            e,
            salvq::Error::LimitExceeded {
                limit: salvq_bitstream::limits::LimitKind::Anchors,
                ..
            }
        )),
        "x-limit-allocation" => Some(matches!(
            e,
            salvq::Error::LimitExceeded {
                limit: salvq_bitstream::limits::LimitKind::AllocationBytes,
                ..
            }
        )),
        _ => None,
    }
}
