//! `salvq extract`: one rate of a multi-rate stream as a stream of its own, without
//! re-coding (spec §7.5).

use std::path::PathBuf;

use salvq::Limits;
use salvq_encoder::Error;

use super::files::{self, Ctx};

/// `salvq extract`'s arguments.
#[derive(clap::Args)]
pub(crate) struct ExtractArgs {
    /// Input stream (`-`: standard input).
    input: PathBuf,
    /// The rate to keep (rate 0 is the finest; `salvq info` lists a stream's rates).
    #[arg(long)]
    rate: u8,
    /// Output stream (default: the input's name with `.rate<R>.salvq`; `-`: standard
    /// output).
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Print what was written as JSON on standard output.
    #[arg(long)]
    json: bool,
}

/// What `--json` prints.
#[derive(serde::Serialize)]
struct Written {
    output: String,
    rate: u8,
    bytes: u64,
    input_bytes: u64,
}

/// `salvq extract`.
pub(crate) fn run(a: ExtractArgs, ctx: Ctx) -> Result<(), Error> {
    let extension = format!("rate{}.salvq", a.rate);
    let output = ctx.output(a.output.as_deref(), &a.input, &extension, &[&a.input])?;
    output.require_extension(&["salvq"], "extract writes a SALVQ stream", ".salvq")?;
    files::json_beside(a.json, &output);
    let stream = files::read_input(&a.input)?;
    let one = salvq::extract_rate(&stream, a.rate, &Limits::desktop())?;
    output.write_bytes(&one)?;
    let written = Written {
        output: output.shown(),
        rate: a.rate,
        bytes: one.len() as u64,
        input_bytes: stream.len() as u64,
    };
    if a.json {
        files::print_json(&written);
    }
    ctx.say(&format!(
        "extracted rate {} into {} ({} of {} bytes)",
        written.rate, written.output, written.bytes, written.input_bytes
    ));
    Ok(())
}
