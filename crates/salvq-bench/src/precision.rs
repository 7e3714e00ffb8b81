//! `salvq bench parsimony`, second part: total stream bytes against the precision
//! each model tensor group is stored at, on one generated scene. Writes precision.svg,
//! precision.csv and precision.txt.
//!
//! - **Scaffold-GS MLPs**: binary32 and binary16, the two storages §1.6.2 offers. They never
//!   steer the entropy decoder, so symbol bytes do not move; the cost is the change of their
//!   activated outputs (Annex A.5.2), reported beside the bytes.
//! - **Context MLP** (`mlp_grid`): §1.6.2 stores its weights as i16 or i8 (Table 1-7). Other
//!   widths are a *what-if*: the float weights are rounded to `b`-bit integers (one scale for
//!   layer 0, one per output row for layer 1, as §5.3's `a0` and `a1[o]`), the scene is
//!   encoded, and the model bytes are counted as if the weights took `b` bits each. Its
//!   outputs are the coder's scales, the means and the step adjustments (§5.4), so both
//!   symbol bytes and the reconstruction error move; the feature MSE is reported.
//! - **Hash grid**: one bit per value already (§1.6.1); its only lever is structure, measured
//!   by `--prune-grid` in the first part.

use std::path::Path;

use plotters::prelude::*;

use salvq_bitstream::container::payload::{ContextPrecision, ScaffoldPrecision};
use salvq_bitstream::limits::Limits;
use salvq_bitstream::model::{Mlp, SceneModel};
use salvq_encoder::info::{inspect, ByteClass};
use salvq_encoder::precision::{max_change, rounded};
use salvq_encoder::Result;
use salvq_encoder::{encode_full, values_mse as mse, EncodeOptions};

use super::render_psnr::{RenderReference, HEIGHT, VIEWS, WIDTH};

/// Context MLP weight widths measured (16 is the format's).
const CONTEXT_BITS: [u32; 5] = [16, 12, 10, 8, 6];

/// One measured storage of one group.
#[derive(Debug, Clone)]
pub struct PrecisionPoint {
    pub group: &'static str,
    /// Bits per stored weight.
    pub bits: u32,
    /// In the format (true) or a what-if (false).
    pub in_format: bool,
    pub model_bytes: u64,
    pub anchor_bytes: u64,
    pub total_bytes: u64,
    /// Scaffold-GS MLPs: largest change of an activated output; context MLP: 0.
    pub output_change: f64,
    /// Feature reconstruction MSE (rate 0).
    pub feature_mse: f64,
    /// Render PSNR (dB, Annex C.5) of this storage's decoded scene against the group's
    /// widest storage's decoded scene; `+∞` for the widest itself.
    pub render_psnr_db: f64,
    /// Render PSNR (dB) of this storage's decoded scene against the uncompressed model.
    pub render_psnr_original_db: f64,
}

fn split(stream: &[u8]) -> Result<(u64, u64)> {
    let info = inspect(stream, &Limits::default())?;
    let model = info
        .chunks
        .iter()
        .filter(|c| c.class == ByteClass::Model)
        .map(|c| c.total_bytes)
        .sum();
    Ok((model, stream.len() as u64 - model))
}

/// `v` rounded to `bits`-bit signed integers times one scale (the largest magnitude maps to
/// `2^(bits−1) − 1`).
fn round_to_bits(v: &mut [f32], bits: u32) {
    let max = v.iter().fold(0.0f64, |a, &x| a.max(f64::from(x).abs()));
    if max == 0.0 {
        return;
    }
    let levels = f64::from((1u32 << (bits - 1)) - 1);
    let unit = max / levels;
    for x in v {
        *x = ((f64::from(*x) / unit).round() * unit) as f32;
    }
}

/// The context MLP with its weights as `bits`-bit integers: one scale for layer 0, one per
/// output row for layer 1 (§5.3's `a0` and `a1[o]`).
fn context_mlp_at(mlp: &Mlp, bits: u32) -> Mlp {
    let mut m = mlp.clone();
    round_to_bits(&mut m.w0, bits);
    let hidden = m.b0.len().max(1);
    for row in m.w1.chunks_mut(hidden) {
        round_to_bits(row, bits);
    }
    m
}

/// The first (widest) storage of a group, rendered; later ones are compared with it.
#[derive(Default)]
struct Widest(Option<RenderReference>);

