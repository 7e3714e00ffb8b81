//! Extracting one rate from a multi-rate stream (spec §7.5): the shared chunks and one symbol
//! layer are copied as they are, `HEAD` is rewritten with the one rate, and nothing is
//! re-coded, so the result is byte-identical to encoding that rate alone.

use crate::container::chunk::{write_chunk, ChunkReader, ChunkTag};
use crate::container::preflight::Preflight;
use crate::container::signature::{Signature, SIGNATURE_LEN};
use crate::decoder::expected_critical;
use crate::error::{Error, Result};
use crate::limits::Limits;

/// The single-rate stream of rate `rate` taken from `data` (§7.5). The container is checked
/// as a decoder checks it (signature, framing, CRC-32C, chunk order, `HEAD`); the payloads of
/// the other chunks are copied without being parsed.
pub fn extract_rate(data: &[u8], rate: u8, limits: &Limits) -> Result<Vec<u8>> {
    if crate::decoder::is_explicit(data) {
        return extract_explicit(data, rate, limits);
    }
    let (_sig, rest) = Signature::parse(data)?;
    let mut reader = ChunkReader::new(rest, SIGNATURE_LEN as u64, limits);
    let mut out = Vec::with_capacity(data.len());
    out.extend_from_slice(&data[..SIGNATURE_LEN]);
    let (mut layers, mut selected) = (0usize, 0usize);
    let mut next_critical = 0usize;
    // The layer the chunks now read belong to (§7.4): None before the first AFEA.
    let mut section: Option<usize> = None;
    let mut head_seen = false;
    loop {
        let Some(chunk) = reader.next_chunk()? else {
            return Err(Error::Truncated {
                structure: crate::error::Structure::ChunkHeader,
                needed: 8,
                available: 0,
            });
        };
        let tag = chunk.tag;
        if !tag.is_critical() {
            if !head_seen {
                return Err(Error::ChunkOrder {
                    found: tag,
                    expected: ChunkTag::HEAD,
                });
            }
            if section.map_or(true, |l| l == selected) {
                write_chunk(&mut out, tag, chunk.payload);
            }
            continue;
        }
        if !ChunkTag::CRITICAL_ORDER.contains(&tag) {
            return Err(Error::UnknownCriticalChunk { tag });
        }
        let expected = if head_seen {
            expected_critical(next_critical, layers)
        } else {
            ChunkTag::HEAD
        };
        if tag != expected {
            return Err(Error::ChunkOrder {
                found: tag,
                expected,
            });
        }
        next_critical += 1;
        match tag {
            ChunkTag::HEAD => {
                let mut head = Preflight::parse(chunk.payload, limits)?;
                (_, selected, layers) = head.select_layer(Some(rate))?;
                head.rate_mask = 1 << rate;
                write_chunk(&mut out, tag, &head.to_payload());
                head_seen = true;
            }
            ChunkTag::AFEA => {
                let layer = section.map_or(0, |l| l + 1);
                section = Some(layer);
                if layer == selected {
                    write_chunk(&mut out, tag, chunk.payload);
                }
            }
            ChunkTag::ASCL | ChunkTag::AOFF => {
                if section == Some(selected) {
                    write_chunk(&mut out, tag, chunk.payload);
                }
            }
            ChunkTag::SEND => {
                if !chunk.payload.is_empty() {
                    return Err(Error::ChunkSizeMismatch {
                        tag,
                        expected: 0,
                        found: chunk.payload.len() as u64,
                    });
                }
                write_chunk(&mut out, tag, chunk.payload);
                let trailing = reader.remaining().len();
                if trailing != 0 {
                    return Err(Error::TrailingData {
                        bytes: trailing as u64,
                    });
                }
                return Ok(out);
            }
            _ => write_chunk(&mut out, tag, chunk.payload),
        }
    }
}

/// §3.7 / §7.5 for the explicit profile: `GHED` with the one rate, `GQUA`, the rate's four
/// layer chunks and the ancillary chunks of the shared section and of that layer, `SEND`.
fn extract_explicit(data: &[u8], rate: u8, limits: &Limits) -> Result<Vec<u8>> {
    use crate::explicit::decode::expected_critical as explicit_expected;
    use crate::explicit::GaussianHeader;
    let (_sig, rest) = Signature::parse(data)?;
    let mut reader = ChunkReader::new(rest, SIGNATURE_LEN as u64, limits);
    let mut out = Vec::with_capacity(data.len());
    out.extend_from_slice(&data[..SIGNATURE_LEN]);
    let (mut layers, mut selected) = (0usize, 0usize);
    let mut next = 0usize;
    // The layer the chunks now read belong to: None before the first GLAY.
    let mut section: Option<usize> = None;
    let known = [
        ChunkTag::GHED,
        ChunkTag::GQUA,
        ChunkTag::GLAY,
        ChunkTag::TILS,
        ChunkTag::APOS,
        ChunkTag::GATT,
        ChunkTag::SEND,
    ];
    loop {
        let Some(chunk) = reader.next_chunk()? else {
            return Err(Error::Truncated {
                structure: crate::error::Structure::ChunkHeader,
                needed: 8,
                available: 0,
            });
        };
        let tag = chunk.tag;
        if !tag.is_critical() {
            if section.map_or(true, |l| l == selected) {
                write_chunk(&mut out, tag, chunk.payload);
            }
            continue;
        }
        if !known.contains(&tag) {
            return Err(Error::UnknownCriticalChunk { tag });
        }
        let expected = explicit_expected(next, layers);
        if tag != expected {
            return Err(Error::ChunkOrder {
                found: tag,
                expected,
            });
        }
        next += 1;
        match tag {
            ChunkTag::GHED => {
                let mut head = GaussianHeader::parse(chunk.payload, limits)?;
                (_, selected, layers) = head.select_layer(Some(rate))?;
                head.rate_mask = 1 << rate;
                write_chunk(&mut out, tag, &head.to_payload());
            }
            ChunkTag::GLAY => {
                let layer = section.map_or(0, |l| l + 1);
                section = Some(layer);
                if layer == selected {
                    write_chunk(&mut out, tag, chunk.payload);
                }
            }
            ChunkTag::TILS | ChunkTag::APOS | ChunkTag::GATT => {
                if section == Some(selected) {
                    write_chunk(&mut out, tag, chunk.payload);
                }
            }
            ChunkTag::SEND => {
                if !chunk.payload.is_empty() {
                    return Err(Error::ChunkSizeMismatch {
                        tag,
                        expected: 0,
                        found: chunk.payload.len() as u64,
                    });
                }
                write_chunk(&mut out, tag, chunk.payload);
                let trailing = reader.remaining().len();
                if trailing != 0 {
                    return Err(Error::TrailingData {
                        bytes: trailing as u64,
                    });
                }
                return Ok(out);
            }
            _ => write_chunk(&mut out, tag, chunk.payload),
        }
    }
}
