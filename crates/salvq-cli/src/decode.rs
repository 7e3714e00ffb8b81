//! `salvq decode`: a stream of either profile into a model file, a PLY file or the canonical
//! form (spec §1.5, §3, §10.3.1, §11.1).

use std::path::PathBuf;
use std::time::Instant;

use salvq_encoder::Error;

use super::tools::parse_fault;
use super::{decode_explicit, secs, write_model};

/// `salvq decode`'s arguments.
#[derive(clap::Args)]
pub(crate) struct DecodeArgs {
    /// Input stream.
    pub(crate) input: PathBuf,
    /// Output model (safetensors).
    #[arg(short, long)]
    pub(crate) output: PathBuf,
    /// The rate to decode (default: the lowest rate the stream carries).
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
    pub(crate) inject_fault: Option<salvq::decoder::Fault>,
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
pub(crate) fn run(args: DecodeArgs) -> Result<(), Error> {
    let DecodeArgs {
        input,
        output,
        rate,
        threads,
        region,
        measure,
        canonical,
        inject_fault,
    } = args;
    let t = Instant::now();
    let stream = salvq_render::io::read_file(&input)?;
    let options = salvq::DecodeOptions::default()
        .with_rate(rate)
        .with_threads(threads.map(|n| n as usize))
        .with_region(region)
        .with_fault(inject_fault);
    if salvq::decoder::is_explicit(&stream) {
        // The canonical form holds the symbols (§11.6); a PLY file only the Gaussians.
        let options = options.with_gaussians_only(!canonical);
        return decode_explicit::run(&stream, &options, &output, canonical, measure, t);
    }
    if canonical {
        let (model, symbols) = salvq::decoder::decode_with_symbols(&stream, &options)?;
        let tensors = salvq_conformance::canonical::canonical_tensors(&model, &symbols);
        let bytes = salvq_conformance::canonical::to_safetensors(&tensors);
        salvq_render::io::write_bytes_atomic(&output, &bytes)?;
        return Ok(());
    }
    let model = salvq::decode_with_options(&stream, &options)?;
    if measure {
        out!(
            "measure decode_secs={} peak_rss_bytes={} anchors={} decoded_bytes={}",
            secs(t),
            salvq_bench::scale::peak_rss_bytes().unwrap_or(0),
            model.dims.anchors,
            salvq::model::decoded_bytes(&model.dims)
        );
        return Ok(());
    }
    if model.dims.anchors == 0 {
        eprintln!("salvq: the region intersects no tile; nothing written");
        return Ok(());
    }
    write_model(&model, &output)?;
    // Which rate was decoded (§7.4): the one asked for, else the lowest coded.
    let decoded_rate = match salvq::Decoder::builder().build().read_header(&stream) {
        Ok(salvq::Header::Anchors(p)) => rate.or(p.coded_rates().first().copied()),
        _ => rate,
    };
    out!(
        "decoded {} anchors (rate {} of {}; rate 0 is the finest) into {} in {:.2} s",
        model.dims.anchors,
        decoded_rate.map_or("?".into(), |r| r.to_string()),
        model.dims.rates,
        output.display(),
        secs(t)
    );
    Ok(())
}
