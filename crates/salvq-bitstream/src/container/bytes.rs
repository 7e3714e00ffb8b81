//! Little-endian field reading and writing inside a payload (spec §0.2).

use crate::container::chunk::ChunkTag;
use crate::error::{Error, Result, Structure};

/// A cursor over one payload; every read that runs out reports `Truncated` for that chunk.
pub struct PayloadReader<'a> {
    tag: ChunkTag,
    rest: &'a [u8],
    total: usize,
}

impl<'a> PayloadReader<'a> {
    /// A reader at the start of `payload`, the payload of chunk `tag` (named in its errors).
    pub fn new(tag: ChunkTag, payload: &'a [u8]) -> Self {
        PayloadReader {
            tag,
            rest: payload,
            total: payload.len(),
        }
    }

    /// Takes the next `n` bytes.
    pub fn take(&mut self, n: usize) -> Result<&'a [u8]> {
        if n > self.rest.len() {
            return Err(Error::Truncated {
                structure: Structure::Payload(self.tag),
                needed: n as u64,
                available: self.rest.len() as u64,
            });
        }
        let (head, rest) = self.rest.split_at(n);
        self.rest = rest;
        Ok(head)
    }

    fn array<const N: usize>(&mut self) -> Result<[u8; N]> {
        let mut a = [0u8; N];
        a.copy_from_slice(self.take(N)?);
        Ok(a)
    }

    /// Reads a `u8` (§0.1).
    pub fn u8(&mut self) -> Result<u8> {
        Ok(self.array::<1>()?[0])
    }
    /// Reads a little-endian `u16` (§0.1).
    pub fn u16(&mut self) -> Result<u16> {
        self.array().map(u16::from_le_bytes)
    }
    /// Reads a little-endian `u32` (§0.1).
    pub fn u32(&mut self) -> Result<u32> {
        self.array().map(u32::from_le_bytes)
    }
    /// Reads a little-endian `u64` (§0.1).
    pub fn u64(&mut self) -> Result<u64> {
        self.array().map(u64::from_le_bytes)
    }
    /// Reads a little-endian binary32 with its bits unchanged (§0.2); finiteness is not checked.
    pub fn f32(&mut self) -> Result<f32> {
        self.array().map(f32::from_le_bytes)
    }

    /// Bytes consumed so far.
    pub fn consumed(&self) -> usize {
        self.total - self.rest.len()
    }

    /// Requires that the whole payload was consumed (§1.6: sizes are exact).
    pub fn finish(self) -> Result<()> {
        if !self.rest.is_empty() {
            return Err(Error::ChunkSizeMismatch {
                tag: self.tag,
                expected: self.consumed() as u64,
                found: self.total as u64,
            });
        }
        Ok(())
    }
}

/// Appends little-endian values to a payload.
#[derive(Default)]
pub struct PayloadWriter {
    /// The payload bytes written so far.
    pub buf: Vec<u8>,
}

impl PayloadWriter {
    /// Appends a `u8`.
    pub fn u8(&mut self, v: u8) {
        self.buf.push(v);
    }
    /// Appends a little-endian `u16`.
    pub fn u16(&mut self, v: u16) {
        self.buf.extend_from_slice(&v.to_le_bytes());
    }
    /// Appends a little-endian `u32`.
    pub fn u32(&mut self, v: u32) {
        self.buf.extend_from_slice(&v.to_le_bytes());
    }
    /// Appends a little-endian `u64`.
    pub fn u64(&mut self, v: u64) {
        self.buf.extend_from_slice(&v.to_le_bytes());
    }
    /// Appends a little-endian binary32 with its bits unchanged.
    pub fn f32(&mut self, v: f32) {
        self.buf.extend_from_slice(&v.to_le_bytes());
    }
    /// Appends each value of `v` as a little-endian binary32, in order.
    pub fn f32s(&mut self, v: &[f32]) {
        self.buf.reserve(v.len() * 4);
        for x in v {
            self.f32(*x);
        }
    }
}

/// Packs bits LSB-first within each byte (§0.2), zero padding.
pub fn pack_bits(bits: impl Iterator<Item = bool>, out: &mut Vec<u8>) {
    let mut byte = 0u8;
    let mut n = 0;
    for b in bits {
        byte |= u8::from(b) << n;
        n += 1;
        if n == 8 {
            out.push(byte);
            byte = 0;
            n = 0;
        }
    }
    if n > 0 {
        out.push(byte);
    }
}

/// Bytes needed for `bits` packed bits.
pub fn packed_len(bits: u64) -> u64 {
    bits.div_ceil(8)
}

/// Unpacks `count` bits LSB-first; the padding bits after them must be zero (§0.2).
pub fn unpack_bits(
    tag: ChunkTag,
    bytes: &[u8],
    count: usize,
) -> Result<impl Iterator<Item = bool> + '_> {
    if bytes.len() as u64 != packed_len(count as u64) {
        return Err(Error::ChunkSizeMismatch {
            tag,
            expected: packed_len(count as u64),
            found: bytes.len() as u64,
        });
    }
    if count % 8 != 0 {
        if let Some(last) = bytes.last() {
            if last >> (count % 8) != 0 {
                return Err(Error::PaddingBitsSet { tag });
            }
        }
    }
    Ok((0..count).map(move |i| bytes[i / 8] >> (i % 8) & 1 == 1))
}
