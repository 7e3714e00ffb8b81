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

/// A preflight rewritten for one rate: its payload, the selected layer, the layer count,
/// and whether the layers nest (§3.8).
type Rewritten = Result<(Vec<u8>, usize, usize, bool)>;

/// What the extraction walk needs of a profile.
struct Profile {
    /// Every critical chunk type of the profile (§1.5 rule 0, §3.7).
    critical: &'static [ChunkTag],
    /// The critical chunk due at position `i` of a stream with `layers` layers, progressive
    /// or not.
    expected: fn(usize, usize, bool) -> ChunkTag,
    /// The chunks that open a layer's section (§7.4: `AFEA`; §3.7: `GLAY`; §3.8: `GREF`).
    layer_start: &'static [ChunkTag],
    /// The preflight with `rate_mask = 2^rate` (in a progressive stream, the coded rates
    /// from `rate` up), and (selected layer, layers, progressive).
    rewrite: fn(&[u8], u8, &Limits) -> Rewritten,
}

const ANCHORS: Profile = Profile {
    critical: &ChunkTag::CRITICAL_ORDER,
    expected: |i, layers, _| crate::anchors::expected_critical(i, layers),
    layer_start: &[ChunkTag::AFEA],
    rewrite: |payload, rate, limits| {
        let mut head = Preflight::parse(payload, limits)?;
        let (_, selected, layers) = head.select_layer(Some(rate))?;
        head.rate_mask = 1 << rate;
        Ok((head.to_payload(), selected, layers, false))
    },
};

const EXPLICIT: Profile = Profile {
    critical: &crate::explicit::order::CRITICAL_CHUNKS,
    expected: crate::explicit::order::expected_critical,
    layer_start: &[ChunkTag::GLAY, ChunkTag::GREF],
    rewrite: |payload, rate, limits| {
        let mut head = GaussianHeader::parse(payload, limits)?;
        let (_, selected, layers) = head.select_layer(Some(rate))?;
        // §3.8: a progressive stream's prefix keeps the coarser layers rate refines.
        head.rate_mask = match head.progressive {
            true => head.rate_mask & !((1u64 << rate) - 1),
            false => 1 << rate,
        };
        Ok((head.to_payload(), selected, layers, head.progressive))
    },
};

/// The single-rate stream of rate `rate` taken from `data` (§7.5). The container is checked
/// as a decoder checks it (signature, framing, CRC-32C, chunk order, the preflight); the
/// payloads of the other chunks are copied without being parsed.
pub fn extract_rate(data: &[u8], rate: u8, limits: &Limits) -> Result<Vec<u8>> {
    let profile = if crate::container::is_explicit(data) {
        &EXPLICIT
    } else {
        &ANCHORS
    };
    let (_sig, rest) = Signature::parse(data)?;
    let mut reader = ChunkReader::new(rest, SIGNATURE_LEN as u64, limits);
    let mut out = Vec::with_capacity(data.len());
    out.extend_from_slice(&data[..SIGNATURE_LEN]);
    let (mut layers, mut selected, mut progressive) = (0usize, 0usize, false);
    // Whether a chunk of section `l` is kept: the selected layer's, and in a progressive
    // stream every layer before it too.
    let kept = |section: Option<usize>, selected: usize, progressive: bool| match section {
        None => true,
        Some(l) => l == selected || (progressive && l < selected),
    };
    let mut next_critical = 0usize;
    // The layer the chunks now read belong to (§7.4): None before the first layer.
    let mut section: Option<usize> = None;
    let mut head_seen = false;
    loop {
        // §1.5 rule 4: the stream ends only with SEND.
        let chunk = match reader.next_before_send() {
            Ok(chunk) => chunk,
            // §3.8: a progressive stream cut after the selected layer is its prefix; cut
            // before its first layer (no layer due yet: GHED, GQUA) it is not.
            Err(e)
                if progressive
                    && e.is_truncation()
                    && next_critical >= crate::explicit::order::FIRST_LAYER_CHUNK
                    && crate::explicit::order::layer_of(next_critical, layers, true)
                        .map_or(true, |l| l > selected) =>
            {
                write_chunk(&mut out, ChunkTag::SEND, &[]);
                return Ok(out);
            }
            Err(e) => return Err(e),
        };
        let tag = chunk.tag;
        if !tag.is_critical() {
            if !head_seen {
                return Err(Error::ChunkOrder {
                    found: tag,
                    expected: ChunkTag::HEAD,
                });
            }
            if kept(section, selected, progressive) {
                write_chunk(&mut out, tag, chunk.payload);
            }
            continue;
        }
        if !profile.critical.contains(&tag) {
            return Err(Error::UnknownCriticalChunk { tag });
        }
        let expected = (profile.expected)(next_critical, layers, progressive);
        if tag != expected {
            return Err(Error::ChunkOrder {
                found: tag,
                expected,
            });
        }
        if next_critical == 0 {
            let payload;
            (payload, selected, layers, progressive) =
                (profile.rewrite)(chunk.payload, rate, limits)?;
            write_chunk(&mut out, tag, &payload);
            head_seen = true;
            next_critical += 1;
            continue;
        }
        next_critical += 1;
        if profile.layer_start.contains(&tag) {
            section = Some(section.map_or(0, |l| l + 1));
        }
        if tag == ChunkTag::SEND {
            crate::container::chunk::check_send(chunk.payload, reader.remaining())?;
            write_chunk(&mut out, tag, chunk.payload);
            return Ok(out);
        }
        if kept(section, selected, progressive) {
            write_chunk(&mut out, tag, chunk.payload);
        }
    }
}
