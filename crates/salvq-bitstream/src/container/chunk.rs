//! Chunk framing (spec §1.3): `length`, `tag`, payload, CRC-32C over tag and payload.

pub use super::tag::ChunkTag;
use crate::error::{Error, Result, Structure};
use crate::limits::{LimitKind, Limits};

/// Bytes of a chunk's length and tag fields, before its payload.
pub const CHUNK_HEADER_LEN: usize = 8;
/// Bytes of a chunk's CRC, after its payload.
pub const CHUNK_CRC_LEN: usize = 4;
/// Bytes of framing around each payload: length (4), tag (4), CRC (4).
pub const CHUNK_OVERHEAD: u64 = (CHUNK_HEADER_LEN + CHUNK_CRC_LEN) as u64;

/// The CRC of a chunk: CRC-32C (Castagnoli) of tag then payload (spec §1.3).
pub fn chunk_crc(tag: ChunkTag, payload: &[u8]) -> u32 {
    crc32c::crc32c_append(crc32c::crc32c(&tag.0), payload)
}

/// §1.5 rules 4-5: `SEND` is empty and nothing follows it (`rest`: the bytes after it).
pub fn check_send(payload: &[u8], rest: &[u8]) -> Result<()> {
    if !payload.is_empty() {
        return Err(Error::ChunkSizeMismatch {
            tag: ChunkTag::SEND,
            expected: 0,
            found: payload.len() as u64,
        });
    }
    if !rest.is_empty() {
        return Err(Error::TrailingData {
            bytes: rest.len() as u64,
        });
    }
    Ok(())
}

/// Appends one framed chunk to `out`.
pub fn write_chunk(out: &mut Vec<u8>, tag: ChunkTag, payload: &[u8]) {
    out.extend_from_slice(&(payload.len() as u32).to_le_bytes());
    out.extend_from_slice(&tag.0);
    out.extend_from_slice(payload);
    out.extend_from_slice(&chunk_crc(tag, payload).to_le_bytes());
}

/// One chunk as read from a stream.
#[derive(Debug, Clone, Copy)]
pub struct Chunk<'a> {
    /// The chunk's four-byte tag (§1.3).
    pub tag: ChunkTag,
    /// Offset of the chunk's length field from the start of the stream.
    pub offset: u64,
    /// The payload bytes, borrowed from the stream.
    pub payload: &'a [u8],
    /// The CRC-32C stored after the payload, checked against [`chunk_crc`] (§1.3).
    pub crc: u32,
}

/// Reads framed chunks one after another (spec §1.3), checking tag bytes, the length
/// against [`Limits::max_chunk_bytes`] and the remaining bytes, and the CRC.
pub struct ChunkReader<'a> {
    rest: &'a [u8],
    offset: u64,
    limits: Limits,
}

impl<'a> ChunkReader<'a> {
    /// A reader over `rest`, whose first byte lies `offset` bytes into the stream; chunk
    /// lengths are checked against `limits`.
    pub fn new(rest: &'a [u8], offset: u64, limits: &Limits) -> Self {
        ChunkReader {
            rest,
            offset,
            limits: *limits,
        }
    }

    /// Bytes not yet read.
    pub fn remaining(&self) -> &'a [u8] {
        self.rest
    }

    /// The next chunk of a stream that must go on to `SEND`: running out of bytes is
    /// **Truncated** (§1.5 rule 4).
    pub fn next_before_send(&mut self) -> Result<Chunk<'a>> {
        self.next_chunk()?.ok_or(Error::Truncated {
            structure: Structure::ChunkHeader,
            needed: CHUNK_HEADER_LEN as u64,
            available: 0,
        })
    }

    /// The next chunk, `Ok(None)` at the end of the bytes.
    pub fn next_chunk(&mut self) -> Result<Option<Chunk<'a>>> {
        if self.rest.is_empty() {
            return Ok(None);
        }
        let [l0, l1, l2, l3, t0, t1, t2, t3, body @ ..] = self.rest else {
            return Err(Error::Truncated {
                structure: Structure::ChunkHeader,
                needed: CHUNK_HEADER_LEN as u64,
                available: self.rest.len() as u64,
            });
        };
        let length = u32::from_le_bytes([*l0, *l1, *l2, *l3]);
        let tag = ChunkTag([*t0, *t1, *t2, *t3]);
        if !tag.is_valid() {
            return Err(Error::ChunkTagInvalid { tag: tag.0 });
        }
        self.limits.check(LimitKind::ChunkBytes, length.into())?;
        let length = length as usize;
        if length > body.len() {
            return Err(Error::ChunkLengthPastEnd {
                tag,
                length: length as u64,
                available: body.len() as u64,
            });
        }
        let (payload, after) = body.split_at(length);
        let [c0, c1, c2, c3, rest @ ..] = after else {
            return Err(Error::Truncated {
                structure: Structure::ChunkCrc,
                needed: 4,
                available: after.len() as u64,
            });
        };
        let stored = u32::from_le_bytes([*c0, *c1, *c2, *c3]);
        let computed = chunk_crc(tag, payload);
        // §1.3: every chunk's CRC is checked before its tag is acted on, so a flipped
        // case bit cannot turn a damaged critical chunk into a skippable ancillary one.
        if stored != computed && !cfg!(fuzzing) {
            return Err(Error::ChunkCrcMismatch {
                tag,
                stored,
                computed,
            });
        }
        let chunk = Chunk {
            tag,
            offset: self.offset,
            payload,
            crc: stored,
        };
        self.offset += CHUNK_OVERHEAD + length as u64;
        self.rest = rest;
        Ok(Some(chunk))
    }
}

/// The payload of the next critical chunk in `rest` if it is tagged `tag` and it, and the
/// ancillary chunks before it, are framed and CRC-checked (§1.3); `None` otherwise (the
/// decoder's own reader reaches it in turn and reports what is wrong). For decoding a chunk
/// alongside the one before it, its outcome reported at its own position.
pub fn peek_critical<'a>(rest: &'a [u8], tag: ChunkTag, limits: &Limits) -> Option<&'a [u8]> {
    let mut reader = ChunkReader::new(rest, 0, limits);
    // Every chunk read takes at least its 12 bytes of framing, so this ends.
    while let Ok(Some(chunk)) = reader.next_chunk() {
        if chunk.tag.is_critical() {
            return (chunk.tag == tag).then_some(chunk.payload);
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crc32c_check_value() {
        // The standard CRC-32C check value (RFC 3720 appendix B.4).
        assert_eq!(crc32c::crc32c(b"123456789"), 0xe306_9283);
    }

    #[test]
    fn critical_is_upper_case_first_byte() {
        assert!(ChunkTag::HEAD.is_critical());
        assert!(!ChunkTag::ENCD.is_critical());
        assert!(!ChunkTag(*b"H\0AD").is_valid());
        assert!(ChunkTag(*b"x1y2").is_valid());
        assert!(!ChunkTag(*b"1xyz").is_valid());
    }
}
