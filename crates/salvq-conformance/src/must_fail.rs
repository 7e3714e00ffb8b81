//! Must-fail vectors (spec §11.5): one malformed stream per error class a stream decoder can
//! report (Table 9-1), each reaching its rule with every earlier rule intact, so a conformant
//! decoder reports exactly that class.
//!
//! Every vector starts from a tiny generated scene (Annex B: 13 anchors, seed 1, narrow MLPs)
//! encoded by the reference encoder, and changes one thing with the chunk surgery of
//! [`salvq_encoder::writers::surgery`], which recomputes CRCs: every CRC a decoder reaches is valid
//! except in `x-chunk-crc-mismatch`. The streams are deterministic: the generator is seeded
//! and nothing else varies.
//!
//! `ScaleIndexOutOfRange` has no vector: §5.4 step 3 computes a scale index as a count of the
//! 63 thresholds of Table 6-1, so no stream can make it fall outside 0 … 63.

mod head;
mod payload;

use salvq_bitstream::container::chunk::ChunkTag;
use salvq_bitstream::container::preflight::Preflight;
use salvq_bitstream::container::signature::SIGNATURE_LEN;
use salvq_bitstream::limits::Limits;
use salvq_bitstream::model::SceneModel;
use salvq_encoder::writers::surgery;
use salvq_encoder::{encode_with_options, EncodeOptions};
use salvq_gen::{generate, GenParams};

/// A stream a conformant decoder must reject with `class`.
#[derive(Debug, Clone)]
pub struct MustFailVector {
    /// File stem, `x-` prefixed (PngSuite's convention), e.g. `x-chunk-crc-mismatch`.
    pub name: &'static str,
    /// The error class (Table 9-1 spelling, [`salvq::Error::class`]).
    pub class: &'static str,
    /// The spec sections whose rule the stream breaks, e.g. `["§1.3"]`.
    pub sections: &'static [&'static str],
    /// One line: what is broken and how.
    pub description: &'static str,
    /// The rate the decoder is asked for.
    pub rate: u8,
    /// The stream.
    pub stream: Vec<u8>,
}

/// Every must-fail vector, in a fixed order: roughly the order of the decoding process
/// (signature, chunk framing, `HEAD`, chunk order, payloads, the layer chunks).
pub fn must_fail_vectors() -> Vec<MustFailVector> {
    // The base stream stores the Scaffold-GS MLPs in binary32 whatever the encoder's default
    // (Annex A.5.2), so that the `MLPS` vectors can narrow them (x-scaffold-precision-length,
    // x-scaffold-f16-not-finite).
    let options = EncodeOptions {
        scaffold_precision: Some(salvq_bitstream::container::payload::ScaffoldPrecision::F32),
        ..Default::default()
    };
    let base = encode(&small_scene(13, false), &options);
    let mut out = container_vectors(&base);
    out.extend(head::head_vectors(&base));
    out.extend(payload::payload_vectors(&base));
    out
}

/// A vector asking for rate 0 (the lowest coded rate of a default-encoded stream).
pub(crate) fn vector(
    name: &'static str,
    class: &'static str,
    sections: &'static [&'static str],
    description: &'static str,
    stream: Vec<u8>,
) -> MustFailVector {
    MustFailVector {
        name,
        class,
        sections,
        description,
        rate: 0,
        stream,
    }
}

/// A tiny generated scene (Annex B): [`GenParams::small`] with `n` anchors, seed 1, K = 2
/// offsets and narrow MLPs (context hidden 4, Scaffold-GS hidden 2), so that a stream is
/// under 2.5 KB; with a learned feature basis (general lattice) or the identity.
fn small_scene(n: u32, feat_basis: bool) -> SceneModel {
    generate(&GenParams {
        feat_basis,
        offsets: 2,
        context_hidden: 4,
        scaffold_hidden: 2,
        ..GenParams::small(n, 1)
    })
}

fn encode(m: &SceneModel, options: &EncodeOptions) -> Vec<u8> {
    encode_with_options(m, options).expect("a generated scene encodes")
}

/// The stream's chunks as (tag, payload).
fn chunks(stream: &[u8]) -> Vec<(ChunkTag, Vec<u8>)> {
    surgery::chunks(stream).expect("a generated stream frames")
}

/// The stream with the first `tag` chunk's payload changed by `f` (CRC recomputed).
fn edit(stream: &[u8], tag: ChunkTag, f: impl FnOnce(&mut Vec<u8>)) -> Vec<u8> {
    surgery::edit_payload(stream, tag, f).expect("the chunk is in a generated stream")
}

