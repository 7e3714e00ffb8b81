//! The explicit profile's must-fail vectors (spec §3, §11.4): a base stream of synthetic
//! Gaussians, layered or progressive, with one rule of §3 broken in each.

use salvq_bitstream::container::chunk::ChunkTag;
use salvq_encoder::explicit::ExplicitOptions;
use salvq_encoder::writers::surgery;
use salvq_gen::gaussians::GaussianParams;

use super::explicit_must_fail_bodies;
use super::explicit_vectors::{base_plan, encode_synthetic, rates};
use super::must_fail::{vector as must_fail, MustFailVector};

/// The base stream of the explicit must-fail vectors: 30 Gaussians, SH degree 1, rates 0 and
/// 1 of 3 coded, KLT for SH DC, 2 tiles; layered, or `progressive` (§3.8: rate 1 a full
/// layer, rate 0 its refinement).
fn base_stream(progressive: bool) -> Vec<u8> {
    encode_synthetic(
        &GaussianParams::new(30, 1, 2),
        rates(&base_plan(true), 3),
        ExplicitOptions {
            coded: Some(vec![0, 1]),
            klt: Some(vec![false, false, false, true, false]),
            tile_gaussians: 16,
            progressive,
            ..Default::default()
        },
    )
    .expect("a synthetic scene encodes")
    .stream
}

fn edit(stream: &[u8], tag: ChunkTag, f: impl FnOnce(&mut Vec<u8>)) -> Vec<u8> {
    surgery::edit_payload(stream, tag, f).expect("the chunk is in the base stream")
}

fn chunks(stream: &[u8]) -> Vec<(ChunkTag, Vec<u8>)> {
    surgery::chunks(stream).expect("the base stream frames")
}

/// Byte offsets inside the base stream's `GQUA` payload (§3.3): group 0 (scale, identity)
/// starts at 1: lattice, step (2), gains (6: M = 3).
mod gqua_at {
    pub const GROUP0_STEP: usize = 2;
    pub const GROUP0_GAIN0: usize = 6;

    /// Group 3 (sh_dc) has the KLT basis: its lattice byte, found by walking the groups.
    pub fn dc_lattice() -> usize {
        let mut at = 1;
        for d in [3usize, 1, 3] {
            at += 1 + 4 + 4 * 3 + 4 * d;
        }
        at
    }
}

/// Byte offsets inside the base stream's `GLAY` payload (§3.4): after `coding_method`,
/// `coord_bits` (1), `voxel_size` (2), `pred_level` (6), `rotation_freq` (7), thresholds
/// (13), refine (25), shifts (29), then the scale offsets, predict, the `sh_rest` count's
/// tree (15 nodes: SH degree 1) and the scale table.
mod glay_at {
    pub const COORD_BITS: usize = 1;
    pub const PRED_LEVEL: usize = 6;
    pub const ROTATION_FREQ: usize = 7;
    pub const THRESHOLD: usize = 13;
    pub const REFINE: usize = 25;
    pub const SHIFT: usize = 29;
    /// After the shifts and scale offsets (4 · 4 bytes each for G = 5) and `predict` (5).
    pub const REST_COUNT_FREQ: usize = SHIFT + 16 + 16 + 5;
}

/// Every explicit must-fail vector, in decoding order (§3.2 – §3.7).
pub fn explicit_must_fail_vectors() -> Vec<MustFailVector> {
    let base = base_stream(false);
    let mut out = ghed_vectors(&base);
    out.extend(gqua_value_vectors(&base));
    out.extend(gqua_read_order_vectors(&base));
    out.extend(glay_grid_vectors(&base));
    out.extend(glay_prior_vectors(&base));
    out.extend(order_vectors(&base));
    out.extend(gatt_vectors(&base));
    out.extend(trailing_and_rate_vectors(&base));
    out.extend(explicit_must_fail_bodies::tile_vectors(&base));
    out.extend(explicit_must_fail_bodies::body_vectors(&base));
    out.extend(progressive_vectors(&base_stream(true)));
    out
}

