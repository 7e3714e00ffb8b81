//! Two ANS states decoded in turn against one (not a format feature).
//!
//! `cargo bench --bench ans_interleave` asks how much of the symbol decode is the latency of
//! one ANS state's chain (each symbol's state depends on the one before): the same symbols
//! are coded once as one body (as every body of format 0.12 is) and once as two bodies, the
//! even symbols in one and the odd ones in the other, and decoded with the format's own
//! `SymbolReader` and tables (§6.2, §6.4: escapes included): one reader, or two read in turn
//! in one loop, so that the processor can overlap the two chains. A ratio well below 1 would
//! be what a format with interleaved states could gain in its symbol decode.
//!
//! The symbols are `entropy_precision`'s set: 2^20 values with σ log-uniform in [0.2, 8]
//! (seeded), coded under their scale indices at the format's precision.
//!
//! Environment: `SALVQ_BENCH_SYMBOLS` (default 2^20), `SALVQ_BENCH_RUNS` (default 15 rounds;
//! each round times both decodes, in alternating order).
//!
//! Checks what it measures (a failure panics): both decodes give back every symbol written and
//! end their bodies exactly (`SymbolReader::finish`). Smoke mode (CI, under a second):
//! `SALVQ_BENCH_SYMBOLS=100000 SALVQ_BENCH_RUNS=1 cargo bench --bench ans_interleave`.

use std::hint::black_box;
use std::time::Instant;

use salvq_bench::coder::{median, sigma_to_q16, synthetic_samples};
use salvq_bitstream::container::chunk::ChunkTag;
use salvq_bitstream::entropy::{scale_index, GaussianTables, SymbolReader};
use salvq_encoder::writers::SymbolWriter;

const SEED: u64 = 2026;
const TAG: ChunkTag = ChunkTag::AFEA;

fn env_usize(name: &str, default: usize) -> usize {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// One body holding `symbols` with their scale indices, in order.
fn encode<'a>(
    tables: &GaussianTables,
    symbols: impl Iterator<Item = (&'a i64, &'a u8)>,
) -> Vec<u8> {
    let mut w = SymbolWriter::new(TAG, tables);
    for (&u, &k) in symbols {
        w.symbol(u, k).expect("bench symbols are small");
    }
    w.finish()
}

/// Decodes `ks.len()` symbols from one body into `out`.
fn decode_one(tables: &GaussianTables, body: &[u8], ks: &[u8], out: &mut [i64]) {
    let mut r = SymbolReader::new(TAG, body, tables).expect("valid body");
    for (o, &k) in out.iter_mut().zip(ks) {
        *o = r.symbol(k).expect("valid body");
    }
    r.finish().expect("the body ends with its last symbol");
}

/// Decodes the even symbols from `even` and the odd ones from `odd`, in turn, into `out`.
fn decode_two(tables: &GaussianTables, even: &[u8], odd: &[u8], ks: &[u8], out: &mut [i64]) {
    let mut a = SymbolReader::new(TAG, even, tables).expect("valid body");
    let mut b = SymbolReader::new(TAG, odd, tables).expect("valid body");
    let mut pairs = out.chunks_exact_mut(2);
    let mut k_pairs = ks.chunks_exact(2);
    for (o, k) in (&mut pairs).zip(&mut k_pairs) {
        o[0] = a.symbol(k[0]).expect("valid body");
        o[1] = b.symbol(k[1]).expect("valid body");
    }
    if let (Some(o), Some(&k)) = (
        pairs.into_remainder().first_mut(),
        k_pairs.remainder().first(),
    ) {
        *o = a.symbol(k).expect("valid body");
    }
    a.finish().expect("the body ends with its last symbol");
    b.finish().expect("the body ends with its last symbol");
}

fn main() {
    let n = env_usize("SALVQ_BENCH_SYMBOLS", 1 << 20).max(2);
    let rounds = env_usize("SALVQ_BENCH_RUNS", 15).max(1);
    let tables = GaussianTables::standard();
    let samples = synthetic_samples(n, SEED, 0.2, 8.0);
    let us: Vec<i64> = samples.iter().map(|s| s.u).collect();
    let ks: Vec<u8> = samples
        .iter()
        .map(|s| scale_index(sigma_to_q16(s.sigma)))
        .collect();

    let one = encode(tables, us.iter().zip(&ks));
    let even = encode(tables, us.iter().zip(&ks).step_by(2));
    let odd = encode(tables, us.iter().zip(&ks).skip(1).step_by(2));

    // What is timed is a decode: each gives back the symbols written.
    let mut out = vec![0i64; n];
    decode_one(tables, &one, &ks, &mut out);
    assert_eq!(
        out, us,
        "one body: the decoded symbols differ from those encoded"
    );
    out.fill(0);
    decode_two(tables, &even, &odd, &ks, &mut out);
    assert_eq!(
        out, us,
        "two bodies: the decoded symbols differ from those encoded"
    );

    let (mut t_one, mut t_two, mut ratios) = (Vec::new(), Vec::new(), Vec::new());
    for round in 0..rounds {
        let mut time = |two: bool| {
            let t = Instant::now();
            if two {
                decode_two(tables, black_box(&even), &odd, &ks, &mut out);
            } else {
                decode_one(tables, black_box(&one), &ks, &mut out);
            }
            black_box(&out);
            t.elapsed().as_secs_f64() * 1e9 / n as f64
        };
        // Alternate which goes first, so that a slow moment of the machine hits both alike.
        let (a, b) = if round % 2 == 0 {
            let a = time(false);
            (a, time(true))
        } else {
            let b = time(true);
            (time(false), b)
        };
        t_one.push(a);
        t_two.push(b);
        ratios.push(b / a);
    }
    println!(
        "{n} symbols (σ log-uniform in [0.2, 8]), {rounds} rounds: one state {:.2} ns/symbol, \
         two states in turn {:.2} ns/symbol; per-round ratio two / one: median {:.3} (min {:.3}, \
         max {:.3})",
        median(&mut t_one),
        median(&mut t_two),
        median(&mut ratios.clone()),
        ratios.iter().copied().fold(f64::INFINITY, f64::min),
        ratios.iter().copied().fold(0.0, f64::max),
    );
    println!(
        "bytes: one body {}, two bodies {} + {} (+{} bytes: the second state and word padding)",
        one.len(),
        even.len(),
        odd.len(),
        (even.len() + odd.len()) as i64 - one.len() as i64
    );
    println!("checked: both decodes give back the {n} symbols encoded and end their bodies");
}
