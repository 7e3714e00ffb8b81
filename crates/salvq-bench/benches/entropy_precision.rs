//! Precision / truncation trade-off of the entropy coder (spec §6.5).
//!
//! `cargo bench --bench entropy_precision` measures, for table precisions P and tail widths
//! TAIL, the decode speed of `SymbolReader` and the rate overhead against the exact
//! discretized Gaussian at each symbol's true σ, on 2^20 symbols with σ log-uniform in
//! [0.2, 8] (seeded). It prints a table and writes `target/charts/entropy_precision.svg`
//! (x = rate overhead %, y = decode ns/symbol, one labelled point per configuration), plus
//! the bare `constriction` decode speed with one static model on the same symbols.
//!
//! Environment: `SALVQ_BENCH_SYMBOLS` (default 2^20), `SALVQ_BENCH_RUNS` (default 9).
//!
//! Checks what it measures (a failure panics, so the bench exits non-zero): every
//! configuration decodes the symbols it encoded; each body holds its tables' information plus
//! the 32 … 64 bits of ANS state; from 10⁴ symbols on, no rate overhead against the exact
//! model is negative; the bare coder decodes the symbols it was given. Smoke mode (CI, under a
//! second): `SALVQ_BENCH_SYMBOLS=100000 SALVQ_BENCH_RUNS=1 cargo bench --bench entropy_precision`.

use std::hint::black_box;
use std::path::PathBuf;
use std::time::Instant;

use plotters::prelude::*;
use salvq_bench::coder::{bare_coder_decode_ns, median, sigma_to_q16, synthetic_samples, Sample};
use salvq_bitstream::container::chunk::ChunkTag;
use salvq_bitstream::entropy::{
    scale_index, GaussianTables, SymbolReader, PRECISION, R_MAX, SIGMA_Q16, TAIL_Q4,
};
use salvq_encoder::entropy_analysis::discretized_gaussian_bits;
use salvq_encoder::writers::SymbolWriter;

const PRECISIONS: [u32; 5] = [12, 14, 16, 20, 24];
/// TAIL in 1/16 units: 3, 4, 5, 6.
const TAILS_Q4: [u32; 4] = [48, 64, 80, 96];
const SEED: u64 = 2026;

struct Row {
    precision: u32,
    tail_q4: u32,
    r_max: u32,
    build_ms: f64,
    encode_ns: f64,
    decode_ns: f64,
    overhead_pct: f64,
    table_pct: f64,
    escapes: usize,
    /// The body's bits and Σ ideal_bits under the configuration's own tables.
    coded_bits: f64,
    ideal_bits: f64,
}

