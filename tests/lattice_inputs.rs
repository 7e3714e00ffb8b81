//! Lattice searches on hostile inputs (`salvq_encoder::lattice`): bad bases and targets are
//! typed errors; extreme finite inputs give errors or right answers; extreme scales give the
//! answers of scale one; the fixed generators' sparse storage equals their definitions.

use salvq_encoder::lattice::linalg::mat_vec;
use salvq_encoder::lattice::{
    closest_dn, closest_e8, dn_basis, e8_product_basis, Lattice, LatticeError, SearchMethod,
};
use salvq_gen::rng::Stream as Rng;

mod lattice_bases;
use lattice_bases::{brute_dn, svd_basis, test_basis, times};

#[test]
fn bad_bases_and_targets_are_errors() {
    let mut rng = Rng::new(0x5A17_0006, 0, 0);
    for n in 2..=6 {
        // Rank-deficient: the last column is an integer combination of the others.
        let mut b: Vec<f64> = (0..n * n).map(|_| rng.normal()).collect();
        for i in 0..n {
            let other = if n > 2 { b[i * n + 1] } else { 0.0 };
            b[i * n + n - 1] = 2.0 * b[i * n] - other;
        }
        assert_eq!(Lattice::new(n, &b).unwrap_err(), LatticeError::Singular);
        // Condition 1e14 is singular for this module.
        let b = svd_basis(&mut rng, n, 1e14);
        assert_eq!(Lattice::new(n, &b).unwrap_err(), LatticeError::Singular);
        let mut b = svd_basis(&mut rng, n, 10.0);
        b[1] = f64::INFINITY;
        assert_eq!(
            Lattice::new(n, &b).unwrap_err(),
            LatticeError::NonFiniteBasis
        );
    }
    let b = svd_basis(&mut rng, 4, 10.0);
    let lat = Lattice::new(4, &b).unwrap();
    for m in [
        SearchMethod::Rounding,
        SearchMethod::NearestPlane,
        SearchMethod::ClosestPoint { max_nodes: 100 },
    ] {
        let y = [0.0, f64::NAN, 1.0, 2.0];
        assert_eq!(
            lat.quantize(&y, m).unwrap_err(),
            LatticeError::NonFiniteTarget
        );
        let y = [0.0, 1e200, 1.0, 2.0];
        assert_eq!(lat.quantize(&y, m).unwrap_err(), LatticeError::OutOfRange);
        assert!(matches!(
            lat.quantize(&[0.0; 3], m),
            Err(LatticeError::DimensionMismatch { .. })
        ));
    }
    assert_eq!(
        closest_e8(&[0.0, 0.0, 0.0, f64::NAN, 0.0, 0.0, 0.0, 0.0]).unwrap_err(),
        LatticeError::NonFiniteTarget
    );
}

/// The errors a finite basis can give [`Lattice::new`], and a finite target of the right
/// length can give a search.
fn basis_error(e: LatticeError) -> bool {
    matches!(
        e,
        LatticeError::Singular
            | LatticeError::NonFiniteBasis
            | LatticeError::Overflow
            | LatticeError::ReductionDidNotConverge
    )
}

const METHODS: [SearchMethod; 3] = [
    SearchMethod::Rounding,
    SearchMethod::NearestPlane,
    SearchMethod::ClosestPoint { max_nodes: 10_000 },
];

