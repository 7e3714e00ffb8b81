//! `salvq bench scale`: decode time and peak memory against scene size, with 1 and 2
//! threads, and a region decode of an eighth of the scene's volume (spec §10). Each decode runs in a child
//! process (`salvq decode --measure`) so that its peak resident memory is its own.

use std::path::Path;
use std::process::Command;

use plotters::prelude::*;

use salvq_bitstream::model::SceneModel;
use salvq_encoder::{encode_full, EncodeOptions};
use salvq_encoder::{Error, Result};
use salvq_gen::{generate, GenParams};
use salvq_render::error::IoOp;

/// Scene sizes measured (up to the `max` asked for).
pub const SIZES: [u32; 8] = [
    1_000, 3_000, 10_000, 30_000, 100_000, 300_000, 1_000_000, 2_000_000,
];

/// Decodes per configuration; the median time and the largest peak memory are kept.
const RUNS: usize = 3;

/// The process's peak resident set size (`VmHWM` of `/proc/self/status`), where the system
/// reports it.
pub fn peak_rss_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// CPU time (user and system, all threads) the process has used so far, in seconds, from
/// `/proc/self/stat` (in the kernel's `USER_HZ` of 100 ticks a second), where the system
/// reports it.
pub fn cpu_seconds() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // Fields after the command name (which may hold spaces) in parentheses.
    let rest = &stat[stat.rfind(')')? + 2..];
    let fields: Vec<&str> = rest.split_whitespace().collect();
    let ticks = |k: usize| fields.get(k)?.parse::<u64>().ok();
    Some((ticks(11)? + ticks(12)?) as f64 / 100.0)
}

/// One child decode's report.
#[derive(Debug, Clone, Copy, Default)]
struct Measured {
    secs: f64,
    peak_rss: u64,
    anchors: u64,
    decoded_bytes: u64,
}

fn io_err(path: &Path, e: std::io::Error) -> Error {
    Error::io(IoOp::Write, path, e)
}

/// Runs `salvq decode STREAM --measure` with `args`, `RUNS` times.
fn decode_child(stream: &Path, args: &[String]) -> Result<Measured> {
    let exe = std::env::current_exe().map_err(|e| io_err(stream, e))?;
    let mut runs = Vec::with_capacity(RUNS);
    for _ in 0..RUNS {
        let out = Command::new(&exe)
            .arg("decode")
            .arg(stream)
            .args(["-o", "unused.safetensors", "--measure"])
            .args(args)
            .output()
            .map_err(|e| io_err(&exe, e))?;
        let text = String::from_utf8_lossy(&out.stdout);
        if std::env::var_os("SALVQ_DEBUG").is_some() {
            eprintln!(
                "{:?} {text} {}",
                out.status,
                String::from_utf8_lossy(&out.stderr)
            );
        }
        let line = text
            .lines()
            .find(|l| l.starts_with("measure "))
            .ok_or_else(|| {
                let why = "no 'measure' line in the decoder's output";
                Error::io(
                    IoOp::Read,
                    &exe,
                    std::io::Error::new(std::io::ErrorKind::InvalidData, why),
                )
            })?;
        let field = |name: &str| -> f64 {
            line.split_whitespace()
                .find_map(|kv| kv.strip_prefix(name)?.strip_prefix('='))
                .and_then(|v| v.parse().ok())
                .unwrap_or(f64::NAN)
        };
        runs.push(Measured {
            secs: field("decode_secs"),
            peak_rss: field("peak_rss_bytes") as u64,
            anchors: field("anchors") as u64,
            decoded_bytes: field("decoded_bytes") as u64,
        });
    }
    runs.sort_by(|a, b| a.secs.total_cmp(&b.secs));
    let mut m = runs[RUNS / 2];
    m.peak_rss = runs.iter().map(|r| r.peak_rss).max().unwrap_or(0);
    Ok(m)
}

/// Least-squares slope of `ln y` on `ln x`.
fn log_slope(points: &[(f64, f64)]) -> f64 {
    let n = points.len() as f64;
    let (sx, sy) = points
        .iter()
        .fold((0.0, 0.0), |(a, b), (x, y)| (a + x.ln(), b + y.ln()));
    let (mx, my) = (sx / n, sy / n);
    let (num, den) = points.iter().fold((0.0, 0.0), |(a, b), (x, y)| {
        (a + (x.ln() - mx) * (y.ln() - my), b + (x.ln() - mx).powi(2))
    });
    num / den
}

