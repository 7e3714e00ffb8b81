use super::fit::*;
use super::*;

fn curve(rate: &[f64], psnr: &[f64]) -> Curve {
    Curve::new(rate.to_vec(), psnr.to_vec()).unwrap()
}

const RATE: [f64; 5] = [17.68, 14.30, 11.38, 9.36, 8.15];
const PSNR: [f64; 5] = [27.77, 27.60, 27.34, 27.02, 26.68];

fn assert_close(got: &[f64], want: &[f64], tol: f64) {
    assert_eq!(got.len(), want.len());
    for (g, w) in got.iter().zip(want) {
        assert!(
            (g - w).abs() <= tol * w.abs().max(1.0),
            "{got:?} vs {want:?}"
        );
    }
}

#[test]
fn length_mismatch() {
    let err = Curve::new(vec![1.0, 2.0, 3.0], vec![30.0, 31.0]).unwrap_err();
    assert_eq!(err, BdError::LengthMismatch { rates: 3, psnrs: 2 });
    assert_eq!(err.to_string(), "curve has 3 rate values but 2 PSNR values");
}

#[test]
fn too_few_points() {
    for n in 0..2 {
        let err = Curve::new(vec![1.0; n], vec![30.0; n]).unwrap_err();
        assert_eq!(
            err,
            BdError::TooFewPoints {
                points: n,
                required: 2
            }
        );
    }
    // Three points suffice for PCHIP and Akima, not for the cubic fit.
    let a = curve(&[1.0, 2.0, 4.0], &[30.0, 32.0, 33.0]);
    let t = curve(&[0.9, 1.8, 3.5], &[30.1, 32.2, 33.1]);
    for m in [Interpolation::Pchip, Interpolation::Akima] {
        assert!(bd_rate(&a, &t, m).unwrap().is_finite());
        assert!(bd_psnr(&a, &t, m).unwrap().is_finite());
    }
    let want = BdError::TooFewPoints {
        points: 3,
        required: 4,
    };
    assert_eq!(bd_rate(&a, &t, Interpolation::Cubic), Err(want));
    assert_eq!(bd_psnr(&a, &t, Interpolation::Cubic), Err(want));
    assert_eq!(
        want.to_string(),
        "curve has 3 points, at least 4 are needed"
    );
}

#[test]
fn non_finite() {
    let err = Curve::new(vec![1.0, f64::NAN, 3.0], vec![30.0, 31.0, 32.0]).unwrap_err();
    assert!(matches!(
        err,
        BdError::NonFinite {
            axis: Axis::Rate,
            index: 1,
            value,
        } if value.is_nan()
    ));
    let err = Curve::new(vec![1.0, 2.0, 3.0], vec![30.0, 31.0, f64::INFINITY]).unwrap_err();
    assert_eq!(
        err,
        BdError::NonFinite {
            axis: Axis::Psnr,
            index: 2,
            value: f64::INFINITY
        }
    );
    assert_eq!(err.to_string(), "PSNR value inf at point 2 is not finite");
}

#[test]
fn non_positive_rate() {
    for bad in [0.0, -0.0, -2.0] {
        let err = Curve::new(vec![1.0, 2.0, bad], vec![30.0, 31.0, 32.0]).unwrap_err();
        assert_eq!(
            err,
            BdError::NonPositiveRate {
                index: 2,
                value: bad
            }
        );
    }
}

#[test]
fn non_monotone() {
    // PSNR turns back.
    let err = Curve::new(vec![1.0, 2.0, 3.0, 4.0], vec![30.0, 31.0, 30.5, 32.0]).unwrap_err();
    assert_eq!(
        err,
        BdError::NonMonotone {
            axis: Axis::Psnr,
            index: 2
        }
    );
    // Repeated PSNR.
    let err = Curve::new(vec![1.0, 2.0], vec![30.0, 30.0]).unwrap_err();
    assert_eq!(
        err,
        BdError::NonMonotone {
            axis: Axis::Psnr,
            index: 1
        }
    );
    // Rate decreasing while PSNR increases.
    let err = Curve::new(vec![4.0, 3.0, 2.0], vec![30.0, 31.0, 32.0]).unwrap_err();
    assert_eq!(
        err,
        BdError::NonMonotone {
            axis: Axis::Rate,
            index: 1
        }
    );
    // Rates distinct but equal after log10 (adjacent floats).
    let r = 1e10f64;
    let next = f64::from_bits(r.to_bits() + 1);
    assert_eq!(r.log10(), next.log10());
    let err = Curve::new(vec![r, next], vec![30.0, 31.0]).unwrap_err();
    assert_eq!(
        err,
        BdError::NonMonotone {
            axis: Axis::Rate,
            index: 1
        }
    );
    assert!(err.to_string().contains("not strictly monotone"));
}