fn env_usize(name: &str, default: usize) -> usize {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// The measurement set: samples, their scale indices and their information content.
struct Workload {
    samples: Vec<Sample>,
    ks: Vec<u8>,
    /// Σ −log2 p at each sample's true σ.
    bits_true: f64,
    /// Σ −log2 p at each sample's grid σ_k.
    bits_grid: f64,
}

fn measure(work: &Workload, precision: u32, tail_q4: u32, r_max: u32, runs: usize) -> Row {
    let (samples, ks) = (&work.samples, &work.ks);
    let t0 = Instant::now();
    let tables = GaussianTables::with_tail(precision, tail_q4, r_max);
    let build_ms = t0.elapsed().as_secs_f64() * 1e3;
    let tag = ChunkTag::AFEA;

    let mut encode_times = Vec::new();
    let mut body = Vec::new();
    for _ in 0..runs.clamp(1, 3) {
        let t = Instant::now();
        let mut w = SymbolWriter::new(tag, &tables);
        for (s, &k) in samples.iter().zip(ks) {
            w.symbol(s.u, k).expect("bench symbols are small");
        }
        body = w.finish();
        encode_times.push(t.elapsed().as_nanos() as f64 / samples.len() as f64);
    }

    let mut decode_times = Vec::new();
    for _ in 0..runs {
        let t = Instant::now();
        let mut r = SymbolReader::new(tag, black_box(&body), &tables).expect("valid body");
        let mut check = 0i64;
        for &k in ks {
            check = check.wrapping_add(r.symbol(k).expect("valid body"));
        }
        r.finish().expect("valid body");
        decode_times.push(t.elapsed().as_nanos() as f64 / samples.len() as f64);
        black_box(check);
    }
    // What was timed is a decode: one more, untimed, gives back every symbol written.
    let mut r = SymbolReader::new(tag, &body, &tables).expect("valid body");
    for (i, (s, &k)) in samples.iter().zip(ks).enumerate() {
        let got = r.symbol(k).expect("valid body");
        assert_eq!(
            got,
            s.u,
            "P {precision}, TAIL {}, R_MAX {r_max}: symbol {i} decodes as {got}, encoded {}",
            tail_label(tail_q4),
            s.u
        );
    }
    r.finish().expect("valid body");

    let ideal: f64 = samples
        .iter()
        .zip(ks)
        .map(|(s, &k)| tables.ideal_bits(k, s.u))
        .sum();
    let escapes = samples
        .iter()
        .zip(ks)
        .filter(|(s, &k)| s.u.unsigned_abs() > u64::from(tables.radius(k)))
        .count();
    Row {
        precision,
        tail_q4,
        r_max,
        build_ms,
        encode_ns: median(&mut encode_times),
        decode_ns: median(&mut decode_times),
        overhead_pct: 100.0 * ((body.len() * 8) as f64 / work.bits_true - 1.0),
        table_pct: 100.0 * (ideal / work.bits_grid - 1.0),
        escapes,
        coded_bits: (body.len() * 8) as f64,
        ideal_bits: ideal,
    }
}

fn tail_label(tail_q4: u32) -> String {
    if tail_q4.is_multiple_of(16) {
        format!("{}", tail_q4 / 16)
    } else {
        format!("{:.2}", f64::from(tail_q4) / 16.0)
    }
}

fn chart(rows: &[Row], bare_ns: f64, path: &PathBuf) -> Result<(), Box<dyn std::error::Error>> {
    let x_max = rows.iter().map(|r| r.overhead_pct).fold(0.0, f64::max) * 1.15;
    let y_max = rows.iter().map(|r| r.decode_ns).fold(bare_ns, f64::max) * 1.25;
    let y_min = rows.iter().map(|r| r.decode_ns).fold(bare_ns, f64::min) * 0.8;
    let root = SVGBackend::new(path, (900, 600)).into_drawing_area();
    root.fill(&WHITE)?;
    let mut c = ChartBuilder::on(&root)
        .caption(
            "SALVQ entropy coder: rate overhead vs decode speed (σ_u log-uniform in [0.2, 8])",
            ("sans-serif", 18),
        )
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0..x_max, y_min..y_max)?;
    c.configure_mesh()
        .x_desc("rate overhead vs exact discretized Gaussian at true σ (%)")
        .y_desc("decode ns / symbol (median)")
        .draw()?;
    c.draw_series(std::iter::once(PathElement::new(
        vec![(0.0, bare_ns), (x_max, bare_ns)],
        BLACK.mix(0.5),
    )))?
    .label(format!(
        "bare constriction decoder, one static model: {bare_ns:.2} ns"
    ))
    .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK.mix(0.5)));
    let colors = [RED, BLUE, GREEN, MAGENTA, CYAN];
    for (pi, &p) in PRECISIONS.iter().enumerate() {
        let color = colors[pi % colors.len()];
        let pts: Vec<&Row> = rows.iter().filter(|r| r.precision == p).collect();
        c.draw_series(pts.iter().map(|r| {
            EmptyElement::at((r.overhead_pct, r.decode_ns))
                + Circle::new((0, 0), 4, color.filled())
                + Text::new(
                    format!("P{} T{}", r.precision, tail_label(r.tail_q4)),
                    // Stacked by precision: configurations of equal rate stay readable.
                    (6, -30 + 11 * pi as i32),
                    ("sans-serif", 11).into_font(),
                )
        }))?
        .label(format!("P = {p}"))
        .legend(move |(x, y)| Circle::new((x + 10, y), 4, color.filled()));
    }
    c.configure_series_labels()
        .border_style(BLACK)
        .background_style(WHITE.mix(0.9))
        .position(SeriesLabelPosition::UpperRight)
        .draw()?;
    root.present()?;
    Ok(())
}

/// Rate-only overhead of a table configuration (no coding), in percent: Σ ideal_bits over
/// Σ −log2 p, p the infinite-alphabet discretized Gaussian at the coded σ_k, or with
/// `against_true` at the sample's true σ.
fn table_overhead_pct(
    tables: &GaussianTables,
    samples: &[Sample],
    ks: &[u8],
    against_true: bool,
) -> (f64, usize) {
    let mut ideal = 0.0;
    let mut model = 0.0;
    let mut escapes = 0;
    for (s, &k) in samples.iter().zip(ks) {
        ideal += tables.ideal_bits(k, s.u);
        let sigma = if against_true {
            s.sigma
        } else {
            f64::from(SIGMA_Q16[usize::from(k)]) / 65536.0
        };
        model += discretized_gaussian_bits(s.u, sigma);
        escapes += usize::from(s.u.unsigned_abs() > u64::from(tables.radius(k)));
    }
    (100.0 * (ideal / model - 1.0), escapes)
}

