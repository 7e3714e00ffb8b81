//! `salvq bench real` (Annex A.8.4): the explicit profile on real 3DGS scenes
//! against the formats people use. For each scene, one multi-rate salvq stream (each rate
//! decoded from it) and PlayCanvas splat-transform's SPZ, SOG and compressed PLY, all
//! rendered from the same ring cameras as the input PLY (PSNR and SSIM), with encode and
//! decode times; then the ablations (identity vs fitted bases, causal vs factorized prior,
//! size classes or one class, one multi-rate file vs single-rate files) and bits per
//! Gaussian per attribute group. Writes `real.svg`, `real.csv` and `real.txt`.

use std::path::{Path, PathBuf};
use std::time::Instant;

use plotters::prelude::*;

use salvq_bitstream::limits::Limits;
use salvq_encoder::explicit::{
    encode_prepared, rate_plans, EncodedGaussians, ExplicitOptions, PreparedGaussians, RateControl,
    Variant,
};
use salvq_encoder::{Error, Result};
use salvq_render::compare::RingTarget;
use salvq_render::error::IoOp;
use salvq_render::ply::read_ply;

use super::peers::peer_encode;

/// What to measure.
#[derive(Debug, Clone)]
pub struct RealOptions {
    /// Folder of the scenes (`<name>.ply`).
    pub data: PathBuf,
    /// Scene names (files `<name>.ply` in `data`).
    pub scenes: Vec<String>,
    pub out: PathBuf,
    /// salvq's render-PSNR targets, rate 0 first.
    pub targets: Vec<f64>,
    /// The splat-transform command (e.g. a path to its `.bin/splat-transform`); `None`: no
    /// peers.
    pub splat_transform: Option<String>,
    /// Run the ablations (each a full encode per scene).
    pub ablations: bool,
    pub views: u32,
    pub width: u32,
    pub height: u32,
}

/// Where a scene's file came from (its numbers are quoted with it).
pub fn provenance(scene: &str) -> &'static str {
    match scene {
        "donut" | "fruit_drops" | "alti" | "three_points" => "as trained",
        "guitar" => "lossy source (PlayCanvas compressed PLY)",
        "playbot" => "lossy source (SOG; SH dropped)",
        _ => "unknown source",
    }
}

/// One measured point.
#[derive(Debug, Clone)]
pub struct Row {
    pub scene: String,
    /// `salvq`, an ablation's name, or a peer format.
    pub codec: String,
    /// salvq's rate (its layer), if any.
    pub rate: Option<u8>,
    pub bytes: u64,
    pub bytes_per_gaussian: f64,
    pub psnr_db: f64,
    pub ssim: f64,
    pub encode_s: f64,
    pub decode_s: f64,
}

fn io_err(path: &Path, e: std::io::Error) -> Error {
    Error::io(IoOp::Write, path, e)
}

/// salvq's rows for one encoded stream: each coded rate decoded from the multi-rate stream
/// (timed), its single-rate size, its render quality. Checks every decode against the
/// encoder's prediction (a difference is an error: the bench measures what ships).
fn salvq_rows(
    scene: &str,
    codec: &str,
    e: &EncodedGaussians,
    encode_s: f64,
    reference: &RingTarget,
) -> Result<Vec<Row>> {
    let n = f64::from(e.header.count.max(1));
    let mut rows = Vec::new();
    // Each rate's bytes: what `salvq extract` writes (a progressive rate's prefix, §3.8).
    for ((report, _, expected), read) in e.layers.iter().zip(e.rate_stream_bytes()) {
        let t = Instant::now();
        let d = salvq::Decoder::builder()
            .limits(Limits::default())
            .rate(Some(report.rate))
            .build()
            .decode(&e.stream)
            .and_then(salvq::Scene::try_into_gaussians)?;
        let decode_s = t.elapsed().as_secs_f64();
        if &d.gaussians != expected {
            return Err(Error::FitFailed {
                tensor: "bench real",
                reason: format!(
                    "{scene} {codec} rate {}: the decode DIFFERS from the encoder's prediction",
                    report.rate
                ),
            });
        }
        let (p, s) = reference.psnr_ssim(&d.gaussians)?;
        let bytes = read as u64;
        rows.push(Row {
            scene: scene.into(),
            codec: codec.into(),
            rate: Some(report.rate),
            bytes,
            bytes_per_gaussian: bytes as f64 / n,
            psnr_db: p,
            ssim: s,
            encode_s,
            decode_s,
        });
    }
    Ok(rows)
}

