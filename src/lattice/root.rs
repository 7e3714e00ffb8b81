//! Fast exact decoders for the root lattices D_n and E8 (Conway & Sloane, "Fast quantizing and
//! decoding algorithms for lattice quantizers and codes", IEEE Trans. IT 28(2), 1982).
//!
//! - `D_n = {x ∈ Zⁿ : Σ x_i even}`: round every coordinate; if the sum is odd, round the
//!   coordinate farthest from an integer the other way.
//! - `E8 = D8 ∪ (D8 + ½·1)`: decode in both cosets and keep the closer point.
//!
//! Each decoder returns the point and its integer coordinates in the generator bases of
//! [`dn_basis`] and [`e8_basis`] (`point = B u` exactly). Rounding is f64 `round` (halves away
//! from zero), the worst coordinate is the first one of largest error, and on a tie between
//! the E8 cosets D8 wins, so every result is deterministic.

use super::{check_target, LatticeError, COORD_LIMIT};

/// A decoded point of D_n, E8 or E8^k.
#[derive(Debug, Clone, PartialEq)]
pub struct RootPoint {
    /// The lattice point (integers for D_n, integers or half-integers for E8).
    pub point: Vec<f64>,
    /// Its coordinates in the generator basis ([`dn_basis`], [`e8_basis`], or blockwise
    /// [`e8_basis`] for E8^k): `point = B u`.
    pub u: Vec<i64>,
    /// `‖y − point‖²`.
    pub distance2: f64,
}

/// Generator basis of D_n, row-major `n × n`, columns are the basis vectors:
/// `b_0 = 2e_0` and `b_j = e_j − e_{j−1}` for `1 ≤ j < n` (upper bidiagonal, det 2).
/// For `x ∈ D_n` the coordinates are `u_0 = ½ Σ_i x_i` and `u_j = Σ_{i ≥ j} x_i` (j ≥ 1).
pub fn dn_basis(n: usize) -> Vec<f64> {
    let mut b = vec![0.0; n * n];
    if n == 0 {
        return b;
    }
    b[0] = 2.0;
    for j in 1..n {
        b[j * n + j] = 1.0;
        b[(j - 1) * n + j] = -1.0;
    }
    b
}

/// Generator basis of E8, row-major `8 × 8`, columns are the basis vectors: `c_0 = 2e_0`,
/// `c_j = e_j − e_{j−1}` for `1 ≤ j ≤ 6`, and `c_7 = (½, …, ½)` (det 1).
/// For `x ∈ E8`: `u_7 = 2 x_7`, then with `x' = x − x_7·1` (an integer vector with `x'_7 = 0`
/// and an even sum), `u_0 = ½ Σ_{i ≤ 6} x'_i` and `u_j = Σ_{j ≤ i ≤ 6} x'_i` (1 ≤ j ≤ 6).
pub fn e8_basis() -> Vec<f64> {
    let n = 8;
    let mut b = vec![0.0; n * n];
    b[0] = 2.0;
    for j in 1..7 {
        b[j * n + j] = 1.0;
        b[(j - 1) * n + j] = -1.0;
    }
    for i in 0..n {
        b[i * n + 7] = 0.5;
    }
    b
}

/// Block-diagonal generator basis of E8^k (`n = 8k`, row-major `n × n`): [`e8_basis`] on
/// each block of 8 coordinates.
pub fn e8_product_basis(n: usize) -> Vec<f64> {
    let e8 = e8_basis();
    let mut b = vec![0.0; n * n];
    for blk in 0..n / 8 {
        for i in 0..8 {
            for j in 0..8 {
                b[(8 * blk + i) * n + 8 * blk + j] = e8[i * 8 + j];
            }
        }
    }
    b
}

/// The closest point of D_n to `y` (`n = y.len() ≥ 1`).
pub fn closest_dn(y: &[f64]) -> Result<RootPoint, LatticeError> {
    if y.is_empty() {
        return Err(LatticeError::EmptyDimension);
    }
    check_root(y)?;
    let x = dn_point(y);
    Ok(RootPoint {
        u: dn_coords(&x)?,
        distance2: dist2(y, &x),
        point: x,
    })
}

