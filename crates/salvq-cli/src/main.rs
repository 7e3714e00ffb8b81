//! `salvq`: the command-line interface, a Unix tool that composes in pipes.
//!
//! Standard output carries data alone (`-o -`, reports, `--json`); messages and progress go
//! to standard error. Errors are one line naming the rule broken and its spec section; the
//! exit status is 1 for a failed operation and 2 for a usage error. Output files are
//! written atomically (a failed command leaves nothing behind), an existing one is replaced
//! only with `--force`, and an input never.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

/// `println!` for the command's report: a reader that closes the pipe early (`salvq info x |
/// head`) ends the command quietly instead of a panic ("failed printing to stdout").
macro_rules! out {
    () => {
        $crate::print_line(format_args!(""))
    };
    ($($arg:tt)*) => {
        $crate::print_line(format_args!($($arg)*))
    };
}

/// One line to standard output; a closed pipe ends the process with status 0 (as `head`
/// expects of the commands it reads), any other failure with status 1.
fn print_line(args: std::fmt::Arguments<'_>) {
    print_text(&format!("{args}\n"));
}

/// Text to standard output, as [`print_line`] writes it.
fn print_text(text: &str) {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    if let Err(e) = out.write_all(text.as_bytes()).and_then(|()| out.flush()) {
        std::process::exit(i32::from(e.kind() != std::io::ErrorKind::BrokenPipe));
    }
}

mod bench;
mod compare;
mod decode;
mod decode_explicit;
mod demo;
mod encode;
mod encode_ply;
mod extract;
mod files;
mod gen;
mod info;
mod progress;
mod render;
mod tools;

use demo::demo;
use tools::{conformance, make_vectors};

use clap::{CommandFactory, FromArgMatches, Parser, Subcommand};
use salvq_encoder::Error;

use files::Ctx;

/// Options every command takes, before or after its name.
#[derive(clap::Args, Clone, Copy)]
struct Global {
    /// Replace an output file that exists (an input is never replaced, even with --force);
    /// allow binary data on a terminal.
    #[arg(short, long, global = true)]
    force: bool,
    /// Print nothing on standard error but errors: no progress, notes or summary.
    #[arg(short, long, global = true)]
    quiet: bool,
}

#[derive(Parser)]
#[command(
    name = "salvq",
    about = "SALVQ: compressed 3D Gaussian Splatting scenes. Encodes a trained 3DGS PLY (or \
             an anchor model) into one .salvq file with several rates, and decodes it back.",
    after_help = "A scene: `salvq encode scene.ply` writes scene.salvq; `salvq decode \
                  scene.salvq` writes scene.ply. `-` reads standard input or, as -o, writes \
                  standard output; messages go to standard error. The spec: spec/README.md."
)]
struct Cli {
    #[command(flatten)]
    global: Global,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Encode a 3DGS scene (binary PLY, Inria layout) or an anchor model (safetensors) into a
    /// .salvq stream with several rates (rate 0 the finest).
    Encode(encode::EncodeArgs),
    /// Decode a .salvq stream: a scene to a 3DGS PLY, an anchor model to safetensors.
    Decode(decode::DecodeArgs),
    /// Show what a stream holds (rates, bytes per group, chunks), or what a PLY holds and
    /// how to encode it.
    Info(info::InfoArgs),
    /// Write one rate of a multi-rate stream as a stream of its own, without re-coding.
    Extract(extract::ExtractArgs),
    /// Render a preview image (PNG) of a stream, a model file or a 3DGS PLY file from a
    /// camera of the ring (spec Annex C).
    Render(render::RenderArgs),
    /// Render two scenes (streams, model files or PLY files) from the same cameras and print
    /// PSNR and SSIM per view and overall (spec Annex C.5).
    Compare(compare::CompareArgs),
    /// Export a stream or a model file as a standard 3DGS PLY file (spec Annex C.3), its
    /// view-dependent attributes evaluated from a ring camera.
    ExportPly(render::ExportPlyArgs),
    /// Generate a synthetic anchor model (spec Annex B) and print its SHA-256.
    Gen(gen::GenArgs),
    /// Run a decoder on the conformance vectors and compare its output with the manifest
    /// (spec §11.5). The decoder command gets `{in}`, `{out}` and `{rate}` substituted, or
    /// the three appended.
    Conformance {
        /// The decoder under test (default: this program's `decode --canonical --strict`).
        #[arg(long)]
        decoder: Option<String>,
        /// The command for region decodes (spec §11.7): as `--decoder`, with `{region}`
        /// replaced by `x0,y0,z0,x1,y1,z1` too. Without it, a `--decoder`'s region decodes
        /// are skipped (the reference's run with `--region {region}`).
        #[arg(long)]
        region_decoder: Option<String>,
        /// The vectors folder (with manifest.json).
        #[arg(long, default_value = "conformance/vectors")]
        vectors: PathBuf,
        /// Run only the vectors whose name contains this text.
        #[arg(long)]
        filter: Option<String>,
    },
    /// Generate the conformance vectors, manifest and coverage table (spec §11.4), or with
    /// `--check` verify that the committed ones are what the generator writes.
    MakeVectors {
        /// The vectors folder.
        #[arg(long, default_value = "conformance/vectors")]
        out: PathBuf,
        /// The README whose coverage table is regenerated.
        #[arg(long, default_value = "conformance/README.md")]
        readme: PathBuf,
        /// The spec folder (for the list of normative sections).
        #[arg(long, default_value = "spec")]
        spec: PathBuf,
        /// Compare instead of writing; fail on any difference.
        #[arg(long)]
        check: bool,
    },
    /// Measurements with charts: `bench rd` codes one generated scene with every feature
    /// quantizer and search method (R-D with BD-rates, speed vs accuracy, stability).
    Bench {
        #[command(subcommand)]
        which: bench::Bench,
    },
    /// The main job on an embedded default: generate, encode, decode, verify, report.
    Demo {
        /// Number of anchors of the generated scene.
        #[arg(long, default_value_t = 100_000)]
        anchors: u32,
        /// Random seed.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Keep the generated files in this folder (default: a temporary folder); files of
        /// an earlier run there are replaced only with --force.
        #[arg(long)]
        out: Option<PathBuf>,
    },
}