/// [`peer_encode`] as a row of this bench.
fn peer_row(
    st: &str,
    scene: &str,
    input: &Path,
    format: &str,
    work: &Path,
    n: usize,
    reference: &RingTarget,
) -> Result<Option<Row>> {
    Ok(
        peer_encode(st, scene, input, format, work, reference)?.map(|p| Row {
            scene: scene.into(),
            codec: format.into(),
            rate: None,
            bytes: p.bytes,
            bytes_per_gaussian: p.bytes as f64 / n.max(1) as f64,
            psnr_db: p.psnr_db,
            ssim: p.ssim,
            encode_s: p.encode_s,
            decode_s: p.decode_s,
        }),
    )
}

/// salvq's bytes at `db`, interpolated (log bytes linear in PSNR) between its two nearest
/// rates; `None` outside its range.
pub fn bytes_at(points: &[(f64, f64)], db: f64) -> Option<f64> {
    let mut p: Vec<(f64, f64)> = points.iter().copied().filter(|x| x.1.is_finite()).collect();
    p.sort_by(|a, b| a.1.total_cmp(&b.1));
    p.windows(2).find_map(|w| {
        let ((b0, d0), (b1, d1)) = (w[0], w[1]);
        (d0 <= db && db <= d1 && d1 > d0).then(|| {
            let f = (db - d0) / (d1 - d0);
            (b0.ln() + f * (b1.ln() - b0.ln())).exp()
        })
    })
}

/// The ablations: each a full encode at the same targets.
fn variants() -> Vec<(&'static str, Variant, Option<bool>)> {
    vec![
        ("identity bases", Variant::default(), Some(false)),
        (
            "factorized prior",
            Variant {
                factorized_prior: true,
                ..Variant::default()
            },
            None,
        ),
        (
            "one size class",
            Variant {
                single_class: true,
                ..Variant::default()
            },
            None,
        ),
        (
            "plain (factorized + one class + identity)",
            Variant {
                factorized_prior: true,
                single_class: true,
                ..Variant::default()
            },
            Some(false),
        ),
    ]
}

/// One scene's lines of bits per Gaussian per attribute group, a line per rate, with the
/// groups coded in a fitted (KLT) basis.
fn group_bits_text(scene: &str, e: &EncodedGaussians, n: usize) -> String {
    let names: Vec<&str> = e.groups.iter().map(|gr| gr.kind.name()).collect();
    let mut text = format!(
        "\n{scene} ({}; KLT: {}): bits per Gaussian, rate: position (octree + refinement) {}\n",
        provenance(scene),
        e.groups
            .iter()
            .filter(|gr| gr.basis.is_some())
            .map(|gr| gr.kind.name())
            .collect::<Vec<_>>()
            .join(", "),
        names.join(" ")
    );
    for (report, _, _) in &e.layers {
        let nn = n.max(1) as f64;
        let g: Vec<String> = report
            .group_bits
            .iter()
            .map(|b| format!("{:.2}", b / nn))
            .collect();
        text.push_str(&format!(
            "  rate {}: {:.2} ({:.2} + {:.2}) {}\n",
            report.rate,
            (report.apos_bytes as f64 * 8.0 + report.refine_bits) / nn,
            report.apos_bytes as f64 * 8.0 / nn,
            report.refine_bits / nn,
            g.join(" ")
        ));
    }
    text
}

/// One multi-rate file against single-rate files (each = the extracted rate): one scene's
/// line, from salvq's `rows` of that scene.
fn multi_rate_line(scene: &str, e: &EncodedGaussians, rows: &[Row]) -> String {
    let single: u64 = rows
        .iter()
        .filter(|r| r.scene == scene && r.codec == "salvq")
        .map(|r| r.bytes)
        .sum();
    format!(
        "  {scene}: one file with {} rates {} bytes; the same rates as separate files {} bytes ({:.1} %)\n",
        e.layers.len(),
        e.stream.len(),
        single,
        100.0 * (single as f64 / e.stream.len().max(1) as f64 - 1.0)
    )
}

