//! The fits and their exact integrals (see the module docs of `bdrate`).

use super::Interpolation;

/// `∫_lo^hi f(x) dx` for the fit `f` of `(x, y)` by `method`; `[lo, hi]` lies inside `x`'s range.
pub(super) fn integrate(x: &[f64], y: &[f64], method: Interpolation, lo: f64, hi: f64) -> f64 {
    match method {
        Interpolation::Pchip => hermite_integral(x, y, &pchip_derivatives(x, y), lo, hi),
        Interpolation::Akima => hermite_integral(x, y, &akima_derivatives(x, y), lo, hi),
        Interpolation::Cubic => cubic_fit(x, y).integral(lo, hi),
    }
}

/// NumPy's `sign`: −1, 0 or 1 (0 for ±0, unlike `f64::signum`).
pub(super) fn sign(v: f64) -> f64 {
    if v > 0.0 {
        1.0
    } else if v < 0.0 {
        -1.0
    } else {
        0.0
    }
}

/// Secant slopes `m_k = (y_{k+1} − y_k) / h_k` and spacings `h_k`.
pub(super) fn secants(x: &[f64], y: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let h: Vec<f64> = x.windows(2).map(|w| w[1] - w[0]).collect();
    let m = y
        .windows(2)
        .zip(&h)
        .map(|(w, &hk)| (w[1] - w[0]) / hk)
        .collect();
    (h, m)
}

/// Knot derivatives of `scipy.interpolate.PchipInterpolator` (`_find_derivatives`).
pub(super) fn pchip_derivatives(x: &[f64], y: &[f64]) -> Vec<f64> {
    let (h, m) = secants(x, y);
    let n = x.len();
    if n == 2 {
        return vec![m[0], m[0]];
    }
    let mut d = vec![0.0; n];
    for k in 1..n - 1 {
        let (m0, m1) = (m[k - 1], m[k]);
        if sign(m1) != sign(m0) || m1 == 0.0 || m0 == 0.0 {
            continue; // d_k = 0
        }
        let w1 = 2.0 * h[k] + h[k - 1];
        let w2 = h[k] + 2.0 * h[k - 1];
        let whmean = (w1 / m0 + w2 / m1) / (w1 + w2);
        d[k] = 1.0 / whmean;
    }
    d[0] = pchip_end(h[0], h[1], m[0], m[1]);
    d[n - 1] = pchip_end(h[n - 2], h[n - 3], m[n - 2], m[n - 3]);
    d
}

/// scipy's `PchipInterpolator._edge_case`: the shape-preserving one-sided three-point end
/// derivative (`h0`, `m0`: the end segment; `h1`, `m1`: its neighbour).
pub(super) fn pchip_end(h0: f64, h1: f64, m0: f64, m1: f64) -> f64 {
    let d = ((2.0 * h0 + h1) * m0 - h0 * m1) / (h0 + h1);
    if sign(d) != sign(m0) {
        0.0
    } else if sign(m0) != sign(m1) && d.abs() > 3.0 * m0.abs() {
        3.0 * m0
    } else {
        d
    }
}

/// Knot derivatives of `scipy.interpolate.Akima1DInterpolator(method="akima")`.
pub(super) fn akima_derivatives(x: &[f64], y: &[f64]) -> Vec<f64> {
    let n = x.len();
    let (_, slopes) = secants(x, y);
    if n == 2 {
        return vec![slopes[0], slopes[0]];
    }
    // m[2..n+1] are the secants; two linearly extrapolated slopes on each side.
    let mut m = vec![0.0; n + 3];
    m[2..n + 1].copy_from_slice(&slopes);
    m[1] = 2.0 * m[2] - m[3];
    m[0] = 2.0 * m[1] - m[2];
    m[n + 1] = 2.0 * m[n] - m[n - 1];
    m[n + 2] = 2.0 * m[n + 1] - m[n];
    let dm: Vec<f64> = m.windows(2).map(|w| (w[1] - w[0]).abs()).collect();
    let f1 = &dm[2..];
    let f2 = &dm[..n];
    let f12: Vec<f64> = (0..n).map(|k| f1[k] + f2[k]).collect();
    let mmax = f12.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    const BREAK_MULT: f64 = 1e-9;
    (0..n)
        .map(|k| {
            if f12[k] > BREAK_MULT * mmax {
                m[k + 1] + (f2[k] / f12[k]) * (m[k + 2] - m[k + 1])
            } else {
                0.5 * (m[k + 3] + m[k])
            }
        })
        .collect()
}

