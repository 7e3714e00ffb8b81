//! `salvq bench parsimony`: the model's share of the stream and the total bits per
//! anchor against scene size, as the encoder stores the model plainly, with grid-level pruning
//! (Annex A.5.1), and with pruning and binary16 Scaffold-GS MLPs (§1.6.2). Writes
//! parsimony.svg, parsimony.csv and parsimony.txt; then [`super::precision`]'s total bytes vs
//! precision per tensor group (precision.svg, .csv, .txt).

use std::path::Path;

use plotters::prelude::*;

use salvq_bitstream::container::payload::{ContextPrecision, ScaffoldPrecision};
use salvq_bitstream::limits::Limits;
use salvq_encoder::info::{inspect, ByteClass};
use salvq_encoder::parsimony::prune_grid_levels;
use salvq_encoder::{encode_full, EncodeOptions};
use salvq_encoder::{Error, Result};
use salvq_gen::{generate, GenParams};
use salvq_render::error::IoOp;

/// Scene sizes, smallest first.
const SIZES: [u32; 5] = [1_000, 10_000, 100_000, 1_000_000, 2_000_000];

/// One configuration's stream at one size.
#[derive(Debug, Clone, Copy)]
struct Point {
    model_bytes: u64,
    total_bytes: u64,
}

impl Point {
    fn share(&self) -> f64 {
        100.0 * self.model_bytes as f64 / self.total_bytes.max(1) as f64
    }
}

struct Row {
    anchors: u32,
    plain: Point,
    pruned: Point,
    pruned_f16: Point,
    levels_dropped: usize,
    feat_mse: (f64, f64),
}

fn point(stream: &[u8]) -> Result<Point> {
    let info = inspect(stream, &Limits::default())?;
    let model_bytes = info
        .chunks
        .iter()
        .filter(|c| c.class == ByteClass::Model)
        .map(|c| c.total_bytes)
        .sum();
    Ok(Point {
        model_bytes,
        total_bytes: stream.len() as u64,
    })
}

/// Runs the measurement on generated scenes of up to `max` anchors.
pub fn run(out: &Path, max: u32) -> Result<String> {
    std::fs::create_dir_all(out).map_err(|e| Error::io(IoOp::Write, out, e))?;
    let mut rows = Vec::new();
    for &n in SIZES.iter().filter(|&&n| n <= max) {
        let m = generate(&GenParams {
            feat_basis: false,
            ..GenParams::new(n, 1)
        });
        // Before: every model tensor at its widest storage.
        let f32_options = EncodeOptions {
            scaffold_precision: Some(ScaffoldPrecision::F32),
            context_precision: Some(ContextPrecision::I16),
            ..Default::default()
        };
        let plain = point(&encode_full(&m, &f32_options)?.stream)?;
        let (pruned_model, trials) = prune_grid_levels(&m, &f32_options, 0.01)?;
        let pruned = point(&encode_full(&pruned_model, &f32_options)?.stream)?;
        // After: binary16 Scaffold-GS MLPs and the context MLP as the encoder chooses
        // (Annex A.5.4: i8 when smaller at equal distortion).
        let f16_options = EncodeOptions {
            scaffold_precision: Some(ScaffoldPrecision::F16),
            context_precision: None,
            ..Default::default()
        };
        let pruned_f16 = point(&encode_full(&pruned_model, &f16_options)?.stream)?;
        rows.push(Row {
            anchors: n,
            plain,
            pruned,
            pruned_f16,
            levels_dropped: trials.len(),
            feat_mse: (
                trials.first().map_or(0.0, |t| t.mse_with),
                trials.last().map_or(0.0, |t| t.mse_without),
            ),
        });
    }
    let mut csv = String::from(
        "anchors,plain_model_bytes,plain_total_bytes,pruned_model_bytes,pruned_total_bytes,\
         pruned_f16_model_bytes,pruned_f16_total_bytes,levels_dropped\n",
    );
    let mut text = String::from(
        "Model share of the stream and bits per anchor vs scene size (GenParams::new(N, 1), USQ, rate 0):\n\
         plain = binary32 Scaffold-GS MLPs, i16 context MLP, every grid level; pruned = --prune-grid\n\
         (Annex A.5.1); + f16/i8 = pruned, --scaffold-precision f16 and --context-precision auto\n\
         (§1.6.2, Annex A.5.4).\n\n\
         anchors     model share: plain  pruned  +f16/i8 bits/anchor: plain  pruned  +f16/i8 levels dropped (feature MSE)\n",
    );
    for r in &rows {
        let bpa = |p: &Point| p.total_bytes as f64 * 8.0 / f64::from(r.anchors);
        csv.push_str(&format!(
            "{},{},{},{},{},{},{},{}\n",
            r.anchors,
            r.plain.model_bytes,
            r.plain.total_bytes,
            r.pruned.model_bytes,
            r.pruned.total_bytes,
            r.pruned_f16.model_bytes,
            r.pruned_f16.total_bytes,
            r.levels_dropped
        ));
        text.push_str(&format!(
            "{:>9}   {:>17.1} % {:>5.1} % {:>5.1} %   {:>12.2} {:>7.2} {:>7.2}   {} ({:.4e} -> {:.4e})\n",
            r.anchors,
            r.plain.share(),
            r.pruned.share(),
            r.pruned_f16.share(),
            bpa(&r.plain),
            bpa(&r.pruned),
            bpa(&r.pruned_f16),
            r.levels_dropped,
            r.feat_mse.0,
            r.feat_mse.1
        ));
    }
    super::charts::write_report(out, "parsimony", |p| chart(p, &rows), &csv, &text)?;
    // Part two: total bytes vs precision per tensor group, at 100 k anchors (or `max`).
    let n = max.clamp(SIZES[0], 100_000);
    let m = generate(&GenParams {
        feat_basis: false,
        ..GenParams::new(n, 1)
    });
    text.push('\n');
    text.push_str(&super::precision::report(out, &m)?);
    Ok(text)
}

