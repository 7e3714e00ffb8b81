//! `salvq encode scene.ply`: the explicit-Gaussians profile (spec §3, Annex A.8). Reads a
//! standard 3DGS PLY, says what it changes on input, fits the steps of each rate to its
//! render-PSNR target, codes every rate's layer, and reports per rate what `salvq compare`
//! would measure, with bytes per Gaussian per group.

use std::time::Instant;

use serde::Serialize;

use salvq_bitstream::explicit::Gaussians;
use salvq_encoder::explicit::prepare::{drop_invalid, value_changes, Dropped, ValueChange};
use salvq_encoder::explicit::ratios::{QUALITY_HEIGHT, QUALITY_VIEWS, QUALITY_WIDTH};
use salvq_encoder::explicit::{self, ExplicitOptions, RateControl};
use salvq_encoder::Error;
use salvq_render::compare::RingTarget;

use super::encode::EncodeArgs;
use super::files::{self, Output};
use super::progress::Progress;
use super::secs;

/// A rate lands on its target when its PSNR is at most this far below it (dB): the rate
/// control stops within 0.15 dB when it can.
pub const TARGET_TOLERANCE_DB: f64 = 0.25;

/// One layer of the `--json` summary and the text report.
#[derive(Serialize)]
pub struct LayerLine {
    pub rate: u8,
    pub target_db: Option<f64>,
    /// Render PSNR of the layer against the input: the PSNR of the mean MSE over the
    /// yardstick's ring views, as `salvq compare` measures it.
    pub psnr_db: f64,
    /// Mean SSIM over the same views.
    pub ssim: f64,
    /// Whether the rate reached its target (within [`TARGET_TOLERANCE_DB`]).
    pub target_met: Option<bool>,
    /// Bytes of the single-rate stream (`salvq extract`).
    pub bytes: u64,
    pub bytes_per_gaussian: f64,
    /// Bits per Gaussian: positions (octree and refinement), then each group.
    pub position_bits: f64,
    pub group_bits: Vec<(String, f64)>,
    pub coord_bits: u8,
    pub refine: [u8; 4],
}

/// How `--json` and the summary state the yardstick.
#[derive(Serialize)]
struct Yardstick {
    views: u32,
    width: u32,
    height: u32,
}

#[derive(Serialize)]
struct Summary {
    output: String,
    gaussians: u64,
    sh_degree: u8,
    bytes: u64,
    input_bytes: u64,
    /// Wall seconds from the start to the written stream.
    seconds: f64,
    /// Wall seconds then spent measuring each rate for this summary.
    measure_seconds: f64,
    /// CPU seconds (all threads) to the written stream, where the system reports them.
    cpu_seconds: Option<f64>,
    /// Peak resident memory to the written stream, where the system reports it.
    peak_rss_bytes: Option<u64>,
    psnr_measured_at: Yardstick,
    /// Values changed on input (opacity logits clamped).
    input_changes: Vec<ValueChange>,
    /// With `--drop-invalid`: what was dropped.
    dropped: Option<Dropped>,
    /// Targets as given, when they were sorted to put the finest first.
    targets_given: Option<Vec<f64>>,
    klt: Vec<(String, bool)>,
    /// Whether the rates nest (spec §3.8): each rate's bytes are then the stream's prefix up
    /// to it.
    progressive: bool,
    layers: Vec<LayerLine>,
}

/// The targets, finest first, and the order given when it was another; a usage error when
/// two are equal, or when `--rates` picks among targets given in another order (its indices
/// would change meaning).
fn sorted_targets(a: &EncodeArgs) -> (Vec<f64>, Option<Vec<f64>>) {
    let given = a
        .psnr
        .clone()
        .unwrap_or_else(|| explicit::DEFAULT_PSNR_TARGETS.to_vec());
    let mut sorted = given.clone();
    sorted.sort_by(|x, y| y.total_cmp(x));
    if sorted.windows(2).any(|w| w[0] == w[1]) {
        files::usage("--psnr: two rates have the same target; give each rate its own");
    }
    if sorted == given {
        return (sorted, None);
    }
    if a.rates.is_some() {
        files::usage(
            "--psnr: its targets are not finest first, and --rates picks rates by position; \
             list the targets from the highest PSNR (rate 0) to the lowest",
        );
    }
    (sorted, Some(given))
}

