//! Lattice searches against brute force (`salvq_encoder::lattice`).
//!
//! Brute force: every integer coordinate vector in a box that provably holds all lattice
//! points within the claimed closest distance `d` of `y` (`|u_i − (M⁻¹y)_i| ≤ ‖row i of M⁻¹‖·d`)
//! is tried. The box is taken in the original basis when it is small enough, else in the
//! LLL-reduced basis `B T` (whose transform is checked unimodular separately); cases where
//! both boxes are too large for a debug build are counted and skipped.

use salvq_encoder::lattice::linalg::{det_i64, inverse_from_qr, mat_vec, qr};
use salvq_encoder::lattice::{
    closest_dn, closest_e8, closest_e8_product, dn_basis, e8_basis, e8_product_basis, Lattice,
    SearchMethod, LLL_DELTA,
};
use salvq_gen::rng::Stream as Rng;

mod lattice_bases;
use lattice_bases::{brute_dn, skew, svd_basis, test_basis, times};

fn scale2(y: &[f64], b: &[f64]) -> f64 {
    y.iter().chain(b).map(|v| v * v).sum::<f64>()
}

/// Brute-force minimum of ‖y − M u‖² over the box for radius² `r2`, or None if the box has more
/// than `cap` points.
fn brute(n: usize, m: &[f64], y: &[f64], r2: f64, cap: f64) -> Option<f64> {
    let (q, r) = qr(n, m);
    let inv = inverse_from_qr(n, &q, &r);
    let z = mat_vec(n, &inv, y);
    let d = r2.sqrt() * (1.0 + 1e-9) + 1e-9;
    let mut lo = vec![0i64; n];
    let mut hi = vec![0i64; n];
    let mut volume = 1.0;
    for i in 0..n {
        let ri = (0..n).map(|j| inv[i * n + j].powi(2)).sum::<f64>().sqrt();
        lo[i] = (z[i] - ri * d).ceil() as i64;
        hi[i] = (z[i] + ri * d).floor() as i64;
        volume *= (hi[i] - lo[i] + 1).max(0) as f64;
    }
    if volume > cap {
        return None;
    }
    if volume == 0.0 {
        return Some(f64::INFINITY);
    }
    let mut u = lo.clone();
    let mut best = f64::INFINITY;
    loop {
        // Innermost coordinate 0 runs incrementally from a freshly computed point.
        let uf: Vec<f64> = u.iter().map(|&x| x as f64).collect();
        let mut p = mat_vec(n, m, &uf);
        for _ in lo[0]..=hi[0] {
            let d2: f64 = y.iter().zip(&p).map(|(a, b)| (a - b) * (a - b)).sum();
            best = best.min(d2);
            for (i, pi) in p.iter_mut().enumerate() {
                *pi += m[i * n];
            }
        }
        let mut k = 1;
        loop {
            if k == n {
                return Some(best);
            }
            if u[k] < hi[k] {
                u[k] += 1;
                break;
            }
            u[k] = lo[k];
            k += 1;
        }
    }
}

#[test]
fn closest_point_is_exact_and_beats_the_approximations() {
    let mut rng = Rng::new(0x5A17_0001, 0, 0);
    let (mut tested, mut skipped, mut total) = (0usize, 0usize, 0usize);
    let (mut in_original, mut beat_np) = (0usize, 0usize);
    let mut per_n = Vec::new();
    for n in 2..=6usize {
        per_n.push(0usize);
        for kind in 0..30u64 {
            let b = test_basis(&mut rng, n, kind);
            let lat = Lattice::new(n, &b).expect("random basis");
            for _ in 0..6 {
                let coords: Vec<f64> = (0..n).map(|_| rng.range(-6.0, 6.0)).collect();
                let y = mat_vec(n, &b, &coords);
                let cp = lat.closest_point(&y, u64::MAX).unwrap();
                assert!(cp.exact);
                assert_eq!(cp.distance2, lat.distance2(&y, &cp.u).unwrap());
                let tol = 1e-10 * scale2(&y, &b) + 1e-12;
                for q in [
                    lat.babai_rounding(&y).unwrap(),
                    lat.babai_nearest_plane(&y, false).unwrap(),
                    lat.babai_nearest_plane(&y, true).unwrap(),
                    lat.closest_point(&y, 3).unwrap(),
                ] {
                    assert!(q.distance2 >= cp.distance2 - tol, "n={n} {q:?} vs {cp:?}");
                    assert_eq!(q.distance2, lat.distance2(&y, &q.u).unwrap());
                }
                total += 1;
                let r2 = cp.distance2 + tol;
                let np = lat.babai_nearest_plane(&y, true).unwrap();
                beat_np += usize::from(cp.distance2 < np.distance2 - tol);
                let mut found = brute(n, &b, &y, r2, 2e5);
                if found.is_some() {
                    in_original += 1;
                } else {
                    found = brute(n, lat.reduced_basis(), &y, r2, 2e5);
                }
                match found {
                    Some(bf) => {
                        assert!(
                            (bf - cp.distance2).abs() <= tol,
                            "n={n} kind={kind}: brute {bf} vs closest {}",
                            cp.distance2
                        );
                        tested += 1;
                        *per_n.last_mut().unwrap() += 1;
                    }
                    None => skipped += 1,
                }
            }
        }
    }
    println!(
        "brute-force checked {tested} of {total} cases ({in_original} in the original basis, \
         {skipped} boxes too large); closest point beat LLL nearest plane in {beat_np}"
    );
    assert!(
        beat_np * 20 >= total,
        "too few cases where nearest plane is not optimal"
    );
    assert!(in_original * 4 >= total, "too few cases independent of LLL");
    assert!(tested * 10 >= total * 8, "{tested} of {total}");
    assert!(per_n.iter().all(|&c| c >= 40), "{per_n:?}");
}

