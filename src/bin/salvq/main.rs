//! `salvq`: the command-line interface (DESIGN §4 CLI contract).
//!
//! Errors go to stderr as one line naming the rule broken and its spec section; the exit
//! status is 1 for a failed operation and 2 for a usage error. Output files are written
//! atomically: a failed command leaves nothing behind.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

mod demo;
mod tools;

use demo::demo;
use tools::{conformance, make_vectors, parse_fault};

use clap::{Parser, Subcommand};
use salvq::gen::{generate, GenParams};
use salvq::info::inspect;
use salvq::model::interchange::{model_to_safetensors, read_model, write_model};
use salvq::{Error, Limits};

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
        /// The rates (indices into the model's gains) to code, one symbol layer each, e.g.
        /// `0,1,2,3` (spec §7.4).
        #[arg(long, value_delimiter = ',', default_value = "0")]
        rates: Vec<u8>,
        /// Feature quantizer: `model` (the model's own), `usq` (identity), `dn` (D_n),
        /// `e8` (E8 product; the feature dimension must be a multiple of 8), `salvq` (the
        /// model's learned basis) or `klt` (a basis the encoder fits to the features' residuals,
        /// spec Annex A.5).
        #[arg(long, default_value = "model", value_parser = ["model", "usq", "dn", "e8", "salvq", "klt"])]
        quantizer: String,
        /// Refit the context MLP's feature-scale rows to the coordinates of the chosen
        /// quantizer (spec Annex A.5), as training for that quantizer would.
        #[arg(long)]
        fit_scales: bool,
        /// With `--quantizer klt`: fit one basis per spatial region, R regions of equal
        /// anchor count in Morton order (Sp-SALVQ, spec §7.6).
        #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u16).range(1..))]
        regions: u16,
        /// Anchors per tile (spec §10): tiles decode independently, in parallel or alone.
        #[arg(long, default_value_t = salvq::tiles::DEFAULT_TILE_ANCHORS, value_parser = clap::value_parser!(u32).range(1..))]
        tile_anchors: u32,
        /// How lattice points are searched: `auto` (exact for Z^n, D_n, E8; Babai nearest
        /// plane on the LLL-reduced basis for a learned basis), `rounding`, `nearest-plane`,
        /// `closest` (Schnorr-Euchner, bounded) or `rdo` (auto's point refined for rate and
        /// distortion with the integer entropy model, spec §7.3).
        #[arg(long, default_value = "auto", value_parser = salvq::Search::NAMES)]
        search: String,
        /// Do not write the `ests` chunk (encoder statistics shown by `info`).
        #[arg(long)]
        no_stats: bool,
        /// Drop hash-grid levels that do not pay for themselves: a level goes when the stream
        /// without it is smaller and the feature error grows by at most 1 % (each candidate
        /// is encoded; prints what it chose and why).
        #[arg(long)]
        prune_grid: bool,
        /// How to store the Scaffold-GS MLPs (spec §1.6.2): `auto` (binary16 when their
        /// outputs on the scene's anchors move by at most 2^-9, spec Annex A.5.2), `f32`, `f16`.
        #[arg(long, default_value = "auto", value_parser = ["auto", "f32", "f16"])]
        scaffold_precision: String,
        /// Print the encoder's report as JSON.
        #[arg(long)]
        json: bool,
    },
    /// Decode a SALVQ stream into a model file.
    Decode {
        /// Input stream.
        input: PathBuf,
        /// Output model (safetensors).
        #[arg(short, long)]
        output: PathBuf,
        /// The rate to decode (default: the lowest rate the stream carries).
        #[arg(long)]
        rate: Option<u8>,
        /// Decode tiles on N threads (spec §10.3; the output is the same for every N).
        #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
        threads: Option<u32>,
        /// Decode only the tiles that intersect this world-space box:
        /// `xmin,ymin,zmin,xmax,ymax,zmax` (spec §10.3).
        #[arg(long, value_parser = parse_box, allow_hyphen_values = true)]
        region: Option<[f64; 6]>,
        /// Measure instead of writing: print the decode time and the process's peak resident
        /// memory (used by `bench scale`).
        #[arg(long, hide = true)]
        measure: bool,
        /// Write the canonical decoded form instead of the model file: the model's tensors
        /// and the decoded symbols, as the conformance runner reads them (spec §11.1).
        #[arg(long)]
        canonical: bool,
        /// Decode with a deliberate bug (`table:K`: one wrong entry in scale K's frequency
        /// table), to show that the conformance vectors catch it (spec §11).
        #[arg(long, hide = true, value_parser = parse_fault)]
        inject_fault: Option<salvq::decoder::Fault>,
    },
    /// Run a decoder on the conformance vectors and compare its output with the manifest
    /// (spec §11.5). The decoder command gets `{in}`, `{out}` and `{rate}` substituted, or
    /// the three appended.
    Conformance {
        /// The decoder under test (default: this program's `decode --canonical`).
        #[arg(long)]
        decoder: Option<String>,
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
    /// Model share of the stream and bits per anchor vs scene size, plain, with
    /// `--prune-grid`, and with binary16 Scaffold-GS MLPs (issue 10; SVG, CSV).
    Parsimony {
        /// Output folder.
        #[arg(long, default_value = "charts")]
        out: PathBuf,
        /// Largest scene (anchors).
        #[arg(long, default_value_t = 1_000_000)]
        max: u32,
    },
}