/// Reads the PLY: strictly, or dropping what the format cannot hold (`--drop-invalid`).
fn read(
    a: &EncodeArgs,
    bytes: &[u8],
    progress: &Progress,
) -> Result<(Gaussians, Option<Dropped>), Error> {
    if !a.drop_invalid {
        return Ok((salvq_render::ply::read_ply(bytes)?, None));
    }
    let g = salvq_render::ply::read_ply_lenient(bytes)?;
    let (kept, dropped) = drop_invalid(&g);
    let why = if dropped.dropped == 0 {
        "none has a NaN, or an infinite value other than an opacity logit".to_string()
    } else {
        format!(
            "by the first value each cannot hold: {}",
            super::info::by_property(&dropped)
        )
    };
    progress.say(&format!(
        "--drop-invalid: dropped {} of {} Gaussians ({why})",
        dropped.dropped, dropped.read
    ));
    Ok((kept, Some(dropped)))
}

/// Encodes the PLY file `a.input` (whose bytes are `bytes`) into `output`.
pub fn run(
    a: EncodeArgs,
    output: &Output,
    bytes: &[u8],
    t: Instant,
    progress: &Progress,
) -> Result<(), Error> {
    let (targets, targets_given) = sorted_targets(&a);
    let (g, dropped) = read(&a, bytes, progress)?;
    if g.is_empty() {
        return Err(Error::UnsupportedInput {
            found: "a PLY with no Gaussian (element vertex 0)".into(),
            hint: "a scene needs at least one Gaussian to encode",
        });
    }
    let changes = say_input(&a, bytes, &g, progress);
    if let Some(given) = &targets_given {
        progress.say(&format!(
            "--psnr {}: sorted finest first, so rate 0 is the finest: {}",
            list(given),
            list(&targets)
        ));
    }
    let options = explicit_options(&a, &targets);
    let encoded = explicit::encode_gaussians(&g, &options, &|p| {
        progress.step(p.step, Some((p.done, p.total)))
    })?;
    progress.stage(&format!("writing {}", output.shown()));
    output.write_bytes(&encoded.stream)?;
    let (seconds, cpu_seconds) = (secs(t), salvq_bench::scale::cpu_seconds());
    let peak_rss_bytes = salvq_bench::scale::peak_rss_bytes();
    let measuring = Instant::now();
    progress.stage(&format!(
        "measuring each rate as `salvq compare` does ({QUALITY_VIEWS} views at {QUALITY_WIDTH}x{QUALITY_HEIGHT})"
    ));
    let lines = layer_lines(&g, &encoded, Some(&targets))?;
    progress.done();
    let summary = Summary {
        progressive: encoded.header.progressive,
        output: output.shown(),
        gaussians: g.len() as u64,
        sh_degree: g.sh_degree,
        bytes: encoded.stream.len() as u64,
        input_bytes: bytes.len() as u64,
        seconds,
        measure_seconds: secs(measuring),
        cpu_seconds,
        peak_rss_bytes,
        psnr_measured_at: Yardstick {
            views: QUALITY_VIEWS,
            width: QUALITY_WIDTH,
            height: QUALITY_HEIGHT,
        },
        input_changes: changes,
        dropped,
        targets_given,
        klt: encoded
            .groups
            .iter()
            .map(|gr| (gr.kind.name().to_string(), gr.basis.is_some()))
            .collect(),
        layers: lines,
    };
    if a.json {
        files::print_json(&summary);
    }
    let names: Vec<&str> = encoded.groups.iter().map(|gr| gr.kind.name()).collect();
    progress.say(report(&summary, &names).trim_end());
    Ok(())
}

/// Says what was read from the PLY (`bytes`, decoded as `g`): the Gaussians and where from,
/// the properties left out, and the values changed on input (Annex A.8.1), which it returns
/// for the summary.
fn say_input(a: &EncodeArgs, bytes: &[u8], g: &Gaussians, progress: &Progress) -> Vec<ValueChange> {
    let source = if files::is_stdio(&a.input) {
        "standard input".to_string()
    } else {
        a.input.display().to_string()
    };
    progress.say(&format!(
        "read {} Gaussians (SH degree {}) from {source}",
        g.len(),
        g.sh_degree
    ));
    let ignored = salvq_render::ply::unused_properties(bytes);
    if !ignored.is_empty() {
        progress.say(&format!(
            "ignored PLY properties (not part of a 3DGS Gaussian): {}",
            ignored.join(", ")
        ));
    }
    let changes = value_changes(g);
    for c in &changes {
        progress.say(&format!(
            "changed on input: {} {} values of {} became {} (Annex A.8.1)",
            c.count, c.property, c.was, c.became
        ));
    }
    changes
}