/// One scene's measurements.
struct Row {
    anchors: u32,
    /// Anchors whose voxel centre lies in the region box.
    in_region: u64,
    stream_bytes: u64,
    one: Measured,
    two: Measured,
    region: Measured,
}

/// Runs the measurements and writes `scale.svg`, `scale.csv`, `scale.txt` under `out`.
pub fn run(out: &Path, max: u32) -> Result<String> {
    std::fs::create_dir_all(out).map_err(|e| io_err(out, e))?;
    let dir = tempfile::tempdir().map_err(|e| io_err(out, e))?;
    let mut rows = Vec::new();
    for &n in SIZES.iter().filter(|&&n| n <= max) {
        rows.push(measure_size(dir.path(), n)?);
    }
    let csv = csv(&rows);
    let text = text(&rows);
    super::charts::write_report(out, "scale", |p| chart(p, &rows), &csv, &text)?;
    Ok(text)
}

/// One scene of `n` anchors: generated, encoded into `dir`, and decoded in child processes
/// on 1 and 2 threads and over the region of [`region_box`].
fn measure_size(dir: &Path, n: u32) -> Result<Row> {
    let m = generate(&GenParams {
        feat_basis: false,
        ..GenParams::new(n, 1)
    });
    let e = encode_full(&m, &EncodeOptions::default())?;
    let path = dir.join(format!("s{n}.salvq"));
    std::fs::write(&path, &e.stream).map_err(|err| io_err(&path, err))?;
    let (region, inside) = region_box(&m);
    let t = |k: u32| vec!["--threads".to_string(), k.to_string()];
    let mut region_args = t(1);
    region_args.push("--region".to_string());
    region_args.push(region);
    Ok(Row {
        in_region: inside as u64,
        anchors: n,
        stream_bytes: e.stream.len() as u64,
        one: decode_child(&path, &t(1))?,
        two: decode_child(&path, &t(2))?,
        region: decode_child(&path, &region_args)?,
    })
}

/// An eighth of the scene by volume: the lower half, on every axis, of the box of all
/// anchors, as `--region`'s six comma-separated bounds; and how many anchors' voxel centres
/// lie in it.
fn region_box(m: &SceneModel) -> (String, usize) {
    let (o, vs) = (m.origin.map(f64::from), f64::from(m.voxel_size));
    let (mut lo, mut hi) = ([u32::MAX; 3], [0u32; 3]);
    for v in &m.anchors.voxel {
        for a in 0..3 {
            lo[a] = lo[a].min(v[a]);
            hi[a] = hi[a].max(v[a]);
        }
    }
    let mid = [0, 1, 2].map(|a| (f64::from(lo[a]) + f64::from(hi[a]) + 1.0) / 2.0);
    let inside = m
        .anchors
        .voxel
        .iter()
        .filter(|v| (0..3).all(|a| f64::from(v[a]) + 0.5 < mid[a]))
        .count();
    let region: Vec<String> = (0..6)
        .map(|c| {
            let a = c % 3;
            if c < 3 {
                format!("{}", o[a] + f64::from(lo[a]) * vs)
            } else {
                format!("{}", o[a] + mid[a] * vs - 1e-9 * vs)
            }
        })
        .collect();
    (region.join(","), inside)
}

/// `scale.csv`: a line per scene size.
fn csv(rows: &[Row]) -> String {
    let mut csv = String::from(
        "anchors,stream_bytes,decoded_bytes,secs_1t,secs_2t,peak_rss_1t,peak_rss_2t,region_anchors,region_secs_1t\n",
    );
    for r in rows {
        csv.push_str(&format!(
            "{},{},{},{:.6},{:.6},{},{},{},{:.6}\n",
            r.anchors,
            r.stream_bytes,
            r.one.decoded_bytes,
            r.one.secs,
            r.two.secs,
            r.one.peak_rss,
            r.two.peak_rss,
            r.region.anchors,
            r.region.secs
        ));
    }
    csv
}