/// `GHED`'s vectors (§3.2): reserved and out-of-range fields, a NaN origin, a wrong decoded
/// size, a wrong length.
fn ghed_vectors(base: &[u8]) -> Vec<MustFailVector> {
    let ghed = |f: &dyn Fn(&mut Vec<u8>)| edit(base, ChunkTag::GHED, |p| f(p));
    vec![
        must_fail(
            "x-g-head-flags",
            "ReservedBitsSet",
            &["§3.2"],
            "GHED head_flags = 2 (bit 1 is reserved)",
            ghed(&|p| p[6] = 2),
        ),
        must_fail(
            "x-g-progressive-layered",
            "ChunkOrder",
            &["§3.2", "§3.7", "§3.8"],
            "GHED head_flags = 1 on a layered stream: GREF is due after the first GATT, GLAY \
             comes",
            ghed(&|p| p[6] = 1),
        ),
        must_fail(
            "x-g-sh-degree",
            "FieldOutOfRange",
            &["§3.2"],
            "GHED sh_degree = 4",
            ghed(&|p| p[4] = 4),
        ),
        must_fail(
            "x-g-rate-mask",
            "FieldOutOfRange",
            &["§3.2"],
            "GHED rate_mask has bit 3 set with M = 3",
            ghed(&|p| p[7] |= 8),
        ),
        must_fail(
            "x-g-origin-nan",
            "NonFiniteValue",
            &["§3.2"],
            "GHED origin[1] is NaN",
            ghed(&|p| p[19..23].copy_from_slice(&f32::NAN.to_le_bytes())),
        ),
        must_fail(
            "x-g-decoded-size",
            "DecodedSizeMismatch",
            &["§3.2"],
            "GHED decoded_bytes one too many",
            ghed(&|p| p[27] = p[27].wrapping_add(1)),
        ),
        must_fail(
            "x-g-ghed-length",
            "ChunkSizeMismatch",
            &["§3.2"],
            "GHED one byte too long",
            ghed(&|p| p.push(0)),
        ),
    ]
}

/// `GQUA`'s vectors of values out of range (§3.3): a lattice this profile does not use, a
/// zero step, a step × gain that overflows, a singular KLT basis.
fn gqua_value_vectors(base: &[u8]) -> Vec<MustFailVector> {
    let gqua = |f: &dyn Fn(&mut Vec<u8>)| edit(base, ChunkTag::GQUA, |p| f(p));
    vec![
        must_fail(
            "x-g-lattice",
            "ValueInvalid",
            &["§3.3"],
            "GQUA scale group lattice = 3 (not used by this profile)",
            gqua(&|p| p[1] = 3),
        ),
        must_fail(
            "x-g-step-zero",
            "ValueNotPositive",
            &["§3.3"],
            "GQUA scale step = 0",
            gqua(&|p| {
                p[gqua_at::GROUP0_STEP..gqua_at::GROUP0_STEP + 4]
                    .copy_from_slice(&0f32.to_le_bytes())
            }),
        ),
        must_fail(
            "x-g-gain-overflow",
            "NonFiniteValue",
            &["§3.3"],
            "GQUA scale gain 0 finite but step × gain overflows",
            gqua(&|p| {
                p[gqua_at::GROUP0_STEP..gqua_at::GROUP0_STEP + 4]
                    .copy_from_slice(&1e30f32.to_le_bytes());
                p[gqua_at::GROUP0_GAIN0..gqua_at::GROUP0_GAIN0 + 4]
                    .copy_from_slice(&1e30f32.to_le_bytes());
            }),
        ),
        must_fail(
            "x-g-basis-singular",
            "BasisSingular",
            &["§3.3"],
            "GQUA sh_dc basis_s[1] = 0",
            gqua(&|p| {
                // basis_s follows lattice, step, 3 gains, 3 means and 9 basis_u values.
                let s1 = gqua_at::dc_lattice() + 1 + 4 + 12 + 12 + 18 + 2;
                p[s1..s1 + 2].copy_from_slice(&[0, 0]);
            }),
        ),
    ]
}

