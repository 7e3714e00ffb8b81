//! `salvq encode scene.ply`: the explicit-Gaussians profile (spec §3, Annex A.8). Reads a
//! standard 3DGS PLY, fits the steps of each rate to its render-PSNR target, codes every
//! rate's layer, and reports bytes per Gaussian per group and rate.

use std::path::Path;
use std::time::Instant;

use serde::Serialize;

use salvq::explicit::Gaussians;
use salvq_encoder::explicit::ratios::{FIT_HEIGHT, FIT_VIEWS, FIT_WIDTH};
use salvq_encoder::explicit::{self, ExplicitOptions, RateControl};
use salvq_encoder::Error;
use salvq_render::compare::RingTarget;

use super::encode::EncodeArgs;
use super::progress::Progress;
use super::secs;

/// One layer of the `--json` summary and the text report.
#[derive(Serialize)]
pub struct LayerLine {
    pub rate: u8,
    pub target_db: Option<f64>,
    /// Render PSNR of the layer against the input (Annex A.8.2's fit renders).
    pub psnr_db: f64,
    /// Bytes of the single-rate stream (`salvq extract`).
    pub bytes: u64,
    pub bytes_per_gaussian: f64,
    /// Bits per Gaussian: positions (octree and refinement), then each group.
    pub position_bits: f64,
    pub group_bits: Vec<(String, f64)>,
    pub coord_bits: u8,
    pub refine: [u8; 4],
}

#[derive(Serialize)]
struct Summary {
    output: String,
    gaussians: u64,
    sh_degree: u8,
    bytes: u64,
    seconds: f64,
    klt: Vec<(String, bool)>,
    layers: Vec<LayerLine>,
}

/// Encodes the PLY file `input` (whose bytes are `bytes`) as `a` asks.
pub fn run(a: EncodeArgs, bytes: &[u8], t: Instant, progress: &Progress) -> Result<(), Error> {
    let g = if a.drop_invalid {
        let g = salvq_render::ply::read_ply_lenient(bytes)?;
        let (kept, dropped) = explicit::prepare::drop_invalid(&g);
        progress.say(&format!(
            "--drop-invalid: dropped {dropped} of {} Gaussians with a NaN or infinite value",
            g.len()
        ));
        kept
    } else {
        salvq_render::ply::read_ply(bytes)?
    };
    progress.say(&format!(
        "read {} Gaussians (SH degree {}) from {}",
        g.len(),
        g.sh_degree,
        a.input.display()
    ));
    let ignored = salvq_render::ply::unused_properties(bytes);
    if !ignored.is_empty() {
        progress.say(&format!(
            "ignored PLY properties (not part of a 3DGS Gaussian): {}",
            ignored.join(", ")
        ));
    }
    let targets = a
        .psnr
        .clone()
        .unwrap_or_else(|| explicit::DEFAULT_PSNR_TARGETS.to_vec());
    let options = ExplicitOptions {
        rates: RateControl::Psnr(targets.clone()),
        coded: a.rates.clone(),
        klt: None,
        tile_gaussians: a.tile_anchors.unwrap_or(0),
        note: a.note.clone(),
        variant: Default::default(),
    };
    let encoded = explicit::encode_gaussians(&g, &options, &|m| progress.stage(m.to_string()))?;
    progress.stage(format!("writing {}", a.output.display()));
    salvq_render::io::write_bytes_atomic(&a.output, &encoded.stream)?;
    progress.stage("rendering each rate against the input");
    let lines = layer_lines(&g, &encoded, Some(&targets))?;
    progress.done();
    report(&a.output, &g, &encoded, lines, a.json, a.quiet, secs(t));
    Ok(())
}

/// Per coded layer: bytes, bits per group, and render PSNR against `g`.
pub fn layer_lines(
    g: &Gaussians,
    e: &explicit::EncodedGaussians,
    targets: Option<&[f64]>,
) -> Result<Vec<LayerLine>, Error> {
    let target = RingTarget::new(g, FIT_VIEWS, FIT_WIDTH, FIT_HEIGHT)?;
    let n = g.len().max(1) as f64;
    e.layers
        .iter()
        .map(|(rep, layer_bytes, expected)| {
            let bytes =
                (salvq::container::signature::SIGNATURE_LEN + e.shared_bytes + layer_bytes + 12)
                    as u64;
            Ok(LayerLine {
                rate: rep.rate,
                target_db: targets.and_then(|t| t.get(usize::from(rep.rate)).copied()),
                psnr_db: target.psnr(expected)?,
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
        .collect()
}

fn report(
    output: &Path,
    g: &Gaussians,
    e: &explicit::EncodedGaussians,
    layers: Vec<LayerLine>,
    json: bool,
    quiet: bool,
    seconds: f64,
) {
    let klt: Vec<(String, bool)> = e
        .groups
        .iter()
        .map(|gr| (gr.kind.name().to_string(), gr.basis.is_some()))
        .collect();
    if json {
        let s = Summary {
            output: output.display().to_string(),
            gaussians: g.len() as u64,
            sh_degree: g.sh_degree,
            bytes: e.stream.len() as u64,
            seconds,
            klt,
            layers,
        };
        out!("{}", serde_json::to_string_pretty(&s).unwrap_or_default());
        return;
    }
    if quiet {
        return;
    }
    out!(
        "encoded {} Gaussians (SH degree {}) at {} rates into {} ({} bytes) in {seconds:.2} s",
        g.len(),
        g.sh_degree,
        layers.len(),
        output.display(),
        e.stream.len()
    );
    let fitted: Vec<&str> = klt.iter().filter(|k| k.1).map(|k| k.0.as_str()).collect();
    if !fitted.is_empty() {
        out!("KLT basis fitted for: {}", fitted.join(", "));
    }
    let names: Vec<&str> = e.groups.iter().map(|gr| gr.kind.name()).collect();
    out!(
        "rate  target dB  PSNR dB  bytes (alone)  B/Gaussian  bits/Gaussian: position {}",
        names.join(" ")
    );
    for l in &layers {
        let groups: Vec<String> = l
            .group_bits
            .iter()
            .map(|(_, b)| format!("{b:.2}"))
            .collect();
        out!(
            "{:>4}  {:>9}  {:>7.2}  {:>13}  {:>10.3}  {:.2} {}",
            l.rate,
            l.target_db.map(|t| format!("{t:.1}")).unwrap_or_default(),
            l.psnr_db,
            l.bytes,
            l.bytes_per_gaussian,
            l.position_bits,
            groups.join(" ")
        );
    }
    out!("(rate 0 is the finest; `salvq extract --rate I` writes one rate alone; PSNR from {FIT_VIEWS} ring views at {FIT_WIDTH}x{FIT_HEIGHT})");
}
