//! `salvq`: the command-line interface (DESIGN §4 CLI contract).
//!
//! Errors go to stderr as one line naming the rule broken and its spec section; the exit
//! status is 1 for a failed operation and 2 for a usage error. Output files are written
//! atomically: a failed command leaves nothing behind.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use clap::{Parser, Subcommand};
use salvq::gen::{generate, GenParams};
use salvq::info::{inspect, ByteClass};
use salvq::model::interchange::{model_to_safetensors, read_model, write_model};
use salvq::{Error, Limits};

#[derive(Parser)]
#[command(
    name = "salvq",
    version,
    about = "SALVQ compressed 3DGS scenes: reference encoder and decoder (format 0.1)"
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
        /// Output model file (safetensors, spec Annex A).
        #[arg(short, long)]
        output: PathBuf,
    },
    /// Encode a model file into a SALVQ stream.
    Encode {
        /// Input model (safetensors, spec Annex A).
        input: PathBuf,
        /// Output stream.
        #[arg(short, long)]
        output: PathBuf,
        /// Text for an `encd` ancillary chunk (encoder identification).
        #[arg(long)]
        note: Option<String>,
    },
    /// Decode a SALVQ stream into a model file.
    Decode {
        /// Input stream.
        input: PathBuf,
        /// Output model (safetensors).
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

fn run(cli: Cli) -> Result<(), Error> {
    match cli.command {
        Command::Gen {
            anchors,
            seed,
            small,
            output,
        } => {
            let params = if small {
                GenParams::small(anchors, seed)
            } else {
                GenParams::new(anchors, seed)
            };
            salvq::model::validate::check_field(salvq::error::Field::AnchorCount, anchors.into())?;
            let t = Instant::now();
            let model = generate(&params);
            let bytes = model_to_safetensors(&model);
            salvq::io::write_bytes_atomic(&output, &bytes)?;
            println!(
                "wrote {} ({} anchors, seed {seed}, {} bytes) in {:.2} s\nsha256 {}",
                output.display(),
                anchors,
                bytes.len(),
                secs(t),
                sha256_hex(&bytes)
            );
        }
        Command::Encode {
            input,
            output,
            note,
        } => {
            let t = Instant::now();
            let model = read_model(&input)?;
            let options = salvq::EncodeOptions { encoder_note: note };
            let stream = salvq::encode_with_options(&model, &options)?;
            salvq::io::write_bytes_atomic(&output, &stream)?;
            println!(
                "encoded {} anchors into {} ({} bytes, {:.2} bits/anchor) in {:.2} s",
                model.dims.anchors,
                output.display(),
                stream.len(),
                stream.len() as f64 * 8.0 / f64::from(model.dims.anchors),
                secs(t)
            );
        }
        Command::Decode { input, output } => {
            let t = Instant::now();
            let stream = salvq::io::read_file(&input)?;
            let model = salvq::decode_with_limits(&stream, &Limits::default())?;
            write_model(&model, &output)?;
            println!(
                "decoded {} anchors into {} in {:.2} s",
                model.dims.anchors,
                output.display(),
                secs(t)
            );
        }
        Command::Info { input, json } => {
            let stream = salvq::io::read_file(&input)?;
            let info = inspect(&stream, &Limits::default())?;
            if json {
                println!(
                    "{}",
                    serde_json::to_string_pretty(&info).unwrap_or_default()
                );
            } else {
                print!("{}", info.to_text());
            }
        }
        Command::Demo { anchors, seed, out } => demo(anchors, seed, out.as_deref())?,
    }
    Ok(())
}

/// Generates a scene, encodes it, decodes it, checks the round trip, prints the table.
fn demo(anchors: u32, seed: u64, out: Option<&Path>) -> Result<(), Error> {
    let tmp;
    let dir = match out {
        Some(d) => {
            std::fs::create_dir_all(d).map_err(|e| Error::Io {
                op: salvq::error::IoOp::Write,
                path: d.to_path_buf(),
                kind: e.kind(),
            })?;
            d.to_path_buf()
        }
        None => {
            tmp = tempfile::tempdir().map_err(|e| Error::Io {
                op: salvq::error::IoOp::CreateTemp,
                path: std::env::temp_dir(),
                kind: e.kind(),
            })?;
            tmp.path().to_path_buf()
        }
    };
    println!("salvq demo: format 0.1 (lossless payloads), {anchors} anchors, seed {seed}, HAC-size model\n");
    let params = GenParams::new(anchors, seed);
    salvq::model::validate::check_field(salvq::error::Field::AnchorCount, anchors.into())?;
    let t = Instant::now();
    let model = generate(&params);
    let t_gen = secs(t);
    let model_path = dir.join("scene.safetensors");
    write_model(&model, &model_path)?;
    let input_bytes = std::fs::metadata(&model_path).map(|m| m.len()).unwrap_or(0);

    let t = Instant::now();
    let stream = salvq::encode(&model)?;
    let t_enc = secs(t);
    let stream_path = dir.join("scene.salvq");
    salvq::io::write_bytes_atomic(&stream_path, &stream)?;

    let t = Instant::now();
    let decoded = salvq::decode(&stream)?;
    let t_dec = secs(t);
    let exact = decoded == model;

    let info = inspect(&stream, &Limits::default())?;
    println!("{:<10} {:>10}", "step", "seconds");
    println!("{:<10} {:>10.3}", "generate", t_gen);
    println!("{:<10} {:>10.3}", "encode", t_enc);
    println!("{:<10} {:>10.3}", "decode", t_dec);
    println!();
    println!(
        "{:<6} {:<7} {:>12} {:>8} {:>12}",
        "chunk", "class", "bytes", "share", "bits/anchor"
    );
    let total = info.totals.file_bytes as f64;
    for c in &info.chunks {
        let class = match c.class {
            ByteClass::Model => "model",
            ByteClass::Anchor => "anchor",
            ByteClass::Other => "other",
        };
        println!(
            "{:<6} {:<7} {:>12} {:>7.2}% {:>12.2}",
            c.tag,
            class,
            c.total_bytes,
            100.0 * c.total_bytes as f64 / total,
            c.total_bytes as f64 * 8.0 / f64::from(anchors)
        );
    }
    let t = &info.totals;
    println!(
        "\nmodel bytes {} ({:.2}%), anchor bytes {} ({:.2}%), other {}; total {} bytes = {:.2} bits/anchor",
        t.model_bytes,
        100.0 * t.model_bytes as f64 / total,
        t.anchor_bytes,
        100.0 * t.anchor_bytes as f64 / total,
        t.other_bytes,
        t.file_bytes,
        t.bits_per_anchor
    );
    println!(
        "input model file {} bytes; stream / input = {:.4}",
        input_bytes,
        total / input_bytes.max(1) as f64
    );
    println!(
        "round trip: decoded model {} the input model",
        if exact { "equals" } else { "DIFFERS FROM" }
    );
    if out.is_some() {
        println!("files kept in {}", dir.display());
    }
    if !exact {
        return Err(Error::ValueInvalid {
            tensor: "demo round trip",
            index: vec![],
            value: 0,
            allowed: "decoded == input",
        });
    }
    Ok(())
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("salvq: error[{}]: {e}", e.class());
            ExitCode::FAILURE
        }
    }
}
