//! The decode_speed bench's outputs: the text tables, the CSV and the chart.

use std::path::Path;

use plotters::prelude::*;

use super::{Args, Res, Row, GOAL_GAUSSIANS_PER_S};

/// The text tables; `wake`: [`super::wake_latencies`], seconds.
pub(crate) fn report(a: &Args, rows: &[Row], wake: (f64, Option<f64>)) -> String {
    let mut t = speed_table(a, rows, wake);
    let explicit: Vec<&Row> = rows.iter().filter(|r| r.profile == "explicit").collect();
    t += &explicit_goal(&explicit);
    t += &wasm_lines(rows);
    t += &wasm_worker_lines(rows);
    t += &command_table(&explicit);
    t
}

/// The header (rounds, CPUs, pool wake-up latencies) and the table of decode times, one row a
/// scene.
fn speed_table(a: &Args, rows: &[Row], wake: (f64, Option<f64>)) -> String {
    let mut t = format!(
        "decode speed, medians of {} rounds (interleaved), {} logical CPUs{}\n",
        a.rounds,
        std::thread::available_parallelism().map_or(0, usize::from),
        if a.smoke { ", smoke" } else { "" }
    );
    t += &format!(
        "a sleeping pool thread started a job handed over by a busy one after {:.3} ms (pool unpinned), {} (pinned one per CPU)\n\n",
        wake.0 * 1e3,
        wake.1.map_or("-".into(), |p| format!("{:.3} ms", p * 1e3))
    );
    t += "| profile | scene | size | tiles | symbols | bytes | 1 thread s | 2 threads s | 2 threads again s | 2 threads pinned s | size/s 1T | size/s 2T | size/s 2T again | size/s 2T pinned | 2T/1T | bare coder s (untimed symbols) | receive 50 Mbit/s s | decode 2T / receive |\n|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n";
    let pinned = |r: &Row, f: fn(&Row, f64) -> String| r.two_pinned.map_or("-".into(), |p| f(r, p));
    for r in rows {
        t += &format!(
            "| {} | {} | {} | {} | {} | {} | {:.4} | {:.4} | {:.4} | {} | {:.3e} | {:.3e} | {:.3e} | {} | {:.2} | {} | {:.4} | {:.3} |\n",
            r.profile,
            r.scene,
            r.size,
            r.tiles,
            r.symbols,
            r.bytes,
            r.one,
            r.two,
            r.two_again,
            pinned(r, |_, p| format!("{p:.4}")),
            r.size as f64 / r.one,
            r.size as f64 / r.two,
            r.size as f64 / r.two_again,
            pinned(r, |r, p| format!("{:.3e}", r.size as f64 / p)),
            r.two_over_one,
            r.floor
                .map_or("-".into(), |f| format!("{f:.4} ({})", r.floor_outside)),
            r.receive(),
            r.two / r.receive()
        );
    }
    t
}

/// The explicit profile's scenes against the goal of [`GOAL_GAUSSIANS_PER_S`] on 2 threads;
/// empty without an explicit scene.
fn explicit_goal(explicit: &[&Row]) -> String {
    let mut t = String::new();
    if !explicit.is_empty() {
        t += "\nexplicit profile: goal >= 2 M Gaussians/s on 2 threads (after 50 ms idle; again: the same decoder at once, its threads awake; pinned: a pool whose threads are pinned one per CPU, after 50 ms idle as the first)\n";
        let verdict = |rate: f64| {
            if rate >= GOAL_GAUSSIANS_PER_S {
                "met"
            } else {
                "NOT met"
            }
        };
        for r in explicit {
            let (rate, again) = (r.size as f64 / r.two, r.size as f64 / r.two_again);
            let pinned = r.two_pinned.map_or("-".into(), |p| {
                let rate = r.size as f64 / p;
                format!("{:.2} M: {}", rate * 1e-6, verdict(rate))
            });
            t += &format!(
                "  {}: {:.2} M Gaussians/s on 2 threads ({:.2} M on 1): {}; again {:.2} M: {}; pinned {pinned}\n",
                r.scene,
                rate * 1e-6,
                r.size as f64 / r.one * 1e-6,
                verdict(rate),
                again * 1e-6,
                verdict(again)
            );
        }
    }
    t
}

