//! A payload's first byte, its coding method, and the length check of its body (spec §1.6
//! steps 1-3), shared by every chunk type.

use super::tag::ChunkTag;
use crate::error::{Error, Result};

/// `coding_method` 0: raw little-endian values (§1.6).
pub const METHOD_RAW: u8 = 0;
/// `coding_method` 1: the chunk type's coded form (§1.6, §6.6).
pub const METHOD_CODED: u8 = 1;

/// Splits off the method byte and checks it is the method this chunk type uses (§1.6 steps 1-2).
pub fn body(tag: ChunkTag, payload: &[u8], method: u8) -> Result<&[u8]> {
    match payload {
        [m, rest @ ..] if *m == method => Ok(rest),
        [method, ..] => Err(Error::UnknownCodingMethod {
            tag,
            method: *method,
        }),
        [] => Err(Error::ChunkSizeMismatch {
            tag,
            expected: 1,
            found: 0,
        }),
    }
}

/// Checks the body length before anything is allocated from it (§1.6 step 3).
pub fn expect_len(tag: ChunkTag, body: &[u8], expected: u64) -> Result<()> {
    if body.len() as u64 != expected {
        return Err(Error::ChunkSizeMismatch {
            tag,
            expected: expected + 1,
            found: body.len() as u64 + 1,
        });
    }
    Ok(())
}
