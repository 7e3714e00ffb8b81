//! Bjøntegaard-delta metrics: BD-rate and BD-PSNR (VCEG-M33), computed exactly as the PyPI
//! package `bjontegaard` 1.3.0 computes them with `method` ∈ {`cubic`, `pchip`, `akima`}.
//!
//! The expected values in `tests/data/reference/bdrate_cases.csv` were produced by that package
//! (numpy 2.4.6, scipy 1.17.1); `tests/bdrate.rs` checks this module against all of them.
//!
//! # The metric
//!
//! A rate-distortion [`Curve`] is a list of operating points (rate, PSNR). Rates enter only
//! through `log10(rate)`; the result does not depend on the log base.
//!
//! * **BD-rate** ([`bd_rate`]): fit `y = log10(rate)` as a function of `x = PSNR` for the
//!   anchor and the test curve, integrate both fits exactly over the PSNR overlap
//!   `[lo, hi] = [max(min x_anchor, min x_test), min(max x_anchor, max x_test)]`, and take the
//!   mean difference `d = (∫ test − ∫ anchor) / (hi − lo)`. The result is `(10^d − 1) · 100`,
//!   the average rate change of the test at equal quality, in percent (negative: the test
//!   needs fewer bits).
//! * **BD-PSNR** ([`bd_psnr`]): the same with the axes swapped, `y = PSNR` as a function of
//!   `x = log10(rate)`; the result is the mean difference `d` itself, in dB.
//! * **Overlap** ([`overlap`]): on each axis, the length of the overlap interval divided by the
//!   length of the union `[min, max]` of both curves. The package only *warns* below its
//!   `min_overlap = 0.75`; so does nothing here: every positive overlap yields a value. An
//!   empty overlap (length 0) is [`BdError::NoOverlap`] where the package returns NaN.
//!
//! Points may be given in either order. The package reverses a curve whose `x` decreases
//! (points listed by increasing λ); [`Curve::new`] requires PSNR and `log10(rate)` to be strictly
//! monotone in the same direction and keeps an increasing copy. Unlike the package (whose
//! default `require_matching_points=True` rejects it), anchor and test may have different
//! numbers of points.
//!
//! # The three fits
//!
//! With `h_k = x_{k+1} − x_k` and `m_k = (y_{k+1} − y_k) / h_k` the secant slopes:
//!
//! * [`Interpolation::Pchip`] — `scipy.interpolate.PchipInterpolator`, a piecewise cubic
//!   Hermite interpolant whose knot derivatives `d_k` follow Fritsch–Carlson as scipy computes
//!   them:
//!   * interior knots: `d_k = 0` when `m_{k−1}` and `m_k` differ in sign or either is 0,
//!     otherwise the weighted harmonic mean `1/d_k = (w1/m_{k−1} + w2/m_k) / (w1 + w2)` with
//!     `w1 = 2h_k + h_{k−1}`, `w2 = h_k + 2h_{k−1}`;
//!   * end knots (Moler's `pchiptx`): the one-sided three-point estimate
//!     `d = ((2h_0 + h_1) m_0 − h_0 m_1) / (h_0 + h_1)` (mirrored at the right end), set to 0
//!     when its sign differs from `m_0`'s, else to `3 m_0` when `m_0` and `m_1` differ in sign
//!     and `|d| > 3|m_0|`;
//!   * two points: the straight line (`d_0 = d_1 = m_0`).
//! * [`Interpolation::Akima`] — `scipy.interpolate.Akima1DInterpolator` with its default
//!   `method="akima"` (not `"makima"`), again a cubic Hermite interpolant:
//!   * the slope list is extended by two linearly extrapolated slopes at each end:
//!     `m_{−1} = 2m_0 − m_1`, `m_{−2} = 2m_{−1} − m_0`, and likewise
//!     `m_{n−1} = 2m_{n−2} − m_{n−3}`, `m_n = 2m_{n−1} − m_{n−2}` on the right;
//!   * at knot `k`, with `f1 = |m_{k+1} − m_k|` and `f2 = |m_{k−1} − m_{k−2}|`,
//!     `d_k = m_{k−1} + f2/(f1 + f2) · (m_k − m_{k−1})`;
//!   * where `f1 + f2 ≤ 1e-9 · max_k (f1 + f2)` (scipy's `break_mult`, a *relative* cutoff,
//!     not a test for exact zero) the fill value `d_k = (m_{k−2} + m_{k+1}) / 2` is used;
//!   * two points: the straight line (the package calls `make_interp_spline(k=1)` there).
//! * [`Interpolation::Cubic`] — the original Bjøntegaard fit, `numpy.polyfit(x, y, 3)`: one
//!   cubic polynomial fitted by **least squares** (it interpolates only with exactly 4
//!   points). numpy solves the monomial Vandermonde system `[x³ x² x 1]` in PSNR ≈ 30, which is
//!   ill-conditioned; here `x` is first mapped to `t = (x − c)/s ∈ [−1, 1]` (centre `c` and
//!   half-width `s` of the data) and the `n × 4` system in `[1 t t² t³]` is solved by a
//!   Householder QR factorisation. The least-squares polynomial is the same function; only the
//!   rounding differs (numpy's result carries errors up to ~1e-7 % in BD-rate).
//!
//! # Exact integration
//!
//! A Hermite segment on `[x_k, x_{k+1}]` with values `y_k, y_{k+1}` and derivatives
//! `d_k, d_{k+1}` is, in `u = x − x_k` (scipy's `CubicHermiteSpline` coefficients),
//! `p(u) = c0 + c1 u + c2 u² + c3 u³` with `c0 = y_k`, `c1 = d_k`,
//! `τ = (d_k + d_{k+1} − 2m_k)/h_k`, `c2 = (m_k − d_k)/h_k − τ`, `c3 = τ/h_k`. Its integral over
//! `[a, b] ⊆ [x_k, x_{k+1}]` is `P(b − x_k) − P(a − x_k)` with
//! `P(u) = c0 u + c1 u²/2 + c2 u³/3 + c3 u⁴/4`, summed over the segments that meet `[lo, hi]`.
//! The least-squares cubic `q(t) = Σ β_j t^j` integrates as
//! `∫_lo^hi p(x) dx = s · [Q(t_hi) − Q(t_lo)]` with `Q(t) = Σ β_j t^{j+1}/(j+1)`. The overlap
//! interval always lies inside the data range of both curves, so nothing is extrapolated.
//!
//! # Example
//!
//! ```
//! use salvq_bench::bdrate::{bd_psnr, bd_rate, Curve, Interpolation};
//! let anchor = Curve::new(vec![17.68, 14.30, 11.38, 9.36, 8.15], vec![27.77, 27.60, 27.34, 27.02, 26.68])?;
//! // The same qualities at half the size: BD-rate −50 %, whatever the interpolation.
//! let test = Curve::new(vec![8.84, 7.15, 5.69, 4.68, 4.075], vec![27.77, 27.60, 27.34, 27.02, 26.68])?;
//! let r = bd_rate(&anchor, &test, Interpolation::Akima)?;
//! assert!((r + 50.0).abs() < 1e-9);
//! // The PSNR ranges coincide; the log-rate ranges barely overlap.
//! let o = salvq_bench::bdrate::overlap(&anchor, &test);
//! assert_eq!(o.psnr, 1.0);
//! assert!(o.log_rate < 0.1);
//! assert!(bd_psnr(&anchor, &test, Interpolation::Akima)? > 0.0);
//! # Ok::<(), salvq_bench::bdrate::BdError>(())
//! ```

