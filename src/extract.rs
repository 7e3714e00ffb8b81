//! Extracting one rate from a multi-rate stream (spec §7.5, §3.7): the shared chunks and one
//! layer are copied as they are, the preflight is rewritten with the one rate, and nothing
//! is re-coded, so the result is byte-identical to encoding that rate alone. One walk serves
//! both profiles; a `Profile` says what differs.

use crate::container::chunk::{write_chunk, ChunkReader, ChunkTag};
use crate::container::preflight::Preflight;
use crate::container::signature::{Signature, SIGNATURE_LEN};
use crate::error::{Error, Result};
use crate::explicit::GaussianHeader;
use crate::limits::Limits;

/// A preflight rewritten for one rate: its payload, the selected layer, the layer count.
type Rewritten = Result<(Vec<u8>, usize, usize)>;

/// What the extraction walk needs of a profile.
struct Profile {
    /// Every critical chunk type of the profile (§1.5 rule 0, §3.7).
    critical: &'static [ChunkTag],
    /// The critical chunk due at position `i` of a stream with `layers` layers.
    expected: fn(usize, usize) -> ChunkTag,
    /// The chunk that opens a layer's section (§7.4: `AFEA`; §3.7: `GLAY`).
    layer_start: ChunkTag,
    /// The preflight with `rate_mask = 2^rate`, and (selected layer, layers).
    rewrite: fn(&[u8], u8, &Limits) -> Rewritten,
}

const ANCHORS: Profile = Profile {
    critical: &ChunkTag::CRITICAL_ORDER,
    expected: crate::decoder::expected_critical,
    layer_start: ChunkTag::AFEA,
    rewrite: |payload, rate, limits| {
        let mut head = Preflight::parse(payload, limits)?;
        let (_, selected, layers) = head.select_layer(Some(rate))?;
        head.rate_mask = 1 << rate;
        Ok((head.to_payload(), selected, layers))
    },
};

const EXPLICIT: Profile = Profile {
    critical: &crate::explicit::decode::CRITICAL_CHUNKS,
    expected: crate::explicit::decode::expected_critical,
    layer_start: ChunkTag::GLAY,
    rewrite: |payload, rate, limits| {
        let mut head = GaussianHeader::parse(payload, limits)?;
        let (_, selected, layers) = head.select_layer(Some(rate))?;
        head.rate_mask = 1 << rate;
        Ok((head.to_payload(), selected, layers))
    },
};

/// The single-rate stream of rate `rate` taken from `data` (§7.5). The container is checked
/// as a decoder checks it (signature, framing, CRC-32C, chunk order, the preflight); the
/// payloads of the other chunks are copied without being parsed.
pub fn extract_rate(data: &[u8], rate: u8, limits: &Limits) -> Result<Vec<u8>> {
    let profile = if crate::decoder::is_explicit(data) {
        &EXPLICIT
    } else {
        &ANCHORS
    };
    let (_sig, rest) = Signature::parse(data)?;
    let mut reader = ChunkReader::new(rest, SIGNATURE_LEN as u64, limits);
    let mut out = Vec::with_capacity(data.len());
    out.extend_from_slice(&data[..SIGNATURE_LEN]);
    let (mut layers, mut selected) = (0usize, 0usize);
    let mut next_critical = 0usize;
    // The layer the chunks now read belong to (§7.4): None before the first layer.
    let mut section: Option<usize> = None;
    let mut head_seen = false;
    loop {
        // §1.5 rule 4: the stream ends only with SEND.
        let chunk = reader.next_before_send()?;
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
        if !profile.critical.contains(&tag) {
            return Err(Error::UnknownCriticalChunk { tag });
        }
        let expected = (profile.expected)(next_critical, layers);
        if tag != expected {
            return Err(Error::ChunkOrder {
                found: tag,
                expected,
            });
        }
        if next_critical == 0 {
            let payload;
            (payload, selected, layers) = (profile.rewrite)(chunk.payload, rate, limits)?;
            write_chunk(&mut out, tag, &payload);
            head_seen = true;
            next_critical += 1;
            continue;
        }
        next_critical += 1;
        if tag == profile.layer_start {
            section = Some(section.map_or(0, |l| l + 1));
        }
        if tag == ChunkTag::SEND {
            crate::container::chunk::check_send(chunk.payload, reader.remaining())?;
            write_chunk(&mut out, tag, chunk.payload);
            return Ok(out);
        }
        if section.map_or(true, |l| l == selected) {
            write_chunk(&mut out, tag, chunk.payload);
        }
    }
}
