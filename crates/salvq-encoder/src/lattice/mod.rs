//! Lattice point search for SALVQ encoders (encoder side; not normative).
//!
//! A SALVQ quantizer is a lattice `{B u : u ∈ Zⁿ}` with a learned basis `B = U diag(s) Vᵀ`
//! (spec §2.6). The decoder only ever computes `B u`; which `u` an encoder picks for a target `y`
//! is the encoder's choice, so this module offers several searches, from cheap to exact:
//!
//! | method | cost | result |
//! |---|---|---|
//! | [`Lattice::babai_rounding`]: `u = round(B⁻¹y)` (what SALVQ training uses) | one mat-vec | approximate |
//! | [`Lattice::babai_nearest_plane`]: successive interference cancellation on a QR | one triangular solve | approximate; better on the LLL basis |
//! | [`Lattice::closest_point`]: Schnorr–Euchner enumeration on the LLL basis | grows with n and cond | exact unless the node bound stops it |
//! | [`closest_dn`], [`closest_e8`], [`closest_e8_product`] | O(n) | exact, for D_n, E8, E8^k only |
//!
//! All searches return integer coordinates `u` with respect to the **original** basis (the LLL
//! transform `T` is tracked exactly in integers: `B T` is the reduced basis, and a reduced
//! solution `v` is returned as `u = T v`). Everything runs in f64, single-threaded, with sums in
//! index order: results are deterministic. Nothing panics on finite inputs; bad bases and
//! targets are [`LatticeError`]s.
//!
//! Matrices are row-major `n × n` slices whose **columns** are the basis vectors
//! (`b[i * n + j]` is component `i` of basis vector `j`).
//!
//! Numerical decisions:
//! - a basis is [`LatticeError::Singular`] when a Gram–Schmidt norm `‖b*_k‖` is at most
//!   [`SINGULAR_RTOL`] `= 10⁻¹²` times the longest basis vector (spec §2.6 caps SALVQ bases at
//!   condition 10⁶, far inside this);
//! - coordinates are carried as f64 integers and must stay within [`COORD_LIMIT`] `= 2^50`
//!   (else [`LatticeError::OutOfRange`]), so every integer is exact;
//! - "exact" means exact in f64: two lattice points whose distances differ by a few ulps may
//!   be ranked either way, deterministically.
//!
//! Choosing a method (`cargo bench --bench lattice_search`, SALVQ-like bases, cond ≤ 10³): the
//! exact search costs about 1 µs per vector at n = 8 and 5 µs at n = 16 (a few hundred nodes;
//! rounding costs 0.1–0.3 µs), while at n = 50 proving optimality takes 10⁶–10⁸ nodes, so
//! there the node bound decides. At n = 50 the LLL parameter matters much more than the bound:
//! [`Lattice::with_delta`] with δ = 0.99 cuts the nearest-plane MSE by 3× at cond 10³ against
//! the default δ = 0.75.

pub mod linalg;
pub mod lll;
pub mod root;
mod search;
#[cfg(test)]
mod tests;

use std::fmt;

pub use lll::{Reduction, LLL_DELTA};
pub use root::{
    closest_dn, closest_e8, closest_e8_product, dn_basis, e8_basis, e8_product_basis, RootPoint,
};
use search::{Found, Triangular};

/// Largest coordinate magnitude any search handles (2^50: integers stay exact in f64 with room).
pub const COORD_LIMIT: f64 = 1_125_899_906_842_624.0;
/// Relative threshold below which a Gram–Schmidt norm makes a basis singular.
pub const SINGULAR_RTOL: f64 = 1e-12;
/// The node bound recommended for [`SearchMethod::ClosestPoint`]: complete (exact) for every
/// SALVQ-like basis tried up to n = 16 (16 000 targets per condition needed at most 3 901 nodes
/// at δ = 0.75, 1 053 at δ = 0.99 for cond ≥ 10), about 140 µs per vector at n = 50, where it
/// does not prove optimality (see `benches/lattice_search.rs`).
pub const DEFAULT_MAX_NODES: u64 = 10_000;

/// Why a lattice could not be built or a target not quantized.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LatticeError {
    /// Dimension 0.
    EmptyDimension,
    /// A slice has the wrong length.
    DimensionMismatch {
        /// The length required.
        expected: usize,
        /// The length given.
        got: usize,
    },
    /// The basis has a NaN or infinite entry, or overflows f64 when factored.
    NonFiniteBasis,
    /// The basis is singular (a Gram–Schmidt norm ≤ [`SINGULAR_RTOL`] · longest vector).
    Singular,
    /// The target has a NaN or infinite component.
    NonFiniteTarget,
    /// A coordinate exceeds [`COORD_LIMIT`] or i64.
    OutOfRange,
    /// The LLL transform left the exactly representable range (|T_ij| > 2^53).
    Overflow,
    /// LLL did not finish within its step bound (only possible with pathological rounding).
    ReductionDidNotConverge,
    /// The LLL parameter δ is not in (¼, 1).
    InvalidDelta,
}