/// A chart line: label, colour, and the value it plots.
type Series = (&'static str, RGBColor, fn(&Row) -> f64);

fn chart(path: &Path, rows: &[Row]) -> std::result::Result<(), Box<dyn std::error::Error>> {
    let root = SVGBackend::new(path, (1200, 520)).into_drawing_area();
    root.fill(&WHITE)?;
    let (left, right) = root.split_horizontally(600);
    let xs = super::charts::anchors_range(
        rows.first().map(|r| r.anchors),
        rows.last().map(|r| r.anchors),
    );
    let colors = [
        RGBColor(0, 114, 178),
        RGBColor(213, 94, 0),
        RGBColor(0, 158, 115),
    ];
    let panels: [(&DrawingArea<SVGBackend, _>, &str, &str, [Series; 3]); 2] = [
        (
            &left,
            "Model bytes / stream bytes vs scene size",
            "model share (%)",
            [
                ("plain", colors[0], |r| r.plain.share()),
                ("--prune-grid", colors[1], |r| r.pruned.share()),
                ("--prune-grid + f16 / i8 MLPs", colors[2], |r| {
                    r.pruned_f16.share()
                }),
            ],
        ),
        (
            &right,
            "Total bits per anchor vs scene size",
            "bits / anchor",
            [
                ("plain", colors[0], |r| {
                    r.plain.total_bytes as f64 * 8.0 / f64::from(r.anchors)
                }),
                ("--prune-grid", colors[1], |r| {
                    r.pruned.total_bytes as f64 * 8.0 / f64::from(r.anchors)
                }),
                ("--prune-grid + f16 / i8 MLPs", colors[2], |r| {
                    r.pruned_f16.total_bytes as f64 * 8.0 / f64::from(r.anchors)
                }),
            ],
        ),
    ];
    for (area, caption, ydesc, series) in panels {
        let ys = rows
            .iter()
            .flat_map(|r| series.iter().map(move |s| (s.2)(r)));
        let y0 = ys.clone().fold(f64::INFINITY, f64::min).max(1e-3) * 0.7;
        let y1 = ys.fold(0.0, f64::max) * 1.4;
        let mut c = ChartBuilder::on(area)
            .caption(caption, ("sans-serif", 18))
            .margin(15)
            .x_label_area_size(45)
            .y_label_area_size(60)
            .build_cartesian_2d(xs.clone().log_scale(), (y0..y1).log_scale())?;
        c.configure_mesh().x_desc("anchors").y_desc(ydesc).draw()?;
        for (label, color, get) in series {
            let xy: Vec<(f64, f64)> = rows
                .iter()
                .map(|r| (f64::from(r.anchors), get(r)))
                .collect();
            super::charts::labelled_line(&mut c, label, color, xy).map_err(|e| e.to_string())?;
        }
        // The legend only: the whole figure is presented once, after both panels.
        super::charts::legend(&mut c, SeriesLabelPosition::UpperRight)
            .map_err(|e| e.to_string())?;
    }
    root.present()?;
    Ok(())
}
