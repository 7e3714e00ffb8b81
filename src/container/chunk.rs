//! Chunk framing (spec §1.3): `length`, `tag`, payload, CRC-32C over tag and payload.

use std::fmt;

use crate::error::{Error, Result, Structure};
use crate::limits::{LimitKind, Limits};

/// A four-byte chunk type (spec §1.3). The case of the first byte tells whether a decoder
/// must understand the chunk: upper case is critical, lower case is ancillary.
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
pub struct ChunkTag(pub [u8; 4]);

impl ChunkTag {
    /// Preflight: dimensions, geometry and decoded size (§1.4). Critical, first.
    pub const HEAD: ChunkTag = ChunkTag(*b"HEAD");
    /// Binary hash grid (§1.6.1). Critical.
    pub const GRID: ChunkTag = ChunkTag(*b"GRID");
    /// MLP weights (§1.6.2). Critical.
    pub const MLPS: ChunkTag = ChunkTag(*b"MLPS");
    /// Quantizers: steps, gains, lattice bases (§1.6.3). Critical.
    pub const QUAN: ChunkTag = ChunkTag(*b"QUAN");
    /// Anchor voxel coordinates (§1.6.4). Critical.
    pub const APOS: ChunkTag = ChunkTag(*b"APOS");
    /// Tile table (§10.1).
    pub const TILS: ChunkTag = ChunkTag(*b"TILS");
    /// Anchor offset masks (§1.6.5). Critical.
    pub const AMSK: ChunkTag = ChunkTag(*b"AMSK");
    /// Anchor latent features (§1.6.6). Critical.
    pub const AFEA: ChunkTag = ChunkTag(*b"AFEA");
    /// Anchor scalings (§1.6.6). Critical.
    pub const ASCL: ChunkTag = ChunkTag(*b"ASCL");
    /// Anchor offsets (§1.6.6). Critical.
    pub const AOFF: ChunkTag = ChunkTag(*b"AOFF");
    /// End of stream (§1.5). Critical, last, empty.
    pub const SEND: ChunkTag = ChunkTag(*b"SEND");
    /// Explicit-Gaussians preflight (§3.2). Critical, first.
    pub const GHED: ChunkTag = ChunkTag(*b"GHED");
    /// Explicit-Gaussians attribute groups: lattices, means, steps, gains (§3.3). Critical.
    pub const GQUA: ChunkTag = ChunkTag(*b"GQUA");
    /// Explicit-Gaussians layer header: voxel grid and prior tables (§3.4). Critical.
    pub const GLAY: ChunkTag = ChunkTag(*b"GLAY");
    /// Explicit-Gaussians attribute symbols, one body per tile (§3.5). Critical.
    pub const GATT: ChunkTag = ChunkTag(*b"GATT");
    /// Encoder identification, UTF-8 text (§1.7). Ancillary.
    pub const ENCD: ChunkTag = ChunkTag(*b"encd");
    /// Encoder statistics, JSON (§1.7). Ancillary.
    pub const ESTS: ChunkTag = ChunkTag(*b"ests");

    /// Critical chunks in the order a stream must carry them (spec Table 1-3).
    pub const CRITICAL_ORDER: [ChunkTag; 11] = [
        Self::HEAD,
        Self::MLPS,
        Self::QUAN,
        Self::TILS,
        Self::APOS,
        Self::GRID,
        Self::AMSK,
        Self::AFEA,
        Self::ASCL,
        Self::AOFF,
        Self::SEND,
    ];

    /// Whether a decoder must understand this chunk (first byte upper case).
    pub fn is_critical(self) -> bool {
        self.0[0].is_ascii_uppercase()
    }

    /// Whether the tag's bytes are allowed (§1.3): a letter, then letters or digits.
    pub fn is_valid(self) -> bool {
        self.0[0].is_ascii_alphabetic() && self.0[1..].iter().all(u8::is_ascii_alphanumeric)
    }

    /// The tag as text (only meaningful for valid tags).
    pub fn as_str(&self) -> &str {
        std::str::from_utf8(&self.0).unwrap_or("????")
    }
}

impl fmt::Display for ChunkTag {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.is_valid() {
            f.write_str(self.as_str())
        } else {
            write!(f, "{:02x?}", self.0)
        }
    }
}

impl fmt::Debug for ChunkTag {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "ChunkTag({self})")
    }
}

/// Bytes of framing around each payload: length (4), tag (4), CRC (4).
pub const CHUNK_OVERHEAD: u64 = 12;

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
    pub tag: ChunkTag,
    /// Offset of the chunk's length field from the start of the stream.
    pub offset: u64,
    pub payload: &'a [u8],
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
            needed: 8,
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
                needed: 8,
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
