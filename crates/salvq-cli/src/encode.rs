//! `salvq encode`: options, the encoder's choices (`--auto`, `--prune-grid`, Scaffold-GS
//! precision) printed with their reasons, progress on long work, and the final summary as
//! text or JSON.

use std::path::PathBuf;
use std::time::Instant;

use serde::Serialize;

use salvq::SceneModel;
use salvq_encoder::auto::{self, AutoChoice};
use salvq_encoder::parsimony::LevelTrial;
use salvq_encoder::precision::{PrecisionChoice, PrecisionRule};
use salvq_encoder::Error;
use salvq_render::interchange::model_from_safetensors;

use super::files::{self, Output};
use super::progress::Progress;
use super::secs;

#[derive(clap::Args)]
pub struct EncodeArgs {
    /// Input: a model (safetensors, spec Annex A) or a trained 3DGS scene (standard Inria
    /// PLY: the explicit-Gaussians profile, spec §3).
    pub(crate) input: PathBuf,
    /// Output stream (default: the input's name with `.salvq`; `-`: standard output).
    #[arg(short, long)]
    pub(crate) output: Option<PathBuf>,
    /// Text for an `encd` ancillary chunk (encoder identification).
    #[arg(long)]
    pub(crate) note: Option<String>,
    /// The rates to code, one symbol layer each, e.g. `0,1,2,3` (spec §7.4): indices into a
    /// model's gains (default 0), or into `--psnr`'s targets for a PLY (default: all).
    #[arg(long, value_delimiter = ',')]
    pub(crate) rates: Option<Vec<u8>>,
    /// A PLY's rates each coded alone (spec §3.7), as files before format 0.15 were, rather
    /// than nested, the coarsest first and each finer one refining it (§3.8, the default:
    /// one file that costs about what its finest rate costs, and streams coarse to fine).
    #[arg(long)]
    pub(crate) layered: bool,
    /// PLY input: how hard the rate control searches (Annex A.8.2): `fast` predicts each
    /// part's render error from one pass of per-Gaussian sensitivities and renders nothing
    /// else; `default` calibrates that prediction on a few renders of a sample of the scene
    /// and lands each rate on its target by rendering; `best` renders every trial step of
    /// every part's rate-distortion curve, the whole scene (many times slower).
    #[arg(long, value_enum, default_value_t = EffortArg::Default)]
    pub(crate) effort: EffortArg,
    /// PLY input: the render-PSNR target of each rate in dB against the input (8 ring views
    /// at 512x384, as `salvq compare` measures), e.g. `62,56,50,45,40,35` (the default); sorted
    /// so that rate 0 is the finest.
    #[arg(long, value_delimiter = ',', value_parser = parse_target, allow_hyphen_values = true)]
    pub(crate) psnr: Option<Vec<f64>>,
    /// PLY input: drop (and count, by property) Gaussians with a NaN, or an infinite value
    /// other than an opacity logit, instead of failing on the first (spec Annex A.8.1).
    #[arg(long)]
    pub(crate) drop_invalid: bool,
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
    /// Choose the feature quantizer (identity, the model's own lattice, or fitted bases with
    /// 1, 2, 4 or 8 regions) by total stream bytes at the feature error of the model's own
    /// quantizer (within 1 %; spec Annex A.5.3). Prints what it measured and chose; replaces
    /// `--quantizer`, `--fit-scales` and `--regions`.
    #[arg(long, conflicts_with_all = ["quantizer", "fit_scales", "regions"])]
    auto: bool,
    /// Anchors (or Gaussians) per tile at most (spec §10): tiles decode independently, in
    /// parallel or alone. Default: 16384, and for a scene of fewer than 131072 about 8 tiles
    /// of at least 2048, so that a small scene decodes on several threads too; where those
    /// leave one of 2 threads more than 52 % of the scene, smaller tiles (down to 1024) that
    /// do not.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    pub(crate) tile_anchors: Option<u32>,
    /// How lattice points are searched: `auto` (exact for Z^n, D_n, E8; Babai nearest
    /// plane on the LLL-reduced basis for a learned basis), `rounding`, `nearest-plane`,
    /// `closest` (Schnorr-Euchner, bounded) or `rdo` (auto's point refined for rate and
    /// distortion with the integer entropy model, spec §7.3).
    #[arg(long, default_value = "auto", value_parser = salvq_encoder::Search::NAMES)]
    search: String,
    /// Do not write the `ests` chunk (encoder statistics shown by `info`).
    #[arg(long)]
    no_stats: bool,
    /// Drop hash-grid levels that do not pay for themselves: a level goes when the stream
    /// without it is smaller and the feature error grows by at most 1 % (each candidate
    /// is encoded; prints what it chose and why).
    #[arg(long)]
    prune_grid: bool,
    /// How to store the Scaffold-GS MLPs (spec §1.6.2): `auto` (binary16 when the scene's
    /// renders with binary16 MLPs match those with binary32 at 58.9 dB PSNR or more, the
    /// PSNR of 8-bit rounding; for a model that cannot render neurally, when their outputs
    /// move by at most 2^-9; spec Annex A.5.2), `f32`, `f16`.
    #[arg(long, default_value = "auto", value_parser = ["auto", "f32", "f16"])]
    scaffold_precision: String,
    /// How to store the integer context MLP's weights (spec §1.6.2 Table 1-7): `auto` (i8
    /// when the symbol bytes that costs, measured on a sample, are fewer than the model bytes
    /// it saves, spec Annex A.5.4), `i16`, `i8`.
    #[arg(long, default_value = "auto", value_parser = ["auto", "i16", "i8"])]
    context_precision: String,
    /// Print the summary as JSON on standard output (choices, per-rate reports); messages
    /// stay on standard error.
    #[arg(long)]
    pub(crate) json: bool,
}