/// `scale.txt`: the table, and the log-log slopes of time and memory against size from
/// 10 000 anchors on.
fn text(rows: &[Row]) -> String {
    let mut text = String::from(
        "Decode time and peak memory vs scene size (GenParams::new(N, 1), USQ, rate 0, tiles of 16384; \
         each decode a child process, median of 3):\n\n\
         anchors     µs/anchor 1t  µs/anchor 2t  speedup  peak/decoded 1t  2t    region: in box, decoded, time/full\n",
    );
    for r in rows {
        let per = |m: &Measured| m.secs * 1e6 / f64::from(r.anchors);
        text.push_str(&format!(
            "{:>9}   {:>10.3}  {:>12.3}  {:>7.2}  {:>15.2}  {:>5.2}   {:>5.1} %  {:>5.1} %  {:>6.2}\n",
            r.anchors,
            per(&r.one),
            per(&r.two),
            r.one.secs / r.two.secs,
            r.one.peak_rss as f64 / r.one.decoded_bytes as f64,
            r.two.peak_rss as f64 / r.two.decoded_bytes as f64,
            100.0 * r.in_region as f64 / f64::from(r.anchors),
            100.0 * r.region.anchors as f64 / f64::from(r.anchors),
            r.region.secs / r.one.secs
        ));
    }
    let fit: Vec<&Row> = rows.iter().filter(|r| r.anchors >= 10_000).collect();
    if fit.len() >= 2 {
        let s1 = log_slope(
            &fit.iter()
                .map(|r| (f64::from(r.anchors), r.one.secs))
                .collect::<Vec<_>>(),
        );
        let s2 = log_slope(
            &fit.iter()
                .map(|r| (f64::from(r.anchors), r.two.secs))
                .collect::<Vec<_>>(),
        );
        let sm = log_slope(
            &fit.iter()
                .map(|r| (f64::from(r.anchors), r.one.peak_rss as f64))
                .collect::<Vec<_>>(),
        );
        text.push_str(&format!(
            "\nlog-log slope of decode time, {} … {} anchors: {s1:.3} (1 thread), {s2:.3} (2 threads); of peak memory: {sm:.3}\n",
            fit[0].anchors,
            fit[fit.len() - 1].anchors
        ));
    }
    text
}

/// A chart line: label, colour, and the value it plots.
type Series = (&'static str, RGBColor, fn(&Row) -> f64);

fn chart(path: &Path, rows: &[Row]) -> std::result::Result<(), Box<dyn std::error::Error>> {
    let root = SVGBackend::new(path, (900, 600)).into_drawing_area();
    root.fill(&WHITE)?;
    let xs = super::charts::anchors_range(
        rows.first().map(|r| r.anchors),
        rows.last().map(|r| r.anchors),
    );
    let ys = rows
        .iter()
        .flat_map(|r| [r.one.secs, r.two.secs, r.region.secs]);
    let y0 = ys.clone().fold(f64::INFINITY, f64::min).max(1e-5) * 0.7;
    let y1 = ys.fold(0.0, f64::max) * 1.5;
    let mut c = ChartBuilder::on(&root)
        .caption(
            "Decode time vs scene size (log-log), 1 and 2 threads, and a region of 1/8 of the volume",
            ("sans-serif", 18),
        )
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(60)
        .build_cartesian_2d(xs.log_scale(), (y0..y1).log_scale())?;
    c.configure_mesh()
        .x_desc("anchors")
        .y_desc("decode time (s, median of 3)")
        .draw()?;
    let series: [Series; 3] = [
        ("1 thread", RGBColor(0, 114, 178), |r| r.one.secs),
        ("2 threads", RGBColor(213, 94, 0), |r| r.two.secs),
        (
            "region (box of the first N/8 anchors), 1 thread",
            RGBColor(0, 158, 115),
            |r| r.region.secs,
        ),
    ];
    for (label, color, get) in series {
        let xy: Vec<(f64, f64)> = rows
            .iter()
            .map(|r| (f64::from(r.anchors), get(r)))
            .collect();
        super::charts::labelled_line(&mut c, label, color, xy).map_err(|e| e.to_string())?;
    }
    super::charts::finish(c, &root, SeriesLabelPosition::UpperLeft).map_err(|e| e.to_string())?;
    Ok(())
}
