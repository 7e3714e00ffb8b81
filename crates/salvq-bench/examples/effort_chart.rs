//! Encode time against bytes at equal render PSNR, per `--effort` level, beside
//! splat-transform's SPZ and SOG on the same scenes (Annex A.8.2). Each salvq encode is the
//! CLI a user runs (`salvq encode SCENE --effort E --json`), timed by itself: wall and CPU
//! seconds and peak memory to the written file, then each rate's render PSNR at the
//! yardstick (8 ring views at 512x384). A level's bytes are compared with the reference
//! level's (`best` where it ran, else `default`) at equal PSNR, averaged in log over the
//! PSNRs both reach (a Bjøntegaard-style rate difference); a peer's single file with the
//! reference's bytes at its PSNR. Writes `effort.csv`, `effort.txt`, `effort.svg`, and each
//! encode's progress lines (`SCENE.EFFORT.log`, stamped with seconds: where the time goes).
//!
//! ```sh
//! cargo build --release -p salvq-cli
//! cargo run --release -p salvq-bench --example effort_chart -- \
//!     --scenes ../shared/data/fruit_drops.ply,../shared/data/alti.ply \
//!     --efforts fast,default,best --splat-transform PATH --out docs/encode
//! ```
//! `--before PATH` adds another build's `salvq` at its default effort (level `before`);
//! `--best-up-to N` leaves `best` out on scenes of more than N Gaussians (100,000);
//! `--smoke` checks what it measures on one small scene (CI).
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use plotters::prelude::*;
use salvq_bench::peers::peer_encode;
use salvq_bench::real::{bytes_at, provenance};
use salvq_render::compare::RingTarget;
use salvq_render::Gaussians;

/// One salvq encode, or one peer file.
#[derive(Debug, Clone)]
struct Run {
    scene: String,
    gaussians: u64,
    /// `fast`, `default`, `best`, or the peer's format.
    codec: String,
    wall_s: f64,
    cpu_s: Option<f64>,
    peak_rss: Option<u64>,
    /// Per rate: (target dB, bytes to the rate, render PSNR dB).
    rates: Vec<(Option<f64>, u64, f64)>,
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let value = |name: &str| -> Option<String> {
        let at = args.iter().position(|a| a == name)?;
        args.get(at + 1).cloned()
    };
    let smoke = args.iter().any(|a| a == "--smoke");
    let list = |name: &str, default: &str| -> Vec<String> {
        value(name)
            .unwrap_or_else(|| default.into())
            .split(',')
            .filter(|s| !s.is_empty())
            .map(String::from)
            .collect()
    };
    let scenes = list("--scenes", "../shared/data/fruit_drops.ply");
    let efforts = list(
        "--efforts",
        if smoke { "fast" } else { "fast,default,best" },
    );
    let out = PathBuf::from(value("--out").unwrap_or_else(|| "target/effort".into()));
    let salvq = value("--salvq")
        .map(PathBuf::from)
        .unwrap_or_else(sibling_salvq);
    let peer = value("--splat-transform");
    // Another build's `salvq` (e.g. an earlier commit's) run at its default effort as the
    // level `before`.
    let before = value("--before").map(PathBuf::from);
    // `best` renders every trial of the whole scene: beyond this many Gaussians it is left out.
    let best_up_to: u64 = value("--best-up-to").map_or(Ok(100_000), |v| v.parse())?;
    std::fs::create_dir_all(&out)?;
    let scratch = tempfile::tempdir()?;
    let mut runs = Vec::new();
    for scene in &scenes {
        let path = Path::new(scene);
        let name = path.file_stem().and_then(|s| s.to_str()).unwrap_or("scene");
        let g = salvq_render::ply::read_ply(&std::fs::read(path)?)?;
        if let Some(old) = &before {
            eprintln!("{name}: the earlier build's salvq encode");
            runs.push(encode(
                old,
                path,
                name,
                "default",
                "before",
                scratch.path(),
                &out,
            )?);
        }
        for effort in &efforts {
            if effort == "best" && g.len() as u64 > best_up_to {
                eprintln!("{name}: --effort best left out above {best_up_to} Gaussians");
                continue;
            }
            eprintln!("{name}: salvq encode --effort {effort}");
            runs.push(encode(
                &salvq,
                path,
                name,
                effort,
                effort,
                scratch.path(),
                &out,
            )?);
        }
        if let Some(st) = &peer {
            runs.extend(peer_runs(st, name, path, &g, scratch.path())?);
        }
    }
    let text = table(&runs);
    std::fs::write(out.join("effort.txt"), &text)?;
    std::fs::write(out.join("effort.csv"), csv(&runs))?;
    chart(&out.join("effort.svg"), &runs)?;
    print!("{text}");
    if smoke {
        check_plausible(&runs)?;
    }
    Ok(())
}