#[test]
fn no_overlap() {
    let a = curve(&[1.0, 2.0, 4.0, 8.0], &[30.0, 31.0, 32.0, 33.0]);
    // Disjoint in both PSNR and rate.
    let t = curve(&[16.0, 32.0, 64.0, 128.0], &[34.0, 35.0, 36.0, 37.0]);
    for m in Interpolation::ALL {
        let e = bd_rate(&a, &t, m).unwrap_err();
        assert_eq!(e, BdError::NoOverlap { axis: Axis::Psnr });
        assert_eq!(
            bd_psnr(&a, &t, m).unwrap_err(),
            BdError::NoOverlap { axis: Axis::Rate }
        );
    }
    assert_eq!(
        overlap(&a, &t),
        Overlap {
            psnr: 0.0,
            log_rate: 0.0
        }
    );
    // Touching at one PSNR value only.
    let t = curve(&[1.0, 2.0, 4.0, 8.0], &[33.0, 34.0, 35.0, 36.0]);
    assert_eq!(
        bd_rate(&a, &t, Interpolation::Akima),
        Err(BdError::NoOverlap { axis: Axis::Psnr })
    );
    // Same rates: BD-PSNR is defined although BD-rate is not.
    assert!((bd_psnr(&a, &t, Interpolation::Pchip).unwrap() - 3.0).abs() < 1e-12);
    assert!(BdError::NoOverlap { axis: Axis::Psnr }
        .to_string()
        .contains("do not overlap in PSNR"));
}

#[test]
fn non_finite_result() {
    // log10 ratio of ~600 between the curves: 10^d overflows.
    let a = curve(&[1e-300, 1e-299, 1e-298], &[30.0, 31.0, 32.0]);
    let t = curve(&[1e300, 1e301, 1e302], &[30.0, 31.0, 32.0]);
    assert_eq!(
        bd_rate(&a, &t, Interpolation::Pchip),
        Err(BdError::NonFiniteResult)
    );
}

#[test]
fn exact_shifts() {
    let a = curve(&RATE, &PSNR);
    let half: Vec<f64> = RATE.iter().map(|r| r / 2.0).collect();
    let plus_one: Vec<f64> = PSNR.iter().map(|p| p + 1.0).collect();
    let t_rate = curve(&half, &PSNR);
    let t_psnr = curve(&RATE, &plus_one);
    for m in Interpolation::ALL {
        assert!((bd_rate(&a, &a, m).unwrap()).abs() < 1e-12);
        assert!((bd_psnr(&a, &a, m).unwrap()).abs() < 1e-12);
        assert!(
            (bd_rate(&a, &t_rate, m).unwrap() + 50.0).abs() < 1e-9,
            "{m}"
        );
        assert!((bd_psnr(&a, &t_psnr, m).unwrap() - 1.0).abs() < 1e-9, "{m}");
        assert!((bd_psnr(&t_psnr, &a, m).unwrap() + 1.0).abs() < 1e-9, "{m}");
    }
}

#[test]
fn order_does_not_matter() {
    let rev = |v: &[f64]| v.iter().rev().copied().collect::<Vec<f64>>();
    let a = curve(&RATE, &PSNR);
    let a_rev = Curve::new(rev(&RATE), rev(&PSNR)).unwrap();
    let t = curve(
        &[11.19, 8.31, 6.08, 4.36, 3.24],
        &[27.76, 27.61, 27.40, 27.15, 26.86],
    );
    for m in Interpolation::ALL {
        assert_eq!(bd_rate(&a, &t, m), bd_rate(&a_rev, &t, m));
        assert_eq!(bd_psnr(&a, &t, m), bd_psnr(&a_rev, &t, m));
    }
    assert_eq!(a_rev.rate(), rev(&RATE).as_slice());
    assert_eq!(a_rev.len(), 5);
    assert!(!a_rev.is_empty());
}

#[test]
fn method_names() {
    for m in Interpolation::ALL {
        assert_eq!(Interpolation::from_name(m.name()), Some(m));
    }
    assert_eq!(Interpolation::from_name("makima"), None);
}

