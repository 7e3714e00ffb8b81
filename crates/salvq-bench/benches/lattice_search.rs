//! Lattice search methods on SALVQ-like bases (`salvq_encoder::lattice`, encoder side).
//!
//! `cargo bench --bench lattice_search` builds bases `B = U diag(s) Vᵀ` (U, V Haar-random
//! orthogonal, s log-uniform in [1, cond] with both ends present, cond = 1, 10, 100, 1000) for
//! n = 8, 16, 50, and targets `y = B (u + e)` with u integer in [−20, 20] and e uniform in the
//! unit cube [−½, ½]ⁿ (the rounding error a SALVQ quantizer sees in its `B⁻¹y` domain; rounding
//! gives back u, with error `‖B e‖²`). For each method it prints ns per vector (including the
//! `‖y − B u‖²` evaluation every method does), MSE per dimension, the MSE excess over the
//! reference, the share of vectors where the method is not optimal, the share certified exact,
//! and mean search nodes. The reference is the exact closest point for n ≤ 16; for n = 50 an
//! exact search is out of reach (10⁶–10⁸ nodes per vector), so the reference is the best point
//! of a search bounded at `SALVQ_BENCH_REF_NODES` nodes (default 10⁶) and the `cert` column says
//! how often it is proven. A second table compares the D_n / E8 decoders with the generic search.
//!
//! Environment: `SALVQ_BENCH_REF_NODES` (default 1000000), `SALVQ_BENCH_SCALE` (multiplies the
//! vector counts, default 1). Single-threaded, seeded: the quality columns are reproducible.
//!
//! Checks what it measures (a failure panics, so the bench exits non-zero): every answer is a
//! lattice point `B u` (with the bench's own `B`) at the distance its method reports; no method
//! finds a closer point than one a search certified closest; the complete searches (n ≤ 16)
//! certify every vector; the fast D_n / E8 decoders' points are `B u` at their reported distance
//! and as close as the exact search's. Smoke mode (CI, about a second):
//! `SALVQ_BENCH_SCALE=0.02 SALVQ_BENCH_REF_NODES=10000 cargo bench --bench lattice_search`.

use std::hint::black_box;
use std::time::Instant;

use salvq_encoder::lattice::linalg::{from_svd, mat_vec, qr};
use salvq_encoder::lattice::{
    closest_dn, closest_e8, closest_e8_product, dn_basis, e8_basis, e8_product_basis, Lattice,
    Quantized, SearchMethod,
};
use salvq_gen::rng::Stream as Rng;

const SEED: u64 = 0x5A17_BE4C;

