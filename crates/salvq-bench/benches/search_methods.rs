//! Encoder lattice search methods on generated scenes: encode time vs accuracy of the feature
//! group, per lattice and per [`Search`] method. Run:
//! `cargo bench --bench search_methods [-- N]` (N anchors, default 5 000).
//!
//! Scenes: `GenParams::new(N, 1)` (HAC-size model, F = 50, learned feature basis
//! `B = U diag(s) Vᵀ`, condition number 2..5) for the learned basis and the identity, and the
//! same with `feat_dim = 48` for the E8 product E8⁶ (six 8-d blocks, replacing the model's
//! basis) and its identity row. Every configuration codes rate 0 with
//! [`encode_full`]; the encoder's own report gives the feature group's numbers:
//! - `µs/anchor`: median wall time of 3 encodes over N (the whole encoder: integer prior,
//!   every group's search, entropy coding, statistics; rayon over all cores), after one
//!   untimed warm-up encode; the rounds are interleaved across a scene's configurations;
//! - `MSE`: `squared_error / symbols` of the feature group (per feature value, in feature
//!   units);
//! - `bits/anc`: the feature chunk's `coded_bytes · 8 / N`, and `ideal` the ideal bits
//!   under the integer model (`ideal_bits_integer / N`);
//! - `t/round`: encode time relative to Babai rounding on the same lattice and scene, and
//!   `Δt µs/anc` the difference, which isolates the search cost (note the encoder runs the
//!   feature search twice per anchor: once for the coded symbols and once more for the
//!   float-model statistics);
//! - `MSE/ref`, `bits/ref`: relative to the reference search of the lattice: for E8 `Auto`
//!   (the exact Conway–Sloane decoder); for the learned basis the Schnorr–Euchner search with
//!   the largest node bound, which at n = 50 is a bound-limited search, not a proof of
//!   optimality. The identity rows use their own rounding (exact for Zⁿ) as reference.
//!
//! The quality columns are deterministic (each configuration's four reports are checked to
//! be identical); times depend on the machine and its load, so compare ratios.
//! `SALVQ_BENCH_RUNS` sets the timed encodes per configuration (default 3).
//!
//! Checks what it measures (a failure panics, so the bench exits non-zero): every
//! configuration's stream decodes to the encoder's prediction (`salvq::decode` = `expected()`);
//! the identity rows' features lie within half a step of their reconstructions (rounding);
//! for E8, `closest` reports exactly what `auto` does and no E8 search has a smaller feature
//! MSE than that exact decoder. Smoke mode (CI, about 10 s):
//! `SALVQ_BENCH_RUNS=1 cargo bench --bench search_methods -- 300`.

use std::time::Instant;

use salvq_bitstream::model::{LatticeKind, SceneModel};
use salvq_encoder::{encode_full, EncodeOptions, GroupStats, Search};
use salvq_gen::{generate, GenParams};

/// Timed encodes per configuration (`SALVQ_BENCH_RUNS` changes it).
const RUNS: usize = 3;

/// One configuration's measurement.
struct Row {
    label: &'static str,
    secs: f64,
    feat: GroupStats,
}

