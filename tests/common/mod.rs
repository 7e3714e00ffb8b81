//! Helpers shared by the integration tests: a small valid stream, and chunk surgery that
//! keeps CRCs valid so a test reaches the rule it targets.
#![allow(dead_code)]

use salvq::container::chunk::{write_chunk, ChunkReader, ChunkTag};
use salvq::gen::{generate, GenParams};
use salvq::{Limits, SceneModel};

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
    salvq::encode(&small_model()).expect("valid model encodes")
}

/// What a decoder must output for `small_stream()`.
pub fn small_expected() -> SceneModel {
    salvq::encoder::encode_full(&small_model(), &Default::default())
        .expect("valid model encodes")
        .layers
        .swap_remove(0)
        .expected
}

/// The stream's chunks as (tag, payload).
pub fn chunks(stream: &[u8]) -> Vec<(ChunkTag, Vec<u8>)> {
    let mut r = ChunkReader::new(&stream[12..], 12, &Limits::default());
    let mut out = Vec::new();
    while let Some(c) = r.next_chunk().expect("valid stream") {
        out.push((c.tag, c.payload.to_vec()));
    }
    out
}

/// Re-assembles a stream from its signature and (tag, payload) pairs, with valid CRCs.
pub fn assemble(signature: &[u8], chunks: &[(ChunkTag, Vec<u8>)]) -> Vec<u8> {
    let mut out = signature[..12].to_vec();
    for (tag, payload) in chunks {
        write_chunk(&mut out, *tag, payload);
    }
    out
}

/// The stream with one chunk's payload changed by `f` (CRC recomputed).
pub fn edit_payload(stream: &[u8], tag: ChunkTag, f: impl FnOnce(&mut Vec<u8>)) -> Vec<u8> {
    let mut cs = chunks(stream);
    let c = cs
        .iter_mut()
        .find(|(t, _)| *t == tag)
        .expect("chunk present");
    f(&mut c.1);
    assemble(stream, &cs)
}

/// Byte offset of a chunk's length field.
pub fn chunk_offset(stream: &[u8], tag: ChunkTag) -> usize {
    let mut r = ChunkReader::new(&stream[12..], 12, &Limits::default());
    while let Some(c) = r.next_chunk().expect("valid stream") {
        if c.tag == tag {
            return c.offset as usize;
        }
    }
    panic!("no chunk {tag}");
}
