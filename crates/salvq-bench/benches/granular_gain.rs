//! Granular gain of E8 over the integer lattice Z⁸ on an i.i.d. Gaussian source at high rate.
//!
//! `cargo bench --bench granular_gain` draws 8-d vectors `y` with i.i.d. N(0, 1) components
//! (SplitMix64 + Box–Muller, fixed seed: the numbers are reproducible) and quantizes `y / Δ`
//! with each lattice, reconstructing `Δ · x`:
//! - Z⁸: coordinate-wise rounding;
//! - E8: [`closest_e8`] (exact Conway–Sloane decoder); its generator basis [`e8_basis`] has
//!   determinant 1, so at the same step Δ its cells have the same volume Δ⁸ as those of Z⁸;
//! - D8: [`closest_dn`]; its basis [`dn_basis`] has determinant 2, so it runs at step
//!   `2^(−1/8) Δ` to give the same cell volume Δ⁸.
//!
//! Both determinants are checked at start-up. For each Δ ∈ {2, 1, 0.5, 0.25, 0.1, 0.05} it
//! prints the MSE per dimension, the normalized second moment estimate
//! `G = MSE / V^(2/n) = MSE / Δ²` (V = Δ⁸ for every lattice here) and the gain over Z⁸ in dB,
//! `10 log10(MSE(Z⁸) / MSE(Λ))`, each with a 95% confidence interval from batch means
//! (40 batches, Student t with 39 degrees of freedom). The same vectors are used for every
//! lattice and every Δ (common random numbers). The last line is the E8 gain at the smallest Δ.
//!
//! Theory (high rate, Δ ≪ σ): the quantization error is uniform over the Voronoi cell, so
//! `MSE = G(Λ) V^(2/n)` and the gain is `10 log10(G(Z) / G(E8))` with `G(Z) = 1/12 = 0.0833333`
//! and `G(E8) = 0.0716821` (Conway & Sloane, SPLAG ch. 2 and 21): 0.654 dB. For a Gaussian
//! source the limit is reached very early: by Poisson summation the error deviates from
//! uniform by terms `exp(−2π²σ²‖w‖²/Δ²)` over the nonzero dual-lattice vectors w (for Z,
//! `MSE = Δ²/12 + (Δ²/π²) Σ_k (−1)^k k^−2 exp(−2π²k²σ²/Δ²)`). With ‖w‖² = 1 (Z⁸, D8) that is
//! about 3·10⁻⁹ at Δ = 1 and 7·10⁻³ at Δ = 2; E8 is self-dual with ‖w‖² ≥ 2, so its terms are
//! squared (5·10⁻⁵ at Δ = 2). So Δ ≤ 1 gives the high-rate values within the noise; Δ = 2 is
//! printed to show where they start to move (Z⁸'s G drops to 0.0826, the gain to ≈ 0.62 dB).
//!
//! Environment: `SALVQ_BENCH_SCALE` multiplies the vector count (default 1: 4 000 000 vectors
//! per Δ). Single-threaded.
//!
//! Checks what it measures (a failure panics, so the bench exits non-zero): the determinants
//! and that the decoders' points are `B u` (above); every MSE finite and positive; at Δ ≤ 1
//! (high rate), G of Z⁸ and E8 and the E8 gain within 3 half-widths of their 95% CIs of
//! theory, and the MSEs in the order E8 < D8 < Z⁸; the last E8 gain above 0 with 95%
//! confidence. The CIs widen as the count shrinks, so the checks hold at any scale. Smoke
//! mode (CI, about a second): `SALVQ_BENCH_SCALE=0.1 cargo bench --bench granular_gain`.

use std::time::Instant;

use salvq_encoder::lattice::linalg::{det_i64, mat_vec};
use salvq_encoder::lattice::{closest_dn, closest_e8, dn_basis, e8_basis};

