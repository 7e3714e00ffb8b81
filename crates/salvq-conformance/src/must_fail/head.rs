//! Must-fail vectors of `HEAD` (§1.4) and of the rate selection (§1.5).

use super::{edit, edit_head, encode, small_scene, vector, MustFailVector};
use salvq_bitstream::container::chunk::ChunkTag;
use salvq_bitstream::model::{decoded_bytes, LatticeKind};
use salvq_encoder::EncodeOptions;

/// `HEAD` (§1.4) and the selected rate (§1.5).
pub(super) fn head_vectors(base: &[u8]) -> Vec<MustFailVector> {
    let mut out = head_field_vectors(base);
    out.extend(head_limit_vectors(base));
    out.extend(rate_vectors(base));
    out
}

/// `HEAD`'s payload and fields (§1.4): its length, reserved bits, ranges, and the values its
/// dimensions imply.
fn head_field_vectors(base: &[u8]) -> Vec<MustFailVector> {
    vec![
        vector(
            "x-truncated-head",
            "Truncated",
            &["§1.4"],
            "the HEAD payload cut to its first 20 bytes",
            edit(base, ChunkTag::HEAD, |p| p.truncate(20)),
        ),
        vector(
            "x-reserved-head-flags",
            "ReservedBitsSet",
            &["§1.4"],
            "head_flags = 0x80: a reserved bit set",
            edit(base, ChunkTag::HEAD, |p| p[12] = 0x80),
        ),
        vector(
            "x-head-size-mismatch",
            "ChunkSizeMismatch",
            &["§1.4"],
            "one byte appended to the HEAD payload",
            edit(base, ChunkTag::HEAD, |p| p.push(0)),
        ),
        vector(
            "x-field-out-of-range",
            "FieldOutOfRange",
            &["§1.4"],
            "HEAD feat_dim = 0 (range 1 … 1024)",
            edit_head(base, |h| h.dims.feat_dim = 0),
        ),
        vector(
            "x-lattice-dimension",
            "LatticeDimension",
            &["§1.4", "§7.1"],
            "HEAD scaling_lattice = 2 (E8 product) on the 6 scaling dimensions",
            edit_head(base, |h| h.dims.scaling_lattice = LatticeKind::E8Product),
        ),
        vector(
            "x-origin-not-finite",
            "NonFiniteValue",
            &["§1.4", "§2.3"],
            "HEAD origin[0] is NaN",
            edit_head(base, |h| h.origin[0] = f32::NAN),
        ),
        vector(
            "x-voxel-size-zero",
            "ValueNotPositive",
            &["§1.4", "§2.3"],
            "HEAD voxel_size = 0",
            edit_head(base, |h| h.voxel_size = 0.0),
        ),
        vector(
            "x-decoded-size-mismatch",
            "DecodedSizeMismatch",
            &["§1.4"],
            "HEAD decoded_bytes one more than the size the dimensions imply",
            edit_head(base, |h| h.decoded_bytes += 1),
        ),
    ]
}

/// `HEAD` fields (§1.4) within their ranges but above the decoder's limits (§9.1).
fn head_limit_vectors(base: &[u8]) -> Vec<MustFailVector> {
    vec![
        vector(
            "x-limit-anchors",
            "LimitExceeded",
            &["§1.4", "§9.1"],
            "HEAD anchor_count 2^24 + 1, decoded_bytes to match: above the anchor limit 2^24",
            edit_head(base, |h| {
                h.dims.anchors = (1 << 24) + 1;
                h.decoded_bytes = decoded_bytes(&h.dims);
            }),
        ),
        vector(
            "x-limit-allocation",
            "LimitExceeded",
            &["§1.4", "§9.1"],
            "HEAD anchor_count 2^24, feat_dim 1024, decoded_bytes to match: above the 4 GiB limit",
            edit_head(base, |h| {
                h.dims.anchors = 1 << 24;
                h.dims.feat_dim = 1024;
                h.decoded_bytes = decoded_bytes(&h.dims);
            }),
        ),
    ]
}

/// The rate selection (§1.5): a rate beyond the stream's, and one it does not code.
fn rate_vectors(base: &[u8]) -> Vec<MustFailVector> {
    let rate1 = encode(
        &small_scene(13, false),
        &EncodeOptions {
            rates: vec![1],
            ..Default::default()
        },
    );
    vec![
        MustFailVector {
            rate: 2,
            ..vector(
                "x-rate-out-of-range",
                "FieldOutOfRange",
                &["§1.5", "§7.4"],
                "rate 2 asked of a valid stream with rate_count 2",
                base.to_vec(),
            )
        },
        vector(
            "x-rate-not-coded",
            "RateNotCoded",
            &["§1.5", "§7.4"],
            "rate 0 asked of a stream that codes rate 1 only (rate_mask 0b10)",
            rate1,
        ),
    ]
}
