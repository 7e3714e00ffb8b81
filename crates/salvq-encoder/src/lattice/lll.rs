//! LLL reduction (Lenstra, Lenstra, Lovász 1982) with an exact integer transform.
//!
//! Floating-point LLL in the style of Schnorr and Euchner: the basis stays an exact integer
//! combination `C = B T` of the original basis; `T` is tracked in `i64` with checked arithmetic,
//! and each working vector `c_k` is recomputed from `B t_k` after it changes, so rounding errors
//! never accumulate in the basis itself. Gram–Schmidt data of `c_k` come from classical
//! Gram–Schmidt applied twice against the orthonormal directions of `c_0 … c_{k−1}`.
//!
//! Output guarantees (up to f64 rounding): size-reduced, `|μ_kj| ≤ ½ + 10⁻⁹`, and the Lovász
//! condition `δ ‖c*_{k−1}‖² ≤ ‖c*_k‖² + μ²_{k,k−1} ‖c*_{k−1}‖²` holds for every `k`.

use super::linalg::dot;
use super::LatticeError;

/// The Lovász parameter δ the encoder uses (the textbook value).
pub const LLL_DELTA: f64 = 0.75;

/// Size reduction subtracts `round(μ)` whenever `|μ| > ½ + SIZE_SLACK` (the slack keeps a
/// coefficient at ½ plus rounding noise from flipping forever).
const SIZE_SLACK: f64 = 1e-9;
/// Size-reduction passes per step before it goes on with what it has (never reached in tests).
const MAX_SIZE_PASSES: usize = 32;
/// Transform entries must stay exactly representable in f64.
const T_LIMIT: i64 = 1 << 53;

/// The LLL-reduced basis `C = B T` and the unimodular transform `T` (both row-major, n × n).
#[derive(Debug, Clone)]
pub struct Reduction {
    /// `T`, integer, |det T| = 1: column j of T holds the original coordinates of `c_j`.
    pub transform: Vec<i64>,
    /// `C = B T`, columns are the reduced basis vectors.
    pub reduced: Vec<f64>,
    /// Number of swaps performed.
    pub swaps: u64,
}

struct State<'a> {
    n: usize,
    basis: &'a [f64],
    /// Columns of T.
    t: Vec<Vec<i64>>,
    /// Columns of C = B T.
    c: Vec<Vec<f64>>,
    /// Orthonormal Gram–Schmidt directions of c_0 … c_{k−1}.
    q: Vec<Vec<f64>>,
    /// `rc[j][i] = ⟨q_i, c_j⟩` for i < j and `rc[j][j] = ‖c*_j‖`.
    rc: Vec<Vec<f64>>,
}

