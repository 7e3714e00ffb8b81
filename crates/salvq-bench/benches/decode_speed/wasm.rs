//! The decode_speed bench's WebAssembly timing: salvq-wasm built for Node and timed there.

use std::path::{Path, PathBuf};
use std::process::Command;

use salvq_bench::coder::median;

use super::{target_dir, Res};

/// The wasm package (`wasm-bindgen --target nodejs`) and the timing script beside it.
pub(crate) fn build_wasm() -> Res<PathBuf> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let dir = target_dir().join("decode_speed");
    // Its own target folder: the cargo running this bench may hold the lock on target/.
    let wasm_target = dir.join("wasm-target");
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let status = Command::new(cargo)
        .current_dir(&root)
        .args(["build", "-q", "--release", "-p", "salvq-wasm"])
        .args(["--target", "wasm32-unknown-unknown", "--target-dir"])
        .arg(&wasm_target)
        .status()?;
    if !status.success() {
        return Err("cargo build of salvq-wasm failed".into());
    }
    let pkg = dir.join("pkg");
    let wasm = wasm_target.join("wasm32-unknown-unknown/release/salvq_wasm.wasm");
    let status = Command::new("wasm-bindgen")
        .args(["--target", "nodejs", "--out-dir"])
        .arg(&pkg)
        .arg(&wasm)
        .status()?;
    if !status.success() {
        return Err("wasm-bindgen failed".into());
    }
    std::fs::write(
        pkg.join("decode_time.cjs"),
        include_str!("../../wasm/decode_time.cjs"),
    )?;
    Ok(pkg)
}

/// Decodes `stream` `runs` times in Node: each run's milliseconds and the last output's
/// arrays (see [`dump`]). `workers` 0: `decode` on Node's main thread; W ≥ 1: W worker
/// threads, each decoding its part with `decodePart` (§10.3.2), timed until the last part's
/// arrays reach the main thread (`wasm/decode_time.cjs`).
pub(crate) fn wasm_decode(
    pkg: &Path,
    stream: &Path,
    runs: usize,
    workers: usize,
) -> Res<(Vec<f64>, Vec<u8>)> {
    let dump_path = pkg.join("dump.bin");
    let out = Command::new("node")
        .arg(pkg.join("decode_time.cjs"))
        .arg(pkg.join("salvq_wasm.js"))
        .arg(stream)
        .arg(runs.to_string())
        .arg(&dump_path)
        .arg(workers.to_string())
        .output()?;
    let text = String::from_utf8_lossy(&out.stdout);
    let line = text
        .lines()
        .find_map(|l| l.strip_prefix("RESULT "))
        .ok_or_else(|| format!("node: {}", String::from_utf8_lossy(&out.stderr)))?;
    // `{"ms":[a,b,…],"count":N}`
    let ms = line
        .split('[')
        .nth(1)
        .and_then(|s| s.split(']').next())
        .ok_or("node: no times")?
        .split(',')
        .map(|x| x.parse::<f64>())
        .collect::<Result<Vec<_>, _>>()?;
    Ok((ms, std::fs::read(&dump_path)?))
}

/// The wasm decode's median (runs after the first) and first run, seconds, on `workers`
/// as [`wasm_decode`] says; checks its output against `expected`.
pub(crate) fn wasm_times(
    pkg: &Path,
    stream: &Path,
    rounds: usize,
    expected: &[u8],
    what: &str,
    workers: usize,
) -> Res<(f64, f64)> {
    let (ms, out) = wasm_decode(pkg, stream, rounds + 1, workers)?;
    assert!(
        out == expected,
        "{what}: the wasm decode on {workers} workers equals the native one"
    );
    let first = ms[0] * 1e-3;
    let mut rest: Vec<f64> = ms[1..].iter().map(|m| m * 1e-3).collect();
    Ok((median(&mut rest), first))
}