impl fmt::Display for LatticeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LatticeError::EmptyDimension => f.write_str("lattice: dimension 0"),
            LatticeError::DimensionMismatch { expected, got } => {
                write!(f, "lattice: length {got}, expected {expected}")
            }
            LatticeError::NonFiniteBasis => f.write_str("lattice: basis is not finite"),
            LatticeError::Singular => f.write_str("lattice: basis is singular"),
            LatticeError::NonFiniteTarget => f.write_str("lattice: target is not finite"),
            LatticeError::OutOfRange => {
                f.write_str("lattice: coordinates beyond 2^50 (target too far out)")
            }
            LatticeError::Overflow => f.write_str("lattice: LLL transform overflow"),
            LatticeError::ReductionDidNotConverge => {
                f.write_str("lattice: LLL reduction did not converge")
            }
            LatticeError::InvalidDelta => f.write_str("lattice: LLL δ must lie in (1/4, 1)"),
        }
    }
}

impl std::error::Error for LatticeError {}

/// Which search [`Lattice::quantize`] runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SearchMethod {
    /// Babai rounding `u = round(B⁻¹y)`.
    Rounding,
    /// Babai nearest plane on the LLL-reduced basis.
    NearestPlane,
    /// Schnorr–Euchner closest point, stopped after `max_nodes` visited nodes.
    ClosestPoint {
        /// The node bound.
        max_nodes: u64,
    },
}

/// A quantized vector.
#[derive(Debug, Clone, PartialEq)]
pub struct Quantized {
    /// Integer coordinates in the original basis: the lattice point is `B u`.
    pub u: Vec<i64>,
    /// `‖y − B u‖²`, evaluated directly from the original basis (comparable across methods).
    pub distance2: f64,
    /// True only when the search proved `B u` a closest point (a complete enumeration).
    pub exact: bool,
    /// Search nodes visited (0 for rounding, n for nearest plane).
    pub nodes: u64,
}

/// A lattice with the precomputations its searches need.
#[derive(Debug, Clone)]
pub struct Lattice {
    n: usize,
    basis: Vec<f64>,
    inverse: Vec<f64>,
    plain: Triangular,
    reduction: Reduction,
    reduced: Triangular,
}

pub(crate) fn check_target(y: &[f64]) -> Result<(), LatticeError> {
    if y.iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(LatticeError::NonFiniteTarget)
    }
}

fn to_i64(x: f64) -> Result<i64, LatticeError> {
    if x.abs() <= COORD_LIMIT {
        Ok(x as i64)
    } else {
        Err(LatticeError::OutOfRange)
    }
}

impl Lattice {
    /// Builds a lattice from a row-major `n × n` basis whose columns are the basis vectors:
    /// QR and inverse of B, LLL reduction (δ = [`LLL_DELTA`]) with its exact transform, QR of
    /// the reduced basis.
    pub fn new(n: usize, basis: &[f64]) -> Result<Self, LatticeError> {
        Lattice::with_delta(n, basis, LLL_DELTA)
    }

    /// [`Lattice::new`] with another LLL parameter δ ∈ (¼, 1). A larger δ costs more swaps
    /// once, and gives a better nearest plane and a faster enumeration in high dimension
    /// (δ = 0.99 halves the bounded-search MSE at n = 50, cond 10³; see the bench).
    pub fn with_delta(n: usize, basis: &[f64], delta: f64) -> Result<Self, LatticeError> {
        if !(delta > 0.25 && delta < 1.0) {
            return Err(LatticeError::InvalidDelta);
        }
        if n == 0 {
            return Err(LatticeError::EmptyDimension);
        }
        let expected = n.checked_mul(n).ok_or(LatticeError::DimensionMismatch {
            expected: usize::MAX,
            got: basis.len(),
        })?;
        if basis.len() != expected {
            return Err(LatticeError::DimensionMismatch {
                expected,
                got: basis.len(),
            });
        }
        if basis.iter().any(|v| !v.is_finite()) {
            return Err(LatticeError::NonFiniteBasis);
        }
        let plain = Triangular::new(n, basis, SINGULAR_RTOL)?;
        let inverse = linalg::inverse_from_qr(n, &plain.q, &plain.r);
        if inverse.iter().any(|v| !v.is_finite()) {
            return Err(LatticeError::NonFiniteBasis);
        }
        let reduction = lll::lll(n, basis, delta)?;
        let reduced = Triangular::new(n, &reduction.reduced, SINGULAR_RTOL)?;
        Ok(Lattice {
            n,
            basis: basis.to_vec(),
            inverse,
            plain,
            reduction,
            reduced,
        })
    }

    /// Builds the SALVQ lattice `B = U diag(s) Vᵀ` (U, V row-major `n × n`, as in spec §2.6).
    pub fn from_svd(n: usize, u: &[f64], s: &[f64], v: &[f64]) -> Result<Self, LatticeError> {
        for (len, want) in [(u.len(), n * n), (s.len(), n), (v.len(), n * n)] {
            if len != want {
                return Err(LatticeError::DimensionMismatch {
                    expected: want,
                    got: len,
                });
            }
        }
        Lattice::new(n, &linalg::from_svd(n, u, s, v))
    }