impl State<'_> {
    /// Recomputes column k of C from column k of T.
    fn refresh(&mut self, k: usize) {
        let n = self.n;
        let t = &self.t[k];
        for i in 0..n {
            let row = &self.basis[i * n..(i + 1) * n];
            self.c[k][i] = row.iter().zip(t).fold(0.0, |s, (&b, &x)| s + b * x as f64);
        }
    }

    /// Coefficients `a_i = ⟨q_i, c_k⟩` (i < k) and the residual `c*_k` (CGS2).
    fn project(&self, k: usize) -> (Vec<f64>, Vec<f64>) {
        let mut res = self.c[k].clone();
        let mut a = vec![0.0; k];
        for _ in 0..2 {
            let delta: Vec<f64> = (0..k).map(|i| dot(&self.q[i], &res)).collect();
            for (i, &d) in delta.iter().enumerate() {
                a[i] += d;
                for (r, &qv) in res.iter_mut().zip(&self.q[i]) {
                    *r -= d * qv;
                }
            }
        }
        (a, res)
    }

    /// Makes c_0 the first Gram–Schmidt vector.
    fn init_first(&mut self) -> Result<(), LatticeError> {
        let norm = dot(&self.c[0], &self.c[0]).sqrt();
        if !(norm > 0.0 && norm.is_finite()) {
            return Err(LatticeError::Singular);
        }
        self.q[0] = self.c[0].iter().map(|x| x / norm).collect();
        self.rc[0] = vec![norm];
        Ok(())
    }

    /// `t_k −= m t_j`, checked.
    fn sub_column(&mut self, k: usize, j: usize, m: i64) -> Result<(), LatticeError> {
        for i in 0..self.n {
            let v = m
                .checked_mul(self.t[j][i])
                .and_then(|p| self.t[k][i].checked_sub(p))
                .filter(|v| v.abs() <= T_LIMIT)
                .ok_or(LatticeError::Overflow)?;
            self.t[k][i] = v;
        }
        Ok(())
    }

    /// Size-reduces c_k against c_0 … c_{k−1}; returns its final coefficients and residual.
    fn size_reduce(&mut self, k: usize) -> Result<(Vec<f64>, Vec<f64>), LatticeError> {
        for _ in 0..MAX_SIZE_PASSES {
            let (mut a, res) = self.project(k);
            let mut changed = false;
            for j in (0..k).rev() {
                let mu = a[j] / self.rc[j][j];
                if mu.abs() > 0.5 + SIZE_SLACK {
                    let m = mu.round();
                    if m.is_nan() || m.abs() > T_LIMIT as f64 {
                        return Err(LatticeError::Overflow);
                    }
                    for (ai, &r) in a.iter_mut().zip(&self.rc[j]) {
                        *ai -= m * r;
                    }
                    self.sub_column(k, j, m as i64)?;
                    changed = true;
                }
            }
            if !changed {
                return Ok((a, res));
            }
            self.refresh(k);
        }
        Ok(self.project(k))
    }
}

/// LLL-reduces the columns of the row-major `n × n` basis (which must be non-singular and
/// finite; [`super::Lattice::new`] checks that first).
pub fn lll(n: usize, basis: &[f64], delta: f64) -> Result<Reduction, LatticeError> {
    let mut st = State {
        n,
        basis,
        t: (0..n)
            .map(|j| (0..n).map(|i| i64::from(i == j)).collect())
            .collect(),
        c: vec![vec![0.0; n]; n],
        q: vec![Vec::new(); n],
        rc: vec![Vec::new(); n],
    };
    for k in 0..n {
        st.refresh(k);
    }
    let mut swaps = 0u64;
    if n > 0 {
        st.init_first()?;
    }
    // A generous bound on the steps (LLL needs O(n² log cond) swaps): a safety net only.
    let max_steps = 10_000u64 + 2_000 * (n as u64) * (n as u64);
    let mut steps = 0u64;
    let mut k = 1;
    while k < n {
        steps += 1;
        if steps > max_steps {
            return Err(LatticeError::ReductionDidNotConverge);
        }
        let (a, res) = st.size_reduce(k)?;
        let rkk2 = dot(&res, &res);
        let prev = st.rc[k - 1][k - 1];
        if delta * prev * prev > rkk2 + a[k - 1] * a[k - 1] {
            st.t.swap(k - 1, k);
            st.c.swap(k - 1, k);
            swaps += 1;
            if k == 1 {
                st.init_first()?;
            } else {
                k -= 1;
            }
        } else {
            let rkk = rkk2.sqrt();
            if !(rkk > 0.0 && rkk.is_finite()) {
                return Err(LatticeError::Singular);
            }
            st.q[k] = res.iter().map(|x| x / rkk).collect();
            let mut col = a;
            col.push(rkk);
            st.rc[k] = col;
            k += 1;
        }
    }
    let mut transform = vec![0i64; n * n];
    let mut reduced = vec![0.0; n * n];
    for j in 0..n {
        st.refresh(j);
        for i in 0..n {
            transform[i * n + j] = st.t[j][i];
            reduced[i * n + j] = st.c[j][i];
        }
    }
    Ok(Reduction {
        transform,
        reduced,
        swaps,
    })
}