/// `xmin,ymin,zmin,xmax,ymax,zmax`: six finite numbers, each min ≤ its max.
fn parse_box(s: &str) -> Result<[f64; 6], String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|x| x.trim().parse::<f64>().map_err(|e| format!("'{x}': {e}")))
        .collect::<Result<_, _>>()?;
    let b: [f64; 6] = v
        .try_into()
        .map_err(|v: Vec<f64>| format!("6 numbers expected, {} given", v.len()))?;
    if b.iter().any(|x| !x.is_finite()) || (0..3).any(|a| b[a] > b[a + 3]) {
        return Err("the box needs finite numbers and min <= max on each axis".into());
    }
    Ok(b)
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
            quantizer,
            output,
        } => {
            let mut params = if small {
                GenParams::small(anchors, seed)
            } else {
                GenParams::new(anchors, seed)
            };
            params.feat_basis = quantizer == "salvq";
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
            rates,
            quantizer,
            search,
            fit_scales,
            regions,
            tile_anchors,
            no_stats,
            prune_grid,
            scaffold_precision,
            json,
        } => {
            let t = Instant::now();
            let mut model = read_model(&input)?;
            let feat_lattice = match quantizer.as_str() {
                "usq" => Some(salvq::LatticeKind::Identity),
                "dn" => Some(salvq::LatticeKind::Dn),
                "e8" => Some(salvq::LatticeKind::E8Product),
                "salvq" => Some(salvq::LatticeKind::General),
                _ => None,
            };
            let options = salvq::EncodeOptions {
                encoder_note: note,
                rates,
                statistics: !no_stats,
                feat_lattice,
                search: salvq::Search::from_name(&search).unwrap_or_default(),
                fit_basis: quantizer == "klt",
                feat_regions: regions,
                fit_scales,
                tile_anchors,
                scaffold_precision: match scaffold_precision.as_str() {
                    "f32" => Some(salvq::container::payload::ScaffoldPrecision::F32),
                    "f16" => Some(salvq::container::payload::ScaffoldPrecision::F16),
                    _ => None,
                },
            };
            if prune_grid {
                let (pruned, trials) =
                    salvq::encoder::parsimony::prune_grid_levels(&model, &options, 0.01)?;
                for tr in &trials {
                    let basis = if tr.sample_anchors < model.n() {
                        format!(", estimated from {} sampled anchors", tr.sample_anchors)
                    } else {
                        String::new()
                    };
                    eprintln!(
                        "dropped {} (resolution {}): {} -> {} bytes, feature MSE {:.4e} -> {:.4e}{basis}",
                        tr.level,
                        tr.resolution,
                        tr.bytes_with,
                        tr.bytes_without,
                        tr.mse_with,
                        tr.mse_without
                    );
                }
                if trials.is_empty() {
                    eprintln!("kept every grid level: no removal made the stream smaller");
                }
                model = pruned;
            }
            let encoded = salvq::encoder::encode_full(&model, &options)?;
            let sc = &encoded.scaffold;
            eprintln!(
                "Scaffold-GS MLPs stored as {:?}: binary16 changes their outputs by at most {:.2e} \
                 (tolerance {:.2e}); {} bytes saved",
                sc.precision, sc.max_output_change, sc.tolerance, sc.bytes_saved
            );
            let stream = &encoded.stream;
            salvq::io::write_bytes_atomic(&output, stream)?;
            let reports: Vec<_> = encoded.layers.iter().map(|l| &l.report).collect();
            if json {
                println!(
                    "{}",
                    serde_json::to_string_pretty(&reports).unwrap_or_default()
                );
            } else {
                let rates: Vec<u8> = reports.iter().map(|r| r.rate).collect();
                println!(
                    "encoded {} anchors at rates {rates:?} into {} ({} bytes, {:.2} bits/anchor) in {:.2} s",
                    model.dims.anchors,
                    output.display(),
                    stream.len(),
                    stream.len() as f64 * 8.0 / f64::from(model.dims.anchors),
                    secs(t)
                );
                for r in reports {
                    println!("rate {}:", r.rate);
                    print!("{}", salvq::info::groups_text(r));
                }
            }
        }
        Command::Extract {
            input,
            rate,
            output,
        } => {
            let stream = salvq::io::read_file(&input)?;
            let one = salvq::extract_rate(&stream, rate, &Limits::default())?;
            salvq::io::write_bytes_atomic(&output, &one)?;
            println!(
                "extracted rate {rate} into {} ({} of {} bytes)",
                output.display(),
                one.len(),
                stream.len()
            );
        }
        Command::Decode {
            input,
            output,
            rate,
            threads,
            region,
            measure,
            canonical,
            inject_fault,
        } => {
            let t = Instant::now();
            let stream = salvq::io::read_file(&input)?;
            let options = salvq::DecodeOptions {
                limits: Limits::default(),
                rate,
                threads: threads.map(|n| n as usize),
                region,
                fault: inject_fault,
            };
            if canonical {
                let (model, symbols) = salvq::decoder::decode_with_symbols(&stream, &options)?;
                let tensors = salvq::conformance::canonical::canonical_tensors(&model, &symbols);
                let bytes = salvq::conformance::canonical::to_safetensors(&tensors);
                salvq::io::write_bytes_atomic(&output, &bytes)?;
                return Ok(());
            }
            let model = salvq::decode_with_options(&stream, &options)?;
            if measure {
                println!(
                    "measure decode_secs={} peak_rss_bytes={} anchors={} decoded_bytes={}",
                    secs(t),
                    salvq::rdbench::scale::peak_rss_bytes().unwrap_or(0),
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
            println!(
                "decoded {} anchors into {} in {:.2} s",
                model.dims.anchors,
                output.display(),
                secs(t)
            );
        }
        // Handled in `main`: their failures are mismatches, not stream errors.
        Command::Conformance { .. } | Command::MakeVectors { .. } => {}
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
        Command::Bench {
            which: Bench::Rd { out, anchors, seed },
        } => {
            let t = Instant::now();
            let text = salvq::rdbench::run(&salvq::rdbench::RdOptions {
                anchors,
                seed,
                out: out.clone(),
            })?;
            print!("{text}");
            println!("wrote rd.svg, rd_correlation.svg, search_speed.svg, stability.svg, rd.csv, summary.txt to {} in {:.1} s", out.display(), secs(t));
        }
        Command::Bench {
            which: Bench::Scale { out, max },
        } => {
            let t = Instant::now();
            let text = salvq::rdbench::scale::run(&out, max)?;
            print!("{text}");
            println!(
                "wrote scale.svg, scale.csv, scale.txt to {} in {:.1} s",
                out.display(),
                secs(t)
            );
        }
        Command::Bench {
            which: Bench::Parsimony { out, max },
        } => {
            let t = Instant::now();
            let text = salvq::rdbench::parsimony::run(&out, max)?;
            print!("{text}");
            println!(
                "wrote parsimony.svg, parsimony.csv, parsimony.txt to {} in {:.1} s",
                out.display(),
                secs(t)
            );
        }
        Command::Demo { anchors, seed, out } => demo(anchors, seed, out.as_deref())?,
    }
    Ok(())
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    // The conformance tools fail on mismatches, not on stream errors: plain messages.
    let tool = match &cli.command {
        Command::Conformance {
            decoder,
            vectors,
            filter,
        } => Some(conformance(decoder.clone(), vectors, filter.as_deref())),
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
        Err(e) => {
            eprintln!("salvq: error[{}]: {e}", e.class());
            ExitCode::FAILURE
        }
    }
}
