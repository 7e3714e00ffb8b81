//! The decoder allocates no more than its preflight allows (spec §9.1): peak heap
//! during a decode, counted by a capping global allocator, against
//! `salvq_conformance::fuzzing::allocation_bound` — the same bound the fuzz targets enforce. Each decode
//! runs in a child process of this test so its peak is its own.
//!
//! Quiet when it passes (one summary line); the table of every decode's peak comes with a
//! failure, or always with `SALVQ_TEST_VERBOSE=1`.

use std::alloc::System;
use std::path::PathBuf;
use std::process::Command;

use cap::Cap;

#[global_allocator]
static ALLOCATOR: Cap<System> = Cap::new(System, usize::MAX);

const CHILD: &str = "SALVQ_ALLOCATION_CHILD";

/// Child: decode one stream at one rate; print `peak decoded stream`.
fn child(spec: &str) {
    let (path, rate) = spec.rsplit_once(':').expect("PATH:RATE");
    let stream = std::fs::read(path).expect("stream");
    let options = salvq::Decoder::builder()
        .rate(Some(rate.parse().expect("rate")))
        .threads(2);
    let before = ALLOCATOR.allocated();
    let decoded = options.build().decode(&stream).expect("valid vector");
    let peak = ALLOCATOR.max_allocated() - before;
    let decoded = match decoded {
        salvq::Scene::Anchors(model) => salvq_bitstream::model::decoded_bytes(&model.dims),
        salvq::Scene::Gaussians(d) => d.header.decoded_bytes(),
    };
    println!("{peak} {decoded} {}", stream.len());
}

fn main() {
    if let Ok(spec) = std::env::var(CHILD) {
        child(&spec);
        return;
    }
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let dir = root.join("conformance/vectors");
    let manifest = salvq_conformance::runner::read_manifest(&dir).expect("manifest");
    let exe = std::env::current_exe().expect("test binary");
    let mut worst: f64 = 0.0;
    let mut failures = Vec::new();
    let mut table = Vec::new();
    for v in &manifest.vectors {
        // Whole decodes only: a region decode allocates less, and a must-fail vector lists
        // region decodes only (spec §11.7).
        for e in v.decodes.iter().filter(|e| e.region.is_none()) {
            let out = Command::new(&exe)
                .env(CHILD, format!("{}:{}", dir.join(&v.file).display(), e.rate))
                .output()
                .expect("child runs");
            let text = String::from_utf8_lossy(&out.stdout);
            let nums: Vec<u64> = text
                .split_whitespace()
                .filter_map(|s| s.parse().ok())
                .collect();
            let [peak, decoded, len] = nums[..] else {
                failures.push(format!(
                    "{}: child failed: {}",
                    v.name,
                    String::from_utf8_lossy(&out.stderr)
                ));
                continue;
            };
            let bound = salvq_conformance::fuzzing::allocation_bound(decoded, len);
            let ratio = peak as f64 / (decoded + len) as f64;
            worst = worst.max(ratio);
            table.push(format!(
                "{:<22} rate {:>2}: peak heap {:>9} B, decoded {:>9} B, stream {:>7} B, peak/(decoded+stream) {:.2}",
                v.name, e.rate, peak, decoded, len, ratio
            ));
            if peak > bound {
                failures.push(format!("{}: peak {peak} above the bound {bound}", v.name));
            }
        }
    }
    let verbose = std::env::var_os("SALVQ_TEST_VERBOSE").is_some_and(|v| v == "1");
    if verbose || !failures.is_empty() {
        println!("{}", table.join("\n"));
    }
    println!(
        "allocation_bound: {} decodes, largest peak/(decoded+stream) {worst:.2}{}",
        table.len(),
        if failures.is_empty() {
            ", all within the bound"
        } else {
            ""
        }
    );
    if !failures.is_empty() {
        eprintln!("{}", failures.join("\n"));
        std::process::exit(1);
    }
}