/// The first `tag` chunk's payload.
fn payload_of(stream: &[u8], tag: ChunkTag) -> Vec<u8> {
    chunks(stream)
        .into_iter()
        .find(|(t, _)| *t == tag)
        .map(|(_, p)| p)
        .expect("the chunk is in a generated stream")
}

/// Offset of the first `tag` chunk's length field.
fn offset(stream: &[u8], tag: ChunkTag) -> usize {
    surgery::chunk_offset(stream, tag).expect("the chunk is in a generated stream")
}

/// The stream's `HEAD`, parsed.
fn head_of(stream: &[u8]) -> Preflight {
    Preflight::parse(&payload_of(stream, ChunkTag::HEAD), &Limits::default())
        .expect("a generated stream has a valid HEAD")
}

/// The stream with its `HEAD` fields changed by `f` and re-serialized (Table 1-4).
fn edit_head(stream: &[u8], f: impl FnOnce(&mut Preflight)) -> Vec<u8> {
    let mut h = head_of(stream);
    f(&mut h);
    edit(stream, ChunkTag::HEAD, |p| *p = h.to_payload())
}

/// The stream with a chunk inserted at index `at` of its chunk list.
fn insert_chunk(stream: &[u8], at: usize, tag: ChunkTag, payload: &[u8]) -> Vec<u8> {
    let mut cs = chunks(stream);
    cs.insert(at, (tag, payload.to_vec()));
    surgery::assemble(stream, &cs)
}

/// The stream with its bytes changed by `f`, CRCs left as they are.
fn changed(stream: &[u8], f: impl FnOnce(&mut Vec<u8>)) -> Vec<u8> {
    let mut s = stream.to_vec();
    f(&mut s);
    s
}

/// Signature, chunk framing, chunk order and the end of the stream (§1.2, §1.3, §1.5).
fn container_vectors(base: &[u8]) -> Vec<MustFailVector> {
    let mut out = signature_vectors(base);
    out.extend(framing_vectors(base));
    out.extend(order_vectors(base));
    out
}

/// The signature's vectors (§1.2, §1.2.1): a wrong magic, a truncated signature, versions the
/// decoder does not implement, a reserved flag.
fn signature_vectors(base: &[u8]) -> Vec<MustFailVector> {
    vec![
        vector(
            "x-signature-mismatch",
            "SignatureMismatch",
            &["§1.2"],
            "magic byte 1 changed from 'S' to 'P'",
            changed(base, |s| s[1] = b'P'),
        ),
        vector(
            "x-truncated-signature",
            "Truncated",
            &["§1.2"],
            "the stream is the magic and the major version only (9 bytes)",
            base[..9].to_vec(),
        ),
        vector(
            "x-unsupported-major-version",
            "UnsupportedMajorVersion",
            &["§1.2", "§1.2.1"],
            "major version 1 (the decoder implements 0)",
            changed(base, |s| s[8] = 1),
        ),
        vector(
            "x-unsupported-minor-version",
            "UnsupportedMinorVersion",
            &["§1.2", "§1.2.1"],
            "minor version one above the decoder's in the draft series",
            changed(base, |s| {
                s[9] = salvq_bitstream::container::signature::FORMAT_MINOR + 1
            }),
        ),
        vector(
            "x-older-minor-version",
            "UnsupportedMinorVersion",
            &["§1.2", "§1.2.1"],
            "minor version one below the decoder's in the draft series (draft versions are \
             never read by a later draft's decoder)",
            changed(base, |s| {
                s[9] = salvq_bitstream::container::signature::FORMAT_MINOR - 1
            }),
        ),
        vector(
            "x-reserved-file-flags",
            "ReservedBitsSet",
            &["§1.2"],
            "file_flags = 0x8000: a reserved bit set",
            changed(base, |s| s[SIGNATURE_LEN - 1] = 0x80),
        ),
    ]
}

