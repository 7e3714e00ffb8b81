//! Unit tests of the lattice module's pieces (the brute-force comparisons are in
//! `tests/lattice.rs`).

use super::linalg::{det_i64, inverse_from_qr, mat_mul, qr};
use super::*;
use salvq_gen::rng::Stream as Rng;

fn close(a: &[f64], b: &[f64], tol: f64) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| (x - y).abs() <= tol)
}

#[test]
fn qr_reconstructs_and_inverts() {
    let n = 4;
    let a = [
        2.0, -1.0, 0.5, 3.0, //
        1.0, 4.0, -2.0, 0.0, //
        0.0, 1.5, 1.0, -1.0, //
        -3.0, 0.25, 2.0, 1.0,
    ];
    let (q, r) = qr(n, &a);
    assert!(close(&mat_mul(n, &q, &r), &a, 1e-12));
    for k in 0..n {
        assert!(r[k * n + k] > 0.0);
        for i in k + 1..n {
            assert_eq!(r[i * n + k], 0.0);
        }
    }
    let inv = inverse_from_qr(n, &q, &r);
    let mut id = vec![0.0; n * n];
    for i in 0..n {
        id[i * n + i] = 1.0;
    }
    assert!(close(&mat_mul(n, &a, &inv), &id, 1e-12));
}

#[test]
fn integer_determinants() {
    assert_eq!(det_i64(2, &[1, 2, 3, 4]), Some(-2));
    assert_eq!(det_i64(3, &[0, 1, 0, 1, 0, 0, 0, 0, 1]), Some(-1));
    assert_eq!(det_i64(2, &[1, 2, 2, 4]), Some(0));
    assert_eq!(det_i64(3, &[2, 0, 1, 1, 3, 2, 1, 1, 2]), Some(6));
    assert_eq!(det_i64(3, &[0, 2, 1, 1, 0, 0, 0, 1, 1]), Some(-1));
}

#[test]
fn root_bases_have_the_right_determinant() {
    for n in 1..10 {
        let (_, r) = qr(n, &dn_basis(n));
        let det: f64 = (0..n).map(|k| r[k * n + k]).product();
        assert!((det - 2.0).abs() < 1e-12, "D_{n}: det {det}");
    }
    let (_, r) = qr(8, &e8_basis());
    let det: f64 = (0..8).map(|k| r[k * 8 + k]).product();
    assert!((det - 1.0).abs() < 1e-12);
}

#[test]
fn root_coordinates_reproduce_the_point() {
    let y = [0.3, -1.7, 2.45, 0.51, -0.49, 3.9, -2.2, 0.05];
    let dn = closest_dn(&y).unwrap();
    let b = dn_basis(8);
    let p: Vec<f64> = (0..8)
        .map(|i| (0..8).map(|j| b[i * 8 + j] * dn.u[j] as f64).sum())
        .collect();
    assert_eq!(p, dn.point);
    assert_eq!(dn.point.iter().sum::<f64>() % 2.0, 0.0);
    let e8 = closest_e8(&y).unwrap();
    let b = e8_basis();
    let p: Vec<f64> = (0..8)
        .map(|i| (0..8).map(|j| b[i * 8 + j] * e8.u[j] as f64).sum())
        .collect();
    assert_eq!(p, e8.point);
    assert!(e8.distance2 <= dn.distance2);
}

#[test]
fn dn_parity_fix_rounds_the_worst_coordinate_the_other_way() {
    // Rounds to (0, 0, 1): odd; the worst coordinate is 0.4 → 1.
    let p = closest_dn(&[0.4, 0.1, 0.9]).unwrap();
    assert_eq!(p.point, vec![1.0, 0.0, 1.0]);
    // An odd integer point: every neighbour is at distance 1; the first coordinate goes up.
    let p = closest_dn(&[1.0, 0.0, 0.0]).unwrap();
    assert_eq!(p.point, vec![2.0, 0.0, 0.0]);
    assert_eq!(p.distance2, 1.0);
}

