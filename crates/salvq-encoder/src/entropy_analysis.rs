//! Informative floating-point helpers for measurements, in no coding path: the format's
//! tables are integer (spec §6.3.3), and these f64 functions measure how close they come to the
//! discretized Gaussian (the rate overheads of §6.5, accuracy tests). `erf` and `erfc` are the
//! `libm` crate's (a port of FreeBSD msun's, accurate in the tails).

use libm::{erf, erfc};

/// The standard normal CDF Φ(x) (f64).
pub fn phi(x: f64) -> f64 {
    0.5 * erfc(-x / std::f64::consts::SQRT_2)
}

/// P(round(X) = u) for X ~ N(0, σ²): Φ((u + ½)/σ) − Φ((u − ½)/σ), computed in the tail that
/// keeps precision (f64).
pub fn discretized_gaussian(u: i64, sigma: f64) -> f64 {
    let m = u.unsigned_abs() as f64;
    let k = 1.0 / (sigma * std::f64::consts::SQRT_2);
    if m == 0.0 {
        erf(0.5 * k)
    } else {
        0.5 * (erfc((m - 0.5) * k) - erfc((m + 0.5) * k))
    }
}

/// −log2 P(round(X) = u) for X ~ N(0, σ²) (f64). Far in the tail, where the difference of
/// `erfc` underflows, the density at |u| stands in for the probability.
pub fn discretized_gaussian_bits(u: i64, sigma: f64) -> f64 {
    let p = discretized_gaussian(u, sigma);
    if p > 1e-300 {
        -p.log2()
    } else {
        let z = u.unsigned_abs() as f64 / sigma;
        let ln_p = -0.5 * z * z - (sigma * (2.0 * std::f64::consts::PI).sqrt()).ln();
        -ln_p / std::f64::consts::LN_2
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn phi_reference_values() {
        // Values from Abramowitz & Stegun / mpmath.
        assert!((phi(1.0) - 0.841_344_746_068_542_9).abs() < 1e-15);
        assert!((phi(-4.0) / 3.167_124_183_311_992e-5 - 1.0).abs() < 1e-13);
        assert!((discretized_gaussian(0, 1.0) - 0.382_924_922_548_026).abs() < 1e-15);
    }

    #[test]
    fn discretized_gaussian_sums_to_one() {
        for sigma in [0.2, 1.0, 7.5] {
            let s: f64 = (-200..=200).map(|u| discretized_gaussian(u, sigma)).sum();
            assert!((s - 1.0).abs() < 1e-14, "{sigma}: {s}");
        }
    }
}