/// `GQUA`'s vectors of the order its values are checked in (§3.3: each as it is read), and
/// of its length.
fn gqua_read_order_vectors(base: &[u8]) -> Vec<MustFailVector> {
    let gqua = |f: &dyn Fn(&mut Vec<u8>)| edit(base, ChunkTag::GQUA, |p| f(p));
    vec![
        must_fail(
            "x-g-basis-zero-then-nan",
            "NonFiniteValue",
            &["§3.3"],
            "GQUA sh_dc basis_s = [0, NaN, …]: each value's finiteness is checked as it is read, \
             the zero only after the last",
            gqua(&|p| {
                let s0 = gqua_at::dc_lattice() + 1 + 4 + 12 + 12 + 18;
                p[s0..s0 + 2].copy_from_slice(&[0, 0]);
                p[s0 + 2..s0 + 4].copy_from_slice(&0x7e00u16.to_le_bytes());
            }),
        ),
        must_fail(
            "x-g-gain-zero-then-nan",
            "ValueNotPositive",
            &["§3.3"],
            "GQUA scale gains = [0, NaN, …]: each gain is checked whole (finite, then > 0) \
             before the next is read",
            gqua(&|p| {
                let g = gqua_at::GROUP0_GAIN0;
                p[g..g + 4].copy_from_slice(&0f32.to_le_bytes());
                p[g + 4..g + 8].copy_from_slice(&f32::NAN.to_le_bytes());
            }),
        ),
        must_fail(
            "x-g-gqua-length",
            "ChunkSizeMismatch",
            &["§3.3"],
            "GQUA one byte too long",
            gqua(&|p| p.push(0)),
        ),
    ]
}

/// `GLAY`'s vectors of the layer's grid (§3.4): `coord_bits`, `pred_level`, `rotation_freq`,
/// `size_threshold` and `refine` out of range.
fn glay_grid_vectors(base: &[u8]) -> Vec<MustFailVector> {
    let glay = |f: &dyn Fn(&mut Vec<u8>)| edit(base, ChunkTag::GLAY, |p| f(p));
    vec![
        must_fail(
            "x-g-coord-bits",
            "FieldOutOfRange",
            &["§3.4"],
            "GLAY coord_bits = 22",
            glay(&|p| p[glay_at::COORD_BITS] = 22),
        ),
        must_fail(
            "x-g-pred-level",
            "FieldOutOfRange",
            &["§3.4"],
            "GLAY pred_level above coord_bits",
            glay(&|p| p[glay_at::PRED_LEVEL] = 30),
        ),
        must_fail(
            "x-g-rotation-freq",
            "FieldOutOfRange",
            &["§3.4"],
            "GLAY rotation_freq[1] = 0",
            glay(&|p| {
                p[glay_at::ROTATION_FREQ + 2..glay_at::ROTATION_FREQ + 4].copy_from_slice(&[0, 0])
            }),
        ),
        must_fail(
            "x-g-threshold",
            "ValueInvalid",
            &["§3.4"],
            "GLAY size_threshold[1] below size_threshold[0]",
            glay(&|p| {
                let t0 = i32::from_le_bytes([p[13], p[14], p[15], p[16]]);
                let at = glay_at::THRESHOLD + 4;
                p[at..at + 4].copy_from_slice(&(t0 - 1).to_le_bytes());
            }),
        ),
        must_fail(
            "x-g-refine",
            "FieldOutOfRange",
            &["§3.4"],
            "GLAY refine[0] above 24 − coord_bits",
            glay(&|p| p[glay_at::REFINE] = 24),
        ),
    ]
}