#[test]
fn identity_lattice_is_rounding() {
    let n = 5;
    let mut b = vec![0.0; n * n];
    for i in 0..n {
        b[i * n + i] = 1.0;
    }
    let lat = Lattice::new(n, &b).unwrap();
    let y = [0.4, -1.6, 2.5, 7.49, -0.2];
    let want = vec![0, -2, 3, 7, 0];
    for m in [
        SearchMethod::Rounding,
        SearchMethod::NearestPlane,
        SearchMethod::ClosestPoint { max_nodes: 1000 },
    ] {
        assert_eq!(lat.quantize(&y, m).unwrap().u, want, "{m:?}");
    }
    assert!(lat.closest_point(&y, 1000).unwrap().exact);
}

#[test]
fn lll_reduces_a_skewed_basis_of_z2() {
    // Columns (1, 0) and (1000, 1): the lattice is Z², LLL must find unit vectors.
    let b = [1.0, 1000.0, 0.0, 1.0];
    let lat = Lattice::new(2, &b).unwrap();
    let c = lat.reduced_basis();
    for j in 0..2 {
        let norm2 = c[j] * c[j] + c[2 + j] * c[2 + j];
        assert!((norm2 - 1.0).abs() < 1e-12, "{c:?}");
    }
    assert_eq!(det_i64(2, lat.transform()).map(|d| d.abs()), Some(1));
    // A target near (0.4, 0.6): rounding in the skewed basis is far off, the others are not.
    let y = [0.4, 0.6];
    let r = lat.babai_rounding(&y).unwrap();
    let cp = lat.closest_point(&y, 100).unwrap();
    assert!(cp.exact);
    assert_eq!(lat.point(&cp.u).unwrap(), vec![0.0, 1.0]);
    assert!(r.distance2 >= cp.distance2);
}

#[test]
fn errors_instead_of_panics() {
    assert_eq!(
        Lattice::new(0, &[]).unwrap_err(),
        LatticeError::EmptyDimension
    );
    assert!(matches!(
        Lattice::new(2, &[1.0, 0.0, 0.0]),
        Err(LatticeError::DimensionMismatch { .. })
    ));
    assert_eq!(
        Lattice::new(2, &[1.0, 2.0, 2.0, 4.0]).unwrap_err(),
        LatticeError::Singular
    );
    assert_eq!(
        Lattice::new(2, &[1.0, f64::NAN, 0.0, 1.0]).unwrap_err(),
        LatticeError::NonFiniteBasis
    );
    let lat = Lattice::new(2, &[1.0, 0.5, 0.0, 1.0]).unwrap();
    assert_eq!(
        lat.closest_point(&[f64::NAN, 0.0], 10).unwrap_err(),
        LatticeError::NonFiniteTarget
    );
    assert_eq!(
        lat.babai_rounding(&[1e300, 0.0]).unwrap_err(),
        LatticeError::OutOfRange
    );
    assert_eq!(
        lat.closest_point(&[0.0, -1e300], 10).unwrap_err(),
        LatticeError::OutOfRange
    );
    assert!(matches!(
        closest_e8(&[0.0; 7]),
        Err(LatticeError::DimensionMismatch { .. })
    ));
    assert_eq!(closest_dn(&[]).unwrap_err(), LatticeError::EmptyDimension);
    for delta in [0.25, 1.0, f64::NAN] {
        assert_eq!(
            Lattice::with_delta(2, &[1.0, 0.0, 0.0, 1.0], delta).unwrap_err(),
            LatticeError::InvalidDelta
        );
    }
    assert_eq!(
        closest_e8_product(&[f64::INFINITY; 16]).unwrap_err(),
        LatticeError::NonFiniteTarget
    );
}

#[test]
fn node_bound_zero_returns_nearest_plane_unproven() {
    let b = [2.0, 0.9, 0.3, 0.0, 1.0, 0.7, 0.0, 0.0, 0.5];
    let lat = Lattice::new(3, &b).unwrap();
    let y = [0.37, -1.2, 0.81];
    let np = lat.babai_nearest_plane(&y, true).unwrap();
    let cp = lat.closest_point(&y, 0).unwrap();
    assert!(!cp.exact);
    assert_eq!(cp.nodes, 0);
    assert_eq!(cp.u, np.u);
}

