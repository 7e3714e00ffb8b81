//! Helpers shared by the integration tests: a small valid stream, and chunk surgery that
//! keeps CRCs valid so a test reaches the rule it targets.
#![allow(dead_code)]

use salvq::SceneModel;
use salvq_bitstream::container::chunk::ChunkTag;
use salvq_encoder::writers::surgery;
use salvq_gen::{generate, GenParams};

/// 13 anchors of the small configuration with the identity basis (what format 0.2 codes).
pub fn small_model() -> SceneModel {
    generate(&GenParams {
        feat_basis: false,
        ..GenParams::small(13, 1)
    })
}

/// The same scene with a learned feature basis (SALVQ), for model-validation tests.
pub fn small_salvq_model() -> SceneModel {
    generate(&GenParams::small(13, 1))
}

pub fn small_stream() -> Vec<u8> {
    salvq_encoder::encode(&small_model()).expect("valid model encodes")
}

/// What a decoder must output for `small_stream()`.
pub fn small_expected() -> SceneModel {
    salvq_encoder::encode_full(&small_model(), &Default::default())
        .expect("valid model encodes")
        .layers
        .swap_remove(0)
        .expected
}

/// The stream's chunks as (tag, payload).
pub fn chunks(stream: &[u8]) -> Vec<(ChunkTag, Vec<u8>)> {
    surgery::chunks(stream).expect("valid stream")
}

/// Re-assembles a stream from its signature and (tag, payload) pairs, with valid CRCs.
pub fn assemble(signature: &[u8], chunks: &[(ChunkTag, Vec<u8>)]) -> Vec<u8> {
    surgery::assemble(signature, chunks)
}

/// The stream with one chunk's payload changed by `f` (CRC recomputed).
pub fn edit_payload(stream: &[u8], tag: ChunkTag, f: impl FnOnce(&mut Vec<u8>)) -> Vec<u8> {
    surgery::edit_payload(stream, tag, f).expect("chunk present")
}

/// Where each of `tiles` bodies starts in a tiled payload (§10.1: the method byte, each
/// tile's body length in bytes, then the bodies).
#[allow(dead_code)] // not every test file uses it
pub fn tile_body_starts(payload: &[u8], tiles: usize) -> Vec<usize> {
    let mut at = 1 + 4 * tiles;
    (0..tiles)
        .map(|t| {
            let b = &payload[1 + 4 * t..5 + 4 * t];
            let len = u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize;
            at += len;
            at - len
        })
        .collect()
}

/// Byte offset of a chunk's length field.
pub fn chunk_offset(stream: &[u8], tag: ChunkTag) -> usize {
    surgery::chunk_offset(stream, tag).unwrap_or_else(|| panic!("no chunk {tag}"))
}

/// A file of the real scenes beside the checkout (`../shared/data`, or the folder named by
/// `SALVQ_DATA_DIR`), or `None` when it is not there: the caller returns, its work skipped.
///
/// What a missing file does: where `SALVQ_REQUIRE_DATA` is set or `CI=true` (`.ci/run` runs
/// with `CI=true`, and also sets `SALVQ_REQUIRE_DATA` where the scenes are present) the test
/// fails. Elsewhere it passes and says so with a `SKIPPED` line written to the process's
/// stderr through `std::io::stderr()`, which libtest does not capture (it captures `print!` /
/// `eprint!` only), so `cargo test` shows the line even though the test passes.
pub fn shared_data(name: &str) -> Option<Vec<u8>> {
    use std::io::Write;
    let dir = std::env::var_os("SALVQ_DATA_DIR")
        .map_or_else(|| repo_root().join("../shared/data"), Into::into);
    let path = dir.join(name);
    match std::fs::read(&path) {
        Ok(b) => Some(b),
        Err(e) if data_required() => panic!(
            "{}: {e} (SALVQ_REQUIRE_DATA or CI=true: the real scenes must be present)",
            path.display()
        ),
        Err(_) => {
            let thread = std::thread::current();
            let test = thread.name().unwrap_or("a test");
            let _ = writeln!(
                std::io::stderr(),
                "SKIPPED {test}: {} not found (passes without its work)",
                path.display()
            );
            None
        }
    }
}

/// Whether a missing scene of [`shared_data`] fails the test: `SALVQ_REQUIRE_DATA` set, or
/// `CI=true`.
fn data_required() -> bool {
    std::env::var_os("SALVQ_REQUIRE_DATA").is_some()
        || std::env::var("CI").is_ok_and(|v| v.eq_ignore_ascii_case("true") || v == "1")
}

/// The repository root (the workspace root, which holds `spec/`), from whichever crate of
/// the workspace the test belongs to.
pub fn repo_root() -> std::path::PathBuf {
    let here = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    here.ancestors()
        .find(|d| d.join("spec").is_dir())
        .unwrap_or(here)
        .to_path_buf()
}
