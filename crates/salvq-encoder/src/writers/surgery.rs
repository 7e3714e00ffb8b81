//! Chunk surgery on valid streams: split a stream into its chunks, change one, and put it back
//! together with valid CRCs, so a malformed stream reaches the rule it targets instead of
//! failing at the CRC (§1.3). Used by the must-fail conformance vectors, the tests and the
//! fuzz harness; never by the decoder.

use salvq_bitstream::container::chunk::{write_chunk, ChunkReader, ChunkTag};
use salvq_bitstream::container::signature::{self, SIGNATURE_LEN};
use salvq_bitstream::error::Result;
use salvq_bitstream::limits::Limits;

/// The stream's chunks as (tag, payload), in order.
///
/// # Errors
/// The first framing error of the stream (§1.2, §1.3); a stream shorter than the signature is
/// [`salvq_bitstream::Error::Truncated`].
pub fn chunks(stream: &[u8]) -> Result<Vec<(ChunkTag, Vec<u8>)>> {
    let (_, rest) = signature::Signature::parse(stream)?;
    let mut r = ChunkReader::new(rest, SIGNATURE_LEN as u64, &Limits::default());
    let mut out = Vec::new();
    while let Some(c) = r.next_chunk()? {
        out.push((c.tag, c.payload.to_vec()));
    }
    Ok(out)
}

/// Re-assembles a stream from the first [`SIGNATURE_LEN`] bytes of `signature` and (tag,
/// payload) pairs, each with its CRC computed.
pub fn assemble(signature: &[u8], chunks: &[(ChunkTag, Vec<u8>)]) -> Vec<u8> {
    let mut out = signature[..SIGNATURE_LEN.min(signature.len())].to_vec();
    for (tag, payload) in chunks {
        write_chunk(&mut out, *tag, payload);
    }
    out
}

/// The stream with the first chunk tagged `tag` changed by `f` (CRC recomputed); `None` when
/// the stream does not frame or has no such chunk.
pub fn edit_payload(stream: &[u8], tag: ChunkTag, f: impl FnOnce(&mut Vec<u8>)) -> Option<Vec<u8>> {
    let mut cs = chunks(stream).ok()?;
    let c = cs.iter_mut().find(|(t, _)| *t == tag)?;
    f(&mut c.1);
    Some(assemble(stream, &cs))
}

/// Byte offset (from the start of the stream) of the first chunk tagged `tag`, that is of its
/// length field; `None` when the stream does not frame or has no such chunk.
pub fn chunk_offset(stream: &[u8], tag: ChunkTag) -> Option<usize> {
    let (_, rest) = signature::Signature::parse(stream).ok()?;
    let mut r = ChunkReader::new(rest, SIGNATURE_LEN as u64, &Limits::default());
    while let Ok(Some(c)) = r.next_chunk() {
        if c.tag == tag {
            return usize::try_from(c.offset).ok();
        }
    }
    None
}