/// splat-transform's SPZ and SOG files of `scene` (`g`, its Gaussians), each a run at the
/// quality yardstick (8 ring views at 512x384); a format it could not write is left out.
fn peer_runs(
    st: &str,
    name: &str,
    path: &Path,
    g: &Gaussians,
    work: &Path,
) -> Result<Vec<Run>, Box<dyn std::error::Error>> {
    let mut runs = Vec::new();
    let reference = RingTarget::new(g, 8, 512, 384)?;
    for format in ["spz", "sog"] {
        eprintln!("{name}: splat-transform {format}");
        if let Some(p) = peer_encode(st, name, path, format, work, &reference)? {
            runs.push(Run {
                scene: name.into(),
                gaussians: g.len() as u64,
                codec: format.into(),
                wall_s: p.encode_s,
                cpu_s: None,
                peak_rss: None,
                rates: vec![(None, p.bytes, p.psnr_db)],
            });
        }
    }
    Ok(runs)
}

/// The smoke run's check: every run took time and has rates, each with bytes and a PSNR over
/// 10 dB, their bytes not growing from one rate to the next.
fn check_plausible(runs: &[Run]) -> Result<(), Box<dyn std::error::Error>> {
    for r in runs {
        let ok = r.wall_s > 0.0
            && !r.rates.is_empty()
            && r.rates
                .iter()
                .all(|x| x.1 > 0 && x.2.is_finite() && x.2 > 10.0)
            && r.rates.windows(2).all(|w| w[0].1 >= w[1].1);
        if !ok {
            return Err(format!("smoke: implausible measurement {r:?}").into());
        }
    }
    eprintln!("smoke: {} runs measured and checked", runs.len());
    Ok(())
}

/// `target/release/salvq` beside this example's `target/release/examples/`.
fn sibling_salvq() -> PathBuf {
    let exe = std::env::current_exe().unwrap_or_default();
    let dir = exe
        .parent()
        .and_then(Path::parent)
        .unwrap_or(Path::new("."));
    dir.join("salvq")
}

