//! In-process decode time of stream files, for comparing two builds in turn: each
//! file decoded `--runs` times per round by `salvq::Decoder::builder().threads(n)`, for each
//! thread count, rounds interleaving the files and thread counts; prints each round's median
//! and minimum, then the median over the rounds of both. Checks what it measures: every decode
//! equals the first, bit for bit.
//!
//! Run: `cargo bench --bench decode_time -- FILE... [--threads 1,2] [--runs 7] [--rounds 5]
//! [--gaussians-only]` (the last: explicit streams decoded as a viewer does, without keeping
//! the symbols).
//! To compare two commits on a noisy machine, build this bench at each
//! (`cargo bench --bench decode_time --no-run` prints the binary's path) and run the two
//! binaries in turn, several times; compare their per-round medians as ratios. With no FILE
//! (CI's smoke mode), a generated explicit-profile stream of 20 000 Gaussians and a generated
//! anchors stream of 2 000 anchors, one round of 2 runs.

use std::time::Instant;

use salvq::Scene;
use salvq_conformance::explicit_vectors::encode_synthetic;
use salvq_encoder::explicit::{ExplicitOptions, RatePlan};
use salvq_encoder::{encode_full, EncodeOptions};
use salvq_gen::gaussians::GaussianParams;
use salvq_gen::{generate, GenParams};

struct Args {
    files: Vec<String>,
    threads: Vec<usize>,
    runs: usize,
    rounds: usize,
    gaussians_only: bool,
}

fn parse_args() -> Args {
    let mut args = Args {
        files: Vec::new(),
        threads: vec![1, 2],
        runs: 7,
        rounds: 5,
        gaussians_only: false,
    };
    let mut it = std::env::args().skip(1);
    while let Some(a) = it.next() {
        let mut value = |name: &str| it.next().unwrap_or_else(|| panic!("{name} needs a value"));
        match a.as_str() {
            "--threads" => {
                args.threads = value("--threads")
                    .split(',')
                    .map(|t| t.parse().expect("--threads: numbers, comma-separated"))
                    .collect()
            }
            "--runs" => args.runs = value("--runs").parse().expect("--runs: a number"),
            "--rounds" => args.rounds = value("--rounds").parse().expect("--rounds: a number"),
            "--gaussians-only" => args.gaussians_only = true,
            // `cargo bench` passes `--bench` to every bench binary.
            "--bench" => {}
            f => args.files.push(f.to_string()),
        }
    }
    assert!(
        args.runs > 0 && args.rounds > 0,
        "--runs and --rounds: at least 1"
    );
    args
}

/// Generated streams of both profiles, small (CI's smoke mode).
fn generated() -> Vec<(String, Vec<u8>)> {
    let plan = RatePlan {
        voxel: 0.02,
        refine: [3, 2, 1, 0],
        steps: vec![0.05, 0.2, 0.02, 0.02, 0.03],
        shift: vec![[1, 0, 0, -1]; 4],
    };
    let explicit = encode_synthetic(
        &GaussianParams::new(20_000, 1, 5),
        vec![plan],
        ExplicitOptions::default(),
    )
    .expect("encodes");
    let model = generate(&GenParams {
        feat_basis: false,
        ..GenParams::new(2_000, 1)
    });
    let anchors = encode_full(&model, &EncodeOptions::default()).expect("encodes");
    vec![
        ("generated explicit 20000".into(), explicit.stream),
        ("generated anchors 2000".into(), anchors.stream),
    ]
}

fn median(mut t: Vec<f64>) -> f64 {
    t.sort_by(f64::total_cmp);
    t[t.len() / 2]
}

fn main() {
    let args = parse_args();
    let (streams, runs, rounds) = if args.files.is_empty() {
        (generated(), 2, 1)
    } else {
        let read = |f: &String| (f.clone(), std::fs::read(f).expect("a readable stream file"));
        (
            args.files.iter().map(read).collect(),
            args.runs,
            args.rounds,
        )
    };
    // Per (file, thread count): each round's median and minimum, in seconds.
    let mut rows: Vec<(String, usize, Vec<f64>, Vec<f64>)> = Vec::new();
    let mut first: Vec<Option<Scene>> = vec![None; streams.len()];
    for round in 0..rounds {
        let mut row = 0;
        for (s, (name, bytes)) in streams.iter().enumerate() {
            for &threads in &args.threads {
                let mut builder = salvq::Decoder::builder().threads(threads);
                if args.gaussians_only {
                    builder = builder.gaussians_only(true);
                }
                let decoder = builder.build();
                let mut times = Vec::with_capacity(runs);
                for _ in 0..runs {
                    let t = Instant::now();
                    let decoded = decoder.decode(bytes).expect("a valid stream");
                    times.push(t.elapsed().as_secs_f64());
                    match &first[s] {
                        Some(reference) => assert!(
                            *reference == decoded,
                            "{name}: a decode on {threads} threads differs from the first"
                        ),
                        None => first[s] = Some(decoded),
                    }
                }
                let min = times.iter().copied().fold(f64::INFINITY, f64::min);
                let med = median(times);
                println!(
                    "round {round} {name} {threads} threads: median {:.2} ms, min {:.2} ms",
                    med * 1e3,
                    min * 1e3
                );
                if round == 0 {
                    rows.push((name.clone(), threads, Vec::new(), Vec::new()));
                }
                rows[row].2.push(med);
                rows[row].3.push(min);
                row += 1;
            }
        }
    }
    println!("\n{runs} decodes per round, {rounds} rounds:");
    for (name, threads, medians, mins) in rows {
        println!(
            "{name}, {threads} threads: median of round medians {:.2} ms, median of round minimums {:.2} ms",
            median(medians) * 1e3,
            median(mins) * 1e3
        );
    }
    println!(
        "checked: every decode of each stream equals its first ({} streams)",
        streams.len()
    );
}