/// The WebAssembly decode (one thread in Node) against the native one; empty without a wasm run.
fn wasm_lines(rows: &[Row]) -> String {
    let mut t = String::new();
    if rows.iter().any(|r| r.wasm.is_some()) {
        t += "\nWebAssembly (salvq-wasm `decode` in Node's V8, one thread, WebAssembly SIMD; median of the runs after the first)\n";
        for r in rows {
            if let Some((w, first)) = r.wasm {
                t += &format!(
                    "  {} {}: wasm {:.1} ms = {:.3e} per s (first run {:.1} ms), native 1 thread {:.1} ms{}: wasm/native {:.2}\n",
                    r.profile,
                    r.scene,
                    w * 1e3,
                    r.size as f64 / w,
                    first * 1e3,
                    r.wasm_native * 1e3,
                    if r.profile == "anchors" {
                        " (decode + neural Gaussians of ring camera 0, as the wasm call does)"
                    } else {
                        ""
                    },
                    w / r.wasm_native
                );
            }
        }
    }
    t
}

/// The WebAssembly decode split over Node worker threads (spec §10.3.2); empty without one.
fn wasm_worker_lines(rows: &[Row]) -> String {
    let mut t = String::new();
    if rows.iter().any(|r| r.wasm_workers.is_some()) {
        t += "\nWebAssembly in Node worker threads (salvq-wasm `decodePart`, spec §10.3.2: each worker its part of the tiles; from sending the bytes to the last part's arrays on the main thread)\n";
        for r in rows {
            if let Some([w1, w2]) = r.wasm_workers {
                t += &format!(
                    "  {} {}: 1 worker {:.1} ms, 2 workers {:.1} ms = {:.3e} per s: 2 workers / 1 {:.2}, 2 workers / {} {:.2}\n",
                    r.profile,
                    r.scene,
                    w1 * 1e3,
                    w2 * 1e3,
                    r.size as f64 / w2,
                    w2 / w1,
                    if r.profile == "anchors" {
                        "wasm decode (with neural Gaussians) on the main thread"
                    } else {
                        "native 2 threads"
                    },
                    w2 / if r.profile == "anchors" {
                        r.wasm.map_or(f64::NAN, |w| w.0)
                    } else {
                        r.two
                    }
                );
            }
        }
    }
    t
}

/// The whole-process table: `salvq decode` and splat-transform's conversions, wall clock;
/// empty without a timed command.
fn command_table(explicit: &[&Row]) -> String {
    let mut t = String::new();
    if explicit.iter().any(|r| r.command.is_some()) {
        t += "\nwhole process (wall clock, output written; splat-transform runs in Node, its startup included)\n";
        t += "| scene | salvq decode -o out.ply | splat-transform SPZ -> PLY | SOG -> PLY | SPZ -> null | SOG -> null | splat-transform --version |\n|---|---:|---:|---:|---:|---:|---:|\n";
        for r in explicit {
            let p = |i: usize| r.peers.map_or("-".into(), |p| format!("{:.3} s", p[i]));
            t += &format!(
                "| {} | {:.3} s | {} | {} | {} | {} | {} |\n",
                r.scene,
                r.command.unwrap_or(f64::NAN),
                p(0),
                p(1),
                p(2),
                p(3),
                p(4)
            );
        }
    }
    t
}