/// The encoder's options from the command line, the PSNR `targets` sorted finest first.
fn explicit_options(a: &EncodeArgs, targets: &[f64]) -> ExplicitOptions {
    ExplicitOptions {
        rates: RateControl::Psnr(targets.to_vec()),
        coded: a.rates.clone(),
        klt: None,
        tile_gaussians: a.tile_anchors.unwrap_or(0),
        note: a.note.clone(),
        variant: Default::default(),
        progressive: !a.layered,
        effort: match a.effort {
            crate::encode::EffortArg::Fast => explicit::curves::Effort::Fast,
            crate::encode::EffortArg::Default => explicit::curves::Effort::Default,
            crate::encode::EffortArg::Best => explicit::curves::Effort::Best,
        },
    }
}

/// `62, 56, 50` for a list of targets.
fn list(v: &[f64]) -> String {
    v.iter()
        .map(|x| x.to_string())
        .collect::<Vec<_>>()
        .join(",")
}

/// Per coded layer: bytes, bits per group, and render PSNR and SSIM against `g` at the
/// yardstick.
pub fn layer_lines(
    g: &Gaussians,
    e: &explicit::EncodedGaussians,
    targets: Option<&[f64]>,
) -> Result<Vec<LayerLine>, Error> {
    let target = RingTarget::new(g, QUALITY_VIEWS, QUALITY_WIDTH, QUALITY_HEIGHT)?;
    let n = g.len().max(1) as f64;
    let mut lines = e
        .layers
        .iter()
        .zip(e.rate_stream_bytes())
        .map(|((rep, _, expected), bytes)| {
            let bytes = bytes as u64;
            let target_db = targets.and_then(|t| t.get(usize::from(rep.rate)).copied());
            let (psnr_db, ssim) = target.psnr_ssim(expected)?;
            Ok(LayerLine {
                rate: rep.rate,
                target_db,
                psnr_db,
                ssim,
                target_met: target_db.map(|t| psnr_db >= t - TARGET_TOLERANCE_DB),
                bytes,
                bytes_per_gaussian: bytes as f64 / n,
                position_bits: (rep.apos_bytes as f64 * 8.0 + rep.refine_bits) / n,
                group_bits: e
                    .groups
                    .iter()
                    .zip(&rep.group_bits)
                    .map(|(gr, b)| (gr.kind.name().to_string(), b / n))
                    .collect(),
                coord_bits: rep.coord_bits,
                refine: rep.refine,
            })
        })
        .collect::<Result<Vec<_>, Error>>()?;
    // Finest first, whatever the stream's order.
    lines.sort_by_key(|l| l.rate);
    Ok(lines)
}

/// The summary as text.
fn report(s: &Summary, names: &[&str]) -> String {
    let rates = s.layers.len();
    let mut t = format!(
        "encoded {} Gaussians (SH degree {}) at {rates} rate{} into {} ({} bytes, {:.1} % of the \
         input's {}) in {:.2} s{}; measured the rates in {:.2} s\n",
        s.gaussians,
        s.sh_degree,
        if rates == 1 { "" } else { "s" },
        s.output,
        s.bytes,
        100.0 * s.bytes as f64 / s.input_bytes.max(1) as f64,
        s.input_bytes,
        s.seconds,
        match (s.cpu_seconds, s.peak_rss_bytes) {
            (Some(cpu), Some(rss)) => format!(
                " ({cpu:.2} s of CPU, peak memory {:.0} MB)",
                rss as f64 / 1e6
            ),
            _ => String::new(),
        },
        s.measure_seconds
    );
    let fitted: Vec<&str> = s.klt.iter().filter(|k| k.1).map(|k| k.0.as_str()).collect();
    if !fitted.is_empty() {
        t.push_str(&format!("KLT basis fitted for: {}\n", fitted.join(", ")));
    }
    t.push_str(&rate_table(s, names));
    let missed = s
        .layers
        .iter()
        .filter(|l| l.target_met == Some(false))
        .count();
    if missed > 0 {
        t.push_str(&format!(
            "{missed} of {rates} rates missed their target by more than {TARGET_TOLERANCE_DB} dB\n"
        ));
    }
    let extract = match s.progressive {
        true => {
            "the rates nest: a rate's bytes are the stream's prefix up to it, and `salvq \
                 extract --rate I` writes that prefix"
        }
        false => "`salvq extract --rate I` writes one rate alone",
    };
    t.push_str(&format!(
        "(rate 0 is the finest; {extract}; PSNR and SSIM \
         against the input from {QUALITY_VIEWS} ring views at {QUALITY_WIDTH}x{QUALITY_HEIGHT}, \
         what `salvq compare INPUT STREAM --rate-b I` prints)\n"
    ));
    t
}