impl Widest {
    /// Render PSNR of `e`'s decoded scene against the widest; `+∞` for the widest itself.
    fn psnr(&mut self, e: &salvq_encoder::Encoded) -> Result<f64> {
        match &self.0 {
            Some(r) => Ok(r.compare(e.expected())?.0),
            None => {
                self.0 = Some(RenderReference::new(e.expected(), VIEWS, WIDTH, HEIGHT)?);
                Ok(f64::INFINITY)
            }
        }
    }
}

/// Measures every storage on `model` (coded at rate 0 with its own quantizer).
pub fn measure(model: &SceneModel) -> Result<Vec<PrecisionPoint>> {
    let mut out = Vec::new();
    let original = RenderReference::new(model, VIEWS, WIDTH, HEIGHT)?;
    // Each group's widest storage, rendered once; every narrower one is compared with it.
    let mut widest = Widest::default();
    for (precision, bits) in [(ScaffoldPrecision::F32, 32), (ScaffoldPrecision::F16, 16)] {
        let options = EncodeOptions {
            scaffold_precision: Some(precision),
            context_precision: Some(ContextPrecision::I16),
            ..Default::default()
        };
        let e = encode_full(model, &options)?;
        let (model_bytes, anchor_bytes) = split(&e.stream)?;
        let feature_mse = mse(&model.anchors.feat, &e.expected().anchors.feat);
        let mlps = [&model.mlp_opacity, &model.mlp_cov, &model.mlp_color];
        let half = mlps.map(|x| rounded(x, ScaffoldPrecision::F16));
        let max_output_change = max_change(model, mlps, [&half[0], &half[1], &half[2]]);
        out.push(PrecisionPoint {
            group: "Scaffold-GS MLPs",
            bits,
            in_format: true,
            model_bytes,
            anchor_bytes,
            total_bytes: e.stream.len() as u64,
            output_change: if bits == 32 { 0.0 } else { max_output_change },
            feature_mse,
            render_psnr_db: widest.psnr(&e)?,
            render_psnr_original_db: original.compare(e.expected())?.0,
        });
    }
    let mut widest = Widest::default();
    let weights = model.mlp_grid.w0.len() + model.mlp_grid.w1.len();
    for bits in CONTEXT_BITS {
        // 16 and 8 are the format's (Table 1-7); the others are stored as i16 and counted.
        let in_format = bits == 16 || bits == 8;
        let mut m = model.clone();
        if !in_format {
            m.mlp_grid = context_mlp_at(&model.mlp_grid, bits);
        }
        let options = EncodeOptions {
            scaffold_precision: Some(ScaffoldPrecision::F32),
            context_precision: Some(if bits == 8 {
                ContextPrecision::I8
            } else {
                ContextPrecision::I16
            }),
            ..Default::default()
        };
        let e = encode_full(&m, &options)?;
        let (model_bytes, anchor_bytes) = split(&e.stream)?;
        let feature_mse = mse(&model.anchors.feat, &e.expected().anchors.feat);
        let saved = if in_format {
            0
        } else {
            (weights as u64 * (16 - u64::from(bits))).div_ceil(8)
        };
        let model_bytes = model_bytes - saved;
        out.push(PrecisionPoint {
            group: "context MLP (mlp_grid weights)",
            bits,
            in_format,
            model_bytes,
            anchor_bytes,
            total_bytes: model_bytes + anchor_bytes,
            output_change: 0.0,
            feature_mse,
            render_psnr_db: widest.psnr(&e)?,
            render_psnr_original_db: original.compare(e.expected())?.0,
        });
    }
    Ok(out)
}