use std::fmt;

/// How each rate-distortion curve is turned into a function before integration.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Interpolation {
    /// One least-squares cubic polynomial (`numpy.polyfit(x, y, 3)`); needs 4 points.
    Cubic,
    /// Piecewise cubic Hermite, Fritsch–Carlson slopes (`scipy.interpolate.PchipInterpolator`);
    /// the method of the JCT-VC/JVET common-test-conditions sheets.
    Pchip,
    /// Piecewise cubic Hermite, Akima slopes (`scipy.interpolate.Akima1DInterpolator`,
    /// `method="akima"`); the method the `bjontegaard` package recommends.
    Akima,
}

impl Interpolation {
    /// All methods, in the order `cubic`, `pchip`, `akima`.
    pub const ALL: [Interpolation; 3] = [
        Interpolation::Cubic,
        Interpolation::Pchip,
        Interpolation::Akima,
    ];

    /// The package's name of the method: `"cubic"`, `"pchip"` or `"akima"`.
    pub fn name(self) -> &'static str {
        match self {
            Interpolation::Cubic => "cubic",
            Interpolation::Pchip => "pchip",
            Interpolation::Akima => "akima",
        }
    }

    /// The method with the package's name `name`, if any.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|m| m.name() == name)
    }

    /// The fewest points per curve the method accepts.
    pub fn min_points(self) -> usize {
        match self {
            Interpolation::Cubic => 4,
            Interpolation::Pchip | Interpolation::Akima => 2,
        }
    }
}

impl fmt::Display for Interpolation {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// One axis of the rate-distortion plane, as named in a [`BdError`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Axis {
    /// The rate, or `log10(rate)` where integration and overlap are concerned.
    Rate,
    /// The PSNR in dB.
    Psnr,
}

