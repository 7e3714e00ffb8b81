//! Replays every kept fuzz finding (listed in [`FINDINGS`]: the files under
//! `tests/fuzz_regressions/`, `<target>-<name>.bin`, and the findings kept elsewhere) and every
//! seed under `fuzz/seeds/<target>/` through the same checks the fuzz targets run
//! (`salvq_conformance::fuzzing`), so a fixed bug stays fixed and the seeds stay valid inputs
//! (`cargo run -p salvq-conformance --example write_fuzz_seeds` writes the seeds anew).
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
    // (decode, re-encode, decode again), which panic if the shift is taken unchecked.
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
    match (salvq::Decoder::builder()).build().decode(data) {
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
                let options = salvq::Decoder::builder();
                assert!(options.build().decode(&data).is_ok(), "{}", path.display());
            }
            count += 1;
        }
    }
    assert!(count >= 8, "only {count} seeds");
}