const SEED: u64 = 0x6A1E_E8E8_0654_0DB5;
const VECTORS: f64 = 4_000_000.0;
const BATCHES: usize = 40;
/// Student t quantile t_{0.975} with `BATCHES − 1 = 39` degrees of freedom.
const T975: f64 = 2.022_690_911_734_728;
const DELTAS: [f64; 6] = [2.0, 1.0, 0.5, 0.25, 0.1, 0.05];
const G_Z: f64 = 1.0 / 12.0;
const G_E8: f64 = 0.071_682_1;
/// The high-rate regime the theory checks apply to (see the module docs).
const HIGH_RATE_DELTA: f64 = 1.0;
/// A measured value agrees with theory when within this many 95% half-widths (about 6
/// standard errors: a correct quantizer fails it with a probability near 10⁻⁶ per check).
const CI_WIDTHS: f64 = 3.0;

/// The crate's seeded SplitMix64 stream (Annex B.1) with its Box–Muller normals.
struct Rng(salvq_gen::rng::Stream);

impl Rng {
    fn new(seed: u64) -> Rng {
        Rng(salvq_gen::rng::Stream::new(seed, 0, 0))
    }

    /// Eight i.i.d. N(0, 1) values.
    fn normal8(&mut self) -> [f64; 8] {
        std::array::from_fn(|_| self.0.normal())
    }
}

fn env_f64(name: &str, default: f64) -> f64 {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// The lattices compared, in table order.
#[derive(Clone, Copy)]
enum Kind {
    Z8,
    D8,
    E8,
}

const KINDS: [Kind; 3] = [Kind::Z8, Kind::D8, Kind::E8];

impl Kind {
    fn name(self) -> &'static str {
        match self {
            Kind::Z8 => "Z^8",
            Kind::D8 => "D8",
            Kind::E8 => "E8",
        }
    }

    /// Step multiplier giving cell volume Δ⁸ (the generator basis determinant to the −1/8).
    fn step_scale(self) -> f64 {
        match self {
            Kind::Z8 | Kind::E8 => 1.0,
            Kind::D8 => 2f64.powf(-1.0 / 8.0),
        }
    }

    /// Theoretical normalized second moment, where known for certain.
    fn theory_g(self) -> Option<f64> {
        match self {
            Kind::Z8 => Some(G_Z),
            Kind::D8 => None,
            Kind::E8 => Some(G_E8),
        }
    }

    /// `‖y − step · Q(y / step)‖²`, evaluated in the source domain.
    fn error2(self, y: &[f64; 8], step: f64) -> f64 {
        let mut t = [0.0; 8];
        for (ti, yi) in t.iter_mut().zip(y) {
            *ti = yi / step;
        }
        let x: [f64; 8] = match self {
            Kind::Z8 => t.map(f64::round),
            Kind::D8 => to8(&closest_dn(&t).expect("finite target").point),
            Kind::E8 => to8(&closest_e8(&t).expect("finite target").point),
        };
        y.iter()
            .zip(&x)
            .fold(0.0, |s, (yi, xi)| s + (yi - step * xi) * (yi - step * xi))
    }
}

fn to8(v: &[f64]) -> [f64; 8] {
    v.try_into().expect("8 coordinates")
}

/// Mean and 95% half-width (batch means, Student t) of per-batch values.
fn mean_ci(v: &[f64]) -> (f64, f64) {
    let n = v.len() as f64;
    let mean = v.iter().sum::<f64>() / n;
    let var = v.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / (n - 1.0);
    (mean, T975 * (var / n).sqrt())
}

/// `|det B|` of a basis whose entries are multiples of ½ (exact: det(2B) / 2⁸).
fn det_half_integer(b: &[f64]) -> f64 {
    let twice: Vec<i64> = b.iter().map(|&v| (2.0 * v) as i64).collect();
    assert!(
        twice.iter().zip(b).all(|(&t, &v)| t as f64 == 2.0 * v),
        "basis entries are multiples of 1/2"
    );
    det_i64(8, &twice).expect("no overflow").abs() as f64 / 256.0
}