/// Derivatives and integrals printed by scipy 1.17.1 (`.derivative()(x)`,
/// `.integrate(x[0] + 0.3, x[-1] - 0.2)`).
#[test]
fn matches_scipy_derivatives() {
    struct Case {
        x: &'static [f64],
        y: &'static [f64],
        pchip: &'static [f64],
        pchip_int: f64,
        akima: &'static [f64],
        akima_int: f64,
    }
    let cases = [
        // PCHIP: sign changes, zero slopes, end derivative set to 0.
        Case {
            x: &[0., 1., 3., 4., 7., 8.],
            y: &[0., 2., 2.5, 1., 1., 3.],
            pchip: &[2.5833333333333335, 0.4864864864864865, 0., 0., 0., 2.5],
            pchip_int: 11.713144725975976,
            akima: &[
                2.875,
                1.125,
                -0.6923076923076923,
                -0.8,
                0.8571428571428571,
                3.0,
            ],
            akima_int: 10.925305494505494,
        },
        // PCHIP end derivatives: sign flip (→ 0) and the 3·m0 cap.
        Case {
            x: &[0., 1., 1.5, 4.],
            y: &[0., 1., 3., 2.],
            pchip: &[0., 1.7142857142857142, 0., -1.2000000000000004],
            pchip_int: 7.834118685714285,
            akima: &[
                -0.5,
                2.2162162162162162,
                2.216216216216216,
                -2.5999999999999996,
            ],
            akima_int: 9.589044543243244,
        },
        // Akima: m1 == m2 != m3 == m4 uses the fill value (0.5 at x = 2).
        Case {
            x: &[0., 1., 2., 3., 4., 5., 6.],
            y: &[0., 0., 0., 1., 2., 2.5, 7.],
            pchip: &[0., 0., 0., 1., 0.6666666666666666, 0.8999999999999999, 6.5],
            pchip_int: 7.186626666666665,
            akima: &[0., 0., 0.5, 1., 1., 0.9444444444444444, 6.5],
            akima_int: 7.186525925925924,
        },
        // Three points.
        Case {
            x: &[1., 2.5, 3.],
            y: &[2., -1., 4.],
            pchip: &[-6., 0., 13.],
            pchip_int: -0.7899000000000003,
            akima: &[-8., 4., 16.],
            akima_int: -1.7880000000000003,
        },
    ];
    for c in &cases {
        let (lo, hi) = (c.x[0] + 0.3, c.x[c.x.len() - 1] - 0.2);
        let dp = pchip_derivatives(c.x, c.y);
        let da = akima_derivatives(c.x, c.y);
        assert_close(&dp, c.pchip, 1e-15);
        assert_close(&da, c.akima, 1e-15);
        assert_close(
            &[hermite_integral(c.x, c.y, &dp, lo, hi)],
            &[c.pchip_int],
            1e-14,
        );
        assert_close(
            &[hermite_integral(c.x, c.y, &da, lo, hi)],
            &[c.akima_int],
            1e-14,
        );
    }
}

/// scipy's relative cutoff `f1 + f2 ≤ 1e-9 · max(f1 + f2)`: at x = 2 the weights are
/// 1e-11 and 3e-11, tiny next to the jump to slope 100, so the fill value ≈ 2.0 applies
/// where the weighted formula would give ≈ 2.5.
#[test]
fn akima_relative_cutoff() {
    let x = [0., 1., 2., 3., 4., 5.];
    let y = [
        0.0,
        1.0,
        2.00000000003,
        5.00000000003,
        8.00000000004,
        108.00000000004,
    ];
    let want = [
        0.999999999985,
        1.0,
        2.000000000005,
        3.000000000000202,
        3.00000000002,
        148.499999999995,
    ];
    assert_close(&akima_derivatives(&x, &y), &want, 1e-13);
}

#[test]
fn cubic_fit_reproduces_cubics_and_least_squares() {
    // A cubic is reproduced exactly; its integral is known in closed form.
    let p = |x: f64| 2.0 - 3.0 * x + 0.5 * x * x - 0.25 * x * x * x;
    let big_p = |x: f64| 2.0 * x - 1.5 * x * x + x * x * x / 6.0 - x * x * x * x / 16.0;
    let x = [26.68, 27.02, 27.34, 27.60, 27.77];
    let y: Vec<f64> = x.iter().map(|&v| p(v)).collect();
    let fit = cubic_fit(&x, &y);
    let (lo, hi) = (26.9, 27.7);
    let want = big_p(hi) - big_p(lo);
    assert!((fit.integral(lo, hi) - want).abs() < 1e-9 * want.abs());
    // Least squares, not interpolation: with 5 points the residual is orthogonal to
    // every cubic, here to 1 and t.
    let y = [1.0, 3.0, 2.0, 5.0, 4.0];
    let fit = cubic_fit(&x, &y);
    let [b0, b1, b2, b3] = fit.beta;
    let t: Vec<f64> = x.iter().map(|v| (v - fit.centre) / fit.scale).collect();
    let r: Vec<f64> = t
        .iter()
        .zip(&y)
        .map(|(t, y)| y - (b0 + t * (b1 + t * (b2 + t * b3))))
        .collect();
    assert!(r.iter().any(|v| v.abs() > 1e-3));
    assert!(r.iter().sum::<f64>().abs() < 1e-12);
    assert!(r.iter().zip(&t).map(|(r, t)| r * t).sum::<f64>().abs() < 1e-12);
}