/// One `salvq encode --effort EFFORT --json` of `scene`, its report read back, labelled.
fn encode(
    salvq: &Path,
    scene: &Path,
    name: &str,
    effort: &str,
    label: &str,
    work: &Path,
    out: &Path,
) -> Result<Run, Box<dyn std::error::Error>> {
    let output = work.join(format!("{name}.{label}.salvq"));
    let t = Instant::now();
    let run = Command::new(salvq)
        .arg("encode")
        .arg(scene)
        .args(["--effort", effort, "--json", "-f", "-o"])
        .arg(&output)
        .output()?;
    let wall = t.elapsed().as_secs_f64();
    // Its progress lines, each stamped with the seconds since it started: where time goes.
    std::fs::write(out.join(format!("{name}.{label}.log")), &run.stderr)?;
    if !run.status.success() {
        return Err(format!(
            "{} encode {} failed: {}",
            salvq.display(),
            scene.display(),
            String::from_utf8_lossy(&run.stderr)
        )
        .into());
    }
    let json: serde_json::Value = serde_json::from_slice(&run.stdout)?;
    // An earlier build's summary may count its measuring in `seconds`: its progress line
    // `[  733.1 s] writing ...` says when the stream was written.
    let written = String::from_utf8_lossy(&run.stderr)
        .lines()
        .filter(|l| l.contains("] writing "))
        .find_map(|l| {
            l.trim_start_matches('[')
                .split_whitespace()
                .next()?
                .parse::<f64>()
                .ok()
        });
    let num = |v: &serde_json::Value| v.as_f64();
    let rates = json["layers"]
        .as_array()
        .map(|layers| {
            layers
                .iter()
                .map(|l| {
                    (
                        num(&l["target_db"]),
                        num(&l["bytes"]).unwrap_or(0.0) as u64,
                        num(&l["psnr_db"]).unwrap_or(f64::NAN),
                    )
                })
                .collect()
        })
        .unwrap_or_default();
    Ok(Run {
        scene: name.into(),
        gaussians: num(&json["gaussians"]).unwrap_or(0.0) as u64,
        codec: label.into(),
        // The encode to the written file; the rest of `wall` measured the rates.
        wall_s: written.or(num(&json["seconds"])).unwrap_or(wall),
        cpu_s: num(&json["cpu_seconds"]),
        peak_rss: num(&json["peak_rss_bytes"]).map(|b| b as u64),
        rates,
    })
}

/// The level every other run of `scene` is compared with: `best` where it ran, else
/// `default`, else the first.
fn reference<'a>(runs: &'a [Run], scene: &str) -> Option<&'a Run> {
    let mine = || runs.iter().filter(move |r| r.scene == scene);
    ["best", "default"]
        .iter()
        .find_map(|c| mine().find(|r| r.codec == *c))
        .or_else(|| mine().next())
}

/// `run`'s bytes over the reference's at equal PSNR: the geometric mean over the PSNRs both
/// reach (every 0.1 dB), or at the peer's one PSNR; `None` when they share none.
fn relative_bytes(run: &Run, reference: &Run) -> Option<f64> {
    let points =
        |r: &Run| -> Vec<(f64, f64)> { r.rates.iter().map(|x| (x.1 as f64, x.2)).collect() };
    let (a, b) = (points(run), points(reference));
    if a.len() == 1 {
        return bytes_at(&b, a[0].1).map(|rb| a[0].0 / rb);
    }
    let range = |p: &[(f64, f64)]| {
        p.iter()
            .map(|x| x.1)
            .filter(|d| d.is_finite())
            .fold((f64::INFINITY, f64::NEG_INFINITY), |m, d| {
                (m.0.min(d), m.1.max(d))
            })
    };
    let ((a0, a1), (b0, b1)) = (range(&a), range(&b));
    let (lo, hi) = (a0.max(b0), a1.min(b1));
    let mut sum = (0.0, 0usize);
    let mut db = lo;
    while db <= hi {
        if let (Some(x), Some(y)) = (bytes_at(&a, db), bytes_at(&b, db)) {
            sum = (sum.0 + (x / y).ln(), sum.1 + 1);
        }
        db += 0.1;
    }
    (sum.1 > 0).then(|| (sum.0 / sum.1 as f64).exp())
}