/// Runs the bench; returns the text summary (also written to `real.txt`).
pub fn run(o: &RealOptions, progress: &dyn Fn(&str)) -> Result<String> {
    std::fs::create_dir_all(&o.out).map_err(|e| io_err(&o.out, e))?;
    // The peers' files are only measured: they go to a temporary folder.
    let scratch = tempfile::tempdir().map_err(|e| io_err(&o.out, e))?;
    let work = scratch.path().to_path_buf();
    let mut rows: Vec<Row> = Vec::new();
    let mut groups_text = String::new();
    let mut multi_text = String::new();
    for scene in &o.scenes {
        let input = o.data.join(format!("{scene}.ply"));
        let g = read_ply(&salvq_render::io::read_file(&input)?)?;
        let n = g.len();
        progress(&format!("{scene}: {n} Gaussians, rendering the input"));
        let reference = RingTarget::new(&g, o.views, o.width, o.height)?;
        let p = PreparedGaussians::new(&g)?;
        // A line when the step changes, not at every trial render.
        let last_step = std::cell::RefCell::new(String::new());
        let encode = |variant: Variant, klt: Option<bool>| -> Result<(EncodedGaussians, f64)> {
            let t = Instant::now();
            let klt = klt.map(|k| vec![k; p.kinds.len()]);
            let fit = ExplicitOptions {
                rates: RateControl::Psnr(o.targets.clone()),
                variant,
                klt: klt.clone(),
                ..Default::default()
            };
            let (plans, klt) = rate_plans(&g, &p, &fit, &|m| {
                if *last_step.borrow() != m.step {
                    m.step.clone_into(&mut last_step.borrow_mut());
                    progress(&format!("{scene}: {}", m.step));
                }
            })?;
            let options = ExplicitOptions {
                rates: RateControl::Plans(plans.clone()),
                klt,
                variant,
                ..Default::default()
            };
            let e = encode_prepared(&p, &plans, &options)?;
            Ok((e, t.elapsed().as_secs_f64()))
        };
        progress(&format!("{scene}: salvq"));
        let (e, encode_s) = encode(Variant::default(), None)?;
        rows.extend(salvq_rows(scene, "salvq", &e, encode_s, &reference)?);
        groups_text.push_str(&group_bits_text(scene, &e, n));
        multi_text.push_str(&multi_rate_line(scene, &e, &rows));
        if o.ablations {
            for (name, variant, klt) in variants() {
                progress(&format!("{scene}: ablation {name}"));
                let (e, encode_s) = encode(variant, klt)?;
                rows.extend(salvq_rows(scene, name, &e, encode_s, &reference)?);
            }
        }
        if let Some(st) = &o.splat_transform {
            for format in ["spz", "sog", "compressed.ply"] {
                progress(&format!("{scene}: splat-transform {format}"));
                match peer_row(st, scene, &input, format, &work, n, &reference)? {
                    Some(r) => rows.push(r),
                    None => progress(&format!(
                        "{scene}: splat-transform could not write {format}"
                    )),
                }
            }
        }
    }
    write_csv(&o.out.join("real.csv"), &rows)?;
    chart(&o.out.join("real.svg"), o, &rows)?;
    let text = summary(o, &rows, &groups_text, &multi_text);
    std::fs::write(o.out.join("real.txt"), &text).map_err(|e| io_err(&o.out, e))?;
    Ok(text)
}