pub(crate) fn csv(rows: &[Row]) -> String {
    let mut s = String::from(
        "profile,scene,size,tiles,symbols,bytes,decode_1t_s,decode_2t_s,decode_2t_again_s,decode_2t_pinned_s,two_over_one,bare_coder_s,bare_coder_untimed_symbols,receive_50mbit_s,wasm_s,wasm_first_s,wasm_native_s,wasm_1_worker_s,wasm_2_workers_s,command_s,st_spz_ply_s,st_sog_ply_s,st_spz_null_s,st_sog_null_s,st_version_s\n",
    );
    let o = |v: Option<f64>| v.map_or(String::new(), |x| format!("{x:.6}"));
    for r in rows {
        let p = |i: usize| o(r.peers.map(|p| p[i]));
        s += &format!(
            "{},{},{},{},{},{},{:.6},{:.6},{:.6},{},{:.4},{},{},{:.6},{},{},{:.6},{},{},{},{},{},{},{},{}\n",
            r.profile,
            r.scene,
            r.size,
            r.tiles,
            r.symbols,
            r.bytes,
            r.one,
            r.two,
            r.two_again,
            o(r.two_pinned),
            r.two_over_one,
            o(r.floor),
            r.floor_outside,
            r.receive(),
            o(r.wasm.map(|w| w.0)),
            o(r.wasm.map(|w| w.1)),
            r.wasm_native,
            o(r.wasm_workers.map(|w| w[0])),
            o(r.wasm_workers.map(|w| w[1])),
            o(r.command),
            p(0),
            p(1),
            p(2),
            p(3),
            p(4)
        );
    }
    s
}

/// A chart series: label, colour, dashed, profile, and the value it plots.
type Series = (
    &'static str,
    RGBColor,
    bool,
    &'static str,
    fn(&Row) -> Option<f64>,
);

/// The explicit profile's series: native on 1 and 2 threads, wasm, and the bare coder and
/// network floors.
fn explicit_series() -> [Series; 7] {
    [
        (
            "explicit, native, 1 thread",
            RGBColor(0, 114, 178),
            false,
            "explicit",
            |r| Some(r.one),
        ),
        (
            "explicit, native, 2 threads",
            RGBColor(86, 180, 233),
            false,
            "explicit",
            |r| Some(r.two),
        ),
        (
            "explicit, native, 2 threads pinned one per CPU",
            RGBColor(86, 180, 233),
            true,
            "explicit",
            |r| r.two_pinned,
        ),
        (
            "explicit, wasm (Node V8, 1 thread)",
            RGBColor(0, 158, 115),
            false,
            "explicit",
            |r| r.wasm.map(|w| w.0),
        ),
        (
            "explicit, wasm (Node V8, 2 workers, decodePart)",
            RGBColor(0, 158, 115),
            true,
            "explicit",
            |r| r.wasm_workers.map(|w| w[1]),
        ),
        (
            "explicit, bare ANS coder on its lattice coordinates",
            RGBColor(0, 114, 178),
            true,
            "explicit",
            |r| r.floor,
        ),
        (
            "explicit, receive at 50 Mbit/s",
            RGBColor(120, 120, 120),
            true,
            "explicit",
            |r| Some(r.receive()),
        ),
    ]
}

/// The anchors profile's series: native on 1 and 2 threads, wasm (with the neural Gaussians
/// the wasm call computes), and the bare coder and network floors.
fn anchors_series() -> [Series; 8] {
    [
        (
            "anchors, native, 1 thread",
            RGBColor(213, 94, 0),
            false,
            "anchors",
            |r| Some(r.one),
        ),
        (
            "anchors, native, 2 threads",
            RGBColor(230, 159, 0),
            false,
            "anchors",
            |r| Some(r.two),
        ),
        (
            "anchors, native, 2 threads pinned one per CPU",
            RGBColor(230, 159, 0),
            true,
            "anchors",
            |r| r.two_pinned,
        ),
        (
            "anchors, wasm (decode + neural Gaussians, camera 0)",
            RGBColor(204, 121, 167),
            false,
            "anchors",
            |r| r.wasm.map(|w| w.0),
        ),
        (
            "anchors, wasm (2 workers, decodePart)",
            RGBColor(148, 103, 189),
            true,
            "anchors",
            |r| r.wasm_workers.map(|w| w[1]),
        ),
        (
            "anchors, native, 1 thread, decode + neural Gaussians (as the wasm call)",
            RGBColor(204, 121, 167),
            true,
            "anchors",
            |r| r.wasm.map(|_| r.wasm_native),
        ),
        (
            "anchors, bare ANS coder on its symbols",
            RGBColor(213, 94, 0),
            true,
            "anchors",
            |r| r.floor,
        ),
        (
            "anchors, receive at 50 Mbit/s",
            RGBColor(0, 0, 0),
            true,
            "anchors",
            |r| Some(r.receive()),
        ),
    ]
}