fn sha256_hex(bytes: &[u8]) -> String {
    use sha2::{Digest, Sha256};
    Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

fn secs(t: Instant) -> f64 {
    t.elapsed().as_secs_f64()
}

/// `salvq --version`: the crate's version, the format version it reads and writes, and the
/// commit it was built from.
fn version() -> String {
    format!(
        "{} (format {}.{}, commit {})",
        env!("CARGO_PKG_VERSION"),
        salvq_bitstream::container::FORMAT_MAJOR,
        salvq_bitstream::container::FORMAT_MINOR,
        env!("SALVQ_COMMIT")
    )
}

fn run(command: Command, ctx: Ctx) -> Result<(), Error> {
    match command {
        Command::Gen(args) => gen::run(args, ctx)?,
        Command::Encode(args) => encode(args, ctx)?,
        Command::Extract(args) => extract::run(args, ctx)?,
        Command::Decode(args) => decode::run(args, ctx)?,
        // Handled in `main`: their failures are mismatches, not stream errors.
        Command::Conformance { .. } | Command::MakeVectors { .. } => {}
        Command::Info(args) => info::run(args)?,
        Command::Bench { which } => bench::run(which)?,
        Command::Demo { anchors, seed, out } => demo(anchors, seed, out.as_deref(), ctx)?,
        Command::Render(args) => render::render(args, ctx)?,
        Command::ExportPly(args) => render::export_ply(args, ctx)?,
        Command::Compare(args) => compare::run(args)?,
    }
    Ok(())
}

fn main() -> ExitCode {
    // Built once, for the life of the process (clap keeps a 'static string).
    let version: &'static str = Box::leak(version().into_boxed_str());
    let matches = Cli::command().version(version).get_matches();
    let cli = match Cli::from_arg_matches(&matches) {
        Ok(cli) => cli,
        Err(e) => e.exit(),
    };
    // The conformance tools fail on mismatches, not on stream errors: plain messages.
    let tool = match &cli.command {
        Command::Conformance {
            decoder,
            region_decoder,
            vectors,
            filter,
        } => Some(conformance(
            decoder.clone(),
            region_decoder.clone(),
            vectors,
            filter.as_deref(),
        )),
        Command::MakeVectors {
            out,
            readme,
            spec,
            check,
        } => Some(make_vectors(out, readme, spec, *check)),
        _ => None,
    };
    if let Some(result) = tool {
        return match result {
            Ok(()) => ExitCode::SUCCESS,
            Err(e) => {
                eprintln!("salvq: {e}");
                ExitCode::FAILURE
            }
        };
    }
    let ctx = Ctx {
        force: cli.global.force,
        quiet: cli.global.quiet,
    };
    match run(cli.command, ctx) {
        Ok(()) => ExitCode::SUCCESS,
        // `-o -` into a reader that stopped early (`| head -c 100`): not a failure.
        Err(salvq_encoder::Error::Files(salvq_render::Error::Io { source, .. }))
            if source.kind() == std::io::ErrorKind::BrokenPipe =>
        {
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("salvq: error[{}]: {e}", e.class());
            ExitCode::FAILURE
        }
    }
}

/// `salvq encode`: a PLY scene takes the explicit profile (spec §3), anything else is read as
/// a scene model (Annex A).
fn encode(a: encode::EncodeArgs, ctx: Ctx) -> Result<(), Error> {
    let t = Instant::now();
    let output = ctx.output(a.output.as_deref(), &a.input, "salvq", &[&a.input])?;
    output.require_extension(&["salvq"], "the encoder writes a SALVQ stream", ".salvq")?;
    files::json_beside(a.json, &output);
    let progress = progress::Progress::new(ctx.quiet);
    let bytes = files::read_input(&a.input)?;
    if salvq_encoder::explicit::input::input_kind(&bytes)?
        == salvq_encoder::explicit::input::InputKind::Ply
    {
        return encode_ply::run(a, &output, &bytes, t, &progress);
    }
    encode::run_model(a, &output, bytes, t, &progress)
}