/// Redraws `real.svg` in `dir` from its `real.csv` (no measurement).
pub fn replot(dir: &Path, o: &RealOptions) -> Result<()> {
    let path = dir.join("real.csv");
    let text = String::from_utf8_lossy(&salvq_render::io::read_file(&path)?).into_owned();
    // A line that is not a row of `write_csv`'s.
    let bad = |line: usize| {
        let why = format!("line {} is not a row of this bench", line + 1);
        Error::io(
            IoOp::Read,
            &path,
            std::io::Error::new(std::io::ErrorKind::InvalidData, why),
        )
    };
    let mut rows = Vec::new();
    let mut scenes: Vec<String> = Vec::new();
    for (i, line) in text.lines().enumerate().skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        let [scene, _, codec, rate, bytes, bpg, db, s, enc, dec] = f[..] else {
            return Err(bad(i + 1));
        };
        let num = |v: &str| v.parse::<f64>().map_err(|_| bad(i + 1));
        if !scenes.iter().any(|x| x == scene) {
            scenes.push(scene.to_string());
        }
        rows.push(Row {
            scene: scene.into(),
            codec: codec.into(),
            rate: rate.parse().ok(),
            bytes: num(bytes)? as u64,
            bytes_per_gaussian: num(bpg)?,
            psnr_db: num(db)?,
            ssim: num(s)?,
            encode_s: num(enc)?,
            decode_s: num(dec)?,
        });
    }
    let o = RealOptions {
        scenes,
        ..o.clone()
    };
    chart(&dir.join("real.svg"), &o, &rows)
}

fn write_csv(path: &Path, rows: &[Row]) -> Result<()> {
    let mut s = String::from(
        "scene,source,codec,rate,bytes,bytes_per_gaussian,psnr_db,ssim,encode_s,decode_s\n",
    );
    for r in rows {
        s.push_str(&format!(
            "{},{},{},{},{},{:.4},{:.3},{:.5},{:.3},{:.4}\n",
            r.scene,
            provenance(&r.scene),
            r.codec,
            r.rate.map(|x| x.to_string()).unwrap_or_default(),
            r.bytes,
            r.bytes_per_gaussian,
            r.psnr_db,
            r.ssim,
            r.encode_s,
            r.decode_s
        ));
    }
    std::fs::write(path, s).map_err(|e| io_err(path, e))
}

fn points(rows: &[Row], scene: &str, codec: &str) -> Vec<(f64, f64)> {
    rows.iter()
        .filter(|r| r.scene == scene && r.codec == codec)
        .map(|r| (r.bytes as f64, r.psnr_db))
        .collect()
}

fn summary(o: &RealOptions, rows: &[Row], groups: &str, multi: &str) -> String {
    let mut s = format!(
        "salvq bench real: render PSNR / SSIM against the input PLY from {} ring views at {}x{}\n\n",
        o.views, o.width, o.height
    );
    s.push_str("scene          source                                   codec            rate  B/Gaussian  PSNR dB   SSIM     encode s  decode s\n");
    for r in rows {
        s.push_str(&format!(
            "{:<14} {:<40} {:<16} {:>4}  {:>10.3}  {:>7.2}  {:.5}  {:>8.2}  {:>8.3}\n",
            r.scene,
            provenance(&r.scene),
            r.codec,
            r.rate.map(|x| x.to_string()).unwrap_or_default(),
            r.bytes_per_gaussian,
            r.psnr_db,
            r.ssim,
            r.encode_s,
            r.decode_s
        ));
    }
    s.push_str("\nsalvq's bytes at each peer's PSNR (interpolated between its rates), as a fraction of the peer's:\n");
    for scene in &o.scenes {
        let ours = points(rows, scene, "salvq");
        for r in rows
            .iter()
            .filter(|r| &r.scene == scene && r.rate.is_none())
        {
            let line = match bytes_at(&ours, r.psnr_db) {
                Some(b) => format!(
                    "{:.2}x ({:.3} vs {:.3} B/Gaussian)",
                    b / r.bytes as f64,
                    b / r.bytes as f64 * r.bytes_per_gaussian,
                    r.bytes_per_gaussian
                ),
                None => "outside salvq's rates".into(),
            };
            s.push_str(&format!(
                "  {scene} vs {} at {:.2} dB: {line}\n",
                r.codec, r.psnr_db
            ));
        }
    }
    if o.ablations {
        s.push_str("\nablations: bytes of each variant at the reference encoder's PSNRs, as a fraction of the reference's (interpolated):\n");
        for scene in &o.scenes {
            let ours = points(rows, scene, "salvq");
            for (name, _, _) in variants() {
                let theirs = points(rows, scene, name);
                let ratios: Vec<String> = ours
                    .iter()
                    .map(|&(b, db)| match bytes_at(&theirs, db) {
                        Some(t) => format!("{:.2}", t / b),
                        None => "-".into(),
                    })
                    .collect();
                s.push_str(&format!("  {scene:<12} {name:<40} {}\n", ratios.join(" ")));
            }
        }
    }
    s.push_str("\none multi-rate file against single-rate files:\n");
    s.push_str(multi);
    s.push_str("\nbits per Gaussian per attribute group:");
    s.push_str(groups);
    s
}

