//! Small dense linear algebra in f64 for the lattice searches (encoder side, not normative).
//!
//! Matrices are square, `n × n`, row-major in a flat slice: `a[i * n + j]` is row `i`, column
//! `j`. Sums run in index order, so every result is a pure function of the inputs.

/// `a · x` for a row-major `n × n` matrix `a` and a vector `x` of length `n`.
pub fn mat_vec(n: usize, a: &[f64], x: &[f64]) -> Vec<f64> {
    (0..n).map(|i| dot(&a[i * n..(i + 1) * n], x)).collect()
}

/// `aᵀ · x` for a row-major `n × n` matrix `a`.
pub fn mat_t_vec(n: usize, a: &[f64], x: &[f64]) -> Vec<f64> {
    let mut out = vec![0.0; n];
    for (i, &xi) in x.iter().enumerate().take(n) {
        for (o, &aij) in out.iter_mut().zip(&a[i * n..(i + 1) * n]) {
            *o += aij * xi;
        }
    }
    out
}

/// `a · b` for row-major `n × n` matrices.
pub fn mat_mul(n: usize, a: &[f64], b: &[f64]) -> Vec<f64> {
    let mut out = vec![0.0; n * n];
    for i in 0..n {
        for k in 0..n {
            let aik = a[i * n + k];
            for j in 0..n {
                out[i * n + j] += aik * b[k * n + j];
            }
        }
    }
    out
}

/// Dot product in index order.
pub fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).fold(0.0, |s, (x, y)| s + x * y)
}

/// `‖y − a·u‖²` for a row-major `n × n` matrix `a` and integer coordinates `u`.
pub fn residual2(n: usize, a: &[f64], u: &[i64], y: &[f64]) -> f64 {
    let mut d2 = 0.0;
    for i in 0..n {
        let row = &a[i * n..(i + 1) * n];
        let p = row
            .iter()
            .zip(u)
            .fold(0.0, |s, (&aij, &uj)| s + aij * uj as f64);
        let e = y[i] - p;
        d2 += e * e;
    }
    d2
}

/// Householder QR of a square row-major matrix: `a = q · r`, `q` orthogonal, `r` upper
/// triangular with `r[i][i] ≥ 0`. Columns of `a` that are (numerically) zero give a zero
/// diagonal; the caller decides what is singular.
pub fn qr(n: usize, a: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let mut r = a.to_vec();
    let mut vs: Vec<Vec<f64>> = Vec::with_capacity(n);
    for k in 0..n {
        let norm = (k..n)
            .fold(0.0, |s, i| s + r[i * n + k] * r[i * n + k])
            .sqrt();
        let x0 = r[k * n + k];
        let alpha = if x0 < 0.0 { norm } else { -norm };
        let mut v: Vec<f64> = (k..n).map(|i| r[i * n + k]).collect();
        v[0] -= alpha;
        let vn = v.iter().fold(0.0, |s, x| s + x * x).sqrt();
        if vn.is_nan() || vn <= 1e-300 {
            vs.push(Vec::new());
            continue;
        }
        v.iter_mut().for_each(|x| *x /= vn);
        for j in k..n {
            let d = (k..n).fold(0.0, |s, i| s + v[i - k] * r[i * n + j]);
            for i in k..n {
                r[i * n + j] -= 2.0 * v[i - k] * d;
            }
        }
        for i in k + 1..n {
            r[i * n + k] = 0.0;
        }
        vs.push(v);
    }
    // Q = H_0 H_1 … H_{n−1} applied to the identity, last reflection first.
    let mut q = vec![0.0; n * n];
    for i in 0..n {
        q[i * n + i] = 1.0;
    }
    for k in (0..n).rev() {
        let v = &vs[k];
        if v.is_empty() {
            continue;
        }
        for j in 0..n {
            let d = (k..n).fold(0.0, |s, i| s + v[i - k] * q[i * n + j]);
            for i in k..n {
                q[i * n + j] -= 2.0 * v[i - k] * d;
            }
        }
    }
    // Make the diagonal of R non-negative: flip row k of R and column k of Q together.
    for k in 0..n {
        if r[k * n + k] < 0.0 {
            for j in 0..n {
                r[k * n + j] = -r[k * n + j];
                q[j * n + k] = -q[j * n + k];
            }
        }
    }
    (q, r)
}

/// `a⁻¹ = r⁻¹ qᵀ` from a QR factorization whose diagonal is non-zero.
pub fn inverse_from_qr(n: usize, q: &[f64], r: &[f64]) -> Vec<f64> {
    let mut inv = vec![0.0; n * n];
    // Column j of a⁻¹ solves r x = (row j of q)ᵀ … i.e. r x = qᵀ e_j.
    for j in 0..n {
        let rhs: Vec<f64> = (0..n).map(|i| q[j * n + i]).collect();
        let x = back_substitute(n, r, &rhs);
        for i in 0..n {
            inv[i * n + j] = x[i];
        }
    }
    inv
}

/// Solves the upper triangular system `r x = b`.
pub fn back_substitute(n: usize, r: &[f64], b: &[f64]) -> Vec<f64> {
    let mut x = vec![0.0; n];
    for i in (0..n).rev() {
        let s = (i + 1..n).fold(b[i], |s, j| s - r[i * n + j] * x[j]);
        x[i] = s / r[i * n + i];
    }
    x
}

/// `u · diag(s) · vᵀ` for row-major `n × n` matrices `u`, `v`.
pub fn from_svd(n: usize, u: &[f64], s: &[f64], v: &[f64]) -> Vec<f64> {
    let mut b = vec![0.0; n * n];
    for i in 0..n {
        for j in 0..n {
            b[i * n + j] = (0..n).fold(0.0, |acc, k| acc + u[i * n + k] * s[k] * v[j * n + k]);
        }
    }
    b
}

/// The exact determinant of an integer matrix (fraction-free Bareiss elimination in i128), or
/// `None` if an intermediate value overflows i128.
pub fn det_i64(n: usize, a: &[i64]) -> Option<i128> {
    let mut m: Vec<i128> = a.iter().map(|&x| x as i128).collect();
    let mut sign = 1i128;
    let mut prev = 1i128;
    for k in 0..n {
        if m[k * n + k] == 0 {
            let Some(p) = (k + 1..n).find(|&i| m[i * n + k] != 0) else {
                return Some(0);
            };
            for j in 0..n {
                m.swap(k * n + j, p * n + j);
            }
            sign = -sign;
        }
        for i in k + 1..n {
            for j in k + 1..n {
                let v = m[i * n + j]
                    .checked_mul(m[k * n + k])?
                    .checked_sub(m[i * n + k].checked_mul(m[k * n + j])?)?;
                m[i * n + j] = v / prev;
            }
        }
        prev = m[k * n + k];
    }
    if n == 0 {
        return Some(1);
    }
    Some(sign * m[(n - 1) * n + n - 1])
}
