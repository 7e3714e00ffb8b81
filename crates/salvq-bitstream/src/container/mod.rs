//! The chunked container (spec §1): signature, chunk framing, preflight, the chunk order of
//! both profiles.

pub mod bytes;
pub mod chunk;
pub mod method;
pub mod mlps;
pub mod order;
pub mod payload;
pub mod preflight;
pub mod signature;
pub mod tag;

pub use chunk::{Chunk, ChunkReader, ChunkTag};
pub use preflight::Preflight;
pub use signature::{Signature, FORMAT_MAJOR, FORMAT_MINOR, SIGNATURE_LEN};

use crate::limits::Limits;

/// Whether `data` is an explicit-profile stream: a valid signature and a first chunk, framed
/// and CRC-checked, tagged `GHED` (§3). Anything else is decoded, and its errors reported,
/// as the anchors profile.
pub fn is_explicit(data: &[u8]) -> bool {
    let Ok((_, rest)) = Signature::parse(data) else {
        return false;
    };
    let limits = Limits::default();
    let mut reader = ChunkReader::new(rest, SIGNATURE_LEN as u64, &limits);
    matches!(reader.next_chunk(), Ok(Some(c)) if c.tag == ChunkTag::GHED)
}