    /// The dimension n.
    pub fn dim(&self) -> usize {
        self.n
    }

    /// The original basis B (row-major, columns are basis vectors).
    pub fn basis(&self) -> &[f64] {
        &self.basis
    }

    /// `B⁻¹` (row-major).
    pub fn inverse(&self) -> &[f64] {
        &self.inverse
    }

    /// The LLL-reduced basis `B T` (row-major, columns are basis vectors).
    pub fn reduced_basis(&self) -> &[f64] {
        &self.reduction.reduced
    }

    /// The unimodular transform T (row-major): reduced basis vector j is `B · (column j of T)`.
    pub fn transform(&self) -> &[i64] {
        &self.reduction.transform
    }

    /// Number of swaps LLL made.
    pub fn lll_swaps(&self) -> u64 {
        self.reduction.swaps
    }

    /// The lattice point `B u`.
    pub fn point(&self, u: &[i64]) -> Result<Vec<f64>, LatticeError> {
        self.check_len(u.len())?;
        let uf: Vec<f64> = u.iter().map(|&x| x as f64).collect();
        Ok(linalg::mat_vec(self.n, &self.basis, &uf))
    }

    /// `‖y − B u‖²` in f64.
    pub fn distance2(&self, y: &[f64], u: &[i64]) -> Result<f64, LatticeError> {
        self.check_len(y.len())?;
        self.check_len(u.len())?;
        Ok(linalg::residual2(self.n, &self.basis, u, y))
    }

    fn check_len(&self, got: usize) -> Result<(), LatticeError> {
        if got == self.n {
            Ok(())
        } else {
            Err(LatticeError::DimensionMismatch {
                expected: self.n,
                got,
            })
        }
    }

    fn check(&self, y: &[f64]) -> Result<(), LatticeError> {
        self.check_len(y.len())?;
        check_target(y)
    }

    /// Wraps coordinates of the original basis.
    fn finish(
        &self,
        y: &[f64],
        x: &[f64],
        exact: bool,
        nodes: u64,
    ) -> Result<Quantized, LatticeError> {
        let u = x
            .iter()
            .map(|&v| to_i64(v))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Quantized {
            distance2: linalg::residual2(self.n, &self.basis, &u, y),
            u,
            exact,
            nodes,
        })
    }

    /// Wraps coordinates of the reduced basis: `u = T v`, exactly in i128.
    fn finish_reduced(&self, y: &[f64], f: Found) -> Result<Quantized, LatticeError> {
        let n = self.n;
        let v =
            f.x.iter()
                .map(|&x| to_i64(x))
                .collect::<Result<Vec<_>, _>>()?;
        let t = &self.reduction.transform;
        let mut u = Vec::with_capacity(n);
        for i in 0..n {
            let s = (0..n).fold(0i128, |s, j| s + t[i * n + j] as i128 * v[j] as i128);
            u.push(i64::try_from(s).map_err(|_| LatticeError::OutOfRange)?);
        }
        Ok(Quantized {
            distance2: linalg::residual2(n, &self.basis, &u, y),
            u,
            exact: f.exact,
            nodes: f.nodes,
        })
    }

    /// Babai rounding: `u = round(B⁻¹ y)`, the SALVQ training quantizer.
    pub fn babai_rounding(&self, y: &[f64]) -> Result<Quantized, LatticeError> {
        self.check(y)?;
        let z = linalg::mat_vec(self.n, &self.inverse, y);
        let x: Vec<f64> = z.iter().map(|v| v.round()).collect();
        self.finish(y, &x, false, 0)
    }

    /// Babai nearest plane on the QR of B (`reduced = false`) or of the LLL-reduced basis.
    pub fn babai_nearest_plane(&self, y: &[f64], reduced: bool) -> Result<Quantized, LatticeError> {
        self.check(y)?;
        if reduced {
            let f = self.reduced.nearest_plane(&self.reduced.scaled_target(y))?;
            self.finish_reduced(y, f)
        } else {
            let f = self.plain.nearest_plane(&self.plain.scaled_target(y))?;
            self.finish(y, &f.x, false, f.nodes)
        }
    }

    /// Closest lattice point by Schnorr–Euchner enumeration on the LLL-reduced basis, starting
    /// from the nearest-plane point's radius. `exact` is false when `max_nodes` stopped it (the
    /// result is then the best point found, never worse than nearest plane on the LLL basis).
    pub fn closest_point(&self, y: &[f64], max_nodes: u64) -> Result<Quantized, LatticeError> {
        self.check(y)?;
        let ys = self.reduced.scaled_target(y);
        let start = self.reduced.nearest_plane(&ys)?;
        let f = self.reduced.closest(&ys, start, max_nodes);
        self.finish_reduced(y, f)
    }

    /// Quantizes `y` with the chosen method.
    pub fn quantize(&self, y: &[f64], method: SearchMethod) -> Result<Quantized, LatticeError> {
        match method {
            SearchMethod::Rounding => self.babai_rounding(y),
            SearchMethod::NearestPlane => self.babai_nearest_plane(y, true),
            SearchMethod::ClosestPoint { max_nodes } => self.closest_point(y, max_nodes),
        }
    }
}