/// The chunk framing's vectors (§1.3, §9.1): an invalid tag, lengths too large or past the
/// end, a stream cut in a chunk's header or CRC, a CRC that does not match.
fn framing_vectors(base: &[u8]) -> Vec<MustFailVector> {
    let set_len = |s: &mut Vec<u8>, tag: ChunkTag, len: u32| {
        let at = offset(s, tag);
        s[at..at + 4].copy_from_slice(&len.to_le_bytes());
    };
    let send = offset(base, ChunkTag::SEND);
    vec![
        vector(
            "x-chunk-tag-invalid",
            "ChunkTagInvalid",
            &["§1.3"],
            "the GRID chunk's tag is G#ID",
            changed(base, |s| {
                let at = offset(s, ChunkTag::GRID) + 5;
                s[at] = b'#';
            }),
        ),
        vector(
            "x-limit-chunk-length",
            "LimitExceeded",
            &["§1.3", "§9.1"],
            "the MLPS chunk's length is 2^30 + 1, above the default chunk limit of 1 GiB",
            changed(base, |s| set_len(s, ChunkTag::MLPS, (1 << 30) + 1)),
        ),
        vector(
            "x-chunk-length-past-end",
            "ChunkLengthPastEnd",
            &["§1.3"],
            "the AOFF chunk's length is 1 000 000, past the end of the stream",
            changed(base, |s| set_len(s, ChunkTag::AOFF, 1_000_000)),
        ),
        vector(
            "x-truncated-chunk-header",
            "Truncated",
            &["§1.3"],
            "the stream ends 3 bytes into the SEND chunk's header",
            base[..send + 3].to_vec(),
        ),
        vector(
            "x-truncated-chunk-crc",
            "Truncated",
            &["§1.3"],
            "the stream ends 2 bytes into the SEND chunk's CRC",
            base[..base.len() - 2].to_vec(),
        ),
        vector(
            "x-chunk-crc-mismatch",
            "ChunkCrcMismatch",
            &["§1.3"],
            "one bit of the AFEA payload flipped, its CRC left as it was",
            changed(base, |s| {
                let at = offset(s, ChunkTag::AFEA) + 8 + 5;
                s[at] ^= 0x10;
            }),
        ),
    ]
}

/// The chunk order's and the stream end's vectors (§1.5, §6.6.2, §10.2): unknown and
/// misplaced chunks, no `SEND`, data after it, and which of two broken rules is reported first.
fn order_vectors(base: &[u8]) -> Vec<MustFailVector> {
    let send = offset(base, ChunkTag::SEND);
    let mut swapped = chunks(base);
    swapped.swap(1, 2);
    vec![
        vector(
            "x-unknown-critical-chunk",
            "UnknownCriticalChunk",
            &["§1.5"],
            "a critical chunk ABCD (3-byte payload) inserted after HEAD",
            insert_chunk(base, 1, ChunkTag(*b"ABCD"), &[1, 2, 3]),
        ),
        vector(
            "x-chunk-order",
            "ChunkOrder",
            &["§1.5"],
            "QUAN before MLPS",
            surgery::assemble(base, &swapped),
        ),
        vector(
            "x-chunk-order-ancillary-first",
            "ChunkOrder",
            &["§1.5"],
            "an ancillary encd chunk before HEAD",
            insert_chunk(base, 0, ChunkTag::ENCD, b"too early"),
        ),
        vector(
            "x-truncated-before-send",
            "Truncated",
            &["§1.5"],
            "the stream ends at a chunk boundary, before SEND",
            base[..send].to_vec(),
        ),
        vector(
            "x-send-not-empty",
            "ChunkSizeMismatch",
            &["§1.5"],
            "SEND has a 1-byte payload",
            edit(base, ChunkTag::SEND, |p| p.push(0)),
        ),
        vector(
            "x-trailing-data",
            "TrailingData",
            &["§1.5"],
            "4 bytes after SEND",
            changed(base, |s| s.extend_from_slice(b"junk")),
        ),
        vector(
            "x-layer-chunk-by-chunk",
            "ChunkSizeMismatch",
            &["§6.6.2", "§10.2"],
            "AFEA's tile lengths add up to one byte more than its words and ASCL's coding_method = 7: AFEA's method and tile framing are checked before ASCL's",
            {
                let s = edit(base, ChunkTag::AFEA, |p| {
                    let l = u32::from_le_bytes([p[1], p[2], p[3], p[4]]) + 1;
                    p[1..5].copy_from_slice(&l.to_le_bytes());
                });
                edit(&s, ChunkTag::ASCL, |p| p[0] = 7)
            },
        ),
        vector(
            "x-trailing-data-before-layer",
            "TrailingData",
            &["§1.5", "§6.6.2"],
            "4 bytes after SEND and AFEA coding_method = 7 (CRC valid): SEND's rules are checked when it is read, before the selected layer is decoded",
            {
                let mut s = edit(base, ChunkTag::AFEA, |p| p[0] = 7);
                s.extend_from_slice(b"junk");
                s
            },
        ),
    ]
}

#[cfg(test)]
mod tests;
