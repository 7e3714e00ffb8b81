//! SVG charts of `salvq bench rd` (plotters).

use std::path::Path;

use plotters::prelude::*;

use super::Point;
use salvq_encoder::{Error, Result};
use salvq_render::error::IoOp;

/// The charts' line colours (the Okabe–Ito palette's, black first), in order.
pub(super) const COLORS: [RGBColor; 8] = [
    RGBColor(0, 0, 0),
    RGBColor(0, 114, 178),
    RGBColor(213, 94, 0),
    RGBColor(120, 120, 120),
    RGBColor(0, 158, 115),
    RGBColor(204, 121, 167),
    RGBColor(230, 159, 0),
    RGBColor(86, 180, 233),
];

/// Draws `xy` as a labelled line with dots, and its legend entry.
pub(super) fn labelled_line<'a, DB, CT>(
    c: &mut ChartContext<'a, DB, CT>,
    label: &str,
    color: RGBColor,
    xy: Vec<(f64, f64)>,
) -> std::result::Result<(), Box<dyn std::error::Error + 'a>>
where
    DB: DrawingBackend + 'a,
    CT: CoordTranslate<From = (f64, f64)>,
{
    c.draw_series(LineSeries::new(xy.clone(), color.stroke_width(2)))?
        .label(label)
        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color));
    c.draw_series(xy.into_iter().map(|p| Circle::new(p, 3, color.filled())))?;
    Ok(())
}

/// Draws the legend box of `c`'s labelled series at `position` (every chart's one style).
pub(super) fn legend<'a, DB, CT>(
    c: &mut ChartContext<'a, DB, CT>,
    position: SeriesLabelPosition,
) -> std::result::Result<(), Box<dyn std::error::Error + 'a>>
where
    DB: DrawingBackend + 'a,
    CT: CoordTranslate,
{
    c.configure_series_labels()
        .border_style(BLACK)
        .background_style(WHITE.mix(0.9))
        .position(position)
        .draw()?;
    Ok(())
}

/// Draws the legend box at `position` and writes the file.
pub(super) fn finish<'a, DB, CT>(
    mut c: ChartContext<'a, DB, CT>,
    root: &DrawingArea<DB, plotters::coord::Shift>,
    position: SeriesLabelPosition,
) -> std::result::Result<(), Box<dyn std::error::Error + 'a>>
where
    DB: DrawingBackend + 'a,
    CT: CoordTranslate,
{
    legend(&mut c, position)?;
    root.present()?;
    Ok(())
}

fn err(path: &Path) -> impl Fn(String) -> Error + '_ {
    move |why| Error::io(IoOp::Write, path, std::io::Error::other(why))
}

fn range(v: impl Iterator<Item = f64> + Clone, pad: f64) -> (f64, f64) {
    let lo = v.clone().fold(f64::INFINITY, f64::min);
    let hi = v.fold(f64::NEG_INFINITY, f64::max);
    let d = (hi - lo).max(1e-9) * pad;
    (lo - d, hi + d)
}

