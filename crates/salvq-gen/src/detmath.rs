//! Deterministic elementary functions (Annex B.2).
//!
//! `f64::exp`, `ln`, `sin`, `cos` call the platform's libm, whose last-bit results differ between
//! machines; the generator must produce the same bytes everywhere, so it uses these instead. They
//! are built only from IEEE-754 basic operations (`+ - * /`, `sqrt`, comparisons, `floor`/`round`,
//! integer <-> float conversions and bit manipulation), each correctly rounded by IEEE-754, in a
//! fixed evaluation order (Rust never contracts `a * b + c` into a fused multiply-add). Range
//! reduction plus a Taylor polynomial evaluated by Horner's rule gives a relative error of about
//! 1e-15, far below what the generator needs.

/// ln 2 split for Cody-Waite reduction (fdlibm's ln2_hi = 0x3FE62E42FEE00000, ln2_lo =
/// 0x3DEA39EF35793C76): `LN2_HI` has 32 significant bits, so `n * LN2_HI` is exact for |n| < 2^20.
const LN2_HI: f64 = 0.693_147_180_369_123_8;
const LN2_LO: f64 = 1.908_214_929_270_587_7e-10;
const INV_LN2: f64 = std::f64::consts::LOG2_E;
const SQRT2: f64 = std::f64::consts::SQRT_2;
const TAU: f64 = std::f64::consts::TAU;

/// 1/k for k = 1..=13 (each the correctly rounded quotient), for the exp series.
const INV_K: [f64; 13] = [
    1.0,
    1.0 / 2.0,
    1.0 / 3.0,
    1.0 / 4.0,
    1.0 / 5.0,
    1.0 / 6.0,
    1.0 / 7.0,
    1.0 / 8.0,
    1.0 / 9.0,
    1.0 / 10.0,
    1.0 / 11.0,
    1.0 / 12.0,
    1.0 / 13.0,
];
/// 1/((2k)(2k+1)) for k = 1..=9, for the sine series.
const SIN_C: [f64; 9] = [
    1.0 / 6.0,
    1.0 / 20.0,
    1.0 / 42.0,
    1.0 / 72.0,
    1.0 / 110.0,
    1.0 / 156.0,
    1.0 / 210.0,
    1.0 / 272.0,
    1.0 / 342.0,
];
/// 1/((2k-1)(2k)) for k = 1..=10, for the cosine series.
const COS_C: [f64; 10] = [
    1.0 / 2.0,
    1.0 / 12.0,
    1.0 / 30.0,
    1.0 / 56.0,
    1.0 / 90.0,
    1.0 / 132.0,
    1.0 / 182.0,
    1.0 / 240.0,
    1.0 / 306.0,
    1.0 / 380.0,
];

/// 2^n as an f64, for any integer n (0 below the subnormal range, infinity above 1023).
pub fn pow2i(n: i32) -> f64 {
    if n > 1023 {
        f64::INFINITY
    } else if n >= -1022 {
        f64::from_bits(((n + 1023) as u64) << 52)
    } else if n >= -1074 {
        // 2^-1022 * 2^(n + 1022): the product is an exact subnormal power of two.
        f64::from_bits(1u64 << 52) * f64::from_bits(((n + 1022 + 1023) as u64) << 52)
    } else {
        0.0
    }
}

/// e^x.
pub fn exp(x: f64) -> f64 {
    if x.is_nan() {
        return x;
    }
    if x > 709.782_712_893_384 {
        return f64::INFINITY;
    }
    if x < -745.2 {
        return 0.0;
    }
    // x = n ln2 + r, |r| <= ln2 / 2.
    let n = (x * INV_LN2).round();
    let r = (x - n * LN2_HI) - n * LN2_LO;
    // Taylor series of e^r to degree 13 (remainder < 4e-18 relative), Horner form
    // e^r = 1 + r (1 + r/2 (1 + r/3 (... (1 + r/13)))),
    // each 1/k a constant multiplication.
    let mut p = 1.0;
    for inv in INV_K.iter().rev() {
        p = 1.0 + r * inv * p;
    }
    let n = n as i32;
    // Split the scaling so that intermediate results never overflow or flush early.
    if !(-1000..=1000).contains(&n) {
        let half = n / 2;
        p * pow2i(half) * pow2i(n - half)
    } else {
        p * pow2i(n)
    }
}

/// Natural logarithm; NaN for negative or NaN input, -inf for 0, +inf for +inf.
pub fn ln(x: f64) -> f64 {
    if x.is_nan() || x < 0.0 {
        return f64::NAN;
    }
    if x == 0.0 {
        return f64::NEG_INFINITY;
    }
    if x.is_infinite() {
        return x;
    }
    let mut x = x;
    let mut e: i32 = 0;
    if x < f64::MIN_POSITIVE {
        x *= pow2i(54);
        e -= 54;
    }
    let bits = x.to_bits();
    e += ((bits >> 52) & 0x7ff) as i32 - 1023;
    // Mantissa m in [1, 2), then in [sqrt(1/2), sqrt(2)).
    let mut m = f64::from_bits((bits & ((1u64 << 52) - 1)) | (1023u64 << 52));
    if m > SQRT2 {
        m *= 0.5;
        e += 1;
    }
    // ln m = 2 atanh(s), s = (m - 1) / (m + 1), |s| <= 0.1716: series to s^25.
    let s = (m - 1.0) / (m + 1.0);
    let s2 = s * s;
    let mut p = 1.0 / 25.0;
    let mut k = 23;
    while k >= 1 {
        p = p * s2 + 1.0 / f64::from(k);
        k -= 2;
    }
    let lnm = 2.0 * s * p;
    let ef = f64::from(e);
    ef * LN2_HI + (lnm + ef * LN2_LO)
}