fn table(runs: &[Run]) -> String {
    let mut t = String::from(
        "scene (source), Gaussians | codec | encode wall s | CPU s | peak MB | whole file B | \
         finest PSNR dB (target) | rates > 0.25 dB under target | bytes vs reference at equal PSNR\n",
    );
    for r in runs {
        let finest = r.rates.first();
        let missed = r
            .rates
            .iter()
            .filter(|x| x.0.is_some_and(|t| x.2 < t - 0.25))
            .count();
        let rel = reference(runs, &r.scene)
            .and_then(|base| relative_bytes(r, base))
            .map_or("-".into(), |x| format!("{x:.3}"));
        t.push_str(&format!(
            "{} ({}), {} | {} | {:.1} | {} | {} | {} | {} | {} | {rel}\n",
            r.scene,
            provenance(&r.scene),
            r.gaussians,
            r.codec,
            r.wall_s,
            r.cpu_s.map_or("-".into(), |c| format!("{c:.1}")),
            r.peak_rss
                .map_or("-".into(), |b| format!("{:.0}", b as f64 / 1e6)),
            finest.map_or(0, |x| x.1),
            finest.map_or("-".into(), |x| match x.0 {
                Some(target) => format!("{:.2} ({target})", x.2),
                None => format!("{:.2}", x.2),
            }),
            if r.rates.len() > 1 {
                missed.to_string()
            } else {
                "-".into()
            },
        ));
    }
    t
}

fn csv(runs: &[Run]) -> String {
    let mut t =
        String::from("scene,gaussians,codec,wall_s,cpu_s,peak_rss,target_db,bytes,psnr_db\n");
    for r in runs {
        for x in &r.rates {
            t.push_str(&format!(
                "{},{},{},{:.3},{},{},{},{},{:.3}\n",
                r.scene,
                r.gaussians,
                r.codec,
                r.wall_s,
                r.cpu_s.map_or(String::new(), |c| format!("{c:.3}")),
                r.peak_rss.map_or(String::new(), |b| b.to_string()),
                x.0.map_or(String::new(), |d| d.to_string()),
                x.1,
                x.2
            ));
        }
    }
    t
}

/// Encode seconds (log) against bytes relative to the reference at equal PSNR, one mark
/// per scene and codec.
fn chart(path: &Path, runs: &[Run]) -> Result<(), Box<dyn std::error::Error>> {
    let points: Vec<(&Run, f64)> = runs
        .iter()
        .filter_map(|r| Some((r, relative_bytes(r, reference(runs, &r.scene)?)?)))
        .collect();
    let root = SVGBackend::new(path, (760, 480)).into_drawing_area();
    root.fill(&WHITE)?;
    let (t0, t1) = points.iter().fold((f64::INFINITY, 0f64), |m, p| {
        (m.0.min(p.0.wall_s), m.1.max(p.0.wall_s))
    });
    let (y0, y1) = points
        .iter()
        .fold((f64::INFINITY, 0f64), |m, p| (m.0.min(p.1), m.1.max(p.1)));
    let mut c = ChartBuilder::on(&root)
        .caption(
            "encode time against bytes at equal render PSNR (1 = the reference level)",
            ("sans-serif", 16),
        )
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(56)
        .build_cartesian_2d(
            ((t0.max(0.01) * 0.7)..(t1.max(0.02) * 1.4)).log_scale(),
            ((y0.max(0.01) * 0.9)..(y1.max(0.02) * 1.1)).log_scale(),
        )?;
    c.configure_mesh()
        .x_desc("encode wall seconds (2 cores)")
        .y_desc("bytes / reference's bytes")
        .draw()?;
    let colour = |codec: &str| match codec {
        "fast" => RGBColor(0, 120, 200),
        "before" => RGBColor(120, 120, 120),
        "default" => RGBColor(0, 160, 80),
        "best" => RGBColor(120, 0, 160),
        "spz" => RGBColor(220, 100, 0),
        _ => RGBColor(200, 0, 60),
    };
    for (r, y) in &points {
        let col = colour(&r.codec);
        c.draw_series(std::iter::once(Circle::new(
            (r.wall_s, *y),
            5,
            col.filled(),
        )))?;
        c.draw_series(std::iter::once(Text::new(
            format!("{} {}", r.scene, r.codec),
            (r.wall_s, *y),
            ("sans-serif", 11).into_font().color(&col),
        )))?;
    }
    root.present()?;
    Ok(())
}
