//! Writes the fuzz targets' seeds under `fuzz/seeds/`: of the `decode` and `extract` targets
//! (five small streams and the explicit-profile base), of `geometry` (the tiles' `APOS`
//! bodies of one of them), and of the `payload` and `preflight` targets (each payload of the
//! base streams, and the `HEAD` payloads of the conformance vectors). Run after a format
//! change, then `cargo test --test fuzz_regressions` (which replays every seed):
//!
//! `cargo run -p salvq-conformance --example write_fuzz_seeds`

use std::path::Path;

use salvq_bitstream::model::LatticeKind;
use salvq_encoder::writers::surgery::chunks;
use salvq_encoder::{encode_full, EncodeOptions, Search};
use salvq_gen::{generate, GenParams};

fn files(dir: &Path) -> Vec<std::path::PathBuf> {
    let mut out: Vec<_> = std::fs::read_dir(dir)
        .map(|d| d.filter_map(|e| e.ok().map(|e| e.path())).collect())
        .unwrap_or_default();
    out.sort();
    out
}

/// The `geometry` target's seeds: each tile's `APOS` body of a tiled stream, after its depth
/// and anchor count (`salvq_conformance::fuzzing::geometry_input`'s layout).
fn write_geometry_seeds(dir: &Path, stream: &[u8]) {
    use salvq_bitstream::container::chunk::ChunkTag;
    let all = chunks(stream).unwrap();
    let payload = |tag| &all.iter().find(|(t, _)| *t == tag).unwrap().1;
    let (tils, apos) = (payload(ChunkTag::TILS), payload(ChunkTag::APOS));
    let word = |b: &[u8], at: usize| u32::from_le_bytes(b[at..at + 4].try_into().unwrap());
    let tiles = word(tils, 1) as usize;
    let bodies =
        salvq_bitstream::tiles::split_bodies(ChunkTag::APOS, 1, &apos[1..], tiles).unwrap();
    for old in files(dir) {
        std::fs::remove_file(old).unwrap();
    }
    for (t, body) in bodies.iter().enumerate() {
        // §10.1: each tile entry is 41 bytes (anchors, level, cell, box) after 5.
        let entry = 5 + 41 * t;
        let anchors = word(tils, entry) as u16;
        let mut seed = vec![tils[entry + 4]];
        seed.extend_from_slice(&(anchors - 1).to_le_bytes());
        seed.extend_from_slice(body);
        std::fs::write(dir.join(format!("tile{t}.bin")), seed).unwrap();
    }
}

fn main() {
    // This package's folder is crates/salvq-conformance.
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    write_stream_seeds(&root);
    write_payload_seeds(&root);
    write_preflight_seeds(&root);
}

/// The streams seeding `decode` and `extract`: a name, the generated scene, the encoder's
/// options, and the rate `extract` asks for: small scenes, coded with USQ, two rates, D_n,
/// tiled E8 with RDO, and fitted bases by region.
fn seed_streams() -> [(&'static str, GenParams, EncodeOptions, u8); 5] {
    let small = |n, seed, basis| GenParams {
        feat_basis: basis,
        ..GenParams::small(n, seed)
    };
    [
        ("usq", small(40, 1, false), EncodeOptions::default(), 0),
        (
            "salvq_2rates",
            small(60, 2, true),
            EncodeOptions {
                rates: vec![0, 1],
                ..Default::default()
            },
            1,
        ),
        (
            "dn",
            small(40, 3, false),
            EncodeOptions {
                feat_lattice: Some(LatticeKind::Dn),
                ..Default::default()
            },
            0,
        ),
        (
            "e8_tiles",
            GenParams {
                feat_dim: 16,
                ..small(80, 4, false)
            },
            EncodeOptions {
                feat_lattice: Some(LatticeKind::E8Product),
                tile_anchors: 16,
                search: Search::Rdo { lambda_milli: 1000 },
                ..Default::default()
            },
            0,
        ),
        (
            "klt_regions",
            small(90, 5, true),
            EncodeOptions {
                fit_basis: true,
                feat_regions: 3,
                encoder_note: Some("seed".into()),
                ..Default::default()
            },
            0,
        ),
    ]
}

/// Stream seeds for `decode`, and the same with a rate byte first for `extract`; the tiled
/// one's tiles seed `geometry`.
fn write_stream_seeds(root: &Path) {
    for (name, params, options, rate) in seed_streams() {
        let stream = encode_full(&generate(&params), &options).unwrap().stream;
        std::fs::write(
            root.join(format!("fuzz/seeds/decode/{name}.salvq")),
            &stream,
        )
        .unwrap();
        let mut e = vec![rate];
        e.extend_from_slice(&stream);
        std::fs::write(root.join(format!("fuzz/seeds/extract/{name}.bin")), e).unwrap();
        if name == "e8_tiles" {
            write_geometry_seeds(&root.join("fuzz/seeds/geometry"), &stream);
        }
    }
}

/// The explicit-profile base stream (spec §3) as a `decode` and `extract` seed, and the
/// `payload` target's seeds: each payload of the two base streams after its tag's index.
fn write_payload_seeds(root: &Path) {
    // An explicit-profile stream (spec §3): the payload target's explicit base.
    let explicit = salvq_conformance::fuzzing::explicit_payload_base();
    std::fs::write(root.join("fuzz/seeds/decode/explicit_sh1.salvq"), explicit).unwrap();
    let mut e = vec![1];
    e.extend_from_slice(explicit);
    std::fs::write(root.join("fuzz/seeds/extract/explicit_sh1.bin"), e).unwrap();
    let dir = root.join("fuzz/seeds/payload");
    std::fs::create_dir_all(&dir).unwrap();
    let base = chunks(salvq_conformance::fuzzing::payload_base()).unwrap();
    for (i, tag) in salvq_conformance::fuzzing::PAYLOAD_TAGS.iter().enumerate() {
        let payload = &base.iter().find(|(t, _)| t == tag).unwrap().1;
        let mut seed = vec![i as u8];
        seed.extend_from_slice(payload);
        std::fs::write(dir.join(format!("{}.bin", tag.as_str())), seed).unwrap();
    }
    let explicit = chunks(salvq_conformance::fuzzing::explicit_payload_base()).unwrap();
    for (i, tag) in salvq_conformance::fuzzing::EXPLICIT_PAYLOAD_TAGS
        .iter()
        .enumerate()
    {
        let payload = &explicit.iter().find(|(t, _)| t == tag).unwrap().1;
        let mut seed = vec![(salvq_conformance::fuzzing::PAYLOAD_TAGS.len() + i) as u8];
        seed.extend_from_slice(payload);
        std::fs::write(dir.join(format!("explicit-{}.bin", tag.as_str())), seed).unwrap();
    }
}

/// The `preflight` target's seeds: the `HEAD` payload of each valid anchors-profile
/// conformance vector.
fn write_preflight_seeds(root: &Path) {
    let dir = root.join("fuzz/seeds/preflight");
    std::fs::create_dir_all(&dir).unwrap();
    for v in files(&root.join("conformance/vectors")) {
        if v.extension().is_none_or(|e| e != "salvq") {
            continue;
        }
        let name = v.file_stem().unwrap().to_string_lossy().to_string();
        // Must-fail streams, and explicit-profile streams (their first chunk is GHED).
        if name.starts_with("x-") || name.starts_with("g-") {
            continue;
        }
        let head = chunks(&std::fs::read(&v).unwrap())
            .unwrap()
            .swap_remove(0)
            .1;
        std::fs::write(dir.join(format!("{name}.bin")), head).unwrap();
    }
}