/// Part 2 of the benchmark: rate-only scenarios that decide TAIL and R_MAX beyond the typical
/// σ range: large σ (the top of the grid) and a scale under-predicted by a factor.
fn rate_scenarios(n: usize) {
    let large = synthetic_samples(n, SEED + 1, 8.0, 29.3);
    let large_ks: Vec<u8> = large
        .iter()
        .map(|s| scale_index(sigma_to_q16(s.sigma)))
        .collect();
    let typical = synthetic_samples(n, SEED + 2, 0.2, 8.0);
    let mis_ks = |factor: f64| -> Vec<u8> {
        typical
            .iter()
            .map(|s| scale_index(sigma_to_q16(s.sigma / factor)))
            .collect()
    };
    let mis15 = mis_ks(1.5);
    let mis2 = mis_ks(2.0);
    println!();
    println!("rate-only scenarios, R_MAX = 1023: overhead % (escapes per 10^6 symbols)");
    println!("- σ_u in [8, 29.3]: table overhead, Σ ideal_bits / Σ −log2 p(σ_k) − 1;");
    println!("- σ_u in [0.2, 8] coded with σ_u / 1.5 or σ_u / 2 (scale under-predicted): Σ ideal_bits / Σ −log2 p(true σ) − 1.");
    println!("| P | TAIL | σ_u in [8, 29.3] | coded with σ_u / 1.5 | coded with σ_u / 2 |");
    println!("|---|---|---|---|---|");
    let per_million = |e: usize| e as f64 * 1e6 / n as f64;
    for &p in &PRECISIONS {
        for &t in &TAILS_Q4 {
            let tables = GaussianTables::with_tail(p, t, 1023);
            let (a, ea) = table_overhead_pct(&tables, &large, &large_ks, false);
            let (b, eb) = table_overhead_pct(&tables, &typical, &mis15, true);
            let (c, ec) = table_overhead_pct(&tables, &typical, &mis2, true);
            println!(
                "| {p} | {} | {a:.4} ({:.0}) | {b:.4} ({:.0}) | {c:.4} ({:.0}) |",
                tail_label(t),
                per_million(ea),
                per_million(eb),
                per_million(ec)
            );
        }
    }
    println!();
    println!("R_MAX at P = {PRECISION}, TAIL = {}: table overhead % for σ_u in [8, 29.3] (escapes per 10^6)", tail_label(TAIL_Q4));
    println!("| R_MAX | overhead % | escapes |");
    println!("|---|---|---|");
    for r_max in [64, 96, 127, 160, 1023] {
        let tables = GaussianTables::with_tail(PRECISION, TAIL_Q4, r_max);
        let (a, ea) = table_overhead_pct(&tables, &large, &large_ks, false);
        println!("| {r_max} | {a:.4} | {:.0} |", per_million(ea));
    }
}

/// Checks the rates measured (every configuration has already decoded its symbols back, in
/// [`measure`]); panics on a failure.
///
/// - The coder spends its own model's information and the ANS state: it starts from 2^32 and
///   flushes a state in [2^32, 2^64) as two 32-bit words (§6.2.2, §6.2.5), so the body holds
///   Σ ideal_bits + 32 … 64 bits, give or take the ANS rounding (a 10⁻⁴ share is allowed).
/// - No configuration codes below the exact discretized Gaussian at the true σ (Gibbs'
///   inequality; it holds in expectation, so it is checked from 10⁴ symbols on, where the
///   fixed seed's margin is over 0.04 %).
fn check_rates(rows: &[Row], work: &Workload, n: usize) {
    for r in rows {
        let label = format!(
            "P {}, TAIL {}, R_MAX {}",
            r.precision,
            tail_label(r.tail_q4),
            r.r_max
        );
        let slack = 1e-4 * r.ideal_bits;
        let state = r.coded_bits - r.ideal_bits;
        assert!(
            (32.0 - slack..=64.0 + slack).contains(&state),
            "{label}: {} coded bits for {:.1} bits of the tables' information: {state:.1} more, \
             not the 32 … 64 bits of the ANS state",
            r.coded_bits,
            r.ideal_bits
        );
        assert!(
            n < 10_000 || r.coded_bits >= work.bits_true,
            "{label}: {} coded bits, below the exact model's {:.1} (rate overhead {:.4} %)",
            r.coded_bits,
            work.bits_true,
            r.overhead_pct
        );
    }
    println!(
        "checked: {} configurations decode their {n} symbols; each body = the tables' \
         information + 32 … 64 bits of ANS state{}",
        rows.len(),
        if n < 10_000 {
            ""
        } else {
            "; rate overhead against the exact model >= 0"
        }
    );
}

