//! Small dense linear algebra in f64 with basic operations only (Annex B.2).

use super::rng::Stream;

/// Sum in iteration order starting from +0.0 (`Iterator::sum`'s start value is not part of its
/// contract, so the generator never uses it).
pub fn fsum(it: impl IntoIterator<Item = f64>) -> f64 {
    it.into_iter().fold(0.0, |a, b| a + b)
}

/// Rounds to the nearest binary32 (ties to even), the one conversion from f64 the generator uses.
pub fn round_f32(v: f64) -> f32 {
    v as f32
}

/// A random orthogonal n x n matrix, row-major: Householder QR of a matrix of i.i.d. normals
/// (drawn row by row), Q's columns multiplied by sign(R_ii) so that Q is Haar-distributed.
pub fn orthogonal(s: &mut Stream, n: usize) -> Vec<f64> {
    let mut a: Vec<f64> = (0..n * n).map(|_| s.normal()).collect();
    let mut vs: Vec<Vec<f64>> = Vec::with_capacity(n);
    let mut signs = vec![1.0; n];
    for k in 0..n {
        // Householder vector v (unit) with (I - 2 v v^T) a[k.., k] = alpha e_1.
        let norm = fsum((k..n).map(|i| a[i * n + k] * a[i * n + k])).sqrt();
        let x0 = a[k * n + k];
        let alpha = if x0 < 0.0 { norm } else { -norm };
        let mut v: Vec<f64> = (k..n).map(|i| a[i * n + k]).collect();
        v[0] -= alpha;
        let vn = fsum(v.iter().map(|x| x * x)).sqrt();
        if vn < 1e-300 {
            // Column already reduced: H = I, R_kk = x0.
            signs[k] = if x0 < 0.0 { -1.0 } else { 1.0 };
            vs.push(Vec::new());
            continue;
        }
        v.iter_mut().for_each(|x| *x /= vn);
        for j in k..n {
            let d = fsum((k..n).map(|i| v[i - k] * a[i * n + j]));
            for i in k..n {
                a[i * n + j] -= 2.0 * v[i - k] * d;
            }
        }
        signs[k] = if alpha < 0.0 { -1.0 } else { 1.0 };
        vs.push(v);
    }
    // Q = H_0 H_1 ... H_{n-1}: apply the reflections to I from the last one back.
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
            let d = fsum((k..n).map(|i| v[i - k] * q[i * n + j]));
            for i in k..n {
                q[i * n + j] -= 2.0 * v[i - k] * d;
            }
        }
    }
    for i in 0..n {
        for j in 0..n {
            q[i * n + j] *= signs[j];
        }
    }
    q
}

/// Eigenvalues of a symmetric n x n matrix (cyclic Jacobi), descending. Not part of the
/// generation: the realism statistics ([`crate::stats`]) use it.
pub fn sym_eigenvalues(mut a: Vec<f64>, n: usize) -> Vec<f64> {
    for _sweep in 0..100 {
        let off: f64 = (0..n)
            .flat_map(|i| (0..n).map(move |j| (i, j)))
            .filter(|(i, j)| i != j)
            .map(|(i, j)| a[i * n + j] * a[i * n + j])
            .sum();
        if off < 1e-22 {
            break;
        }
        for p in 0..n {
            for q in p + 1..n {
                let apq = a[p * n + q];
                if apq.abs() < 1e-300 {
                    continue;
                }
                let theta = (a[q * n + q] - a[p * n + p]) / (2.0 * apq);
                let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
                let c = 1.0 / (t * t + 1.0).sqrt();
                let s = t * c;
                for k in 0..n {
                    let (akp, akq) = (a[k * n + p], a[k * n + q]);
                    a[k * n + p] = c * akp - s * akq;
                    a[k * n + q] = s * akp + c * akq;
                }
                for k in 0..n {
                    let (apk, aqk) = (a[p * n + k], a[q * n + k]);
                    a[p * n + k] = c * apk - s * aqk;
                    a[q * n + k] = s * apk + c * aqk;
                }
            }
        }
    }
    let mut ev: Vec<f64> = (0..n).map(|i| a[i * n + i]).collect();
    ev.sort_by(|x, y| y.total_cmp(x));
    ev
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::tag;

    #[test]
    fn orthogonal_is_orthogonal() {
        for n in [1, 2, 6, 50] {
            let q = orthogonal(&mut Stream::new(3, tag::QUANT, 0), n);
            for i in 0..n {
                for j in 0..n {
                    let d: f64 = (0..n).map(|r| q[r * n + i] * q[r * n + j]).sum();
                    let e = if i == j { 1.0 } else { 0.0 };
                    assert!((d - e).abs() < 1e-12, "n={n} ({i},{j}) {d}");
                }
            }
        }
    }

    #[test]
    fn jacobi_finds_eigenvalues() {
        let ev = sym_eigenvalues(vec![2.0, 1.0, 0.0, 1.0, 2.0, 0.0, 0.0, 0.0, 5.0], 3);
        for (a, b) in ev.iter().zip([5.0, 3.0, 1.0]) {
            assert!((a - b).abs() < 1e-12);
        }
    }
}