/// `∫_lo^hi` of the cubic Hermite interpolant of `(x, y)` with knot derivatives `d`
/// (`[lo, hi]` inside `[x_0, x_{n−1}]`).
pub(super) fn hermite_integral(x: &[f64], y: &[f64], d: &[f64], lo: f64, hi: f64) -> f64 {
    let mut sum = 0.0;
    for k in 0..x.len() - 1 {
        let a = lo.max(x[k]);
        let b = hi.min(x[k + 1]);
        if b <= a {
            continue;
        }
        let h = x[k + 1] - x[k];
        let slope = (y[k + 1] - y[k]) / h;
        let tau = (d[k] + d[k + 1] - 2.0 * slope) / h;
        let c3 = tau / h;
        let c2 = (slope - d[k]) / h - tau;
        let (c1, c0) = (d[k], y[k]);
        let antiderivative = |u: f64| u * (c0 + u * (c1 / 2.0 + u * (c2 / 3.0 + u * (c3 / 4.0))));
        sum += antiderivative(b - x[k]) - antiderivative(a - x[k]);
    }
    sum
}

/// The least-squares cubic `p(x) = q((x − centre) / scale)`, `q(t) = Σ beta_j t^j`.
#[derive(Debug, Clone, Copy)]
pub(super) struct CubicFit {
    pub(super) centre: f64,
    pub(super) scale: f64,
    pub(super) beta: [f64; 4],
}

impl CubicFit {
    /// `∫_lo^hi p(x) dx = scale · [Q(t_hi) − Q(t_lo)]`, `Q(t) = Σ beta_j t^{j+1}/(j+1)`.
    pub(super) fn integral(&self, lo: f64, hi: f64) -> f64 {
        let [b0, b1, b2, b3] = self.beta;
        let antiderivative = |t: f64| t * (b0 + t * (b1 / 2.0 + t * (b2 / 3.0 + t * (b3 / 4.0))));
        let t_lo = (lo - self.centre) / self.scale;
        let t_hi = (hi - self.centre) / self.scale;
        self.scale * (antiderivative(t_hi) - antiderivative(t_lo))
    }
}

/// Least-squares cubic through `(x, y)` (`x` strictly increasing, at least 4 points): the
/// `n × 4` system `[1 t t² t³] β ≈ y` in `t ∈ [−1, 1]`, solved by Householder QR.
pub(super) fn cubic_fit(x: &[f64], y: &[f64]) -> CubicFit {
    const P: usize = 4;
    let n = x.len();
    let (x0, x1) = (x[0], x[n - 1]);
    let centre = 0.5 * (x0 + x1);
    let scale = 0.5 * (x1 - x0);
    // Column-major design matrix and right-hand side, reduced in place.
    let mut a: Vec<Vec<f64>> = (0..P)
        .map(|j| {
            x.iter()
                .map(|&xi| ((xi - centre) / scale).powi(j as i32))
                .collect()
        })
        .collect();
    let mut rhs = y.to_vec();
    for j in 0..P {
        // Householder reflector H = I − 2 v vᵀ / (vᵀv) zeroing a[j][j+1..].
        let norm = a[j][j..].iter().map(|v| v * v).sum::<f64>().sqrt();
        let alpha = if a[j][j] > 0.0 { -norm } else { norm };
        let mut v: Vec<f64> = a[j][j..].to_vec();
        v[0] -= alpha;
        let vv: f64 = v.iter().map(|e| e * e).sum();
        if vv == 0.0 {
            continue;
        }
        let reflect = |col: &mut [f64]| {
            let dot: f64 = v.iter().zip(col.iter()).map(|(p, q)| p * q).sum();
            let f = 2.0 * dot / vv;
            for (c, vi) in col.iter_mut().zip(&v) {
                *c -= f * vi;
            }
        };
        for col in a.iter_mut().skip(j) {
            reflect(&mut col[j..]);
        }
        reflect(&mut rhs[j..]);
    }
    // Back substitution R β = (Qᵀ y)[..4].
    let mut beta = [0.0; P];
    for i in (0..P).rev() {
        let tail: f64 = (i + 1..P).map(|j| a[j][i] * beta[j]).sum();
        beta[i] = (rhs[i] - tail) / a[i][i];
    }
    CubicFit {
        centre,
        scale,
        beta,
    }
}
