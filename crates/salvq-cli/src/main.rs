//! `salvq`: the command-line interface (DESIGN §4 CLI contract).
//!
//! Errors go to stderr as one line naming the rule broken and its spec section; the exit
//! status is 1 for a failed operation and 2 for a usage error. Output files are written
//! atomically: a failed command leaves nothing behind.

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

mod compare;
mod decode;
mod decode_explicit;
mod demo;
mod encode;
mod encode_ply;
mod progress;
mod render;
mod tools;

use demo::demo;
use tools::{conformance, make_vectors};

use clap::{Parser, Subcommand};
use salvq::Limits;
use salvq_encoder::info::inspect;
use salvq_encoder::Error;
use salvq_gen::{generate, GenParams};
use salvq_render::interchange::{model_to_safetensors, write_model};

#[derive(Parser)]
#[command(
    name = "salvq",
    version,
    about = "SALVQ compressed 3DGS scenes: reference encoder and decoder"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Generate a synthetic scene model (spec Annex B) and print its SHA-256.
    Gen {
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
        /// Output model file (safetensors, spec Annex A).
        #[arg(short, long)]
        output: PathBuf,
    },
    /// Encode a model file into a SALVQ stream.
    Encode(encode::EncodeArgs),
    /// Decode a SALVQ stream into a model file.
    Decode(decode::DecodeArgs),
    /// Run a decoder on the conformance vectors and compare its output with the manifest
    /// (spec §11.5). The decoder command gets `{in}`, `{out}` and `{rate}` substituted, or
    /// the three appended.
    Conformance {
        /// The decoder under test (default: this program's `decode --canonical`).
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
    /// Write the single-rate stream of one rate of a multi-rate stream, without re-coding
    /// (byte-identical to encoding that rate alone).
    Extract {
        /// Input stream.
        input: PathBuf,
        /// The rate to keep.
        #[arg(long)]
        rate: u8,
        /// Output stream.
        #[arg(short, long)]
        output: PathBuf,
    },
    /// Show what a stream holds: preflight, chunks, model vs anchor bytes.
    Info {
        /// Input stream.
        input: PathBuf,
        /// Print JSON instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Measurements with charts: `bench rd` codes one generated scene with every feature
    /// quantizer and search method (R-D with BD-rates, speed vs accuracy, stability).
    Bench {
        #[command(subcommand)]
        which: Bench,
    },
    /// Render a preview image (PNG) of a stream, a model file or a 3DGS PLY file from a
    /// camera of the ring (spec Annex C).
    Render(render::RenderArgs),
    /// Export a stream or a model file as a standard 3DGS PLY file (spec Annex C.3), its
    /// view-dependent attributes evaluated from a ring camera.
    ExportPly(render::ExportPlyArgs),
    /// Render two scenes (streams, model files or PLY files) from the same cameras and print
    /// PSNR and SSIM per view and overall (spec Annex C.5).
    Compare(compare::CompareArgs),
    /// The main job on an embedded default: generate, encode, decode, verify, report.
    Demo {
        /// Number of anchors of the generated scene.
        #[arg(long, default_value_t = 100_000)]
        anchors: u32,
        /// Random seed.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Keep the generated files in this folder (default: a temporary folder).
        #[arg(long)]
        out: Option<PathBuf>,
    },
}

#[derive(Subcommand)]
enum Bench {
    /// Rate-distortion of USQ, D_n, E8 and SALVQ on one generated scene (F = 48), BD-rates,
    /// SALVQ's gain vs feature correlation, search methods' speed vs accuracy, and stability
    /// over basis condition numbers and extreme gains: SVG charts, CSV and summary in OUT.
    Rd {
        /// Output folder.
        #[arg(long, default_value = "charts")]
        out: PathBuf,
        /// Anchors of the generated scene.
        #[arg(long, default_value_t = 20_000)]
        anchors: u32,
        /// Random seed.
        #[arg(long, default_value_t = 1)]
        seed: u64,
    },
    /// Decode time and peak memory against scene size (1 k … `--max` anchors) with 1 and 2
    /// threads, and a region decode of an eighth of the scene: SVG chart, CSV and summary
    /// in OUT.
    Scale {
        /// Output folder.
        #[arg(long, default_value = "charts")]
        out: PathBuf,
        /// Largest scene (anchors).
        #[arg(long, default_value_t = 2_000_000)]
        max: u32,
    },
    /// The explicit profile on real 3DGS scenes (issue 19): salvq's rates from one file
    /// against splat-transform's SPZ, SOG and compressed PLY, render PSNR / SSIM from the
    /// same ring cameras, encode and decode times, ablations and bits per attribute group
    /// (SVG, CSV, text in OUT).
    Real {
        /// Folder holding the scenes as `<name>.ply`.
        #[arg(long, default_value = "../shared/data")]
        data: PathBuf,
        /// Scenes (file stems in `--data`).
        #[arg(
            long,
            value_delimiter = ',',
            default_value = "donut,fruit_drops,alti,guitar,playbot"
        )]
        scenes: Vec<String>,
        /// Output folder.
        #[arg(long, default_value = "charts")]
        out: PathBuf,
        /// salvq's render-PSNR targets (rate 0 first).
        #[arg(long, value_delimiter = ',', default_value = "62,56,50,45,40,35")]
        psnr: Vec<f64>,
        /// The splat-transform command for the peers (e.g. `node_modules/.bin/splat-transform`);
        /// without it the peers are skipped.
        #[arg(long)]
        splat_transform: Option<String>,
        /// Skip the ablations (each a full encode per scene).
        #[arg(long)]
        no_ablations: bool,
        /// Only redraw OUT/real.svg from OUT/real.csv (nothing is measured).
        #[arg(long)]
        replot: bool,
        /// Ring views, image width and height of the renders compared.
        #[arg(long, default_value_t = 8)]
        views: u32,
        #[arg(long, default_value_t = 512)]
        width: u32,
        #[arg(long, default_value_t = 384)]
        height: u32,
    },
    /// Model share of the stream and bits per anchor vs scene size, plain, with
    /// `--prune-grid`, and with binary16 Scaffold-GS MLPs; then total bytes vs precision per
    /// model tensor group at 100 k anchors (issue 10; SVG, CSV).
    Parsimony {
        /// Output folder.
        #[arg(long, default_value = "charts")]
        out: PathBuf,
        /// Largest scene (anchors).
        #[arg(long, default_value_t = 1_000_000)]
        max: u32,
    },
}

