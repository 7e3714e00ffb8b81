//! Test bases and brute-force references shared by the lattice tests (`tests/lattice.rs`,
//! `tests/lattice_inputs.rs`).
#![allow(dead_code)]

use salvq_encoder::lattice::linalg::{mat_vec, qr};
use salvq_gen::rng::Stream as Rng;

/// A random orthogonal matrix (the Q of a Gaussian matrix).
pub fn orthogonal(rng: &mut Rng, n: usize) -> Vec<f64> {
    let a: Vec<f64> = (0..n * n).map(|_| rng.normal()).collect();
    qr(n, &a).0
}

/// SALVQ-like `U diag(s) Vᵀ`, s log-uniform in [1, cond] with both ends present.
pub fn svd_basis(rng: &mut Rng, n: usize, cond: f64) -> Vec<f64> {
    let (u, v) = (orthogonal(rng, n), orthogonal(rng, n));
    let mut s: Vec<f64> = (0..n).map(|_| cond.powf(rng.uniform())).collect();
    s[0] = 1.0;
    if n > 1 {
        s[1] = cond;
    }
    salvq_encoder::lattice::linalg::from_svd(n, &u, &s, &v)
}

/// The same lattice in a worse basis: a few random integer column operations.
pub fn skew(rng: &mut Rng, n: usize, b: &[f64]) -> Vec<f64> {
    let mut b = b.to_vec();
    for _ in 0..2 * n {
        let (i, j) = (rng.below(n as u64) as usize, rng.below(n as u64) as usize);
        if i == j {
            continue;
        }
        let m = rng.below(5) as f64 - 2.0;
        for r in 0..n {
            b[r * n + i] += m * b[r * n + j];
        }
    }
    b
}

/// One of the test bases for dimension n, by kind.
pub fn test_basis(rng: &mut Rng, n: usize, kind: u64) -> Vec<f64> {
    match kind % 3 {
        0 => {
            let cond = 10f64.powf(rng.range(0.0, 3.0));
            svd_basis(rng, n, cond)
        }
        1 => (0..n * n).map(|_| rng.normal()).collect(),
        _ => {
            let cond = 10f64.powf(rng.range(0.0, 1.5));
            let b = svd_basis(rng, n, cond);
            skew(rng, n, &b)
        }
    }
}

/// Brute force over Zⁿ (+ shift): integer vectors within `d` of `y` per coordinate.
pub fn brute_dn(y: &[f64], shift: f64, d: f64) -> f64 {
    let n = y.len();
    let lo: Vec<i64> = y.iter().map(|v| (v - shift - d).ceil() as i64).collect();
    let hi: Vec<i64> = y.iter().map(|v| (v - shift + d).floor() as i64).collect();
    let mut x = lo.clone();
    let mut best = f64::INFINITY;
    loop {
        if x.iter().sum::<i64>() % 2 == 0 {
            let d2: f64 = (0..n).map(|i| (y[i] - x[i] as f64 - shift).powi(2)).sum();
            best = best.min(d2);
        }
        let mut k = 0;
        loop {
            if k == n {
                return best;
            }
            if x[k] < hi[k] {
                x[k] += 1;
                break;
            }
            x[k] = lo[k];
            k += 1;
        }
    }
}

pub fn times(n: usize, b: &[f64], u: &[i64]) -> Vec<f64> {
    mat_vec(n, b, &u.iter().map(|&x| x as f64).collect::<Vec<_>>())
}
