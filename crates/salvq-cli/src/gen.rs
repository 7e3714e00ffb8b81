//! `salvq gen`: a synthetic anchor model (spec Annex B).

use std::path::PathBuf;
use std::time::Instant;

use salvq_encoder::Error;
use salvq_gen::{generate, GenParams};
use salvq_render::interchange::model_to_safetensors;

use super::files::{self, Ctx};
use super::{secs, sha256_hex};

/// `salvq gen`'s arguments.
#[derive(clap::Args)]
pub(crate) struct GenArgs {
    /// Number of anchors.
    #[arg(long)]
    anchors: u32,
    /// Random seed: the same seed gives the same bytes on any machine.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Use the tiny model configuration (tests and examples) instead of HAC's.
    #[arg(long)]
    small: bool,
    /// Feature quantizer of the model: `usq` (identity basis) or `salvq` (a learned
    /// lattice basis B = U diag(s) V^T).
    #[arg(long, default_value = "usq", value_parser = ["usq", "salvq"])]
    quantizer: String,
    /// Feature correlation (Annex B.4.3): the residual mixing matrix's singular values
    /// decay as `d^i`; 1 draws uncorrelated features (a basis has nothing to exploit).
    #[arg(long, default_value_t = salvq_gen::context::FEAT_DECAY, value_parser = parse_decay)]
    feat_decay: f64,
    /// Output model file (safetensors, spec Annex A); `-` for standard output.
    #[arg(short, long)]
    output: PathBuf,
    /// Print what was written as JSON on standard output.
    #[arg(long)]
    json: bool,
}

fn parse_decay(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(d) if d > 0.0 && d <= 1.0 => Ok(d),
        _ => Err(format!("expected a number in (0, 1], got {s}")),
    }
}

/// What `--json` prints.
#[derive(serde::Serialize)]
struct Written {
    output: String,
    anchors: u32,
    seed: u64,
    bytes: u64,
    sha256: String,
    seconds: f64,
}

/// `salvq gen`.
pub(crate) fn run(a: GenArgs, ctx: Ctx) -> Result<(), Error> {
    let output = ctx.check(a.output.clone(), &[])?;
    output.require_extension(&["safetensors"], "gen writes a model file", ".safetensors")?;
    files::json_beside(a.json, &output);
    let mut params = if a.small {
        GenParams::small(a.anchors, a.seed)
    } else {
        GenParams::new(a.anchors, a.seed)
    };
    params.feat_basis = a.quantizer == "salvq";
    params.feat_decay = a.feat_decay;
    salvq_bitstream::model::validate::check_field(
        salvq_bitstream::error::Field::AnchorCount,
        a.anchors.into(),
    )?;
    let t = Instant::now();
    let model = generate(&params);
    let bytes = model_to_safetensors(&model);
    output.write_bytes(&bytes)?;
    let written = Written {
        output: output.shown(),
        anchors: a.anchors,
        seed: a.seed,
        bytes: bytes.len() as u64,
        sha256: sha256_hex(&bytes),
        seconds: secs(t),
    };
    if a.json {
        files::print_json(&written);
    }
    ctx.say(&format!(
        "wrote {} ({} anchors, seed {}, {} bytes) in {:.2} s\nsha256 {}",
        written.output,
        written.anchors,
        written.seed,
        written.bytes,
        written.seconds,
        written.sha256
    ));
    Ok(())
}
