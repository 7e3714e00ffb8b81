//! What the fuzz targets (`fuzz/`) check, shared with the regression tests that replay their
//! findings (`tests/fuzz_regressions.rs`), so a finding replays through exactly the code
//! that found it. Each function panics only when a property is broken: any input the
//! decoder refuses with an error is a pass.

use salvq::extract_rate;
use salvq::DecoderBuilder;
use salvq_bitstream::container::chunk::ChunkTag;
use salvq_bitstream::container::signature::Signature;
use salvq_bitstream::entropy::GaussianTables;
use salvq_bitstream::limits::Limits;
use salvq_bitstream::model::{decoded_bytes, morton3, LatticeKind};
use salvq_encoder::{encode_full, EncodeOptions, Search};
use salvq_gen::{generate, GenParams};

/// The limits the fuzz targets decode under: small enough that a hostile header cannot make
/// a run slow or large.
pub fn fuzz_limits() -> Limits {
    Limits::tight()
        .with_max_anchors(1 << 14)
        .with_max_chunk_bytes(16 << 20)
}

/// The most heap a decode of a `stream_len`-byte stream whose preflight gives
/// `decoded_bytes` may use at its peak (§9.1: the decoded size plus the stream's size, with
/// room for the decoder's working buffers): `3 · (decoded_bytes + stream_len) + 4 MiB`. The
/// fuzz targets enforce it with a capping allocator; `tests/allocation_bound.rs` measures it.
pub fn allocation_bound(decoded_bytes: u64, stream_len: u64) -> u64 {
    decoded_bytes
        .saturating_add(stream_len)
        .saturating_mul(3)
        .saturating_add(4 << 20)
}

/// `data` with every well-framed chunk's CRC-32C recomputed (§1.3), so that a mutated
/// payload reaches the payload's own checks instead of stopping at its CRC.
pub fn with_fixed_crcs(data: &[u8]) -> Vec<u8> {
    let mut out = data.to_vec();
    let mut at = salvq_bitstream::container::signature::SIGNATURE_LEN;
    while let Some(header) = out.get(at..at + 8) {
        let len = u32::from_le_bytes([header[0], header[1], header[2], header[3]]) as usize;
        let tag = salvq_bitstream::container::chunk::ChunkTag([
            header[4], header[5], header[6], header[7],
        ]);
        let Some(end) = (at + 8).checked_add(len) else {
            break;
        };
        if end + 4 > out.len() {
            break;
        }
        let crc = salvq_bitstream::container::chunk::chunk_crc(tag, &out[at + 8..end]);
        out[end..end + 4].copy_from_slice(&crc.to_le_bytes());
        at = end + 4;
    }
    out
}

/// Caps the heap a decode may take: a fuzz target backs it with a capping global allocator,
/// so a decode that allocates past [`allocation_bound`] fails its allocation and aborts,
/// which the fuzzer reports as a crash with the input.
pub trait AllocationMeter {
    /// From now on allow `extra` bytes on top of what is allocated; `None`: no cap.
    fn cap(&self, extra: Option<u64>);
}

/// No cap (the regression tests; `tests/allocation_bound.rs` measures the bound instead).
pub struct NoMeter;

impl AllocationMeter for NoMeter {
    fn cap(&self, _extra: Option<u64>) {}
}

/// The decoded size the stream's `HEAD` states (0 when it does not parse): what the
/// decoder's preflight allows it to allocate (§1.4 step 6).
pub fn stated_decoded_bytes(data: &[u8], limits: &Limits) -> u64 {
    let Ok((_, rest)) = Signature::parse(data) else {
        return 0;
    };
    let mut reader = salvq_bitstream::container::chunk::ChunkReader::new(
        rest,
        salvq_bitstream::container::signature::SIGNATURE_LEN as u64,
        limits,
    );
    match reader.next_chunk() {
        Ok(Some(c)) if c.tag == salvq_bitstream::container::chunk::ChunkTag::HEAD => {
            salvq_bitstream::container::preflight::Preflight::parse(c.payload, limits)
                .map_or(0, |p| p.decoded_bytes)
        }
        Ok(Some(c)) if c.tag == salvq_bitstream::container::chunk::ChunkTag::GHED => {
            salvq_bitstream::explicit::GaussianHeader::parse(c.payload, limits)
                .map_or(0, |h| h.decoded_bytes())
        }
        _ => 0,
    }
}