/// A render-PSNR target: a finite number of dB above 0.
fn parse_target(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(db) if db.is_finite() && db > 0.0 => Ok(db),
        _ => Err(format!("a target is a PSNR in dB above 0, not {s}")),
    }
}

/// The `--json` summary.
#[derive(Serialize)]
struct Summary<'a> {
    output: String,
    anchors: u32,
    bytes: u64,
    bits_per_anchor: f64,
    seconds: f64,
    scaffold: &'a PrecisionChoice,
    context: &'a salvq_encoder::context_precision::ContextChoice,
    #[serde(skip_serializing_if = "Option::is_none")]
    auto: Option<&'a AutoChoice>,
    pruned_levels: Vec<PrunedLevel>,
    layers: Vec<&'a salvq_encoder::EncodeReport>,
}

#[derive(Serialize)]
struct PrunedLevel {
    level: String,
    resolution: u16,
    bytes_with: u64,
    bytes_without: u64,
    mse_with: f64,
    mse_without: f64,
}

/// Encodes a scene model (spec Annex A); `bytes` is the input file, already read, and `t`
/// when the command started.
pub fn run_model(
    a: EncodeArgs,
    output: &Output,
    bytes: Vec<u8>,
    t: Instant,
    progress: &Progress,
) -> Result<(), Error> {
    if a.psnr.is_some() {
        return Err(Error::UnsupportedInput {
            found: "a model file with --psnr".into(),
            hint: "--psnr sets the rates of a PLY input (spec Annex A.8); a model's rates are its gains (--rates)",
        });
    }
    let mut model = model_from_safetensors(&bytes)?;
    drop(bytes);
    let mut options = model_options(&a, &model)?;
    let mut pruned_levels = Vec::new();
    if a.prune_grid {
        let pruned;
        (pruned, pruned_levels) = prune_grid(&model, &options, progress)?;
        model = pruned;
    }
    let mut auto_choice = None;
    if a.auto {
        progress.stage("--auto: measuring feature quantizers at equal distortion");
        let choice = auto::choose(&model, &options)?;
        for line in auto_lines(&choice) {
            progress.say(&line);
        }
        let (m, o) = choice.apply(&model, &options);
        model = m;
        options = o;
        auto_choice = Some(choice);
    }
    progress.stage(&format!("encoding {} anchors", model.n()));
    let encoded = salvq_encoder::encode_full(&model, &options)?;
    progress.say(&scaffold_line(&encoded.scaffold));
    progress.say(&context_line(&encoded.context));
    progress.stage(&format!("writing {}", output.shown()));
    let stream = &encoded.stream;
    output.write_bytes(stream)?;
    progress.done();
    let reports: Vec<_> = encoded.layers.iter().map(|l| &l.report).collect();
    let anchors = model.dims.anchors;
    let bits_per_anchor = stream.len() as f64 * 8.0 / f64::from(anchors.max(1));
    if a.json {
        let summary = Summary {
            output: output.shown(),
            anchors,
            bytes: stream.len() as u64,
            bits_per_anchor,
            seconds: secs(t),
            scaffold: &encoded.scaffold,
            context: &encoded.context,
            auto: auto_choice.as_ref(),
            pruned_levels,
            layers: reports,
        };
        files::print_json(&summary);
    } else {
        let rates: Vec<u8> = reports.iter().map(|r| r.rate).collect();
        progress.say(&format!(
            "encoded {anchors} anchors at rates {rates:?} into {} ({} bytes, {bits_per_anchor:.2} bits/anchor) in {:.2} s",
            output.shown(),
            stream.len(),
            secs(t)
        ));
        for r in reports {
            progress.say(&format!("rate {}:", r.rate));
            progress.say(salvq_encoder::info::groups_text(r).trim_end());
        }
    }
    Ok(())
}