/// Encodes `model` with each configuration: one untimed warm-up round, then `runs` timed
/// rounds, each encoding every configuration once (interleaved, so a change in machine load
/// hits every configuration alike); a row's time is the median of its `runs` encodes.
/// Checks (panics on a failure) that each warm-up stream decodes to the encoder's prediction
/// and that every timed encode reports what the warm-up did.
fn measure(
    model: &SceneModel,
    configs: &[(LatticeKind, Search, &'static str)],
    runs: usize,
) -> Vec<Row> {
    let encode = |&(kind, search, label): &(LatticeKind, Search, &'static str)| {
        let options = EncodeOptions {
            feat_lattice: Some(kind),
            search,
            ..EncodeOptions::default()
        };
        let s = Instant::now();
        let e = encode_full(model, &options).expect("encodes");
        let secs = s.elapsed().as_secs_f64();
        let g = e.report().groups[0].clone();
        assert_eq!(g.group, "feature", "{label}");
        (secs, g, e)
    };
    let feats: Vec<GroupStats> = configs
        .iter()
        .map(|c| {
            let (_, g, e) = encode(c);
            let decoded = salvq::decode(&e.stream)
                .and_then(salvq::Scene::try_into_anchors)
                .expect("the stream decodes");
            assert!(
                &decoded == e.expected(),
                "{}: the stream decodes to another model than the encoder's prediction",
                c.2
            );
            g
        })
        .collect();
    let mut times = vec![Vec::with_capacity(runs); configs.len()];
    for _ in 0..runs {
        for ((c, t), feat) in configs.iter().zip(&mut times).zip(&feats) {
            let (secs, g, e) = encode(c);
            std::hint::black_box(e.stream);
            assert_eq!(&g, feat, "{}: encodes differ between runs", c.2);
            t.push(secs);
        }
    }
    configs
        .iter()
        .zip(times)
        .zip(feats)
        .map(|((c, mut t), feat)| {
            t.sort_by(f64::total_cmp);
            Row {
                label: c.2,
                secs: t[runs / 2],
                feat,
            }
        })
        .collect()
}

fn mse(g: &GroupStats) -> f64 {
    g.squared_error / g.symbols.max(1) as f64
}

/// Prints a table: `rows[baseline]` is the time reference (rounding), `rows[reference]` the
/// distortion reference.
fn print_table(title: &str, n: u32, rows: &[Row], baseline: usize, reference: usize) {
    let per = |s: f64| s * 1e6 / f64::from(n);
    let bits = |g: &GroupStats| g.coded_bytes as f64 * 8.0 / f64::from(n);
    let ideal = |g: &GroupStats| g.ideal_bits_integer / f64::from(n);
    let (base, refr) = (&rows[baseline], &rows[reference]);
    println!("\n{title}");
    println!(
        "  {:<24} {:>10} {:>12} {:>10} {:>10} {:>8} {:>8} {:>12} {:>8} {:>8}",
        "method",
        "µs/anchor",
        "feat MSE",
        "bits/anc",
        "ideal",
        "max err",
        "t/round",
        "Δt µs/anc",
        "MSE/ref",
        "bits/ref"
    );
    for r in rows {
        println!(
            "  {:<24} {:>10.2} {:>12.5e} {:>10.2} {:>10.2} {:>8.3} {:>8.2} {:>12.2} {:>8.4} {:>8.4}",
            r.label,
            per(r.secs),
            mse(&r.feat),
            bits(&r.feat),
            ideal(&r.feat),
            r.feat.max_error_steps,
            r.secs / base.secs,
            per(r.secs - base.secs),
            mse(&r.feat) / mse(&refr.feat),
            bits(&r.feat) / bits(&refr.feat),
        );
    }
}

/// The identity lattice codes by rounding: no feature lies more than half a step from its
/// reconstruction (f32 arithmetic aside).
fn check_identity(rows: &[Row]) {
    for r in rows {
        assert!(
            r.feat.max_error_steps <= 0.5 + 1e-4,
            "{}: a feature {} steps from its reconstruction, rounding gives at most 1/2",
            r.label,
            r.feat.max_error_steps
        );
    }
}

fn main() {
    let wall = Instant::now();
    let n: u32 = std::env::args()
        .skip(1)
        .find_map(|a| a.parse().ok())
        .unwrap_or(5_000);
    let runs: usize = std::env::var("SALVQ_BENCH_RUNS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(RUNS)
        .max(1);
    println!(
        "search_methods: {n} anchors, rate 0, median of {runs} encodes, {} rayon threads; \
         `max err` = largest |x − x̂| / Δ of the feature group",
        rayon::current_num_threads()
    );

    learned_basis(n, runs);
    e8_product(n, runs);

    println!("\ntotal wall time {:.1} s", wall.elapsed().as_secs_f64());
    println!(
        "checked: 10 configurations' streams decode to the encoder's prediction, each \
         encode reports alike; identity rows within 1/2 step; E8 closest = auto, the least MSE \
         of E8's searches"
    );
}

/// The bench's first scene: the learned basis, F = 50, and its identity reference; measures
/// and prints both tables.
fn learned_basis(n: u32, runs: usize) {
    let t = Instant::now();
    let model = generate(&GenParams::new(n, 1));
    println!(
        "generated F = 50 scene in {:.2} s",
        t.elapsed().as_secs_f64()
    );
    let g = LatticeKind::General;
    let rows = measure(
        &model,
        &[
            (g, Search::Rounding, "rounding"),
            (g, Search::NearestPlane, "nearest-plane (LLL, = auto)"),
            (
                g,
                Search::Closest { max_nodes: 1_000 },
                "closest ≤ 1 000 nodes",
            ),
            (
                g,
                Search::Closest { max_nodes: 10_000 },
                "closest ≤ 10 000 nodes",
            ),
            (LatticeKind::Identity, Search::Auto, "identity Z^50"),
        ],
        runs,
    );
    check_identity(&rows[4..]);
    print_table(
        "learned basis B = U diag(s) V^T, F = 50 (reference: closest ≤ 10 000 nodes, a \
         bound-limited search, not proven optimal at n = 50)",
        n,
        &rows[..4],
        0,
        3,
    );
    print_table(
        "identity Z^50 on the same scene (reference row; the generated s has geometric mean 1, \
         so det B = ±1 and the cells have the same volume at the same Δ)",
        n,
        &rows[4..],
        0,
        0,
    );
}

/// The bench's second scene: the E8 product, F = 48, and its identity reference; measures,
/// checks that no E8 search beats the exact decoder, and prints both tables.
fn e8_product(n: u32, runs: usize) {
    let t = Instant::now();
    let model = generate(&GenParams {
        feat_dim: 48,
        ..GenParams::new(n, 1)
    });
    println!(
        "\ngenerated F = 48 scene in {:.2} s",
        t.elapsed().as_secs_f64()
    );
    let e8 = LatticeKind::E8Product;
    let rows = measure(
        &model,
        &[
            (e8, Search::Rounding, "rounding"),
            (e8, Search::Auto, "auto (exact C–S)"),
            (e8, Search::NearestPlane, "nearest-plane (LLL)"),
            (
                e8,
                Search::Closest { max_nodes: 10_000 },
                "closest (→ exact C–S)",
            ),
            (LatticeKind::Identity, Search::Auto, "identity Z^48"),
        ],
        runs,
    );
    check_identity(&rows[4..]);
    // E8: `auto` is the exact Conway–Sloane decoder, and the encoder maps `closest` to it;
    // per anchor it minimizes ‖t − B u‖, so no other search has a smaller feature MSE.
    assert_eq!(
        rows[3].feat, rows[1].feat,
        "E8: closest codes as auto (the exact decoder)"
    );
    for r in &rows[..4] {
        assert!(
            mse(&rows[1].feat) <= mse(&r.feat) * (1.0 + 1e-6),
            "E8: {} has feature MSE {:.6e}, below the exact decoder's {:.6e}",
            r.label,
            mse(&r.feat),
            mse(&rows[1].feat)
        );
    }
    print_table(
        "E8 product E8^6, F = 48 (reference: auto = exact Conway–Sloane; the encoder maps \
         closest to the same exact decoder)",
        n,
        &rows[..4],
        0,
        1,
    );
    print_table(
        "identity Z^48 on the same scene (reference row; E8's generator has det 1, so at \
         the same Δ the cells have the same volume)",
        n,
        &rows[4..],
        0,
        0,
    );
}
