//! `salvq decode`: a stream of either profile into a PLY file (explicit Gaussians), a model
//! file (anchors) or the canonical form (spec §1.5, §3, §10.3.1, §11.1). The output's
//! extension must name the format the stream decodes to; its default name is the input's
//! with that extension.

use std::path::PathBuf;
use std::time::Instant;

use salvq_encoder::Error;

use super::decode_explicit::{self, Decoded};
use super::files::{self, Ctx, Output};
use super::secs;
use super::tools::parse_fault;

/// `salvq decode`'s arguments.
#[derive(clap::Args)]
pub(crate) struct DecodeArgs {
    /// Input stream (`-`: standard input).
    pub(crate) input: PathBuf,
    /// Output: a 3DGS PLY (`.ply`) for a scene (explicit profile), a model (`.safetensors`)
    /// for anchors; `-` for standard output. Default: the input's name with that extension.
    #[arg(short, long)]
    pub(crate) output: Option<PathBuf>,
    /// The rate to decode (rate 0 is the finest; default: the finest the stream carries).
    #[arg(long)]
    pub(crate) rate: Option<u8>,
    /// Decode tiles on N threads (spec §10.3; the output is the same for every N).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    pub(crate) threads: Option<u32>,
    /// Decode only the tiles that intersect this world-space box:
    /// `xmin,ymin,zmin,xmax,ymax,zmax` (spec §10.3.1; a face or corner that touches counts).
    #[arg(long, value_parser = parse_box, allow_hyphen_values = true)]
    pub(crate) region: Option<salvq::RegionBox>,
    /// Measure instead of writing: print the decode time and the process's peak resident
    /// memory (used by `bench scale`).
    #[arg(long, hide = true)]
    pub(crate) measure: bool,
    /// Write the canonical decoded form instead of the model file: the model's tensors
    /// and the decoded symbols, as the conformance runner reads them (spec §11.1).
    #[arg(long)]
    pub(crate) canonical: bool,
    /// Decode with a deliberate bug (`table:K`: one wrong entry in scale K's frequency
    /// table), to show that the conformance vectors catch it (spec §11).
    #[arg(long, hide = true, value_parser = parse_fault)]
    pub(crate) inject_fault: Option<salvq::Fault>,
    /// Print what was decoded as JSON on standard output.
    #[arg(long)]
    pub(crate) json: bool,
    /// Fail on a progressive stream that ends early. Without it, a progressive stream cut
    /// after a complete rate (a partial download) decodes to its last complete rate, with a
    /// note saying which (spec §3.8.4).
    #[arg(long)]
    pub(crate) strict: bool,
}

/// The output of a decode, checked before the work, with the extension the profile needs.
fn output_for(args: &DecodeArgs, ctx: Ctx, explicit: bool) -> Result<Output, Error> {
    let (default, allowed, what, extensions): (&str, &[&str], _, _) =
        match (args.canonical, explicit) {
            (true, _) => ("canonical.safetensors", &[], "", ""),
            (false, true) => (
                "ply",
                &["ply"],
                "a scene stream (explicit profile) decodes to a 3DGS PLY",
                ".ply",
            ),
            (false, false) => (
                "safetensors",
                &["safetensors"],
                "an anchor stream decodes to a model file",
                ".safetensors; `salvq export-ply` makes a 3DGS PLY of it",
            ),
        };
    let output = ctx.output(args.output.as_deref(), &args.input, default, &[&args.input])?;
    if !args.canonical {
        output.require_extension(allowed, what, extensions)?;
    }
    files::json_beside(args.json, &output);
    Ok(output)
}

/// `xmin,ymin,zmin,xmax,ymax,zmax`: six numbers (`inf` allowed), each min ≤ its max (§10.3.1).
fn parse_box(s: &str) -> Result<salvq::RegionBox, String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|x| x.trim().parse::<f64>().map_err(|e| format!("'{x}': {e}")))
        .collect::<Result<_, _>>()?;
    let b: [f64; 6] = v
        .try_into()
        .map_err(|v: Vec<f64>| format!("6 numbers expected, {} given", v.len()))?;
    salvq::RegionBox::from_array(b).map_err(|e| e.to_string())
}

