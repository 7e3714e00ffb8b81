//! Replays every fuzz finding kept under `tests/fuzz_regressions/` (`<target>-<name>.bin`)
//! and every seed under `fuzz/seeds/<target>/` through the same checks the fuzz targets run
//! (`salvq::fuzzing`), so a fixed bug stays fixed and the seeds stay valid inputs.

use std::path::Path;

use salvq::fuzzing::{decode_input, extract_input, geometry_input, round_trip, RoundTrip};

fn replay(target: &str, data: &[u8]) {
    match target {
        "decode" => decode_input(data),
        "extract" => extract_input(data),
        "geometry" => geometry_input(data),
        "roundtrip" => round_trip(RoundTrip::from_bytes(data)),
        other => panic!("unknown fuzz target '{other}'"),
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
fn kept_findings_replay_clean() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fuzz_regressions");
    for path in files(&dir)
        .into_iter()
        .filter(|p| p.extension().is_some_and(|e| e == "bin"))
    {
        let name = path.file_name().unwrap().to_string_lossy().to_string();
        let target = name.split('-').next().unwrap_or_default().to_string();
        replay(&target, &std::fs::read(&path).unwrap());
    }
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
                assert!(salvq::decode(&data).is_ok(), "{}", path.display());
            }
            count += 1;
        }
    }
    assert!(count >= 8, "only {count} seeds");
}