fn parse_decay(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(d) if d > 0.0 && d <= 1.0 => Ok(d),
        _ => Err(format!("expected a number in (0, 1], got {s}")),
    }
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

/// The file a command writes, checked before any work is done (a folder, or a path in a
/// folder that does not exist, fails at once rather than after the encode).
fn output_of(command: &Command) -> Option<&std::path::Path> {
    match command {
        Command::Gen { output, .. } | Command::Extract { output, .. } => Some(output),
        Command::Encode(a) => Some(&a.output),
        Command::Decode(a) => Some(&a.output),
        Command::Render(a) => Some(&a.output),
        Command::ExportPly(a) => Some(&a.output),
        _ => None,
    }
}

fn run(cli: Cli) -> Result<(), Error> {
    if let Some(path) = output_of(&cli.command) {
        salvq_render::io::check_output(path)?;
    }
    match cli.command {
        Command::Gen {
            anchors,
            seed,
            small,
            quantizer,
            feat_decay,
            output,
        } => {
            let mut params = if small {
                GenParams::small(anchors, seed)
            } else {
                GenParams::new(anchors, seed)
            };
            params.feat_basis = quantizer == "salvq";
            params.feat_decay = feat_decay;
            salvq::model::validate::check_field(salvq::error::Field::AnchorCount, anchors.into())?;
            let t = Instant::now();
            let model = generate(&params);
            let bytes = model_to_safetensors(&model);
            salvq_render::io::write_bytes_atomic(&output, &bytes)?;
            out!(
                "wrote {} ({} anchors, seed {seed}, {} bytes) in {:.2} s\nsha256 {}",
                output.display(),
                anchors,
                bytes.len(),
                secs(t),
                sha256_hex(&bytes)
            );
        }
        Command::Encode(args) => encode(args)?,
        Command::Extract {
            input,
            rate,
            output,
        } => {
            let stream = salvq_render::io::read_file(&input)?;
            let one = salvq::extract_rate(&stream, rate, &Limits::default())?;
            salvq_render::io::write_bytes_atomic(&output, &one)?;
            out!(
                "extracted rate {rate} into {} ({} of {} bytes)",
                output.display(),
                one.len(),
                stream.len()
            );
        }
        Command::Decode(args) => decode::run(args)?,
        // Handled in `main`: their failures are mismatches, not stream errors.
        Command::Conformance { .. } | Command::MakeVectors { .. } => {}
        Command::Info { input, json } => {
            let stream = salvq_render::io::read_file(&input)?;
            if salvq::decoder::is_explicit(&stream) {
                let info =
                    salvq_encoder::info::explicit::inspect_explicit(&stream, &Limits::default())?;
                if json {
                    out!(
                        "{}",
                        serde_json::to_string_pretty(&info).unwrap_or_default()
                    );
                } else {
                    crate::print_text(&info.to_text());
                }
                return Ok(());
            }
            let info = inspect(&stream, &Limits::default())?;
            if json {
                out!(
                    "{}",
                    serde_json::to_string_pretty(&info).unwrap_or_default()
                );
            } else {
                crate::print_text(&info.to_text());
            }
        }
        Command::Bench {
            which: Bench::Rd { out, anchors, seed },
        } => {
            let t = Instant::now();
            let text = salvq_bench::run(&salvq_bench::RdOptions {
                anchors,
                seed,
                out: out.clone(),
            })?;
            crate::print_text(&text);
            out!("wrote rd.svg, rd_correlation.svg, search_speed.svg, stability.svg, rd.csv, summary.txt to {} in {:.1} s", out.display(), secs(t));
        }
        Command::Bench {
            which: Bench::Scale { out, max },
        } => {
            let t = Instant::now();
            let text = salvq_bench::scale::run(&out, max)?;
            crate::print_text(&text);
            out!(
                "wrote scale.svg, scale.csv, scale.txt to {} in {:.1} s",
                out.display(),
                secs(t)
            );
        }
        Command::Bench {
            which:
                Bench::Real {
                    data,
                    scenes,
                    out,
                    psnr,
                    splat_transform,
                    no_ablations,
                    replot,
                    views,
                    width,
                    height,
                },
        } => {
            let t = Instant::now();
            let options = salvq_bench::real::RealOptions {
                data,
                scenes,
                out: out.clone(),
                targets: psnr,
                splat_transform,
                ablations: !no_ablations,
                views,
                width,
                height,
            };
            if replot {
                salvq_bench::real::replot(&out, &options)?;
                out!("redrew {}", out.join("real.svg").display());
                return Ok(());
            }
            let text = salvq_bench::real::run(&options, &|m| eprintln!("{m}"))?;
            crate::print_text(&text);
            out!(
                "wrote real.svg, real.csv, real.txt to {} in {:.1} s",
                out.display(),
                secs(t)
            );
        }
        Command::Bench {
            which: Bench::Parsimony { out, max },
        } => {
            let t = Instant::now();
            let text = salvq_bench::parsimony::run(&out, max)?;
            crate::print_text(&text);
            out!(
                "wrote parsimony and precision .svg, .csv, .txt to {} in {:.1} s",
                out.display(),
                secs(t)
            );
        }
        Command::Demo { anchors, seed, out } => demo(anchors, seed, out.as_deref())?,
        Command::Render(args) => render::render(args)?,
        Command::ExportPly(args) => render::export_ply(args)?,
        Command::Compare(args) => compare::run(args)?,
    }
    Ok(())
}

fn main() -> ExitCode {
    let cli = Cli::parse();
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
    match run(cli) {
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
fn encode(a: encode::EncodeArgs) -> Result<(), Error> {
    let t = Instant::now();
    let progress = progress::Progress::new(a.quiet);
    progress.stage(format!("reading {}", a.input.display()));
    let bytes = salvq_render::io::read_file(&a.input)?;
    if salvq_encoder::explicit::input::input_kind(&bytes)?
        == salvq_encoder::explicit::input::InputKind::Ply
    {
        return encode_ply::run(a, &bytes, t, &progress);
    }
    encode::run_model(a, bytes, t, &progress)
}