use super::charts::COLORS;

fn chart(path: &Path, o: &RealOptions, rows: &[Row]) -> Result<()> {
    draw(path, o, rows)
        .map_err(|e| Error::io(IoOp::Write, path, std::io::Error::other(e.to_string())))
}

fn draw(
    path: &Path,
    o: &RealOptions,
    rows: &[Row],
) -> std::result::Result<(), Box<dyn std::error::Error>> {
    let cols = o.scenes.len().clamp(1, 3);
    let lines = o.scenes.len().div_ceil(cols).max(1);
    let root = SVGBackend::new(path, (560 * cols as u32, 420 * lines as u32)).into_drawing_area();
    root.fill(&WHITE)?;
    let areas = root.split_evenly((lines, cols));
    for (scene, area) in o.scenes.iter().zip(areas) {
        let mine: Vec<&Row> = rows
            .iter()
            .filter(|r| &r.scene == scene && r.psnr_db.is_finite())
            .collect();
        if mine.is_empty() {
            continue;
        }
        let x = |r: &Row| r.bytes_per_gaussian.max(1e-3).log2();
        let (x0, x1) = mine
            .iter()
            .map(|r| x(r))
            .fold((f64::INFINITY, f64::NEG_INFINITY), |a, v| {
                (a.0.min(v), a.1.max(v))
            });
        let (y0, y1) = mine
            .iter()
            .map(|r| r.psnr_db)
            .fold((f64::INFINITY, f64::NEG_INFINITY), |a, v| {
                (a.0.min(v), a.1.max(v))
            });
        let mut c = ChartBuilder::on(&area)
            .caption(
                format!("{scene} ({})", provenance(scene)),
                ("sans-serif", 16),
            )
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(50)
            // Headroom above the points for the legend (upper left).
            .build_cartesian_2d(
                (x0 - 0.2)..(x1 + 0.2),
                (y0 - 1.0)..(y1 + 0.6 * (y1 - y0) + 1.0),
            )?;
        c.configure_mesh()
            .x_desc("bytes per Gaussian (log2)")
            .y_desc("render PSNR vs input (dB)")
            .x_label_formatter(&|v| format!("{:.1}", v.exp2()))
            .draw()?;
        let mut codecs: Vec<String> = Vec::new();
        for r in &mine {
            if !codecs.contains(&r.codec) {
                codecs.push(r.codec.clone());
            }
        }
        for (i, codec) in codecs.iter().enumerate() {
            let color = COLORS[i % COLORS.len()];
            let mut pts: Vec<(f64, f64)> = mine
                .iter()
                .filter(|r| &r.codec == codec)
                .map(|r| (x(r), r.psnr_db))
                .collect();
            pts.sort_by(|a, b| a.0.total_cmp(&b.0));
            if pts.len() > 1 {
                let width = if codec == "salvq" { 3 } else { 1 };
                c.draw_series(LineSeries::new(pts.clone(), color.stroke_width(width)))?
                    .label(codec.as_str())
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color));
                c.draw_series(pts.into_iter().map(|p| Circle::new(p, 3, color.filled())))?;
            } else {
                c.draw_series(
                    pts.into_iter()
                        .map(|p| TriangleMarker::new(p, 7, color.filled())),
                )?
                .label(codec.as_str())
                .legend(move |(x, y)| TriangleMarker::new((x + 10, y), 6, color.filled()));
            }
        }
        c.configure_series_labels()
            .border_style(BLACK)
            .background_style(WHITE.mix(0.9))
            .position(SeriesLabelPosition::UpperLeft)
            .label_font(("sans-serif", 11))
            .draw()?;
    }
    root.present()?;
    Ok(())
}