/// (sin, cos) of the angle `2 pi t` (t in turns). Exact reduction to |r| <= 1/8 turn.
pub fn sincos_turns(t: f64) -> (f64, f64) {
    if !t.is_finite() {
        return (f64::NAN, f64::NAN);
    }
    // t - floor(t) is exact for |t| < 2^52 (and 0 beyond, where every t is an integer).
    let f = t - t.floor();
    // q = nearest quarter turn; r = f - q/4 is exact (Sterbenz) and |r| <= 1/8.
    let q4 = (f * 4.0).round();
    let r = f - q4 * 0.25;
    let x = r * TAU;
    let x2 = x * x;
    // sin x = x (1 - x^2/(2*3) (1 - x^2/(4*5) (...))) to x^19,
    // cos x = 1 - x^2/(1*2) (1 - x^2/(3*4) (...)) to x^20.
    let mut s = 1.0;
    for c in SIN_C.iter().rev() {
        s = 1.0 - x2 * c * s;
    }
    let s = x * s;
    let mut c = 1.0;
    for k in COS_C.iter().rev() {
        c = 1.0 - x2 * k * c;
    }
    match (q4 as i64) & 3 {
        0 => (s, c),
        1 => (c, -s),
        2 => (-s, -c),
        _ => (-c, s),
    }
}

/// cos(2 pi t).
pub fn cos_turns(t: f64) -> f64 {
    sincos_turns(t).1
}

/// The logistic function 1 / (1 + e^-x).
pub fn sigmoid(x: f64) -> f64 {
    1.0 / (1.0 + exp(-x))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rel(a: f64, b: f64) -> f64 {
        if a == b {
            0.0
        } else {
            (a - b).abs() / b.abs().max(f64::MIN_POSITIVE)
        }
    }

    #[test]
    fn exp_matches_std() {
        let mut worst: f64 = 0.0;
        for i in -70_000..=70_000 {
            let x = f64::from(i) * 0.01 + 0.000_123;
            worst = worst.max(rel(exp(x), x.exp()));
        }
        for x in [-745.0, -740.0, -708.5, -0.0, 0.0, 1e-300, 1e-10, 709.7] {
            worst = worst.max(rel(exp(x), x.exp()));
        }
        assert!(worst < 1e-12, "worst relative error {worst:e}");
        assert_eq!(exp(800.0), f64::INFINITY);
        assert_eq!(exp(-800.0), 0.0);
        assert_eq!(exp(0.0), 1.0);
    }

    #[test]
    fn ln_matches_std() {
        let mut worst: f64 = 0.0;
        let mut x = 1e-310;
        while x < 1e300 {
            worst = worst.max(rel(ln(x), x.ln()));
            x *= 1.000_731;
        }
        for i in 1..20_000 {
            let x = 0.5 + f64::from(i) * 1e-4;
            let d = (ln(x) - x.ln()).abs();
            worst = worst.max(d / x.ln().abs().max(1e-4));
        }
        assert!(worst < 1e-12, "worst relative error {worst:e}");
        assert_eq!(ln(1.0), 0.0);
        assert!(ln(-1.0).is_nan());
        assert_eq!(ln(0.0), f64::NEG_INFINITY);
    }

    #[test]
    fn sincos_matches_std() {
        let mut worst: f64 = 0.0;
        for i in -100_000..=100_000 {
            let t = f64::from(i) * 0.000_37 + 0.000_011;
            let (s, c) = sincos_turns(t);
            let a = t * TAU;
            // Relative to max(1, |value|): near zeros the reference's own argument rounding dominates.
            worst = worst.max((s - a.sin()).abs()).max((c - a.cos()).abs());
        }
        assert!(worst < 1e-12, "worst error {worst:e}");
        assert_eq!(sincos_turns(0.0), (0.0, 1.0));
        assert_eq!(sincos_turns(0.25).0, 1.0);
        assert_eq!(sincos_turns(0.5).1, -1.0);
    }

    #[test]
    fn pow2i_covers_subnormals() {
        assert_eq!(pow2i(0), 1.0);
        assert_eq!(pow2i(-1074), f64::from_bits(1));
        assert_eq!(pow2i(-1075), 0.0);
        assert_eq!(pow2i(1024), f64::INFINITY);
        assert_eq!(pow2i(-1030), f64::from_bits(1u64 << 44));
    }
}