/// Whole-stream decode of `data` as it is and with its CRCs fixed ([`with_fixed_crcs`]): see
/// [`decode_checked`].
pub fn decode_input(data: &[u8]) {
    decode_input_metered(data, &NoMeter);
}

/// [`decode_input`] with each decode's heap capped by `meter` at [`allocation_bound`].
pub fn decode_input_metered(data: &[u8], meter: &dyn AllocationMeter) {
    decode_checked(data, meter);
    decode_checked(&with_fixed_crcs(data), meter);
}

/// Whole-stream decode: never panics; allocates at most [`allocation_bound`] of what the
/// preflight allows; an explicit-profile stream fed in pieces decodes to the same result; a decoded model stays within the limits; a decoded stream whose model
/// the encoder accepts re-encodes to a stream that decodes.
pub fn decode_checked(data: &[u8], meter: &dyn AllocationMeter) {
    let limits = fuzz_limits();
    let options = salvq::Decoder::builder()
        .limits(limits)
        .rate(data.last().map(|b| b % 4));
    let allowed = stated_decoded_bytes(data, &limits).min(limits.max_alloc_bytes);
    meter.cap(Some(allocation_bound(allowed, data.len() as u64)));
    let decoded = options.build().decode(data);
    meter.cap(None);
    if salvq_bitstream::container::is_explicit(data) {
        // Fed in pieces, the stream decodes to the same result or the same error.
        let piece = 1 + usize::from(data.first().copied().unwrap_or(0)) * 7;
        let mut streaming = options.build().stream();
        for p in data.chunks(piece) {
            if streaming.feed(p).is_err() {
                break;
            }
        }
        assert_eq!(
            streaming.finish(),
            decoded,
            "streamed in pieces of {piece} bytes"
        );
        check_parts(data, &options, &decoded);
    }
    let model = match decoded {
        Ok(salvq::Scene::Anchors(model)) => model,
        Ok(salvq::Scene::Gaussians(d)) => {
            check_explicit_decode(&d, &limits);
            return;
        }
        Err(_) => return,
    };
    let size = decoded_bytes(&model.dims);
    assert!(
        size <= limits.max_alloc_bytes,
        "decoded {size} bytes past the limit"
    );
    if let Ok(e) = encode_full(&model, &EncodeOptions::default()) {
        let again = (salvq::Decoder::builder())
            .build()
            .decode(&e.stream)
            .and_then(salvq::Scene::try_into_anchors);
        assert!(again.is_ok(), "re-encoded stream fails: {:?}", again.err());
    }
}

/// Part decodes (§10.3.2) of an explicit-profile stream never panic, and where the whole
/// stream decodes, so does each of two parts, to its tiles' Gaussians of the whole decode.
fn check_parts(data: &[u8], options: &DecoderBuilder, whole: &salvq::Result<salvq::Scene>) {
    for index in 0..2 {
        let part = salvq::TilePart::new(index, 2);
        let decoded = (options.clone().part(part)).build().decode(data);
        let Ok(salvq::Scene::Gaussians(whole)) = whole else {
            continue;
        };
        let Ok(salvq::Scene::Gaussians(mine)) = decoded else {
            panic!("part {index} of 2 fails where the whole stream decodes: {decoded:?}");
        };
        let t = &whole.tiles;
        let kept = t.select(whole.header.origin, whole.layer.voxel_size, None, part);
        let rows: Vec<usize> = (0..t.len())
            .filter(|&i| kept[i])
            .flat_map(|i| t.range(i))
            .collect();
        assert_eq!(mine.gaussians.len(), rows.len(), "part {index} of 2");
        for (j, &i) in rows.iter().enumerate() {
            assert_eq!(mine.voxels[j], whole.voxels[i], "part {index} of 2");
            assert_eq!(
                mine.gaussians.positions[j].map(f32::to_bits),
                whole.gaussians.positions[i].map(f32::to_bits),
                "part {index} of 2"
            );
        }
    }
}