/// Feature SNR vs whole-stream bits per anchor, one line per quantizer.
pub fn rd(path: &Path, curves: &[(&'static str, Vec<Point>)]) -> Result<()> {
    draw(path, curves).map_err(|e| err(path)(e.to_string()))
}

fn draw(
    path: &Path,
    curves: &[(&'static str, Vec<Point>)],
) -> std::result::Result<(), Box<dyn std::error::Error>> {
    let root = SVGBackend::new(path, (1500, 600)).into_drawing_area();
    root.fill(&WHITE)?;
    let (left, right) = root.split_horizontally(750);
    type Get = fn(&Point) -> f64;
    let panels: [(&DrawingArea<SVGBackend, _>, &str, &str, Get); 2] = [
        (
            &left,
            "Rate vs feature distortion (F = 48, scales fitted per quantizer)",
            "feature SNR (dB)",
            |p| p.snr_db,
        ),
        (
            &right,
            "Rate vs render PSNR of the decoded scene (Annex C.5)",
            "render PSNR (dB) vs the uncompressed scene",
            |p| p.render_psnr_db,
        ),
    ];
    for (area, caption, ydesc, get) in panels {
        let all = curves.iter().flat_map(|c| c.1.iter());
        let (x0, x1) = range(all.clone().map(|p| p.bits_per_anchor), 0.05);
        let (y0, y1) = range(all.map(get).filter(|v| v.is_finite()), 0.05);
        let mut c = ChartBuilder::on(area)
            .caption(caption, ("sans-serif", 18))
            .margin(15)
            .x_label_area_size(45)
            .y_label_area_size(60)
            .build_cartesian_2d(x0..x1, y0..y1)?;
        c.configure_mesh()
            .x_desc("whole stream, bits per anchor")
            .y_desc(ydesc)
            .draw()?;
        for (i, (label, pts)) in curves.iter().enumerate() {
            let color = COLORS[i % COLORS.len()];
            let xy: Vec<(f64, f64)> = pts
                .iter()
                .map(|p| (p.bits_per_anchor, get(p)))
                .filter(|(_, y)| y.is_finite())
                .collect();
            labelled_line(&mut c, label, color, xy).map_err(|e| e.to_string())?;
        }
        legend(&mut c, SeriesLabelPosition::LowerRight).map_err(|e| e.to_string())?;
    }
    root.present()?;
    Ok(())
}

/// Encode time per anchor vs feature MSE, one point per search method.
pub fn search_speed(path: &Path, rows: &[(&'static str, Point)], anchors: u32) -> Result<()> {
    let go = || -> std::result::Result<(), Box<dyn std::error::Error>> {
        let us = |p: &Point| p.secs * 1e6 / f64::from(anchors);
        let (x0, x1) = range(rows.iter().map(|r| us(&r.1)), 0.15);
        let (y0, y1) = range(rows.iter().map(|r| r.1.mse), 0.25);
        let root = SVGBackend::new(path, (900, 600)).into_drawing_area();
        root.fill(&WHITE)?;
        let mut c = ChartBuilder::on(&root)
            .caption(
                "Search methods on a learned basis (F = 48): encode time vs feature MSE",
                ("sans-serif", 18),
            )
            .margin(15)
            .x_label_area_size(45)
            .y_label_area_size(70)
            .build_cartesian_2d(x0.max(0.0)..x1, y0..y1)?;
        c.configure_mesh()
            .x_desc("whole encode, µs per anchor")
            .y_desc("feature MSE")
            .draw()?;
        for (i, (label, p)) in rows.iter().enumerate() {
            let color = COLORS[(i + 1) % COLORS.len()];
            c.draw_series(std::iter::once(
                EmptyElement::at((us(p), p.mse))
                    + Circle::new((0, 0), 5, color.filled())
                    + Text::new(
                        format!("{label}: {:.1} bits/anchor", p.bits_per_anchor),
                        (8, -4),
                        ("sans-serif", 12).into_font(),
                    ),
            ))?;
        }
        root.present()?;
        Ok(())
    };
    go().map_err(|e| err(path)(e.to_string()))
}

/// MSE relative to the bounded exact search vs basis condition number (log10), per method;
/// conditions the encoder refuses are marked on the axis.
pub fn stability(
    path: &Path,
    rows: &[(f64, Vec<Option<Point>>, String)],
    methods: &[&'static str],
) -> Result<()> {
    let go = || -> std::result::Result<(), Box<dyn std::error::Error>> {
        let rel = |r: &(f64, Vec<Option<Point>>, String), k: usize| -> Option<f64> {
            let e = r.1.get(3)?.as_ref()?.mse;
            r.1.get(k)?.as_ref().map(|p| p.mse / e)
        };
        let vals: Vec<f64> = rows
            .iter()
            .flat_map(|r| (0..methods.len()).filter_map(move |k| rel(r, k)))
            .collect();
        let y1 = vals.iter().copied().fold(2.0, f64::max) * 1.5;
        let root = SVGBackend::new(path, (900, 600)).into_drawing_area();
        root.fill(&WHITE)?;
        let mut c = ChartBuilder::on(&root)
            .caption(
                "Search methods vs basis condition number (× marks: encoder refuses the basis)",
                ("sans-serif", 18),
            )
            .margin(15)
            .x_label_area_size(45)
            .y_label_area_size(60)
            .build_cartesian_2d(-0.3f64..8.3f64, (0.9f64..y1).log_scale())?;
        c.configure_mesh()
            .x_desc("log10 condition number of B")
            .y_desc("feature MSE / closest (≤10k nodes), log scale")
            .draw()?;
        for (k, label) in methods.iter().enumerate() {
            let color = COLORS[(k + 1) % COLORS.len()];
            let xy: Vec<(f64, f64)> = rows
                .iter()
                .filter_map(|r| rel(r, k).map(|v| (r.0.log10(), v)))
                .collect();
            c.draw_series(LineSeries::new(xy.clone(), color.stroke_width(2)))?
                .label(*label)
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color));
            c.draw_series(xy.into_iter().map(|p| Circle::new(p, 3, color.filled())))?;
        }
        c.draw_series(
            rows.iter()
                .filter(|r| !r.2.is_empty())
                .map(|r| Cross::new((r.0.log10(), 1.0), 6, RED.stroke_width(2))),
        )?;
        legend(&mut c, SeriesLabelPosition::UpperLeft).map_err(|e| e.to_string())?;
        root.present()?;
        Ok(())
    };
    go().map_err(|e| err(path)(e.to_string()))
}

/// BD-rate of the fitted SALVQ vs USQ against the residual correlation.
pub fn correlation(path: &Path, rows: &[(f64, f64)]) -> Result<()> {
    let go = || -> std::result::Result<(), Box<dyn std::error::Error>> {
        let (y0, y1) = range(rows.iter().map(|r| r.1).chain([0.0]), 0.1);
        let root = SVGBackend::new(path, (900, 600)).into_drawing_area();
        root.fill(&WHITE)?;
        let mut c = ChartBuilder::on(&root)
            .caption(
                "BD-rate of SALVQ (fitted basis) vs USQ by residual correlation",
                ("sans-serif", 18),
            )
            .margin(15)
            .x_label_area_size(45)
            .y_label_area_size(60)
            .build_cartesian_2d(0.78f64..1.02f64, y0..y1)?;
        c.configure_mesh()
            .x_desc("feat_decay (singular values of the mixing decay as decay^i; 1 = uncorrelated)")
            .y_desc("BD-rate, whole stream, pchip (%)")
            .draw()?;
        let color = COLORS[4];
        c.draw_series(LineSeries::new(rows.to_vec(), color.stroke_width(2)))?;
        c.draw_series(rows.iter().map(|&p| Circle::new(p, 4, color.filled())))?;
        root.present()?;
        Ok(())
    };
    go().map_err(|e| err(path)(e.to_string()))
}

/// Writes `<stem>.svg` (drawn by `draw`), `<stem>.csv` and `<stem>.txt` into `out`.
pub(super) fn write_report(
    out: &Path,
    stem: &str,
    draw: impl FnOnce(&Path) -> std::result::Result<(), Box<dyn std::error::Error>>,
    csv: &str,
    text: &str,
) -> Result<()> {
    let svg = out.join(format!("{stem}.svg"));
    draw(&svg).map_err(|e| err(&svg)(e.to_string()))?;
    salvq_render::io::write_bytes_atomic(&out.join(format!("{stem}.csv")), csv.as_bytes())?;
    salvq_render::io::write_bytes_atomic(&out.join(format!("{stem}.txt")), text.as_bytes())?;
    Ok(())
}

/// The x range of a log-scale chart over scene sizes, with a margin on both sides.
pub(super) fn anchors_range(first: Option<u32>, last: Option<u32>) -> std::ops::Range<f64> {
    first.map_or(1e3, f64::from) * 0.8..last.map_or(1e6, f64::from) * 1.25
}
