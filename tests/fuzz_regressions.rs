//! Replays every kept fuzz finding (listed in [`FINDINGS`]: the files under
//! `tests/fuzz_regressions/`, `<target>-<name>.bin`, and the findings kept elsewhere) and every
//! seed under `fuzz/seeds/<target>/` through the same checks the fuzz targets run
//! (`salvq_conformance::fuzzing`), so a fixed bug stays fixed and the seeds stay valid inputs.
//! A kept finding also states what the decoder must answer for it, and that answer is checked.

use std::path::Path;

use salvq_conformance::fuzzing::{
    decode_input, extract_input, geometry_input, payload_input, preflight_input, round_trip,
    RoundTrip,
};

fn replay(target: &str, data: &[u8]) {
    match target {
        "decode" => decode_input(data),
        "extract" => extract_input(data),
        "geometry" => geometry_input(data),
        "payload" => payload_input(data),
        "preflight" => preflight_input(data),
        "roundtrip" => round_trip(RoundTrip::from_bytes(data)),
        other => panic!("unknown fuzz target '{other}'"),
    }
}

/// One kept finding: the input (a path from the repository root), the fuzz target whose checks
/// it replays through, and, for whole streams (target `decode`), what the reference decoder
/// answers with default options: `"ok"` or `"error:<Class>"`, spelled as the conformance
/// manifest spells it (`salvq::Error::class`).
struct Finding {
    file: &'static str,
    target: &'static str,
    expect: Option<&'static str>,
}

/// Every kept finding. A new one (`tests/fuzz_regressions/<target>-<name>.bin`) needs a line
/// here: [`every_file_in_the_findings_folder_is_listed`] fails until it has one.
const FINDINGS: &[Finding] = &[
    // §5.4 step 1: step-adjustment outputs with the unit exponent 8 + 30 + 30 = 68. The
    // rounding shift by 68 panicked in debug builds ("shift left with overflow") and wrapped
    // modulo 64 in release. Found by the Python decoder, kept as a conformance vector (see
    // tests/fuzz_regressions/README.md); replayed here through the `decode` target's checks
    // (decode, re-encode, decode again), which panic on the old code.
    Finding {
        file: "conformance/vectors/extreme-exponents.salvq",
        target: "decode",
        expect: Some("ok"),
    },
    // §3.8.4: a progressive stream cut inside GQUA, before any layer. The extractor took a
    // truncation with no layer due as a cut after the selected layer and wrote GHED and SEND
    // alone, a stream that does not extract again (found by libFuzzer, target `extract`).
    Finding {
        file: "tests/fuzz_regressions/extract-progressive-cut-in-gqua.bin",
        target: "extract",
        expect: None,
    },
];

/// What the reference decoder answers for a whole stream, as [`Finding::expect`] spells it.
fn outcome(data: &[u8]) -> String {
    match salvq::decoder::decode_any(data, &salvq::DecodeOptions::default()) {
        Ok(_) => "ok".to_string(),
        Err(e) => format!("error:{}", e.class()),
    }
}

/// Replays `data` through `target`'s checks (which panic when a property breaks) and compares
/// the decoder's answer with `expect`.
fn check(target: &str, data: &[u8], expect: Option<&str>) -> Result<(), String> {
    replay(target, data);
    match expect {
        Some(want) if target == "decode" => {
            let got = outcome(data);
            if got == want {
                Ok(())
            } else {
                Err(format!("expected {want}, the decoder answers {got}"))
            }
        }
        Some(_) => Err(format!("no outcome to compare for target '{target}'")),
        None => Ok(()),
    }
}

fn files(dir: &Path) -> Vec<std::path::PathBuf> {
    let mut out: Vec<_> = std::fs::read_dir(dir)
        .map(|d| d.filter_map(|e| e.ok().map(|e| e.path())).collect())
        .unwrap_or_default();
    out.sort();
    out
}

#[test]
fn kept_findings_replay_to_their_expected_outcome() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    assert!(!FINDINGS.is_empty(), "no kept finding to replay");
    for f in FINDINGS {
        let data = std::fs::read(root.join(f.file))
            .unwrap_or_else(|e| panic!("kept finding {}: {e}", f.file));
        if let Err(e) = check(f.target, &data, f.expect) {
            panic!("kept finding {}: {e}", f.file);
        }
    }
}