fn env_f64(name: &str, default: f64) -> f64 {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

fn orthogonal(rng: &mut Rng, n: usize) -> Vec<f64> {
    let a: Vec<f64> = (0..n * n).map(|_| rng.normal()).collect();
    qr(n, &a).0
}

fn salvq_basis(rng: &mut Rng, n: usize, cond: f64) -> Vec<f64> {
    let (u, v) = (orthogonal(rng, n), orthogonal(rng, n));
    let mut s: Vec<f64> = (0..n).map(|_| cond.powf(rng.uniform())).collect();
    s[0] = 1.0;
    s[1] = cond;
    from_svd(n, &u, &s, &v)
}

fn targets(rng: &mut Rng, n: usize, b: &[f64], count: usize) -> Vec<Vec<f64>> {
    (0..count)
        .map(|_| {
            let c: Vec<f64> = (0..n)
                .map(|_| (rng.uniform() * 41.0).floor() - 20.0 + rng.uniform() - 0.5)
                .collect();
            mat_vec(n, b, &c)
        })
        .collect()
}

/// One method's accumulated results over all bases of a configuration.
#[derive(Default, Clone)]
struct Acc {
    secs: f64,
    vectors: usize,
    d2: Vec<f64>,
    /// Per vector: the search proved its point a closest one.
    proven: Vec<bool>,
    exact: usize,
    nodes: u64,
}

/// A row of the table: a search on the δ = 0.75 or the δ = 0.99 lattice.
struct Method {
    name: String,
    delta99: bool,
    /// None: nearest plane on the unreduced basis (not a `SearchMethod`).
    search: Option<SearchMethod>,
}

impl Method {
    fn new(name: String, delta99: bool, search: Option<SearchMethod>) -> Self {
        Method {
            name,
            delta99,
            search,
        }
    }
}

/// `‖y − B u‖²` from the basis the bench built (not the lattice's own copy).
fn distance2(n: usize, b: &[f64], y: &[f64], u: &[i64]) -> f64 {
    let u: Vec<f64> = u.iter().map(|&v| v as f64).collect();
    let p = mat_vec(n, b, &u);
    y.iter().zip(&p).map(|(a, c)| (a - c) * (a - c)).sum()
}

/// `a` and `b` agree to rounding (relative 10⁻⁹, absolute 10⁻⁹).
fn agree(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-9 * a.abs().max(b.abs()).max(1.0)
}

/// Runs one method on every target (timed as one batch), keeping per-vector results.
/// Checks each answer (untimed): `n` integer coordinates whose lattice point `B u`, with the
/// bench's own `B`, lies at the distance the method reports.
fn run(lat: &Lattice, b: &[f64], ys: &[Vec<f64>], method: &Method, acc: &mut Acc) {
    let search = method.search;
    let start = Instant::now();
    let out: Vec<Quantized> = ys
        .iter()
        .map(|y| {
            let q = match search {
                Some(m) => lat.quantize(black_box(y), m),
                None => lat.babai_nearest_plane(black_box(y), false),
            };
            black_box(q.expect("quantizes"))
        })
        .collect();
    acc.secs += start.elapsed().as_secs_f64();
    acc.vectors += ys.len();
    let n = lat.dim();
    for (y, q) in ys.iter().zip(&out) {
        assert_eq!(q.u.len(), n, "{}: coordinates of a point", method.name);
        let d2 = distance2(n, b, y, &q.u);
        assert!(
            agree(d2, q.distance2),
            "{}: reported distance² {} but ‖y − B u‖² = {d2}",
            method.name,
            q.distance2
        );
    }
    for q in out {
        acc.d2.push(q.distance2);
        acc.proven.push(q.exact);
        acc.exact += usize::from(q.exact);
        acc.nodes += q.nodes;
    }
}

struct Config {
    n: usize,
    bases: usize,
    vectors: usize,
    bounds: &'static [u64],
}

fn methods(cfg: &Config, reference_bound: u64) -> Vec<Method> {
    let mut out = vec![
        Method::new("rounding".into(), false, Some(SearchMethod::Rounding)),
        Method::new("nearest plane (B)".into(), false, None),
        Method::new(
            "nearest plane, δ .75".into(),
            false,
            Some(SearchMethod::NearestPlane),
        ),
        Method::new(
            "nearest plane, δ .99".into(),
            true,
            Some(SearchMethod::NearestPlane),
        ),
    ];
    for &max_nodes in cfg.bounds {
        for (delta99, d) in [(false, ".75"), (true, ".99")] {
            out.push(Method::new(
                format!("closest ≤{max_nodes:.0e}, δ {d}"),
                delta99,
                Some(SearchMethod::ClosestPoint { max_nodes }),
            ));
        }
    }
    let name = if reference_bound == u64::MAX {
        "closest exact, δ .99".to_string()
    } else {
        format!("closest ≤{reference_bound:.0e}, δ .99")
    };
    out.push(Method::new(
        name,
        true,
        Some(SearchMethod::ClosestPoint {
            max_nodes: reference_bound,
        }),
    ));
    out
}

fn main() {
    let ref_nodes = env_f64("SALVQ_BENCH_REF_NODES", 1e6) as u64;
    let scale = env_f64("SALVQ_BENCH_SCALE", 1.0);
    let configs = [
        Config {
            n: 8,
            bases: 4,
            vectors: 4000,
            bounds: &[10, 100],
        },
        Config {
            n: 16,
            bases: 4,
            vectors: 1500,
            bounds: &[100, 1_000],
        },
        Config {
            n: 50,
            bases: 3,
            vectors: 40,
            bounds: &[1_000, 10_000, 100_000],
        },
    ];
    let t_all = Instant::now();
    println!(
        "lattice_search: y = B(u + e), e ~ U[-1/2, 1/2]^n. 'vs best' and 'not opt' compare with"
    );
    println!("the best point any method found for the vector: the exact closest point for n <= 16");
    println!("(the last row of each block is a complete search), the best known for n = 50.\n");
    println!(
        "{:>3} {:>5} {:<24} {:>11} {:>10} {:>9} {:>8} {:>6} {:>9}",
        "n", "cond", "method", "ns/vector", "MSE/dim", "vs best", "not opt", "exact", "nodes"
    );
    let mut rng = Rng::new(SEED, 0, 0);
    let mut checks = Checks::default();
    for cfg in &configs {
        let n = cfg.n;
        let vectors = ((cfg.vectors as f64 * scale).round() as usize).max(1);
        let reference_bound = if n <= 16 { u64::MAX } else { ref_nodes };
        let methods = methods(cfg, reference_bound);
        for cond in [1.0, 10.0, 100.0, 1000.0] {
            condition_block(
                &mut rng,
                cfg,
                cond,
                vectors,
                &methods,
                reference_bound,
                &mut checks,
            );
        }
    }
    let roots = root_table(&mut rng, scale);
    println!("total {:.1} s", t_all.elapsed().as_secs_f64());
    println!(
        "checked: {} answers are lattice points at their reported distance; {} certified exact \
         ones are closest among all methods' (the complete searches for n <= 16 certify every \
         vector); {roots} fast D_n / E8 answers equal the exact search's distance",
        checks.answers, checks.proven
    );
}

/// One block of the table, lattices of dimension `cfg.n` and condition number `cond`: every
/// method on `vectors` targets for each of `cfg.bases` random bases; prints a row per method
/// and the bases' reduction times, and counts the answers checked into `checks`.
fn condition_block(
    rng: &mut Rng,
    cfg: &Config,
    cond: f64,
    vectors: usize,
    methods: &[Method],
    reference_bound: u64,
    checks: &mut Checks,
) {
    let n = cfg.n;
    let mut accs = vec![Acc::default(); methods.len()];
    let mut build = [0.0f64; 2];
    for _ in 0..cfg.bases {
        let b = salvq_basis(rng, n, cond);
        let t = Instant::now();
        let l75 = Lattice::new(n, &b).expect("SALVQ basis");
        build[0] += t.elapsed().as_secs_f64();
        let t = Instant::now();
        let l99 = Lattice::with_delta(n, &b, 0.99).expect("SALVQ basis");
        build[1] += t.elapsed().as_secs_f64();
        let ys = targets(rng, n, &b, vectors);
        for (m, acc) in methods.iter().zip(accs.iter_mut()) {
            run(if m.delta99 { &l99 } else { &l75 }, &b, &ys, m, acc);
        }
    }
    let total = accs[0].d2.len();
    let best: Vec<f64> = (0..total)
        .map(|i| accs.iter().map(|a| a.d2[i]).fold(f64::INFINITY, f64::min))
        .collect();
    let best_mse = best.iter().sum::<f64>() / total as f64;
    checks.answers += total * methods.len();
    checks.proven += check_proven(methods, &accs, &best, reference_bound);
    for (m, acc) in methods.iter().zip(&accs) {
        let mse = acc.d2.iter().sum::<f64>() / total as f64;
        let not_opt = acc
            .d2
            .iter()
            .zip(&best)
            .filter(|(d, r)| **d > **r * (1.0 + 1e-9) + 1e-12)
            .count();
        println!(
            "{:>3} {:>5} {:<24} {:>11.0} {:>10.4} {:>8.2}% {:>7.1}% {:>5.0}% {:>9.0}",
            n,
            cond,
            m.name,
            acc.secs * 1e9 / total as f64,
            mse / n as f64,
            (mse / best_mse - 1.0) * 100.0,
            100.0 * not_opt as f64 / total as f64,
            100.0 * acc.exact as f64 / total as f64,
            acc.nodes as f64 / total as f64,
        );
    }
    println!(
        "{:>3} {:>5} Lattice::new per basis: {:.0} µs (δ .75), {:.0} µs (δ .99)\n",
        n,
        cond,
        build[0] * 1e6 / cfg.bases as f64,
        build[1] * 1e6 / cfg.bases as f64
    );
}

/// Counts of the answers checked.
#[derive(Default)]
struct Checks {
    answers: usize,
    proven: usize,
}

/// Checks the certified answers of one block (panics on a failure) and returns how many there
/// were: no method finds a closer point than one a search proved closest, and a complete
/// search (`reference_bound = u64::MAX`, the last method) proves every vector.
fn check_proven(methods: &[Method], accs: &[Acc], best: &[f64], reference_bound: u64) -> usize {
    let mut proven = 0;
    for (m, acc) in methods.iter().zip(accs) {
        for (i, (&d, &p)) in acc.d2.iter().zip(&acc.proven).enumerate() {
            assert!(
                !p || d <= best[i] * (1.0 + 1e-9) + 1e-12,
                "{}: vector {i} certified closest at distance² {d}, but a method found {}",
                m.name,
                best[i]
            );
            proven += usize::from(p);
        }
    }
    if reference_bound == u64::MAX {
        let (m, acc) = (&methods[methods.len() - 1], &accs[accs.len() - 1]);
        assert_eq!(
            acc.exact,
            acc.d2.len(),
            "{}: a complete search certifies every vector",
            m.name
        );
    }
    proven
}

/// Fast D_n / E8 decoders against the generic exact search on the same lattice. Checks (panics
/// on a failure) that each fast answer is the point `B u` at its reported distance, and that
/// it is as close as the exact search's; returns how many answers were compared.
fn root_table(rng: &mut Rng, scale: f64) -> usize {
    println!(
        "{:<8} {:>18} {:>18} {:>10}",
        "lattice", "fast ns/vector", "generic ns/vector", "same d2"
    );
    let count = ((20_000.0 * scale).round() as usize).max(1);
    let mut compared = 0;
    type Fast =
        fn(
            &[f64],
        )
            -> Result<salvq_encoder::lattice::RootPoint, salvq_encoder::lattice::LatticeError>;
    let cases: [(&str, usize, Vec<f64>, Fast); 5] = [
        ("D8", 8, dn_basis(8), closest_dn),
        ("D16", 16, dn_basis(16), closest_dn),
        ("E8", 8, e8_basis(), closest_e8),
        ("E8^2", 16, e8_product_basis(16), closest_e8_product),
        ("E8^6", 48, e8_product_basis(48), closest_e8_product),
    ];
    for (name, n, basis, fast) in cases {
        let lat = Lattice::new(n, &basis).expect("root basis");
        let ys: Vec<Vec<f64>> = (0..count)
            .map(|_| (0..n).map(|_| 8.0 * rng.uniform() - 4.0).collect())
            .collect();
        let t = Instant::now();
        let f: Vec<f64> = ys
            .iter()
            .map(|y| black_box(fast(black_box(y)).expect("decodes")).distance2)
            .collect();
        let t_fast = t.elapsed().as_secs_f64();
        // The generic search is slow for E8^6; time it on a prefix.
        let m = if n > 16 {
            ((200.0 * scale).round() as usize).clamp(1, count)
        } else {
            count
        };
        let t = Instant::now();
        let g: Vec<f64> = ys[..m]
            .iter()
            .map(|y| black_box(lat.closest_point(black_box(y), u64::MAX).expect("cp")).distance2)
            .collect();
        let t_gen = t.elapsed().as_secs_f64();
        let same = f
            .iter()
            .zip(&g)
            .filter(|(a, b)| (*a - *b).abs() <= 1e-9)
            .count();
        for y in &ys[..m] {
            let p = fast(y).expect("decodes");
            let u: Vec<f64> = p.u.iter().map(|&v| v as f64).collect();
            assert_eq!(mat_vec(n, &basis, &u), p.point, "{name}: point = B u");
            let d2 = distance2(n, &basis, y, &p.u);
            assert!(
                agree(d2, p.distance2),
                "{name}: reported distance² {} but ‖y − B u‖² = {d2}",
                p.distance2
            );
        }
        assert_eq!(
            same, m,
            "{name}: the fast decoder is as close as the exact search on every vector"
        );
        compared += m;
        println!(
            "{:<8} {:>18.0} {:>18.0} {:>9.1}%",
            name,
            t_fast * 1e9 / count as f64,
            t_gen * 1e9 / m as f64,
            100.0 * same as f64 / m as f64
        );
    }
    compared
}