/// Checks the equal-volume premise and that the decoders' points are in the lattices.
fn check_lattices() {
    let (e8, d8) = (e8_basis(), dn_basis(8));
    assert_eq!(det_half_integer(&e8), 1.0, "det of e8_basis");
    assert_eq!(det_half_integer(&d8), 2.0, "det of dn_basis(8)");
    let mut rng = Rng::new(SEED ^ 0xC0FF_EE00);
    for _ in 0..1000 {
        let y = rng.normal8().map(|v| 7.0 * v);
        let p = closest_e8(&y).expect("finite");
        let u: Vec<f64> = p.u.iter().map(|&v| v as f64).collect();
        assert_eq!(mat_vec(8, &e8, &u), p.point, "E8 point = B u");
        let p = closest_dn(&y).expect("finite");
        let u: Vec<f64> = p.u.iter().map(|&v| v as f64).collect();
        assert_eq!(mat_vec(8, &d8, &u), p.point, "D8 point = B u");
    }
}

/// Per-batch sums of squared errors for every lattice at one Δ.
fn measure(delta: f64, per_batch: usize) -> [Vec<f64>; 3] {
    // The same seed for every Δ: common random numbers across the whole table.
    let mut rng = Rng::new(SEED);
    let steps = KINDS.map(|k| delta * k.step_scale());
    let mut sums: [Vec<f64>; 3] = Default::default();
    for _ in 0..BATCHES {
        let mut acc = [0.0; 3];
        for _ in 0..per_batch {
            let y = rng.normal8();
            for (i, k) in KINDS.iter().enumerate() {
                acc[i] += k.error2(&y, steps[i]);
            }
        }
        for (s, a) in sums.iter_mut().zip(acc) {
            s.push(a);
        }
    }
    sums
}

/// The gain of lattice `i` over Z⁸ (`sums[0]`) in dB over all batches, and the 95% CI
/// half-width of the per-batch gains.
fn gain_over_z(sums: &[Vec<f64>; 3], i: usize) -> (f64, f64) {
    let gains: Vec<f64> = sums[0]
        .iter()
        .zip(&sums[i])
        .map(|(z, l)| 10.0 * (z / l).log10())
        .collect();
    let (_, ci) = mean_ci(&gains);
    let z_total: f64 = sums[0].iter().sum();
    let gain = 10.0 * (z_total / sums[i].iter().sum::<f64>()).log10();
    (gain, ci)
}

