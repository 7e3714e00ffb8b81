//! `salvq bench`: the measurements with charts (rate-distortion, scale, real scenes,
//! parsimony). Their reports are data: standard output.

use std::path::PathBuf;
use std::time::Instant;

use clap::Subcommand;
use salvq_encoder::Error;

use super::secs;

#[derive(Subcommand)]
pub(crate) enum Bench {
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
    /// The explicit profile on real 3DGS scenes: salvq's rates from one file
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
    /// model tensor group at 100 k anchors (SVG, CSV).
    Parsimony {
        /// Output folder.
        #[arg(long, default_value = "charts")]
        out: PathBuf,
        /// Largest scene (anchors).
        #[arg(long, default_value_t = 1_000_000)]
        max: u32,
    },
}

/// Runs one bench.
pub(crate) fn run(which: Bench) -> Result<(), Error> {
    match which {
        Bench::Rd { out, anchors, seed } => {
            let t = Instant::now();
            let text = salvq_bench::run(&salvq_bench::RdOptions {
                anchors,
                seed,
                out: out.clone(),
            })?;
            crate::print_text(&text);
            out!("wrote rd.svg, rd_correlation.svg, search_speed.svg, stability.svg, rd.csv, summary.txt to {} in {:.1} s", out.display(), secs(t));
        }
        Bench::Scale { out, max } => {
            let t = Instant::now();
            let text = salvq_bench::scale::run(&out, max)?;
            crate::print_text(&text);
            out!(
                "wrote scale.svg, scale.csv, scale.txt to {} in {:.1} s",
                out.display(),
                secs(t)
            );
        }
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
        Bench::Parsimony { out, max } => {
            let t = Instant::now();
            let text = salvq_bench::parsimony::run(&out, max)?;
            crate::print_text(&text);
            out!(
                "wrote parsimony and precision .svg, .csv, .txt to {} in {:.1} s",
                out.display(),
                secs(t)
            );
        }
    }
    Ok(())
}