#[test]
fn bounded_search_is_flagged_and_never_worse_than_nearest_plane() {
    let mut rng = Rng::new(0x5A17_0002, 0, 0);
    let n = 12;
    let b = svd_basis(&mut rng, n, 1e3);
    let lat = Lattice::new(n, &b).unwrap();
    let mut stopped = 0;
    for _ in 0..50 {
        let y: Vec<f64> = (0..n).map(|_| rng.range(-50.0, 50.0)).collect();
        let np = lat.babai_nearest_plane(&y, true).unwrap();
        let q = lat.closest_point(&y, 20).unwrap();
        assert!(q.nodes <= 20);
        assert!(q.distance2 <= np.distance2 + 1e-9 * scale2(&y, &b));
        if !q.exact {
            stopped += 1;
        }
        let full = lat.closest_point(&y, u64::MAX).unwrap();
        assert!(full.exact && full.distance2 <= q.distance2 + 1e-9 * scale2(&y, &b));
    }
    assert!(
        stopped > 0,
        "a 20-node bound should stop some searches in dimension 12"
    );
}

/// Gram–Schmidt of the columns by modified Gram–Schmidt: (μ, ‖b*_k‖²).
fn gram_schmidt(n: usize, c: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let cols: Vec<Vec<f64>> = (0..n)
        .map(|j| (0..n).map(|i| c[i * n + j]).collect())
        .collect();
    let mut star: Vec<Vec<f64>> = Vec::new();
    let mut norm2 = vec![0.0; n];
    let mut mu = vec![0.0; n * n];
    for k in 0..n {
        let mut v = cols[k].clone();
        for j in 0..k {
            let m = cols[k]
                .iter()
                .zip(&star[j])
                .map(|(a, b)| a * b)
                .sum::<f64>()
                / norm2[j];
            mu[k * n + j] = m;
            let vj: f64 = v.iter().zip(&star[j]).map(|(a, b)| a * b).sum::<f64>() / norm2[j];
            for (x, s) in v.iter_mut().zip(&star[j]) {
                *x -= vj * s;
            }
        }
        norm2[k] = v.iter().map(|x| x * x).sum();
        star.push(v);
    }
    (mu, norm2)
}