impl fmt::Display for Axis {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Axis::Rate => "rate",
            Axis::Psnr => "PSNR",
        })
    }
}

/// Why a curve or a Bjøntegaard delta was rejected.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum BdError {
    /// The rate and PSNR lists of a curve have different lengths.
    LengthMismatch {
        /// Number of rates.
        rates: usize,
        /// Number of PSNR values.
        psnrs: usize,
    },
    /// A curve has fewer points than the curve or the interpolation method needs.
    TooFewPoints {
        /// Points in the curve.
        points: usize,
        /// Points needed.
        required: usize,
    },
    /// A value is NaN or infinite.
    NonFinite {
        /// Which list holds it.
        axis: Axis,
        /// Its position in that list.
        index: usize,
        /// The value.
        value: f64,
    },
    /// A rate is zero or negative, so it has no logarithm.
    NonPositiveRate {
        /// Its position in the list.
        index: usize,
        /// The value.
        value: f64,
    },
    /// The values on `axis` are not strictly monotone (for [`Axis::Rate`]: `log10(rate)` is not
    /// strictly monotone in the same direction as the PSNR).
    NonMonotone {
        /// The axis whose values break monotonicity.
        axis: Axis,
        /// The first point (index into the list as given) that breaks it.
        index: usize,
    },
    /// The two curves do not overlap on the integration axis ([`Axis::Psnr`] for BD-rate,
    /// [`Axis::Rate`], i.e. `log10(rate)`, for BD-PSNR), or only touch at one value.
    NoOverlap {
        /// The integration axis.
        axis: Axis,
    },
    /// The fits are finite but the result is not (e.g. `10^d` overflows for an absurd rate
    /// ratio).
    NonFiniteResult,
}

impl fmt::Display for BdError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            BdError::LengthMismatch { rates, psnrs } => {
                write!(f, "curve has {rates} rate values but {psnrs} PSNR values")
            }
            BdError::TooFewPoints { points, required } => write!(
                f,
                "curve has {points} points, at least {required} are needed"
            ),
            BdError::NonFinite { axis, index, value } => {
                write!(f, "{axis} value {value} at point {index} is not finite")
            }
            BdError::NonPositiveRate { index, value } => write!(
                f,
                "rate {value} at point {index} is not positive, so it has no logarithm"
            ),
            BdError::NonMonotone {
                axis: Axis::Psnr,
                index,
            } => write!(f, "PSNR values are not strictly monotone at point {index}"),
            BdError::NonMonotone {
                axis: Axis::Rate,
                index,
            } => write!(
                f,
                "log10(rate) values are not strictly monotone in the direction of the PSNR \
                 values at point {index}"
            ),
            BdError::NoOverlap { axis: Axis::Psnr } => {
                f.write_str("the curves do not overlap in PSNR, BD-rate is undefined")
            }
            BdError::NoOverlap { axis: Axis::Rate } => {
                f.write_str("the curves do not overlap in log10(rate), BD-PSNR is undefined")
            }
            BdError::NonFiniteResult => f.write_str("the Bjøntegaard delta is not finite"),
        }
    }
}

impl std::error::Error for BdError {}

/// A rate-distortion curve: at least two (rate, PSNR) points, both coordinates strictly
/// monotone in the same direction, rates positive.
#[derive(Debug, Clone, PartialEq)]
pub struct Curve {
    rate: Vec<f64>,
    psnr: Vec<f64>,
    /// `log10(rate)`, increasing.
    log_rate_inc: Vec<f64>,
    /// PSNR, increasing.
    psnr_inc: Vec<f64>,
}

impl Curve {
    /// Checks and stores a curve given as parallel lists, in increasing or decreasing order
    /// (the package's convention: points by increasing λ, i.e. decreasing rate and PSNR).
    pub fn new(rate: Vec<f64>, psnr: Vec<f64>) -> Result<Curve, BdError> {
        if rate.len() != psnr.len() {
            return Err(BdError::LengthMismatch {
                rates: rate.len(),
                psnrs: psnr.len(),
            });
        }
        if rate.len() < 2 {
            return Err(BdError::TooFewPoints {
                points: rate.len(),
                required: 2,
            });
        }
        for (axis, values) in [(Axis::Rate, &rate), (Axis::Psnr, &psnr)] {
            if let Some((index, &value)) = values.iter().enumerate().find(|(_, v)| !v.is_finite()) {
                return Err(BdError::NonFinite { axis, index, value });
            }
        }
        if let Some((index, &value)) = rate.iter().enumerate().find(|(_, &r)| r <= 0.0) {
            return Err(BdError::NonPositiveRate { index, value });
        }
        let log_rate: Vec<f64> = rate.iter().map(|r| r.log10()).collect();
        // The direction is set by the first two PSNR values; both axes must follow it.
        let increasing = psnr[1] > psnr[0];
        let ordered = |a: f64, b: f64| if increasing { b > a } else { b < a };
        for (axis, values) in [(Axis::Psnr, &psnr), (Axis::Rate, &log_rate)] {
            if let Some(k) = (1..values.len()).find(|&k| !ordered(values[k - 1], values[k])) {
                return Err(BdError::NonMonotone { axis, index: k });
            }
        }
        let (mut log_rate_inc, mut psnr_inc) = (log_rate, psnr.clone());
        if !increasing {
            log_rate_inc.reverse();
            psnr_inc.reverse();
        }
        Ok(Curve {
            rate,
            psnr,
            log_rate_inc,
            psnr_inc,
        })
    }