/// Decodes `args.input` as asked.
pub(crate) fn run(args: DecodeArgs, ctx: Ctx) -> Result<(), Error> {
    let t = Instant::now();
    let stream = files::read_input(&args.input)?;
    // What the input is comes first: a file that is no stream fails as such, before its
    // output's name is judged by a profile it does not have.
    if let Err(e) = salvq_bitstream::container::signature::Signature::parse(&stream) {
        if stream.starts_with(b"ply") {
            return Err(Error::UnsupportedInput {
                found: "a 3DGS PLY, not a SALVQ stream".into(),
                hint: "`salvq encode` encodes it into one",
            });
        }
        return Err(e.into());
    }
    let explicit = salvq_bitstream::container::is_explicit(&stream);
    let output = if args.measure {
        None
    } else {
        Some(output_for(&args, ctx, explicit)?)
    };
    let DecodeArgs {
        rate,
        threads,
        region,
        canonical,
        inject_fault,
        json,
        strict,
        ..
    } = args;
    let mut options = salvq::Decoder::builder()
        .limits(salvq::Limits::desktop())
        .rate(rate)
        .region(region)
        .fault(inject_fault);
    if let Some(n) = threads {
        options = options.threads(n as usize);
    }
    if explicit {
        // The canonical form holds the symbols (§11.6); a PLY file only the Gaussians.
        let options = options.gaussians_only(!canonical).accept_prefix(!strict);
        let how = decode_explicit::How {
            canonical,
            json,
            ctx,
        };
        return decode_explicit::run(&stream, &options, output.as_ref(), how, t);
    }
    let Some(output) = output else {
        return measure_anchors(&stream, &options, t);
    };
    if canonical {
        let (model, symbols) = options.build().decode_with_symbols(&stream)?;
        let tensors = salvq_conformance::canonical::canonical_tensors(&model, &symbols);
        let bytes = salvq_conformance::canonical::to_safetensors(&tensors);
        return output.write_bytes(&bytes);
    }
    let model = options
        .build()
        .decode(&stream)
        .and_then(salvq::Scene::try_into_anchors)?;
    if model.dims.anchors == 0 {
        ctx.say("salvq: the region intersects no tile; nothing written");
        return Ok(());
    }
    output.write(|w| salvq_render::interchange::write_safetensors(&model, w))?;
    // Which rate was decoded (§7.4): the one asked for, else the lowest coded.
    let decoded_rate = match salvq::Decoder::builder()
        .limits(salvq::Limits::desktop())
        .build()
        .read_header(&stream)
    {
        Ok(salvq::Header::Anchors(p)) => rate.or(p.coded_rates().first().copied()),
        _ => rate,
    };
    let decoded = Decoded {
        output: output.shown(),
        profile: "anchors",
        count: model.dims.anchors.into(),
        rate: decoded_rate,
        rates: model.dims.rates,
        seconds: secs(t),
    };
    if json {
        files::print_json(&decoded);
    }
    ctx.say(&format!(
        "decoded {} anchors at rate {} (of rates 0 … {}; rate 0 is the finest) into {} in {:.2} s",
        decoded.count,
        decoded_rate.map_or("?".into(), |r| r.to_string()),
        decoded.rates.saturating_sub(1),
        decoded.output,
        decoded.seconds
    ));
    Ok(())
}

/// `decode --measure` of an anchors stream: the time and peak memory, nothing written.
fn measure_anchors(
    stream: &[u8],
    options: &salvq::DecoderBuilder,
    t: Instant,
) -> Result<(), Error> {
    let model = options
        .build()
        .decode(stream)
        .and_then(salvq::Scene::try_into_anchors)?;
    out!(
        "measure decode_secs={} peak_rss_bytes={} anchors={} decoded_bytes={}",
        secs(t),
        salvq_bench::scale::peak_rss_bytes().unwrap_or(0),
        model.dims.anchors,
        salvq_bitstream::model::decoded_bytes(&model.dims)
    );
    Ok(())
}
