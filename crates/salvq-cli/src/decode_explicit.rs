//! `salvq decode` of an explicit-profile stream (spec §3).

use std::time::Instant;

use salvq_encoder::Error;

use super::files::{self, Ctx, Output};
use super::secs;

/// What `decode --json` prints, for either profile.
#[derive(serde::Serialize)]
pub(crate) struct Decoded {
    pub(crate) output: String,
    pub(crate) profile: &'static str,
    /// Gaussians (explicit profile) or anchors.
    pub(crate) count: u64,
    pub(crate) rate: Option<u8>,
    pub(crate) rates: u8,
    pub(crate) seconds: f64,
}

/// How the decode is written and reported.
pub(crate) struct How {
    /// The canonical form (§11.6) instead of a PLY file.
    pub(crate) canonical: bool,
    /// `--json` on standard output.
    pub(crate) json: bool,
    /// Messages.
    pub(crate) ctx: Ctx,
}

/// `salvq decode` of an explicit-profile stream (spec §3): the Gaussians as a standard 3DGS
/// PLY file, or the canonical form (§11.6); with no output (`--measure`), the decode's time
/// and peak memory.
pub(crate) fn run(
    stream: &[u8],
    options: &salvq::DecoderBuilder,
    output: Option<&Output>,
    how: How,
    t: Instant,
) -> Result<(), Error> {
    let decoded = match options.build().decode(stream)? {
        salvq::Scene::Gaussians(d) => d,
        salvq::Scene::Anchors(_) => unreachable!("is_explicit chose the profile"),
    };
    let n = decoded.gaussians.len();
    if decoded.truncated {
        let asked = match options.build().rate() {
            Some(r) if r != decoded.rate => format!(" (rate {r} was asked for)"),
            _ => String::new(),
        };
        how.ctx.say(&format!(
            "salvq: note: the stream ends early (a progressive stream cut before its end \
             chunk): decoded rate {}, the last complete one{asked}; --strict makes this an error",
            decoded.rate
        ));
    }
    let Some(output) = output else {
        out!(
            "measure decode_secs={} peak_rss_bytes={} gaussians={n} decoded_bytes={}",
            secs(t),
            salvq_bench::scale::peak_rss_bytes().unwrap_or(0),
            decoded.header.decoded_bytes()
        );
        return Ok(());
    };
    if how.canonical {
        let tensors = salvq_conformance::canonical::explicit_canonical_tensors(&decoded);
        let bytes = salvq_conformance::canonical::to_safetensors(&tensors);
        return output.write_bytes(&bytes);
    }
    if n == 0 {
        how.ctx
            .say("salvq: the region intersects no tile; nothing written");
        return Ok(());
    }
    output.write(|w| salvq_render::ply::write_ply(&decoded.gaussians, w))?;
    let report = Decoded {
        output: output.shown(),
        profile: "explicit",
        count: n as u64,
        rate: Some(decoded.rate),
        rates: decoded.header.rate_count,
        seconds: secs(t),
    };
    if how.json {
        files::print_json(&report);
    }
    how.ctx.say(&format!(
        "decoded {n} Gaussians at rate {} (of rates 0 … {}; rate 0 is the finest) into {} in {:.2} s",
        decoded.rate,
        report.rates.saturating_sub(1),
        report.output,
        report.seconds
    ));
    Ok(())
}