/// An explicit-profile decode (§3): within the limits, and Gaussians the encoder accepts
/// re-encode (with a fixed plan) to a stream that decodes to the encoder's prediction.
fn check_explicit_decode(d: &salvq::DecodedGaussians, limits: &Limits) {
    let size = d.header.decoded_bytes();
    assert!(
        size <= limits.max_alloc_bytes,
        "decoded {size} bytes past the limit"
    );
    assert_eq!(d.gaussians.len(), d.voxels.len());
    let Ok(p) = salvq_encoder::explicit::PreparedGaussians::new(&d.gaussians) else {
        return;
    };
    let plan = explicit_plan(&p);
    let options = salvq_encoder::explicit::ExplicitOptions {
        rates: salvq_encoder::explicit::RateControl::Plans(vec![plan.clone()]),
        ..Default::default()
    };
    if let Ok(e) = salvq_encoder::explicit::encode_prepared(&p, &[plan], &options) {
        let again = salvq::Decoder::builder()
            .limits(Limits::default())
            .rate(None)
            .build()
            .decode(&e.stream)
            .and_then(salvq::Scene::try_into_gaussians);
        match again {
            Ok(a) => assert!(
                a.gaussians == e.layers[0].2,
                "re-encoded stream decodes differently"
            ),
            Err(err) => panic!("re-encoded stream fails: {err}"),
        }
    }
}

/// A fixed plan for re-encoding fuzzed Gaussians: voxels of 1/64 of the box, moderate steps.
fn explicit_plan(
    p: &salvq_encoder::explicit::PreparedGaussians,
) -> salvq_encoder::explicit::RatePlan {
    salvq_encoder::explicit::RatePlan {
        voxel: (p.extent / 64.0).max(1e-6),
        refine: [2, 1, 0, 0],
        steps: [0.1, 0.25, 0.03, 0.03, 0.04][..p.kinds.len()].to_vec(),
        shift: vec![[1, 0, 0, -1]; p.kinds.len() - 1],
    }
}

/// The payload chunks [`payload_input`] replaces, selected by its first byte.
pub const PAYLOAD_TAGS: [ChunkTag; 9] = [
    ChunkTag::MLPS,
    ChunkTag::QUAN,
    ChunkTag::TILS,
    ChunkTag::APOS,
    ChunkTag::GRID,
    ChunkTag::AMSK,
    ChunkTag::AFEA,
    ChunkTag::ASCL,
    ChunkTag::AOFF,
];

/// The valid stream [`payload_input`] splices into: 24 anchors with a learned feature basis,
/// two rates, tiles of at most 8 anchors (built once).
pub fn payload_base() -> &'static [u8] {
    static BASE: std::sync::OnceLock<Vec<u8>> = std::sync::OnceLock::new();
    BASE.get_or_init(|| {
        let model = generate(&GenParams::small(24, 5));
        let options = EncodeOptions {
            rates: vec![0, 1],
            tile_anchors: 8,
            ..Default::default()
        };
        encode_full(&model, &options).map_or_else(|_| Vec::new(), |e| e.stream)
    })
}

/// The explicit profile's payload chunks [`payload_input`] replaces (§3).
pub const EXPLICIT_PAYLOAD_TAGS: [ChunkTag; 6] = [
    salvq_bitstream::container::order::EXPLICIT_CRITICAL[0],
    salvq_bitstream::container::order::EXPLICIT_CRITICAL[1],
    salvq_bitstream::container::order::EXPLICIT_CRITICAL[2],
    salvq_bitstream::container::order::EXPLICIT_CRITICAL[3],
    salvq_bitstream::container::order::EXPLICIT_CRITICAL[4],
    salvq_bitstream::container::order::EXPLICIT_CRITICAL[5],
];