#[test]
fn enumeration_on_an_unreduced_basis_agrees_with_the_reduced_one() {
    // On an LLL basis the optimum rarely lies beyond the first two children of a node; on a
    // skewed basis it often does, which exercises the whole zig-zag and the lazy center sums.
    let mut rng = Rng::new(0x5A17_00AA, 0, 0);
    let mut far = 0;
    for case in 0..200 {
        let n = 2 + case % 5;
        let mut b: Vec<f64> = (0..n * n).map(|_| 2.0 * rng.uniform() - 1.0).collect();
        for _ in 0..3 * n {
            let i = (rng.next_u64() % n as u64) as usize;
            let j = (rng.next_u64() % n as u64) as usize;
            let m = (rng.next_u64() % 7) as f64 - 3.0;
            if i != j {
                for r in 0..n {
                    b[r * n + i] += m * b[r * n + j];
                }
            }
        }
        let Ok(lat) = Lattice::new(n, &b) else {
            continue;
        };
        let tri = search::Triangular::new(n, &b, SINGULAR_RTOL).unwrap();
        for _ in 0..5 {
            let y: Vec<f64> = (0..n).map(|_| 20.0 * 2.0 * rng.uniform() - 1.0).collect();
            let ys = tri.scaled_target(&y);
            let start = tri.nearest_plane(&ys).unwrap();
            let f = tri.closest(&ys, start, u64::MAX);
            assert!(f.exact);
            let u: Vec<i64> = f.x.iter().map(|&v| v as i64).collect();
            let d_plain = lat.distance2(&y, &u).unwrap();
            let d_red = lat.closest_point(&y, u64::MAX).unwrap().distance2;
            let tol = 1e-9 * (1.0 + d_red + y.iter().map(|v| v * v).sum::<f64>());
            assert!(
                (d_plain - d_red).abs() <= tol,
                "case {case}: {d_plain} vs {d_red}"
            );
            // Did the optimum need a child beyond the first two at some level?
            let x = &f.x;
            let center = |k: usize| {
                (k + 1..n).fold(ys[k], |s, j| s - tri.r[k * n + j] / tri.r[k * n + k] * x[j])
            };
            far += usize::from((0..n).any(|k| (center(k) - x[k]).abs() > 1.0));
        }
    }
    assert!(
        far >= 50,
        "only {far} cases exercised the zig-zag beyond two children"
    );
}

/// §7.2: the rows of `B⁻¹` are the short dual bases the spec names (`e_j`, `½·1` for D_n; the
/// roots `e_j − e_{j+1}`, `e_5 + e_6`, `½·1` for E8), so `R B = I` exactly with `R` built
/// from the spec's text; every E8 row has norm² 2.
#[test]
fn root_generators_have_the_short_dual_bases_of_section_7_2() {
    let check = |n: usize, b: &[f64], r: &[f64]| {
        let rb = mat_mul(n, r, b);
        for i in 0..n {
            for j in 0..n {
                assert_eq!(
                    rb[i * n + j],
                    f64::from(u8::from(i == j)),
                    "n {n}: ({i}, {j})"
                );
            }
        }
    };
    for n in 2..12 {
        let mut r = vec![0.0; n * n];
        for j in 0..n - 1 {
            r[j * n + j] = 1.0;
        }
        r[(n - 1) * n..].fill(0.5);
        check(n, &dn_basis(n), &r);
    }
    let mut r = vec![0.0; 64];
    for j in 0..6 {
        r[j * 8 + j] = 1.0;
        r[j * 8 + j + 1] = -1.0;
    }
    r[6 * 8 + 5] = 1.0;
    r[6 * 8 + 6] = 1.0;
    r[56..].fill(0.5);
    for row in r.chunks(8) {
        assert_eq!(row.iter().map(|v| v * v).sum::<f64>(), 2.0);
    }
    check(8, &e8_basis(), &r);
}
