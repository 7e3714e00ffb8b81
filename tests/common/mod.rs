//! Helpers shared by the integration tests: a small valid stream, and chunk surgery that
//! keeps CRCs valid so a test reaches the rule it targets.
#![allow(dead_code)]

use salvq::container::chunk::ChunkTag;
use salvq::container::surgery;
use salvq::SceneModel;
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

/// A file of `../shared/data` (the real scenes beside the checkout), or `None` with a
/// "skipped" note when it is not there (a panic where `SALVQ_REQUIRE_DATA` is set).
pub fn shared_data(name: &str) -> Option<Vec<u8>> {
    let path = repo_root().join("../shared/data").join(name);
    match std::fs::read(&path) {
        Ok(b) => Some(b),
        // Where the scenes are known to be present (CI sets SALVQ_REQUIRE_DATA), a missing
        // one is a failure, not a test that passes by doing nothing.
        Err(e) if std::env::var_os("SALVQ_REQUIRE_DATA").is_some() => {
            panic!("{}: {e} (SALVQ_REQUIRE_DATA is set)", path.display())
        }
        Err(_) => {
            eprintln!("skipped: {} not found", path.display());
            None
        }
    }
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