/// The explicit-profile stream [`payload_input`] splices into: 40 synthetic Gaussians of SH
/// degree 1, two rates, KLT bases, tiles of at most 16 (built once).
pub fn explicit_payload_base() -> &'static [u8] {
    static BASE: std::sync::OnceLock<Vec<u8>> = std::sync::OnceLock::new();
    BASE.get_or_init(|| {
        use salvq_gen::gaussians::{generate_gaussians, GaussianParams};
        let g = generate_gaussians(&GaussianParams::new(40, 1, 5));
        let Ok(p) = salvq_encoder::explicit::PreparedGaussians::new(&g) else {
            return Vec::new();
        };
        let plan = explicit_plan(&p);
        let plans = vec![plan.clone(), plan.scaled(2.0)];
        let options = salvq_encoder::explicit::ExplicitOptions {
            rates: salvq_encoder::explicit::RateControl::Plans(plans.clone()),
            klt: Some(vec![false, false, false, true, true]),
            tile_gaussians: 16,
            ..Default::default()
        };
        salvq_encoder::explicit::encode_prepared(&p, &plans, &options)
            .map_or_else(|_| Vec::new(), |e| e.stream)
    })
}

/// One payload of a valid stream replaced by fuzz bytes (`data[0]` picks the chunk from
/// [`PAYLOAD_TAGS`], the rest is the payload), CRCs valid: the payload decoders meet hostile
/// bytes behind a valid signature, `HEAD` and chunk order, which whole-stream mutation
/// rarely keeps. Checked as [`decode_checked`] checks.
pub fn payload_input(data: &[u8]) {
    let Some((&which, payload)) = data.split_first() else {
        return;
    };
    let pick = usize::from(which) % (PAYLOAD_TAGS.len() + EXPLICIT_PAYLOAD_TAGS.len());
    let (base, tag) = match PAYLOAD_TAGS.get(pick) {
        Some(&tag) => (payload_base(), tag),
        None => (
            explicit_payload_base(),
            EXPLICIT_PAYLOAD_TAGS[pick - PAYLOAD_TAGS.len()],
        ),
    };
    if let Some(stream) =
        salvq_encoder::writers::surgery::edit_payload(base, tag, |p| *p = payload.to_vec())
    {
        decode_checked(&stream, &NoMeter);
    }
}

/// The `HEAD` preflight (§1.4) on arbitrary bytes: never panics; an accepted payload states a
/// decoded size within the limits and writes back to the same bytes (one encoding per
/// preflight).
pub fn preflight_input(data: &[u8]) {
    let limits = fuzz_limits();
    let Ok(p) = salvq_bitstream::container::preflight::Preflight::parse(data, &limits) else {
        return;
    };
    assert!(p.decoded_bytes <= limits.max_alloc_bytes);
    assert_eq!(
        p.to_payload(),
        data,
        "an accepted HEAD writes back differently"
    );
}

/// Extraction: never panics; what it writes decodes at that rate, and extracting the same
/// rate from it gives the same bytes.
pub fn extract_input(data: &[u8]) {
    let Some((&first, stream)) = data.split_first() else {
        return;
    };
    let rate = first % 4;
    let limits = fuzz_limits();
    let Ok(single) = extract_rate(stream, rate, &limits) else {
        return;
    };
    assert!(Signature::parse(&single).is_ok());
    let again = extract_rate(&single, rate, &limits).expect("an extracted stream extracts");
    assert_eq!(again, single, "extraction is not idempotent");
    let _ = (salvq::Decoder::builder().limits(limits).rate(Some(rate)))
        .build()
        .decode(&single)
        .and_then(salvq::Scene::try_into_anchors);
}