/// The encoder options the arguments ask for on `model`.
fn model_options(
    a: &EncodeArgs,
    model: &SceneModel,
) -> Result<salvq_encoder::EncodeOptions, Error> {
    let feat_lattice = match a.quantizer.as_str() {
        "usq" => Some(salvq_bitstream::model::LatticeKind::Identity),
        "dn" => Some(salvq_bitstream::model::LatticeKind::Dn),
        "e8" => Some(salvq_bitstream::model::LatticeKind::E8Product),
        "salvq" => Some(salvq_bitstream::model::LatticeKind::General),
        _ => None,
    };
    if feat_lattice == Some(salvq_bitstream::model::LatticeKind::General)
        && model.quant_feat.basis.is_none()
    {
        return Err(Error::OptionUnsupported {
            option: "--quantizer salvq",
            reason: "the model has no learned lattice basis (quant.feat.basis_u, _s, _v)",
            hint: "--quantizer klt fits one to its features (Annex A.5); --quantizer usq codes them with the identity",
        });
    }
    Ok(salvq_encoder::EncodeOptions {
        encoder_note: a.note.clone(),
        rates: a.rates.clone().unwrap_or_else(|| vec![0]),
        statistics: !a.no_stats,
        feat_lattice,
        search: salvq_encoder::Search::from_name(&a.search).unwrap_or_default(),
        fit_basis: a.quantizer == "klt",
        feat_regions: a.regions,
        fit_scales: a.fit_scales,
        tile_anchors: a.tile_anchors.unwrap_or(0),
        scaffold_precision: match a.scaffold_precision.as_str() {
            "f32" => Some(salvq_bitstream::container::payload::ScaffoldPrecision::F32),
            "f16" => Some(salvq_bitstream::container::payload::ScaffoldPrecision::F16),
            _ => None,
        },
        context_precision: match a.context_precision.as_str() {
            "i16" => Some(salvq_bitstream::container::payload::ContextPrecision::I16),
            "i8" => Some(salvq_bitstream::container::payload::ContextPrecision::I8),
            _ => None,
        },
    })
}

/// `--prune-grid`: the model without the grid levels whose removal made the stream smaller
/// and what each trial measured.
fn prune_grid(
    model: &SceneModel,
    options: &salvq_encoder::EncodeOptions,
    progress: &Progress,
) -> Result<(SceneModel, Vec<PrunedLevel>), Error> {
    progress.stage("--prune-grid: encoding the model without each grid level");
    let (pruned, trials) = salvq_encoder::parsimony::prune_grid_levels(model, options, 0.01)?;
    let mut levels = Vec::new();
    for tr in &trials {
        progress.say(&pruned_line(tr, model.n()));
        levels.push(PrunedLevel {
            level: tr.level.to_string(),
            resolution: tr.resolution,
            bytes_with: tr.bytes_with,
            bytes_without: tr.bytes_without,
            mse_with: tr.mse_with,
            mse_without: tr.mse_without,
        });
    }
    if trials.is_empty() {
        progress.say("kept every grid level: no removal made the stream smaller");
    }
    Ok((pruned, levels))
}