/// A file dropped into `tests/fuzz_regressions/` without a line in [`FINDINGS`] would replay
/// nowhere: every file there but the README must be listed, under the target its name gives.
#[test]
fn every_file_in_the_findings_folder_is_listed() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fuzz_regressions");
    let listed = files(&dir);
    assert!(
        listed.iter().any(|p| p.ends_with("README.md")),
        "{} has no README",
        dir.display()
    );
    for path in listed {
        let name = path.file_name().unwrap().to_string_lossy().to_string();
        if name == "README.md" {
            continue;
        }
        let file = format!("tests/fuzz_regressions/{name}");
        let entry = FINDINGS.iter().find(|f| f.file == file);
        let entry = entry.unwrap_or_else(|| panic!("{file} is not listed in FINDINGS"));
        let target = name.strip_suffix(".bin").and_then(|n| n.split_once('-'));
        assert_eq!(
            target.map(|(t, _)| t),
            Some(entry.target),
            "{file}: not named <{}>-<name>.bin",
            entry.target
        );
    }
}

/// The replay catches a finding whose answer changed: a planted input (a valid stream with
/// its last CRC byte flipped) passes with its true answer and fails with any other.
#[test]
fn the_replay_reports_a_changed_outcome() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut data = std::fs::read(root.join("fuzz/seeds/decode/usq.salvq")).unwrap();
    *data.last_mut().unwrap() ^= 1;
    assert_eq!(
        check("decode", &data, Some("error:ChunkCrcMismatch")),
        Ok(())
    );
    let wrong = check("decode", &data, Some("ok"));
    assert_eq!(
        wrong,
        Err("expected ok, the decoder answers error:ChunkCrcMismatch".to_string())
    );
}

#[test]
fn seeds_replay_clean_and_the_stream_seeds_decode() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz/seeds");
    let mut count = 0;
    for target in ["decode", "extract", "geometry", "roundtrip"] {
        for path in files(&root.join(target)) {
            let data = std::fs::read(&path).unwrap();
            replay(target, &data);
            if target == "decode" {
                // A seed is a valid stream: the fuzzer starts from inputs that decode.
                let options = salvq::DecodeOptions::default();
                assert!(
                    salvq::decoder::decode_any(&data, &options).is_ok(),
                    "{}",
                    path.display()
                );
            }
            count += 1;
        }
    }
    assert!(count >= 8, "only {count} seeds");
}

/// The `geometry` target's seeds: each tile's `APOS` body of a tiled stream, after its depth
/// and anchor count (`salvq_conformance::fuzzing::geometry_input`'s layout).
fn write_geometry_seeds(dir: &Path, stream: &[u8]) {
    use salvq::container::chunk::ChunkTag;
    use salvq::container::surgery::chunks;
    let all = chunks(stream).unwrap();
    let payload = |tag| &all.iter().find(|(t, _)| *t == tag).unwrap().1;
    let (tils, apos) = (payload(ChunkTag::TILS), payload(ChunkTag::APOS));
    let word = |b: &[u8], at: usize| u32::from_le_bytes(b[at..at + 4].try_into().unwrap());
    let tiles = word(tils, 1) as usize;
    let bodies = salvq::tiles::split_bodies(ChunkTag::APOS, 1, &apos[1..], tiles).unwrap();
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

/// Writes the seeds of the `decode` and `extract` targets (five small streams), and of the
/// `payload` and `preflight` targets (each payload of the base stream, and the `HEAD`
/// payloads of the conformance vectors); run after a format change:
/// `SALVQ_WRITE_SEEDS=1 cargo test --test fuzz_regressions write_seeds -- --ignored`.
#[test]
#[ignore]
fn write_seeds() {
    use salvq::container::surgery::chunks;
    if std::env::var("SALVQ_WRITE_SEEDS").is_err() {
        return;
    }
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    // Stream seeds for `decode`, and the same with a rate byte first for `extract`.
    use salvq::LatticeKind;
    use salvq_encoder::{encode_full, EncodeOptions, Search};
    use salvq_gen::{generate, GenParams};
    let small = |n, seed, basis| GenParams {
        feat_basis: basis,
        ..GenParams::small(n, seed)
    };
    let streams: [(&str, GenParams, EncodeOptions, u8); 5] = [
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
    ];
    for (name, params, options, rate) in streams {
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
    let dir = root.join("fuzz/seeds/preflight");
    std::fs::create_dir_all(&dir).unwrap();
    for v in files(&root.join("conformance/vectors")) {
        if v.extension().map_or(true, |e| e != "salvq") {
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