/// The octree decoder (§8) on arbitrary bytes: never panics; what it decodes has the asked
/// count, coordinates below `2^depth` in Morton order, and re-encodes to a body that decodes
/// to the same voxels.
pub fn geometry_input(data: &[u8]) {
    let [d, a0, a1, body @ ..] = data else {
        return;
    };
    let depth = d % 22;
    let anchors = 1 + u32::from(u16::from_le_bytes([*a0, *a1]) % 4096);
    let tables = GaussianTables::standard();
    let Ok(voxels) = salvq_bitstream::geometry::decode(body, depth, anchors, tables) else {
        return;
    };
    assert_eq!(voxels.len(), anchors as usize);
    assert!(voxels
        .iter()
        .flatten()
        .all(|&c| u64::from(c) < 1u64 << depth));
    assert!(voxels.windows(2).all(|w| morton3(w[0]) <= morton3(w[1])));
    let again = salvq_encoder::writers::encode_geometry(&voxels, depth, tables)
        .expect("decoded voxels encode");
    let back = salvq_bitstream::geometry::decode(&again, depth, anchors, tables)
        .expect("re-encoded decodes");
    assert_eq!(back, voxels);
}

/// Parameters of a structured round trip, each reduced to a small range.
#[derive(Debug, Clone, Copy)]
pub struct RoundTrip {
    pub anchors: u16,
    pub seed: u64,
    pub feat_dim: u8,
    pub rates: u8,
    pub lattice: u8,
    pub search: u8,
    pub tile_anchors: u16,
    pub fit: bool,
}

impl RoundTrip {
    /// Reads the parameters from the first 19 bytes of `data` (little-endian, in field
    /// order; missing bytes are 0), so that a fuzzer's raw input and a stored finding replay
    /// the same way.
    pub fn from_bytes(data: &[u8]) -> RoundTrip {
        let mut b = [0u8; 19];
        for (dst, src) in b.iter_mut().zip(data) {
            *dst = *src;
        }
        let u16_at = |i: usize| u16::from_le_bytes([b[i], b[i + 1]]);
        let mut seed = [0u8; 8];
        seed.copy_from_slice(&b[2..10]);
        RoundTrip {
            anchors: u16_at(0),
            seed: u64::from_le_bytes(seed),
            feat_dim: b[10],
            rates: b[11],
            lattice: b[12],
            search: b[13],
            tile_anchors: u16_at(14),
            fit: b[16] & 1 == 1,
        }
    }
}

/// A small generated scene encoded with the given options: the encoder either refuses with a
/// typed error or writes a stream that decodes, at every coded rate, to exactly its prediction.
pub fn round_trip(p: RoundTrip) {
    let params = GenParams {
        feat_dim: 1 + u16::from(p.feat_dim % 24),
        rates: 1 + p.rates % 3,
        feat_basis: p.lattice % 5 == 3,
        ..GenParams::small(1 + u32::from(p.anchors % 400), p.seed)
    };
    let model = generate(&params);
    let lattice = match p.lattice % 5 {
        0 => Some(LatticeKind::Identity),
        1 => Some(LatticeKind::Dn),
        2 => Some(LatticeKind::E8Product),
        3 => Some(LatticeKind::General),
        _ => None,
    };
    let search = match p.search % 5 {
        0 => Search::Auto,
        1 => Search::Rounding,
        2 => Search::NearestPlane,
        3 => Search::Closest { max_nodes: 200 },
        _ => Search::Rdo { lambda_milli: 1000 },
    };
    let rates: Vec<u8> = (0..params.rates).collect();
    let options = EncodeOptions {
        rates: rates.clone(),
        feat_lattice: lattice,
        search,
        tile_anchors: 1 + u32::from(p.tile_anchors % 500),
        fit_scales: p.fit,
        ..Default::default()
    };
    let Ok(e) = encode_full(&model, &options) else {
        return;
    };
    for layer in &e.layers {
        let d = (salvq::Decoder::builder().rate(Some(layer.rate)))
            .build()
            .decode(&e.stream)
            .and_then(salvq::Scene::try_into_anchors)
            .expect("an encoded stream decodes");
        assert_eq!(d, layer.expected, "rate {}", layer.rate);
    }
}
