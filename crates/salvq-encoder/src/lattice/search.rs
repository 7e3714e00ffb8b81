//! Nearest-plane (Babai) and Schnorr–Euchner closest-point search on a QR factorization.
//!
//! With `C = Q R` (R upper triangular, positive diagonal), `‖y − C x‖² = ‖Qᵀy − R x‖²`, and
//! coordinate `x_k` only meets the rows `0 … k` of R. Both searches fix `x_{n−1}` first and go
//! down to `x_0`; the center of level k is `c_k = (ŷ_k − Σ_{j>k} R_kj x_j) / R_kk`.
//! Coordinates are carried as f64 integers (exact below 2^53) and checked against
//! [`super::COORD_LIMIT`].

use super::linalg::{mat_t_vec, qr};
use super::{LatticeError, COORD_LIMIT};

/// The QR data of one basis that the searches need.
#[derive(Debug, Clone)]
pub struct Triangular {
    pub n: usize,
    /// Q, row-major.
    pub q: Vec<f64>,
    /// R, row-major upper triangular, `R_kk > 0`.
    pub r: Vec<f64>,
    /// `R_kj / R_kk`, row-major (only j > k used).
    rn: Vec<f64>,
    /// `R_kk²`.
    diag2: Vec<f64>,
}

/// Result of a search in the coordinates of the factored basis.
#[derive(Debug, Clone)]
pub struct Found {
    pub x: Vec<f64>,
    /// `‖Qᵀy − R x‖²`.
    pub d2: f64,
    pub exact: bool,
    pub nodes: u64,
}

impl Triangular {
    /// Factors `c` (row-major, columns are basis vectors). Errors if the basis is singular:
    /// some Gram–Schmidt norm `R_kk ≤ rtol · max_j ‖c_j‖`.
    pub fn new(n: usize, c: &[f64], rtol: f64) -> Result<Self, LatticeError> {
        let (q, r) = qr(n, c);
        if q.iter().chain(&r).any(|v| !v.is_finite()) {
            return Err(LatticeError::NonFiniteBasis);
        }
        let max_norm = (0..n)
            .map(|j| {
                (0..n)
                    .fold(0.0, |s, i| s + c[i * n + j] * c[i * n + j])
                    .sqrt()
            })
            .fold(0.0, f64::max);
        if !(max_norm > 0.0 && max_norm.is_finite()) {
            return Err(LatticeError::Singular);
        }
        if (0..n).any(|k| r[k * n + k].is_nan() || r[k * n + k] <= rtol * max_norm) {
            return Err(LatticeError::Singular);
        }
        let mut rn = vec![0.0; n * n];
        let mut diag2 = vec![0.0; n];
        for k in 0..n {
            let rkk = r[k * n + k];
            diag2[k] = rkk * rkk;
            for j in k + 1..n {
                rn[k * n + j] = r[k * n + j] / rkk;
            }
        }
        Ok(Triangular { n, q, r, rn, diag2 })
    }

    /// The scaled rotated target `ŷ_k / R_kk` with `ŷ = Qᵀ y`.
    pub fn scaled_target(&self, y: &[f64]) -> Vec<f64> {
        let n = self.n;
        let yq = mat_t_vec(n, &self.q, y);
        (0..n).map(|k| yq[k] / self.r[k * n + k]).collect()
    }

    /// Babai's nearest plane (successive interference cancellation).
    pub fn nearest_plane(&self, ys: &[f64]) -> Result<Found, LatticeError> {
        let n = self.n;
        let mut x = vec![0.0; n];
        let mut d2 = 0.0;
        for k in (0..n).rev() {
            let row = &self.rn[k * n..(k + 1) * n];
            let c = (k + 1..n).fold(ys[k], |s, j| s - row[j] * x[j]);
            if c.is_nan() || c.abs() > COORD_LIMIT {
                return Err(LatticeError::OutOfRange);
            }
            x[k] = c.round();
            let e = c - x[k];
            d2 += self.diag2[k] * e * e;
        }
        Ok(Found {
            x,
            d2,
            exact: false,
            nodes: n as u64,
        })
    }

    /// Schnorr–Euchner enumeration (Agrell et al. 2002, Algorithm DECODE): depth first, the
    /// children of a node visited in zig-zag order around the center, so the first leaf is the
    /// nearest-plane point and a branch ends at its first child outside the current radius.
    /// `start` (a lattice point with distance `start_d2`) gives the initial radius; only strictly
    /// closer points replace it. Partial center sums are kept per level and refreshed lazily
    /// (only the coordinates that changed since the level was last entered), so a node costs
    /// O(1) amortized. A node is one tried value of one coordinate; at `max_nodes` the search
    /// stops and returns the best point so far with `exact: false`.
    pub fn closest(&self, ys: &[f64], start: Found, max_nodes: u64) -> Found {
        let n = self.n;
        let w = n + 1;
        let mut best = start.x;
        let mut best_d2 = start.d2;
        let mut x = vec![0.0; n];
        let mut center = vec![0.0; n];
        let mut step = vec![0.0; n];
        let mut partial = vec![0.0; n + 1];
        // sig[k][j] = ys_k − Σ_{i ≥ j} rn[k][i] x_i, for j in k+1 ..= n; sig[k][n] = ys_k.
        let mut sig = vec![0.0; n * w];
        for k in 0..n {
            sig[k * w + n] = ys[k];
        }
        // Row k's entries j in k+1 ..= stale[k] are out of date.
        let mut stale: Vec<usize> = vec![n - 1; n];
        let mut nodes = 0u64;
        let mut exact = true;
        let mut k = n - 1;
        self.enter(k, &mut sig, &mut stale, &mut center, &mut x, &mut step);
        loop {
            if nodes >= max_nodes {
                exact = false;
                break;
            }
            nodes += 1;
            let e = center[k] - x[k];
            let d2 = partial[k + 1] + self.diag2[k] * e * e;
            if d2 < best_d2 {
                if k > 0 {
                    partial[k] = d2;
                    k -= 1;
                    self.enter(k, &mut sig, &mut stale, &mut center, &mut x, &mut step);
                    continue;
                }
                best_d2 = d2;
                best.copy_from_slice(&x);
            }
            // Pruned (or a leaf was recorded, whose siblings are farther): next sibling above.
            if k == n - 1 {
                break;
            }
            k += 1;
            x[k] += step[k];
            step[k] = -step[k] - step[k].signum();
            stale[k - 1] = stale[k - 1].max(k);
        }
        Found {
            x: best,
            d2: best_d2,
            exact,
            nodes,
        }
    }

    /// Enters level k from above: refreshes its partial sums and starts its zig-zag.
    fn enter(
        &self,
        k: usize,
        sig: &mut [f64],
        stale: &mut [usize],
        center: &mut [f64],
        x: &mut [f64],
        step: &mut [f64],
    ) {
        let n = self.n;
        let w = n + 1;
        if k > 0 {
            // Row k−1 will have to absorb what row k absorbs now, and the new x_k.
            stale[k - 1] = stale[k - 1].max(stale[k]).max(k);
        }
        for j in (k + 1..=stale[k]).rev() {
            sig[k * w + j] = sig[k * w + j + 1] - self.rn[k * n + j] * x[j];
        }
        stale[k] = k;
        let c = sig[k * w + k + 1];
        center[k] = c;
        x[k] = c.round();
        step[k] = if c >= x[k] { 1.0 } else { -1.0 };
    }
}
