//! `salvq decode` of an explicit-profile stream (spec §3).

use std::time::Instant;

use salvq_encoder::Error;

use super::secs;

/// `salvq decode` of an explicit-profile stream (spec §3): the Gaussians as a standard 3DGS
/// PLY file, or the canonical form (§11.6).
pub(crate) fn run(
    stream: &[u8],
    options: &salvq::DecodeOptions,
    output: &std::path::Path,
    canonical: bool,
    measure: bool,
    t: Instant,
) -> Result<(), Error> {
    let decoded = match salvq::decoder::decode_any(stream, options)? {
        salvq::decoder::Decoded::Gaussians(d) => d,
        salvq::decoder::Decoded::Anchors(_) => unreachable!("is_explicit chose the profile"),
    };
    if canonical {
        let tensors = salvq_conformance::canonical::explicit_canonical_tensors(&decoded);
        let bytes = salvq_conformance::canonical::to_safetensors(&tensors);
        return Ok(salvq_render::io::write_bytes_atomic(output, &bytes)?);
    }
    let n = decoded.gaussians.len();
    if measure {
        out!(
            "measure decode_secs={} peak_rss_bytes={} gaussians={n} decoded_bytes={}",
            secs(t),
            salvq_bench::scale::peak_rss_bytes().unwrap_or(0),
            decoded.header.decoded_bytes()
        );
        return Ok(());
    }
    if n == 0 {
        eprintln!("salvq: the region intersects no tile; nothing written");
        return Ok(());
    }
    salvq_render::ply::write_ply_file(&decoded.gaussians, output)?;
    out!(
        "decoded {n} Gaussians (rate {} of {}; rate 0 is the finest) into {} in {:.2} s",
        decoded.rate,
        decoded.header.rate_count,
        output.display(),
        secs(t)
    );
    Ok(())
}