/// One Δ's table: measures every lattice and prints a row each; at high rate checks G and
/// E8's gain against theory and the order E8 < D8 < Z⁸. Returns the checks made and E8's
/// gain over Z⁸ in dB with its 95% CI half-width.
fn delta_table(delta: f64, per_batch: usize, theory_gain: f64) -> (usize, Option<(f64, f64)>) {
    let mut checked = 0;
    let mut e8 = None;
    let start = Instant::now();
    let sums = measure(delta, per_batch);
    let secs = start.elapsed().as_secs_f64();
    println!();
    println!("Δ = {delta} ({secs:.1} s)");
    println!(
        "{:<5} {:>9} {:>13} {:>10} {:>10} {:>10} {:>9} {:>9} {:>7}",
        "lat", "step", "MSE/dim", "G", "±95%", "G theory", "gain dB", "±95%", "theory"
    );
    let denom = per_batch as f64 * 8.0 * delta * delta;
    for (i, k) in KINDS.iter().enumerate() {
        let gs: Vec<f64> = sums[i].iter().map(|s| s / denom).collect();
        let (g, g_ci) = mean_ci(&gs);
        let mse = g * delta * delta;
        assert!(
            mse.is_finite() && mse > 0.0 && g_ci.is_finite(),
            "{} at Δ = {delta}: MSE {mse}, ±{g_ci}",
            k.name()
        );
        if let Some(t) = k.theory_g().filter(|_| delta <= HIGH_RATE_DELTA) {
            assert!(
                (g - t).abs() <= CI_WIDTHS * g_ci,
                "{} at Δ = {delta}: G = {g:.7} ± {g_ci:.7}, theory {t:.7}",
                k.name()
            );
            checked += 1;
        }
        let theory = k.theory_g().map_or("-".into(), |t| format!("{t:.7}"));
        let (gain_s, gain_ci_s, gain_th) = if i == 0 {
            ("-".to_string(), "-".to_string(), "-".to_string())
        } else {
            let (gain, ci) = gain_over_z(&sums, i);
            let th = k.theory_g().map(|t| 10.0 * (G_Z / t).log10());
            if matches!(k, Kind::E8) {
                e8 = Some((gain, ci));
                if delta <= HIGH_RATE_DELTA {
                    assert!(
                        (gain - theory_gain).abs() <= CI_WIDTHS * ci,
                        "E8 gain at Δ = {delta}: {gain:.4} ± {ci:.4} dB, theory \
                         {theory_gain:.4} dB"
                    );
                    checked += 1;
                }
            }
            (
                format!("{gain:.4}"),
                format!("{ci:.4}"),
                th.map_or("-".into(), |t| format!("{t:.3}")),
            )
        };
        println!(
            "{:<5} {:>9.6} {:>13.6e} {:>10.7} {:>10.7} {:>10} {:>9} {:>9} {:>7}",
            k.name(),
            delta * k.step_scale(),
            mse,
            g,
            g_ci,
            theory,
            gain_s,
            gain_ci_s,
            gain_th
        );
    }
    // Same cell volume: at high rate the better lattice has the smaller MSE, E8 < D8 < Z⁸
    // (G(D8) = 0.0758 lies between).
    if delta <= HIGH_RATE_DELTA {
        let [z, d, e] = sums.each_ref().map(|v| v.iter().sum::<f64>());
        assert!(
            e < d && d < z,
            "Δ = {delta}: squared errors E8 {e}, D8 {d}, Z^8 {z}: not E8 < D8 < Z^8"
        );
        checked += 1;
    }
    (checked, e8)
}

fn main() {
    let scale = env_f64("SALVQ_BENCH_SCALE", 1.0);
    let per_batch = ((VECTORS * scale) as usize / BATCHES).max(2);
    let vectors = per_batch * BATCHES;
    let theory_gain = 10.0 * (G_Z / G_E8).log10();
    check_lattices();
    println!(
        "Granular gain on an i.i.d. N(0, 1) source, n = 8: {vectors} vectors per Δ \
         ({BATCHES} batches of {per_batch}), seed {SEED:#x}"
    );
    println!(
        "All lattices at cell volume Δ⁸ (det e8_basis = 1, det dn_basis(8) = 2 → D8 step \
         2^(-1/8)·Δ); G = MSE/dim / Δ²; ± = 95% CI (batch means, t_39)"
    );
    println!("theory: G(Z) = 1/12 = {G_Z:.7}, G(E8) = {G_E8:.7}, gain {theory_gain:.3} dB");
    let total = Instant::now();
    let mut last = (0.0, 0.0, 0.0);
    let mut checked = 0;
    for &delta in &DELTAS {
        let (checks, e8) = delta_table(delta, per_batch, theory_gain);
        checked += checks;
        if let Some((gain, ci)) = e8 {
            last = (delta, gain, ci);
        }
    }
    println!();
    println!("total {:.1} s", total.elapsed().as_secs_f64());
    let (delta, gain, ci) = last;
    println!(
        "E8 vs Z^8 granular gain: {gain:.3} dB (95% CI ±{ci:.3}), theory {theory_gain:.3} dB \
         (Δ = {delta})"
    );
    assert!(
        gain - ci > 0.0,
        "E8 gain at Δ = {delta}: {gain:.4} ± {ci:.4} dB, not above 0"
    );
    println!(
        "checked: lattice determinants and decoders' points; {checked} high-rate (Δ <= \
         {HIGH_RATE_DELTA}) values within {CI_WIDTHS} CIs of theory or in order E8 < D8 < Z^8; \
         the E8 gain is above 0 with 95% confidence"
    );
}
