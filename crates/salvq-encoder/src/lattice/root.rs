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
use salvq_bitstream::quantizer::E8_BASIS_TWICE;

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

/// Generator basis of D_n (§7.2), row-major `n × n`, columns are the basis vectors:
/// `b_j = e_j − e_{n−1}` for `j < n − 1` and `b_{n−1} = 2e_{n−1}` (lower triangular, det 2).
/// For `x ∈ D_n` the coordinates are `u_j = x_j` (j < n − 1) and `u_{n−1} = ½ Σ_i x_i`: the
/// rows of `B⁻¹` are `e_j` and `½·1`, the shortest dual basis there is, so the coordinates
/// are as narrow as they can be (their variances are σ² and nσ²/4 for an isotropic source).
pub fn dn_basis(n: usize) -> Vec<f64> {
    let mut b = vec![0.0; n * n];
    if n == 0 {
        return b;
    }
    let last = n - 1;
    for j in 0..last {
        b[j * n + j] = 1.0;
        b[last * n + j] = -1.0;
    }
    b[last * n + last] = 2.0;
    b
}

/// Generator basis of E8 (§7.2, Table 7-2), row-major `8 × 8`, columns are the basis
/// vectors. It is the inverse of the root matrix whose rows are `e_j − e_{j+1}` (j ≤ 5),
/// `e_5 + e_6` and `½·1`, so for `x ∈ E8` the coordinates are `u_j = x_j − x_{j+1}` (j ≤ 5),
/// `u_6 = x_5 + x_6` and `u_7 = ½ Σ_i x_i`: every row of `B⁻¹` is a root (norm² 2, the
/// shortest dual vectors of the self-dual E8), so every coordinate has variance 2σ² for an
/// isotropic source. Entries are multiples of ½ (det 1).
pub fn e8_basis() -> Vec<f64> {
    E8_BASIS_TWICE.iter().map(|&v| f64::from(v) / 2.0).collect()
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
    if !y.len().is_multiple_of(8) {
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

/// Coordinates of `x ∈ D_n` in [`dn_basis`]: `x_j` for j < n − 1, then half the sum (in
/// i128 so that no length overflows).
fn dn_coords(x: &[f64]) -> Result<Vec<i64>, LatticeError> {
    let n = x.len();
    let mut u: Vec<i64> = x[..n - 1].iter().map(|&v| v as i64).collect();
    let sum = x.iter().fold(0i128, |s, &v| s + v as i128);
    u.push(i64::try_from(sum / 2).map_err(|_| LatticeError::OutOfRange)?);
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

/// Coordinates of `x ∈ E8` in [`e8_basis`]: inner products with the rows of `B⁻¹`, computed
/// on `2x` (integers) so that they are exact.
fn e8_coords(x: &[f64]) -> Vec<i64> {
    let t: Vec<i64> = x.iter().map(|&v| (2.0 * v) as i64).collect();
    let mut u = vec![0i64; 8];
    for j in 0..6 {
        u[j] = (t[j] - t[j + 1]) / 2;
    }
    u[6] = (t[5] + t[6]) / 2;
    u[7] = t.iter().sum::<i64>() / 4;
    u
}