/// Writes precision.svg / .csv / .txt for `model` and returns the text.
pub fn report(out: &Path, model: &SceneModel) -> Result<String> {
    let points = measure(model)?;
    let mut csv = String::from(
        "group,bits,in_format,model_bytes,anchor_bytes,total_bytes,max_output_change,feature_mse,render_psnr_vs_widest_db,render_psnr_vs_uncompressed_db\n",
    );
    let mut text = format!(
        "Total bytes vs model precision per tensor group ({} anchors, rate 0, USQ):\n\
         what-if rows are storages the format does not have (weights rounded to b-bit \
         integers, counted at b bits). Render PSNR (Annex C.5, {} ring views at {}x{}) of each \
         row's decoded scene against the group's widest storage's decoded scene and against \
         the uncompressed model.\n\n\
         group                              bits  storage    model B   anchor B    total B  vs widest  feature MSE  render PSNR: vs widest, vs uncompressed  output change\n",
        model.n(),
        VIEWS,
        WIDTH,
        HEIGHT
    );
    let base = |g: &str| {
        points
            .iter()
            .find(|p| p.group == g)
            .map_or(1, |p| p.total_bytes)
    };
    for p in &points {
        csv.push_str(&format!(
            "{},{},{},{},{},{},{:e}\n",
            p.group,
            p.bits,
            p.in_format,
            p.model_bytes,
            p.anchor_bytes,
            p.total_bytes,
            p.output_change
        ));
        let reference = if p.group.starts_with("Scaffold") {
            points.first().map_or(1, |q| q.total_bytes)
        } else {
            base(p.group)
        };
        text.push_str(&format!(
            "{:<34} {:>4}  {:<8} {:>10} {:>10} {:>10}  {:>+8.2} %  {:>11.4e}  {:>12.2} dB {:>10.2} dB  {}\n",
            p.group,
            p.bits,
            if p.in_format { "format" } else { "what-if" },
            p.model_bytes,
            p.anchor_bytes,
            p.total_bytes,
            100.0 * (p.total_bytes as f64 / reference as f64 - 1.0),
            p.feature_mse,
            p.render_psnr_db,
            p.render_psnr_original_db,
            if p.group.starts_with("Scaffold") {
                format!("{:.2e}", p.output_change)
            } else {
                "-".into()
            }
        ));
    }
    super::charts::write_report(out, "precision", |path| chart(path, &points), &csv, &text)?;
    Ok(text)
}

fn chart(
    path: &Path,
    points: &[PrecisionPoint],
) -> std::result::Result<(), Box<dyn std::error::Error>> {
    let root = SVGBackend::new(path, (1200, 520)).into_drawing_area();
    root.fill(&WHITE)?;
    let (left, right) = root.split_horizontally(600);
    let groups = ["Scaffold-GS MLPs", "context MLP (mlp_grid weights)"];
    let colors = [RGBColor(0, 114, 178), RGBColor(213, 94, 0)];
    type Get = fn(&PrecisionPoint) -> f64;
    let panels: [(&DrawingArea<SVGBackend, _>, &str, &str, Get); 2] = [
        (
            &left,
            "Total stream bytes vs bits per stored weight",
            "total bytes",
            |p| p.total_bytes as f64,
        ),
        (
            &right,
            "Model bytes (solid) and symbol bytes (dashed)",
            "bytes",
            |p| p.model_bytes as f64,
        ),
    ];
    for (i, (area, caption, ydesc, get)) in panels.into_iter().enumerate() {
        let ys: Vec<f64> = points
            .iter()
            .flat_map(|p| {
                if i == 0 {
                    vec![get(p)]
                } else {
                    vec![get(p), p.anchor_bytes as f64]
                }
            })
            .collect();
        let y0 = ys.iter().copied().fold(f64::INFINITY, f64::min) * 0.9;
        let y1 = ys.iter().copied().fold(0.0, f64::max) * 1.1;
        let mut c = ChartBuilder::on(area)
            .caption(caption, ("sans-serif", 18))
            .margin(15)
            .x_label_area_size(45)
            .y_label_area_size(80)
            .build_cartesian_2d(4f64..34f64, (y0.max(1.0)..y1).log_scale())?;
        c.configure_mesh()
            .x_desc("bits per weight (format: 32/16 Scaffold-GS, 16/8 context; others what-if)")
            .y_desc(ydesc)
            .draw()?;
        for (g, color) in groups.iter().zip(colors) {
            let xy: Vec<(f64, f64)> = points
                .iter()
                .filter(|p| p.group == *g)
                .map(|p| (f64::from(p.bits), get(p)))
                .collect();
            super::charts::labelled_line(&mut c, g, color, xy).map_err(|e| e.to_string())?;
            if i == 1 {
                let sym: Vec<(f64, f64)> = points
                    .iter()
                    .filter(|p| p.group == *g)
                    .map(|p| (f64::from(p.bits), p.anchor_bytes as f64))
                    .collect();
                c.draw_series(DashedLineSeries::new(sym, 6, 4, color.stroke_width(2)))?;
            }
        }
        super::charts::legend(&mut c, SeriesLabelPosition::UpperRight)
            .map_err(|e| e.to_string())?;
    }
    root.present()?;
    Ok(())
}