/// Extreme but finite bases and targets (magnitudes 1e-300 to 1e300, zeros, mixed scales):
/// nothing panics; a failure is one of the errors such inputs can cause (never, say,
/// `NonFiniteTarget` for a finite target); and every answer is a right one: `u` has n
/// coordinates and `distance2` is `‖y − B u‖²` of that `u`, the closest-point search is never
/// farther than nearest plane (it starts there), and a D_n answer is a point of D_n with the
/// coordinates [`dn_basis`] gives it, no farther from `y` than any point of D_n (brute force).
#[test]
fn extreme_finite_inputs_give_errors_or_right_answers() {
    let mut rng = Rng::new(0x5A17_0007, 0, 0);
    // Answers (not errors) per search method, and from closest_dn.
    let mut answered = [0usize; 4];
    for case in 0..300 {
        let n = 1 + (case % 7);
        let e = rng.range(-300.0, 300.0);
        let b: Vec<f64> = (0..n * n)
            .map(|_| {
                let v = rng.normal() * 10f64.powf(e + rng.range(-20.0, 20.0));
                if rng.below(6) == 0 {
                    0.0
                } else {
                    v.clamp(-f64::MAX, f64::MAX)
                }
            })
            .collect();
        // Targets at any scale, and (every other case) near the lattice, so that searches
        // answer rather than fail with OutOfRange.
        let y: Vec<f64> = (0..n)
            .map(|_| rng.normal() * 10f64.powf(rng.range(-300.0, 300.0)))
            .collect();
        let near: Vec<f64> = (0..n).map(|_| rng.range(-1e3, 1e3)).collect();
        let near = mat_vec(n, &b, &near);
        match closest_dn(&y) {
            Ok(p) => {
                answered[3] += 1;
                assert!(
                    p.point.iter().all(|v| v.fract() == 0.0)
                        && p.point.iter().map(|&v| v as i64).sum::<i64>() % 2 == 0,
                    "case {case}: {:?} is not in D_{n}",
                    p.point
                );
                assert_eq!(times(n, &dn_basis(n), &p.u), p.point, "case {case}: u");
                let d2: f64 = y.iter().zip(&p.point).map(|(a, b)| (a - b) * (a - b)).sum();
                assert_eq!(p.distance2, d2, "case {case}: distance2");
                let d = p.distance2.sqrt() * (1.0 + 1e-12) + 1e-12;
                let best = brute_dn(&y, 0.0, d);
                assert!(
                    p.distance2 <= best,
                    "case {case}: D_{n} point at {} where brute force finds {best}",
                    p.distance2
                );
            }
            Err(err) => assert_eq!(err, LatticeError::OutOfRange, "case {case}: closest_dn"),
        }
        let lat = match Lattice::new(n, &b) {
            Ok(lat) => lat,
            Err(err) => {
                assert!(basis_error(err), "case {case}: Lattice::new: {err:?}");
                continue;
            }
        };
        for target in [&y, &near] {
            let mut q = Vec::new();
            for (i, m) in METHODS.into_iter().enumerate() {
                match lat.quantize(target, m) {
                    Ok(a) => {
                        answered[i] += 1;
                        assert_eq!(a.u.len(), n, "case {case}: {m:?}");
                        let d2 = lat.distance2(target, &a.u).unwrap();
                        assert_eq!(a.distance2.to_bits(), d2.to_bits(), "case {case}: {m:?}");
                        q.push(Some(a));
                    }
                    Err(err) => {
                        assert_eq!(err, LatticeError::OutOfRange, "case {case}: {m:?}");
                        q.push(None);
                    }
                }
            }
            if let (Some(plane), Some(closest)) = (&q[1], &q[2]) {
                assert!(
                    closest.distance2 <= plane.distance2,
                    "case {case}: closest point {} farther than nearest plane {}",
                    closest.distance2,
                    plane.distance2
                );
            }
        }
    }
    // The checks above ran on answers, not only on errors.
    assert!(answered.iter().all(|&a| a >= 20), "answers: {answered:?}");
}

/// A basis and target scaled by 2^k (exact in binary floating point while no value
/// overflows or goes subnormal) give the same answer at every extreme scale as at scale 1:
/// the same `u`, `exact` and node count, and `distance2` scaled by exactly 2^2k. Catches any
/// absolute threshold or magnitude-dependent path that would make a large or tiny lattice
/// answer differently (a wrong `u`, or `Singular` for a well-conditioned basis).
#[test]
fn extreme_scales_give_the_answers_of_scale_one() {
    let mut rng = Rng::new(0x5A17_0008, 0, 0);
    for case in 0..60u64 {
        let n = 1 + (case as usize % 7);
        let b = test_basis(&mut rng, n, case);
        let y: Vec<f64> = (0..n).map(|_| rng.normal() * 20.0).collect();
        let lat = Lattice::new(n, &b).unwrap();
        let want: Vec<_> = METHODS
            .iter()
            .map(|&m| lat.quantize(&y, m).unwrap())
            .collect();
        for k in [-440, -200, 200, 440] {
            let s = 2f64.powi(k);
            let bs: Vec<f64> = b.iter().map(|v| v * s).collect();
            let ys: Vec<f64> = y.iter().map(|v| v * s).collect();
            let lat_s = Lattice::new(n, &bs)
                .unwrap_or_else(|e| panic!("case {case}: basis scaled by 2^{k}: {e:?}"));
            assert_eq!(lat_s.transform(), lat.transform(), "case {case} 2^{k}: LLL");
            for (m, w) in METHODS.iter().zip(&want) {
                let got = lat_s.quantize(&ys, *m).unwrap();
                assert_eq!(
                    (&got.u, got.exact, got.nodes),
                    (&w.u, w.exact, w.nodes),
                    "case {case} 2^{k}: {m:?}"
                );
                assert_eq!(
                    got.distance2,
                    w.distance2 * s * s,
                    "case {case} 2^{k}: {m:?}"
                );
            }
        }
    }
}

#[test]
fn fixed_generators_are_stored_sparse_but_equal_the_dense_definitions() {
    use salvq_bitstream::model::LatticeKind;
    use salvq_bitstream::quantizer::LatticeMatrix;
    for n in [2usize, 3, 8, 50, 1024] {
        let m = LatticeMatrix::new(LatticeKind::Dn, n, None);
        assert_eq!(m.to_f64(), dn_basis(n), "D_{n}");
    }
    for n in [8usize, 24, 1024] {
        let m = LatticeMatrix::new(LatticeKind::E8Product, n, None);
        assert_eq!(m.to_f64(), e8_product_basis(n), "E8^{}", n / 8);
        // B u through the sparse columns equals the dense product (integer-valued, exact).
        let u: Vec<i64> = (0..n as i64).map(|i| (i * 7) % 5 - 2).collect();
        let mut z = vec![0f32; n];
        m.apply(&u, &mut z);
        let dense = times(n, &e8_product_basis(n), &u);
        assert!(z.iter().zip(&dense).all(|(a, b)| f64::from(*a) == *b));
    }
}