/// `GLAY`'s vectors of the layer's prior (§3.4, §3.5): `shift`, `scale_offset`, `predict`,
/// the `sh_rest` count's tree and `scale_table` out of range, and a wrong length.
fn glay_prior_vectors(base: &[u8]) -> Vec<MustFailVector> {
    let glay = |f: &dyn Fn(&mut Vec<u8>)| edit(base, ChunkTag::GLAY, |p| f(p));
    vec![
        must_fail(
            "x-g-shift",
            "ValueInvalid",
            &["§3.4"],
            "GLAY shift[0][2] = 17",
            glay(&|p| p[glay_at::SHIFT + 2] = 17),
        ),
        must_fail(
            "x-g-shift-min",
            "ValueInvalid",
            &["§3.4"],
            "GLAY shift[0][0] = −128 (i8's least value: an absolute value overflows)",
            glay(&|p| p[glay_at::SHIFT] = 0x80),
        ),
        must_fail(
            "x-g-scale-offset",
            "ValueInvalid",
            &["§3.4"],
            "GLAY scale_offset[1][3] = −64",
            glay(&|p| p[glay_at::SHIFT + 4 * 4 + 4 + 3] = (-64i8) as u8),
        ),
        must_fail(
            "x-g-predict",
            "FieldOutOfRange",
            &["§3.4"],
            "GLAY predict[1] = 2",
            glay(&|p| p[glay_at::SHIFT + 8 * 4 + 1] = 2),
        ),
        must_fail(
            "x-g-rest-count-freq",
            "FieldOutOfRange",
            &["§3.4"],
            "GLAY rest_count_freq[2] = 0",
            glay(&|p| {
                let at = glay_at::REST_COUNT_FREQ + 2 * 2;
                p[at..at + 2].copy_from_slice(&[0, 0]);
            }),
        ),
        must_fail(
            "x-g-rest-count",
            "ValueInvalid",
            &["§3.5"],
            "GLAY rest_count_freq all 65535: tile 0's first Gaussian reads the sh_rest count \
             15, above its group's 9 values",
            glay(&|p| {
                for m in 0..15 {
                    let at = glay_at::REST_COUNT_FREQ + 2 * m;
                    p[at..at + 2].copy_from_slice(&u16::MAX.to_le_bytes());
                }
            }),
        ),
        must_fail(
            "x-g-scale-table",
            "FieldOutOfRange",
            &["§3.4"],
            "GLAY's last scale_table entry = 128 (0 … 127 are scales, §6.3.6)",
            glay(&|p| *p.last_mut().expect("a table") = 128),
        ),
        must_fail(
            "x-g-glay-length",
            "ChunkSizeMismatch",
            &["§3.4"],
            "GLAY one byte short",
            glay(&|p| {
                p.pop();
            }),
        ),
    ]
}

/// The chunk-order vectors (§1.5, §3.7): an anchors-profile chunk, `GHED` removed, layer 0's
/// `APOS` before its `TILS`.
fn order_vectors(base: &[u8]) -> Vec<MustFailVector> {
    let swapped = {
        let mut cs = chunks(base);
        let t = cs
            .iter()
            .position(|(t, _)| *t == ChunkTag::TILS)
            .expect("TILS");
        cs.swap(t, t + 1);
        surgery::assemble(base, &cs)
    };
    let unknown = {
        let mut cs = chunks(base);
        cs.insert(2, (ChunkTag::AFEA, vec![1]));
        surgery::assemble(base, &cs)
    };
    vec![
        must_fail(
            "x-g-unknown-critical",
            "UnknownCriticalChunk",
            &["§3.7"],
            "an anchors-profile AFEA chunk after GQUA",
            unknown,
        ),
        must_fail(
            "x-g-first-gqua",
            "UnknownCriticalChunk",
            &["§1.5", "§3.7"],
            "GHED removed: the first chunk, GQUA, makes the stream one of the anchors profile, \
             which does not define it (rule 0 before rule 1)",
            {
                let mut cs = chunks(base);
                cs.retain(|(t, _)| *t != ChunkTag::GHED);
                surgery::assemble(base, &cs)
            },
        ),
        must_fail(
            "x-g-chunk-order",
            "ChunkOrder",
            &["§3.7"],
            "layer 0's APOS before its TILS",
            swapped,
        ),
    ]
}