/// How the context MLP's weights are stored and what the choice measured (Annex A.5.4).
fn context_line(cc: &salvq_encoder::context_precision::ContextChoice) -> String {
    if cc.sample_anchors > 0 {
        format!(
            "context MLP weights stored as {:?}: i8 saves {} model bytes and costs {} symbol bytes, \
             MSE x{:.4} / x{:.4} / x{:.4} with base steps x{:.4} / x{:.4} / x{:.4} (feature / \
             scaling / offsets; measured on {} anchors)",
            cc.precision,
            cc.model_bytes_saved,
            cc.symbol_bytes_cost,
            cc.mse_ratio[0],
            cc.mse_ratio[1],
            cc.mse_ratio[2],
            cc.step_factors[0],
            cc.step_factors[1],
            cc.step_factors[2],
            cc.sample_anchors
        )
    } else {
        format!("context MLP weights stored as {:?}", cc.precision)
    }
}

/// What Annex A.5.2 chose for the Scaffold-GS MLPs, what it measured and which rule decided.
fn scaffold_line(sc: &PrecisionChoice) -> String {
    let why = match sc.rule {
        PrecisionRule::Requested => "as requested".to_string(),
        PrecisionRule::Range => "a value is beyond binary16's range".to_string(),
        PrecisionRule::Render => format!(
            "renders with binary16 MLPs against binary32 at {:.2} dB PSNR (threshold {:.2} dB; \
             {} ring views of {} anchors, {} covered pixels)",
            sc.render_psnr_db.unwrap_or(f64::NAN),
            sc.psnr_threshold_db,
            salvq_encoder::precision::RENDER_VIEWS,
            sc.render_anchors,
            sc.render_pixels
        ),
        PrecisionRule::Outputs => format!(
            "the model does not render neurally, so by its outputs: binary16 changes them by \
             at most {:.2e} (tolerance {:.2e})",
            sc.max_output_change.unwrap_or(f64::NAN),
            sc.tolerance
        ),
    };
    format!(
        "Scaffold-GS MLPs stored as {:?}: {why}; {} bytes saved",
        sc.precision, sc.bytes_saved
    )
}

fn pruned_line(tr: &LevelTrial, anchors: usize) -> String {
    let basis = if tr.sample_anchors < anchors {
        format!(", estimated from {} sampled anchors", tr.sample_anchors)
    } else {
        String::new()
    };
    format!(
        "dropped {} (resolution {}): {} -> {} bytes, feature MSE {:.4e} -> {:.4e}{basis}",
        tr.level, tr.resolution, tr.bytes_with, tr.bytes_without, tr.mse_with, tr.mse_without
    )
}

/// What `--auto` measured, one line per candidate, then the choice and why.
fn auto_lines(c: &AutoChoice) -> Vec<String> {
    let mut out = vec![format!(
        "--auto: feature quantizers at the model's own feature MSE {:.4e} (within {:.0} %), \
         measured on {} anchors",
        c.target_mse,
        c.tolerance * 100.0,
        c.sample_anchors
    )];
    for (i, k) in c.candidates.iter().enumerate() {
        out.push(format!(
            "  {} {:<40} step x{:.3}  MSE {:.4e}  {:>10} bytes (model {:>8})",
            if i == c.chosen { "*" } else { " " },
            k.quantizer.to_string(),
            k.step_factor,
            k.mse,
            k.bytes,
            k.model_bytes
        ));
    }
    if let Some(best) = c.candidates.get(c.chosen) {
        let runner_up = c
            .candidates
            .iter()
            .enumerate()
            .filter(|&(i, _)| i != c.chosen)
            .map(|(_, k)| k)
            .min_by_key(|k| k.bytes);
        let why = match runner_up {
            Some(r) => format!(
                "{} bytes ({:.2} %) fewer than the next best, {}",
                r.bytes.saturating_sub(best.bytes),
                100.0 * (r.bytes as f64 - best.bytes as f64) / r.bytes.max(1) as f64,
                r.quantizer
            ),
            None => "the only candidate that could be fitted".into(),
        };
        out.push(format!(
            "--auto chose {}: the smallest stream at equal distortion, {why}",
            best.quantizer
        ));
    }
    out
}

/// `--effort`'s levels.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum EffortArg {
    Fast,
    Default,
    Best,
}