/// The bench's symbols: `n` samples with σ_u log-uniform in [0.2, 8] (seed [`SEED`]), their
/// scale indices, and their information at the true σ and at the scale grid's σ_k.
fn workload(n: usize) -> Workload {
    let samples = synthetic_samples(n, SEED, 0.2, 8.0);
    let ks: Vec<u8> = samples
        .iter()
        .map(|s| scale_index(sigma_to_q16(s.sigma)))
        .collect();
    let bits_true: f64 = samples
        .iter()
        .map(|s| discretized_gaussian_bits(s.u, s.sigma))
        .sum();
    let bits_grid: f64 = samples
        .iter()
        .zip(&ks)
        .map(|(s, &k)| {
            discretized_gaussian_bits(s.u, f64::from(SIGMA_Q16[usize::from(k)]) / 65536.0)
        })
        .sum();
    Workload {
        samples,
        ks,
        bits_true,
        bits_grid,
    }
}

/// The table of every configuration's times and overheads; `bare`: the bare coder's
/// nanoseconds per symbol at each precision.
fn print_table(rows: &[Row], bare: &[(u32, f64)]) {
    println!();
    println!("| P | TAIL | R_MAX | build ms | encode ns/sym | decode ns/sym | decode / bare | rate overhead % | table overhead % | escapes |");
    println!("|---|---|---|---|---|---|---|---|---|---|");
    for r in rows {
        let bare_p = bare
            .iter()
            .find(|(p, _)| *p == r.precision)
            .map_or(f64::NAN, |b| b.1);
        println!(
            "| {} | {} | {} | {:.1} | {:.2} | {:.2} | {:.2} | {:.4} | {:.4} | {} |",
            r.precision,
            tail_label(r.tail_q4),
            r.r_max,
            r.build_ms,
            r.encode_ns,
            r.decode_ns,
            r.decode_ns / bare_p,
            r.overhead_pct,
            r.table_pct,
            r.escapes
        );
    }
    println!();
    println!("rate overhead = coded bits / Σ −log2 p_true − 1 (p_true: exact f64 discretized Gaussian at the true σ);");
    println!("table overhead = Σ ideal_bits / Σ −log2 p(σ_k) − 1 (frequency quantization, tails and escapes alone).");
}

fn main() {
    let n = env_usize("SALVQ_BENCH_SYMBOLS", 1 << 20);
    let runs = env_usize("SALVQ_BENCH_RUNS", 9);
    let work = workload(n);
    let scale_pct = 100.0 * (work.bits_grid / work.bits_true - 1.0);

    println!("entropy_precision: {n} symbols, σ_u log-uniform in [0.2, 8], seed {SEED}, {runs} runs (median)");
    println!(
        "information content at the true σ: {:.4} bits/symbol; at the scale grid's σ_k: {:.4} (scale-index quantization alone: +{scale_pct:.4} %)",
        work.bits_true / n as f64,
        work.bits_grid / n as f64
    );

    let symbols: Vec<i64> = work.samples.iter().map(|s| s.u).collect();
    let mut bare = Vec::new();
    for &p in &PRECISIONS {
        bare.push((p, bare_coder_decode_ns(&symbols, p, runs)));
    }
    for (p, ns) in &bare {
        println!(
            "bare constriction decode, one static categorical model, P = {p}: {ns:.2} ns/symbol"
        );
    }
    let bare_std = bare
        .iter()
        .find(|(p, _)| *p == PRECISION)
        .map_or(f64::NAN, |b| b.1);

    let mut rows = Vec::new();
    for &p in &PRECISIONS {
        for &t in &TAILS_Q4 {
            rows.push(measure(&work, p, t, 1023, runs));
        }
    }
    // The chosen configuration with its R_MAX.
    rows.push(measure(&work, PRECISION, TAIL_Q4, R_MAX, runs));
    check_rates(&rows, &work, n);

    print_table(&rows, &bare);

    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join("target")
        .join("charts");
    let path = dir.join("entropy_precision.svg");
    let chart_rows: Vec<Row> = rows.into_iter().filter(|r| r.r_max == 1023).collect();
    rate_scenarios(n);

    match std::fs::create_dir_all(&dir)
        .map_err(|e| e.into())
        .and_then(|()| chart(&chart_rows, bare_std, &path))
    {
        Ok(()) => println!("chart: {}", path.display()),
        Err(e) => eprintln!("chart not written: {e}"),
    }
}