/// `GATT`'s vectors (§3.5): an unknown coding method, a tile body with a zero top word.
fn gatt_vectors(base: &[u8]) -> Vec<MustFailVector> {
    let base_tiles = chunks(base)
        .into_iter()
        .find(|(t, _)| *t == ChunkTag::TILS)
        .map(|(_, p)| u32::from_le_bytes([p[1], p[2], p[3], p[4]]))
        .expect("TILS");
    vec![
        must_fail(
            "x-g-gatt-method",
            "UnknownCodingMethod",
            &["§3.5"],
            "GATT coding_method = 0",
            edit(base, ChunkTag::GATT, |p| p[0] = 0),
        ),
        must_fail(
            "x-g-gatt-top-word",
            "AnsStreamInvalid",
            &["§3.5", "§6.2.6"],
            "tile 0's GATT body starts with a zero top word",
            edit(base, ChunkTag::GATT, |p| {
                // coding_method, T tile lengths, then tile 0's body (T from TILS, §10.1).
                let at = 1 + 4 * base_tiles as usize;
                p[at..at + 4].copy_from_slice(&[0, 0, 0, 0]);
            }),
        ),
    ]
}

/// A byte after `SEND` (§3.7), and a rate the stream does not code (§3.2).
fn trailing_and_rate_vectors(base: &[u8]) -> Vec<MustFailVector> {
    let mut trailing = base.to_vec();
    trailing.push(0);
    vec![
        must_fail(
            "x-g-trailing",
            "TrailingData",
            &["§3.7"],
            "a byte after SEND",
            trailing,
        ),
        MustFailVector {
            rate: 2,
            ..must_fail(
                "x-g-rate-not-coded",
                "RateNotCoded",
                &["§3.2"],
                "rate 2 of 3 asked for; the stream codes rates 0 and 1",
                base.to_vec(),
            )
        },
    ]
}

/// The progressive stream's vectors (§3.8): `GREF` fields out of range, `GRSY` before `GREF`,
/// a stream cut inside its refinement.
fn progressive_vectors(progressive: &[u8]) -> Vec<MustFailVector> {
    let gref = |f: &dyn Fn(&mut Vec<u8>)| edit(progressive, ChunkTag::GREF, |p| f(p));
    let cut = {
        let at = surgery::chunk_offset(progressive, ChunkTag::GRSY).expect("GRSY");
        progressive[..at + 12].to_vec()
    };
    let refinement_first = {
        let mut cs = chunks(progressive);
        let r = cs
            .iter()
            .position(|(t, _)| *t == ChunkTag::GREF)
            .expect("GREF");
        cs.swap(r, r + 1);
        surgery::assemble(progressive, &cs)
    };
    // GREF (§3.8.1): coding_method, pred_level (1), refine (2 … 5), factor (6 …, 4 per group),
    // then the scale offsets (4 per group; G = 5).
    vec![
        must_fail(
            "x-g-gref-refine",
            "FieldOutOfRange",
            &["§3.8.1"],
            "GREF refine[0] = 24: past 24 bits with the grid's",
            gref(&|p| p[2] = 24),
        ),
        must_fail(
            "x-g-gref-factor",
            "FieldOutOfRange",
            &["§3.8.1"],
            "GREF factor[0][0] = 0",
            gref(&|p| p[6] = 0),
        ),
        must_fail(
            "x-g-gref-offset",
            "ValueInvalid",
            &["§3.8.1"],
            "GREF scale_offset[0][0] = 64",
            gref(&|p| p[6 + 20] = 64),
        ),
        must_fail(
            "x-g-grsy-before-gref",
            "ChunkOrder",
            &["§3.7", "§3.8"],
            "GRSY before GREF",
            refinement_first,
        ),
        must_fail(
            "x-g-progressive-cut",
            "ChunkLengthPastEnd",
            &["§1.3", "§3.8.4"],
            "a progressive stream cut inside its refinement's GRSY (without the caller's \
             consent to a prefix, the truncation is the error)",
            cut,
        ),
    ]
}