    /// The rates, as given.
    pub fn rate(&self) -> &[f64] {
        &self.rate
    }

    /// The PSNR values, as given.
    pub fn psnr(&self) -> &[f64] {
        &self.psnr
    }

    /// Number of points (at least 2).
    pub fn len(&self) -> usize {
        self.rate.len()
    }

    /// Always `false`: a curve has at least 2 points.
    pub fn is_empty(&self) -> bool {
        self.rate.is_empty()
    }
}

/// Overlap of two curves on each axis: overlap length / union length, in `[0, 1]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Overlap {
    /// On the PSNR axis, the integration axis of BD-rate (`psnr_overlap_fraction`).
    pub psnr: f64,
    /// On the `log10(rate)` axis, the integration axis of BD-PSNR
    /// (`log_rate_overlap_fraction`).
    pub log_rate: f64,
}

/// The overlap fractions of `anchor` and `test` on both axes (0 when disjoint). The package
/// warns when the fraction on the integration axis is below 0.75.
pub fn overlap(anchor: &Curve, test: &Curve) -> Overlap {
    Overlap {
        psnr: overlap_fraction(&anchor.psnr_inc, &test.psnr_inc),
        log_rate: overlap_fraction(&anchor.log_rate_inc, &test.log_rate_inc),
    }
}

/// BD-rate of `test` against `anchor`, in percent: the average rate change at equal PSNR.
pub fn bd_rate(anchor: &Curve, test: &Curve, method: Interpolation) -> Result<f64, BdError> {
    let d = bd_mean(
        (&anchor.psnr_inc, &anchor.log_rate_inc),
        (&test.psnr_inc, &test.log_rate_inc),
        method,
        Axis::Psnr,
    )?;
    finite((10f64.powf(d) - 1.0) * 100.0)
}

/// BD-PSNR of `test` against `anchor`, in dB: the average PSNR change at equal rate.
pub fn bd_psnr(anchor: &Curve, test: &Curve, method: Interpolation) -> Result<f64, BdError> {
    let d = bd_mean(
        (&anchor.log_rate_inc, &anchor.psnr_inc),
        (&test.log_rate_inc, &test.psnr_inc),
        method,
        Axis::Rate,
    )?;
    finite(d)
}

fn finite(v: f64) -> Result<f64, BdError> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(BdError::NonFiniteResult)
    }
}

/// `overlap length / union length` of the ranges of two increasing lists.
fn overlap_fraction(a: &[f64], b: &[f64]) -> f64 {
    let (a0, a1) = (a[0], a[a.len() - 1]);
    let (b0, b1) = (b[0], b[b.len() - 1]);
    let union = a1.max(b1) - a0.min(b0);
    (a1.min(b1) - a0.max(b0)).max(0.0) / union
}

/// Mean difference `(∫ test − ∫ anchor) / (hi − lo)` of the two fits `y(x)` over the overlap of
/// their `x` ranges. Each curve is `(x, y)` with `x` strictly increasing.
fn bd_mean(
    anchor: (&[f64], &[f64]),
    test: (&[f64], &[f64]),
    method: Interpolation,
    axis: Axis,
) -> Result<f64, BdError> {
    for (x, _) in [anchor, test] {
        if x.len() < method.min_points() {
            return Err(BdError::TooFewPoints {
                points: x.len(),
                required: method.min_points(),
            });
        }
    }
    let (xa, xt) = (anchor.0, test.0);
    let lo = xa[0].max(xt[0]);
    let hi = xa[xa.len() - 1].min(xt[xt.len() - 1]);
    if hi <= lo {
        return Err(BdError::NoOverlap { axis });
    }
    let integral_anchor = integrate(anchor.0, anchor.1, method, lo, hi);
    let integral_test = integrate(test.0, test.1, method, lo, hi);
    Ok((integral_test - integral_anchor) / (hi - lo))
}

mod fit;
#[cfg(test)]
mod tests;

use fit::integrate;