#[test]
fn lll_output_is_reduced_and_the_transform_unimodular() {
    let mut rng = Rng::new(0x5A17_0003, 0, 0);
    for case in 0..60u64 {
        let n = 2 + (case % 11) as usize;
        let b = match case % 4 {
            0 => svd_basis(&mut rng, n, 1e6),
            3 => {
                let b = svd_basis(&mut rng, n, 1e2);
                let once = skew(&mut rng, n, &b);
                skew(&mut rng, n, &once)
            }
            k => test_basis(&mut rng, n, k),
        };
        let delta = if case % 3 == 2 { 0.99 } else { LLL_DELTA };
        let lat = Lattice::with_delta(n, &b, delta).unwrap();
        let t = lat.transform();
        assert_eq!(det_i64(n, t).map(i128::abs), Some(1), "case {case}");
        // C = B T (to rounding).
        let c = lat.reduced_basis();
        let bt = salvq_encoder::lattice::linalg::mat_mul(
            n,
            &b,
            &t.iter().map(|&x| x as f64).collect::<Vec<_>>(),
        );
        let big = b.iter().map(|v| v.abs()).fold(0.0, f64::max);
        let tmax = t.iter().map(|v| v.abs()).max().unwrap() as f64;
        for (x, y) in c.iter().zip(&bt) {
            assert!(
                (x - y).abs() <= 1e-12 * big * tmax * n as f64,
                "case {case}"
            );
        }
        let (mu, norm2) = gram_schmidt(n, c);
        for k in 1..n {
            for j in 0..k {
                assert!(mu[k * n + j].abs() <= 0.5 + 1e-6, "case {case}: μ{k}{j}");
            }
            let m = mu[k * n + k - 1];
            assert!(
                delta * norm2[k - 1] <= (norm2[k] + m * m * norm2[k - 1]) * (1.0 + 1e-9),
                "case {case}: Lovász at {k}"
            );
        }
    }
}

#[test]
fn dn_and_e8_decoders_are_exact() {
    let mut rng = Rng::new(0x5A17_0004, 0, 0);
    for n in 1..=8usize {
        let basis = dn_basis(n);
        let lat = Lattice::new(n, &basis).unwrap();
        for _ in 0..30 {
            let y: Vec<f64> = (0..n).map(|_| rng.range(-4.0, 4.0)).collect();
            let p = closest_dn(&y).unwrap();
            assert_eq!(times(n, &basis, &p.u), p.point, "B u = point");
            let d = p.distance2.sqrt() + 1e-9;
            assert!((brute_dn(&y, 0.0, d) - p.distance2).abs() < 1e-12);
            let cp = lat.closest_point(&y, u64::MAX).unwrap();
            assert!((cp.distance2 - p.distance2).abs() < 1e-12, "D_{n}");
        }
    }
    let basis = e8_basis();
    let lat = Lattice::new(8, &basis).unwrap();
    for _ in 0..40 {
        let y: Vec<f64> = (0..8).map(|_| rng.range(-4.0, 4.0)).collect();
        let p = closest_e8(&y).unwrap();
        assert_eq!(times(8, &basis, &p.u), p.point, "B u = point");
        let d = p.distance2.sqrt() + 1e-9;
        let bf = brute_dn(&y, 0.0, d).min(brute_dn(&y, 0.5, d));
        assert!(
            (bf - p.distance2).abs() < 1e-12,
            "E8 brute {bf} vs {}",
            p.distance2
        );
        let cp = lat.closest_point(&y, u64::MAX).unwrap();
        assert!((cp.distance2 - p.distance2).abs() < 1e-12);
    }
    let basis = e8_product_basis(24);
    let lat = Lattice::new(24, &basis).unwrap();
    for _ in 0..10 {
        let y: Vec<f64> = (0..24).map(|_| rng.range(-4.0, 4.0)).collect();
        let p = closest_e8_product(&y).unwrap();
        assert_eq!(times(24, &basis, &p.u), p.point);
        let blocks: f64 = y.chunks(8).map(|c| closest_e8(c).unwrap().distance2).sum();
        assert_eq!(blocks, p.distance2);
        let cp = lat.closest_point(&y, u64::MAX).unwrap();
        assert!(cp.exact && (cp.distance2 - p.distance2).abs() < 1e-12);
    }
}

#[test]
fn results_are_deterministic() {
    let run = || {
        let mut rng = Rng::new(0x5A17_0005, 0, 0);
        let n = 10;
        let b = svd_basis(&mut rng, n, 300.0);
        let lat = Lattice::new(n, &b).unwrap();
        let mut out: Vec<u64> = lat.reduced_basis().iter().map(|v| v.to_bits()).collect();
        for _ in 0..20 {
            let y: Vec<f64> = (0..n).map(|_| rng.range(-20.0, 20.0)).collect();
            for m in [
                SearchMethod::Rounding,
                SearchMethod::NearestPlane,
                SearchMethod::ClosestPoint { max_nodes: 500 },
                SearchMethod::ClosestPoint {
                    max_nodes: u64::MAX,
                },
            ] {
                let q = lat.quantize(&y, m).unwrap();
                out.extend(q.u.iter().map(|&v| v as u64));
                out.push(q.distance2.to_bits());
                out.push(q.nodes);
            }
        }
        out
    };
    assert_eq!(run(), run());
}