/// The closest point of E8 to `y` (`y.len() == 8`).
pub fn closest_e8(y: &[f64]) -> Result<RootPoint, LatticeError> {
    if y.len() != 8 {
        return Err(LatticeError::DimensionMismatch {
            expected: 8,
            got: y.len(),
        });
    }
    check_root(y)?;
    Ok(e8_block(y))
}

/// The closest point of E8^k to `y` (`y.len() = 8k`, k ≥ 1): E8 decoded block by block;
/// `u` holds the blocks' [`e8_basis`] coordinates one after the other.
pub fn closest_e8_product(y: &[f64]) -> Result<RootPoint, LatticeError> {
    if y.is_empty() {
        return Err(LatticeError::EmptyDimension);
    }
    if y.len() % 8 != 0 {
        return Err(LatticeError::DimensionMismatch {
            expected: y.len().div_ceil(8) * 8,
            got: y.len(),
        });
    }
    check_root(y)?;
    let mut out = RootPoint {
        point: Vec::with_capacity(y.len()),
        u: Vec::with_capacity(y.len()),
        distance2: 0.0,
    };
    for block in y.chunks_exact(8) {
        let p = e8_block(block);
        out.point.extend_from_slice(&p.point);
        out.u.extend_from_slice(&p.u);
        out.distance2 += p.distance2;
    }
    Ok(out)
}

/// Finite and within [`COORD_LIMIT`].
fn check_root(y: &[f64]) -> Result<(), LatticeError> {
    check_target(y)?;
    if y.iter().all(|v| v.abs() <= COORD_LIMIT) {
        Ok(())
    } else {
        Err(LatticeError::OutOfRange)
    }
}

fn dist2(y: &[f64], x: &[f64]) -> f64 {
    y.iter().zip(x).fold(0.0, |s, (a, b)| s + (a - b) * (a - b))
}

/// Conway & Sloane's f / g: the nearest point of D_n (y checked finite and in range).
fn dn_point(y: &[f64]) -> Vec<f64> {
    let mut x: Vec<f64> = y.iter().map(|v| v.round()).collect();
    let sum = x.iter().fold(0i64, |s, &v| s.wrapping_add(v as i64));
    if sum.rem_euclid(2) == 1 {
        let mut worst = 0;
        let mut worst_err = -1.0;
        for (i, (&yi, &xi)) in y.iter().zip(&x).enumerate() {
            let err = (yi - xi).abs();
            if err > worst_err {
                worst_err = err;
                worst = i;
            }
        }
        x[worst] += if y[worst] >= x[worst] { 1.0 } else { -1.0 };
    }
    x
}

/// Coordinates of `x ∈ D_n` in [`dn_basis`] (suffix sums, in i128 so that no length overflows).
fn dn_coords(x: &[f64]) -> Result<Vec<i64>, LatticeError> {
    let n = x.len();
    let mut u = vec![0i64; n];
    let mut suffix = 0i128;
    for j in (1..n).rev() {
        suffix += x[j] as i128;
        u[j] = i64::try_from(suffix).map_err(|_| LatticeError::OutOfRange)?;
    }
    u[0] = i64::try_from((suffix + x[0] as i128) / 2).map_err(|_| LatticeError::OutOfRange)?;
    Ok(u)
}

/// Nearest point of E8 to one block of 8 (checked finite and in range).
fn e8_block(y: &[f64]) -> RootPoint {
    let a = dn_point(y);
    let shifted: Vec<f64> = y.iter().map(|v| v - 0.5).collect();
    let b: Vec<f64> = dn_point(&shifted).iter().map(|v| v + 0.5).collect();
    let (da, db) = (dist2(y, &a), dist2(y, &b));
    let (x, d) = if db < da { (b, db) } else { (a, da) };
    RootPoint {
        u: e8_coords(&x),
        distance2: d,
        point: x,
    }
}

/// Coordinates of `x ∈ E8` in [`e8_basis`].
fn e8_coords(x: &[f64]) -> Vec<i64> {
    let u7 = (2.0 * x[7]) as i64;
    let half = x[7];
    let xp: Vec<i64> = x[..7].iter().map(|&v| (v - half) as i64).collect();
    let mut u = vec![0i64; 8];
    u[7] = u7;
    let mut suffix = 0i64;
    for j in (1..7).rev() {
        suffix += xp[j];
        u[j] = suffix;
    }
    u[0] = (suffix + xp[0]) / 2;
    u
}