/// The chart: decode time against scene size, log-log, every series of both profiles.
pub(crate) fn chart(path: &Path, rows: &[Row], wasm: bool) -> Res<()> {
    let series: Vec<Series> = explicit_series()
        .into_iter()
        .chain(anchors_series())
        .collect();
    let points = |s: &Series| -> Vec<(f64, f64)> {
        let mut v: Vec<(f64, f64)> = rows
            .iter()
            .filter(|r| r.profile == s.3)
            .filter_map(|r| s.4(r).map(|y| (r.size as f64, y)))
            .collect();
        v.sort_by(|a, b| a.0.total_cmp(&b.0));
        v
    };
    let all: Vec<(f64, f64)> = series.iter().flat_map(points).collect();
    let ((x0, x1), (y0, y1)) = axis_ranges(&all);
    let root = SVGBackend::new(path, (1000, 700)).into_drawing_area();
    root.fill(&WHITE)?;
    let caption = if wasm {
        "Decode time vs scene size (log-log): both profiles, native and wasm"
    } else {
        "Decode time vs scene size (log-log): both profiles, native (wasm not measured in this run)"
    };
    let mut c = ChartBuilder::on(&root)
        .caption(caption, ("sans-serif", 18))
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(65)
        .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())?;
    c.configure_mesh()
        .x_desc("scene size: Gaussians (explicit, real scenes) or anchors (anchors, generated)")
        .y_desc("seconds (median)")
        .x_label_formatter(&|x| format!("{x:.0}"))
        .draw()?;
    for s in &series {
        let xy = points(s);
        if xy.is_empty() {
            continue;
        }
        let color = s.1;
        let style = color.stroke_width(2);
        if s.2 {
            c.draw_series(dashes(&xy, style))?
                .label(s.0)
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 8, y)], color));
        } else {
            c.draw_series(LineSeries::new(xy.clone(), style))?
                .label(s.0)
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color));
        }
        c.draw_series(xy.iter().map(|&p| Circle::new(p, 3, color.filled())))?;
    }
    // The real scenes' names under their 1-thread points.
    c.draw_series(rows.iter().filter(|r| r.profile == "explicit").map(|r| {
        Text::new(
            r.scene.clone(),
            (r.size as f64, r.one * 0.8),
            ("sans-serif", 12).into_font().color(&RGBColor(0, 114, 178)),
        )
    }))?;
    c.configure_series_labels()
        .border_style(BLACK)
        .background_style(WHITE.mix(0.9))
        .position(SeriesLabelPosition::UpperLeft)
        .draw()?;
    root.present()?;
    Ok(())
}

/// The chart's x and y ranges around every point `all`: margins on the log scale, and
/// headroom above the data for the legend (upper left).
fn axis_ranges(all: &[(f64, f64)]) -> ((f64, f64), (f64, f64)) {
    let fold = |f: fn(f64, f64) -> f64, init: f64, sel: fn(&(f64, f64)) -> f64| {
        all.iter().map(sel).fold(init, f)
    };
    let x = (
        fold(f64::min, f64::INFINITY, |p| p.0) * 0.7,
        fold(f64::max, 1.0, |p| p.0) * 1.4,
    );
    let y = (
        fold(f64::min, f64::INFINITY, |p| p.1).max(1e-6) * 0.6,
        fold(f64::max, 1e-5, |p| p.1) * 15.0,
    );
    (x, y)
}

/// A dashed line through `xy`: short segments along each stretch, evenly spaced on the
/// log-log axes.
fn dashes(xy: &[(f64, f64)], style: ShapeStyle) -> Vec<PathElement<(f64, f64)>> {
    let mut dashes = Vec::new();
    for w in xy.windows(2) {
        let (a, b) = (w[0], w[1]);
        for i in 0..12 {
            let (t0, t1) = (i as f64 / 12.0, (i as f64 + 0.5) / 12.0);
            let lerp = |t: f64| {
                (
                    (a.0.ln() + t * (b.0.ln() - a.0.ln())).exp(),
                    (a.1.ln() + t * (b.1.ln() - a.1.ln())).exp(),
                )
            };
            dashes.push(PathElement::new(vec![lerp(t0), lerp(t1)], style));
        }
    }
    dashes
}