/// One line per rate: its target and measured quality, bytes and bits per Gaussian by group;
/// a rate that missed its target says by how much.
fn rate_table(s: &Summary, names: &[&str]) -> String {
    let (bytes_head, bits_head) = match s.progressive {
        true => ("bytes to rate", "bits/Gaussian of the layer"),
        false => ("bytes (alone)", "bits/Gaussian"),
    };
    let mut t = format!(
        "rate  target dB  PSNR dB     SSIM  {bytes_head}  B/Gaussian  {bits_head}: position {}\n",
        names.join(" ")
    );
    for l in &s.layers {
        let groups: Vec<String> = l
            .group_bits
            .iter()
            .map(|(_, b)| format!("{b:.2}"))
            .collect();
        let flag = match (l.target_met, l.target_db) {
            (Some(false), Some(target)) => format!("  MISSED by {:.2} dB", target - l.psnr_db),
            _ => String::new(),
        };
        t.push_str(&format!(
            "{:>4}  {:>9}  {:>7.2}  {:>7.5}  {:>13}  {:>10.3}  {:.2} {}{flag}\n",
            l.rate,
            l.target_db.map(|t| format!("{t:.1}")).unwrap_or_default(),
            l.psnr_db,
            l.ssim,
            l.bytes,
            l.bytes_per_gaussian,
            l.position_bits,
            groups.join(" ")
        ));
    }
    t
}

#[cfg(test)]
mod tests {
    use super::*;

    fn line(rate: u8, target: f64, psnr: f64) -> LayerLine {
        LayerLine {
            rate,
            target_db: Some(target),
            psnr_db: psnr,
            ssim: 0.99,
            target_met: Some(psnr >= target - TARGET_TOLERANCE_DB),
            bytes: 1000,
            bytes_per_gaussian: 1.0,
            position_bits: 1.0,
            group_bits: vec![("scale".into(), 1.0)],
            coord_bits: 10,
            refine: [0; 4],
        }
    }

    #[test]
    fn a_missed_target_is_flagged_in_the_summary() {
        let s = Summary {
            progressive: false,
            output: "x.salvq".into(),
            gaussians: 10,
            sh_degree: 0,
            bytes: 100,
            input_bytes: 1000,
            seconds: 1.0,
            measure_seconds: 0.5,
            cpu_seconds: Some(1.5),
            peak_rss_bytes: Some(64_000_000),
            psnr_measured_at: Yardstick {
                views: QUALITY_VIEWS,
                width: QUALITY_WIDTH,
                height: QUALITY_HEIGHT,
            },
            input_changes: Vec::new(),
            dropped: None,
            targets_given: None,
            klt: Vec::new(),
            layers: vec![line(0, 45.0, 44.9), line(1, 35.0, 34.57)],
        };
        let t = report(&s, &["scale"]);
        let rows: Vec<&str> = t.lines().filter(|l| l.starts_with("   ")).collect();
        assert!(!rows[0].contains("MISSED"), "{t}");
        assert!(rows[1].ends_with("MISSED by 0.43 dB"), "{t}");
        assert!(t.contains("1 of 2 rates missed their target"), "{t}");
        assert!(t.contains("at 2 rates into"), "{t}");
    }

    fn args(psnr: &[f64], rates: Option<Vec<u8>>) -> EncodeArgs {
        use clap::Parser;
        #[derive(Parser)]
        struct Wrap {
            #[command(flatten)]
            a: EncodeArgs,
        }
        let mut w = Wrap::parse_from(["salvq", "scene.ply"]);
        w.a.psnr = Some(psnr.to_vec());
        w.a.rates = rates;
        w.a
    }

    #[test]
    fn targets_are_sorted_finest_first() {
        let (t, given) = sorted_targets(&args(&[30.0, 40.0], None));
        assert_eq!(t, [40.0, 30.0]);
        assert_eq!(given, Some(vec![30.0, 40.0]));
        let (t, given) = sorted_targets(&args(&[50.0, 40.0], None));
        assert_eq!((t, given), (vec![50.0, 40.0], None));
        // Equal targets, and unsorted ones with --rates, are usage errors (exit 2): the
        // integration tests run them.
    }
}
