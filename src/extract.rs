//! Extracting one rate from a multi-rate stream (spec §7.5, §3.7): the shared chunks and one
//! layer are copied as they are, the preflight is rewritten with the one rate, and nothing
//! is re-coded, so the result is byte-identical to encoding that rate alone. One walk serves
//! both profiles; the chunk order's walker says where each chunk stands.

use crate::container::chunk::{write_chunk, ChunkReader, ChunkTag};
use crate::container::order::{ChunkOrder, Position, Profile, EXPLICIT_FIRST_LAYER};
use crate::container::preflight::Preflight;
use crate::container::signature::{Signature, SIGNATURE_LEN};
use crate::error::Result;
use crate::explicit::GaussianHeader;
use crate::limits::Limits;

/// A preflight rewritten for one rate: its payload, the selected layer, the layer count,
/// and whether the layers nest (§3.8).
type Rewritten = Result<(Vec<u8>, usize, usize, bool)>;

/// The preflight of `profile` with `rate_mask = 2^rate` (in a progressive stream, the coded
/// rates from `rate` up), and (selected layer, layers, progressive).
fn rewrite(profile: Profile, payload: &[u8], rate: u8, limits: &Limits) -> Rewritten {
    match profile {
        Profile::Anchors => {
            let mut head = Preflight::parse(payload, limits)?;
            let (_, selected, layers) = head.select_layer(Some(rate))?;
            head.rate_mask = 1 << rate;
            Ok((head.to_payload(), selected, layers, false))
        }
        Profile::Explicit => {
            let mut head = GaussianHeader::parse(payload, limits)?;
            let (_, selected, layers) = head.select_layer(Some(rate))?;
            // §3.8: a progressive stream's prefix keeps the coarser layers rate refines.
            head.rate_mask = match head.progressive {
                true => head.rate_mask & !((1u64 << rate) - 1),
                false => 1 << rate,
            };
            Ok((head.to_payload(), selected, layers, head.progressive))
        }
    }
}

/// The single-rate stream of rate `rate` taken from `data` (§7.5). The container is checked
/// as a decoder checks it (signature, framing, CRC-32C, chunk order, the preflight); the
/// payloads of the other chunks are copied without being parsed.
pub fn extract_rate(data: &[u8], rate: u8, limits: &Limits) -> Result<Vec<u8>> {
    let profile = if crate::container::is_explicit(data) {
        Profile::Explicit
    } else {
        Profile::Anchors
    };
    let (_sig, rest) = Signature::parse(data)?;
    let mut reader = ChunkReader::new(rest, SIGNATURE_LEN as u64, limits);
    let mut out = Vec::with_capacity(data.len());
    out.extend_from_slice(&data[..SIGNATURE_LEN]);
    let mut order = ChunkOrder::new(profile);
    let (mut selected, mut progressive) = (0usize, false);
    // Whether a chunk of section `l` is kept: the selected layer's, and in a progressive
    // stream every layer before it too.
    let kept = |section: Option<usize>, selected: usize, progressive: bool| match section {
        None => true,
        Some(l) => l == selected || (progressive && l < selected),
    };
    // The layer the chunks now read belong to (§7.4): None before the first layer.
    let mut section: Option<usize> = None;
    loop {
        // §1.5 rule 4: the stream ends only with SEND.
        let chunk = match reader.next_before_send() {
            Ok(chunk) => chunk,
            // §3.8: a progressive stream cut after the selected layer is its prefix; cut
            // before its first layer (no layer due yet: GHED, GQUA) it is not.
            Err(e)
                if progressive
                    && e.is_truncation()
                    && order.next_index() >= EXPLICIT_FIRST_LAYER
                    && order.next_layer().map_or(true, |l| l > selected) =>
            {
                write_chunk(&mut out, ChunkTag::SEND, &[]);
                return Ok(out);
            }
            Err(e) => return Err(e),
        };
        let tag = chunk.tag;
        let index = match order.step(tag)? {
            Position::Ancillary => {
                if kept(section, selected, progressive) {
                    write_chunk(&mut out, tag, chunk.payload);
                }
                continue;
            }
            Position::Critical { index, .. } => index,
        };
        if index == 0 {
            let (payload, layers);
            (payload, selected, layers, progressive) =
                rewrite(profile, chunk.payload, rate, limits)?;
            order.set_layers(layers, progressive);
            write_chunk(&mut out, tag, &payload);
            continue;
        }
        if profile.layer_start().contains(&tag) {
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
