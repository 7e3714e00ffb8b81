//! Per-anchor quantization steps and scale indices from the context MLP's outputs
//! (spec §5.4), in integer arithmetic; and the binary32 reconstruction they feed (§5.5).

/// Table 5-2: round((1 + tanh(a / 16)) * 2^16) for a = -64 ..= 64.
pub const STEP_FACTOR: [u32; 129] = [
    44, 50, 56, 64, 72, 82, 93, 105, 119, 135, 153, 174, 197, 223, 253, 286, 324, 367, 416, 471,
    533, 604, 684, 775, 877, 993, 1124, 1273, 1440, 1629, 1843, 2085, 2357, 2665, 3012, 3402, 3842,
    4337, 4893, 5517, 6216, 7000, 7876, 8853, 9943, 11154, 12498, 13984, 15624, 17428, 19405,
    21564, 23911, 26452, 29190, 32124, 35251, 38563, 42051, 45698, 49485, 53390, 57386, 61445,
    65536, 69627, 73686, 77682, 81587, 85374, 89021, 92509, 95821, 98948, 101882, 104620, 107161,
    109508, 111667, 113644, 115448, 117088, 118574, 119918, 121129, 122219, 123196, 124072, 124856,
    125555, 126179, 126735, 127230, 127670, 128060, 128407, 128715, 128987, 129229, 129443, 129632,
    129799, 129948, 130079, 130195, 130297, 130388, 130468, 130539, 130601, 130656, 130705, 130748,
    130786, 130819, 130849, 130875, 130898, 130919, 130937, 130953, 130967, 130979, 130990, 131000,
    131008, 131016, 131022, 131028,
];

/// §5.4 step 1: the step-factor index of an adjustment output `y` (units of 2^-frac):
/// round(16 y / 2^frac), clamped to -64 ..= 64. Exact for every `frac` a stream can give
/// (up to 8 + 30 + 30 = 68): |16 y| < 2^35, so the rounded quotient is 0 from frac = 37 on
/// (a 64-bit shift by 64 or more would be undefined; Rust panics or wraps).
pub fn factor_index(y: i32, frac: i32) -> usize {
    let v = i64::from(y) * 16;
    let a = if frac <= 0 {
        v << (-frac).min(32)
    } else if frac >= 37 {
        0
    } else {
        (v + (1i64 << (frac - 1))) >> frac
    };
    (a.clamp(-64, 64) + 64) as usize
}

/// A group's base step at one rate, G = step * gain in binary32, and its exact decomposition
/// G = mantissa * 2^exponent (spec §5.4 step 2).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BaseStep {
    /// G = step ⊗ gain, the binary32 product (finite and > 0).
    pub g: f32,
    /// m of §5.4 step 2: G's significand as an integer, 1 … 2^24 − 1.
    pub mantissa: u64,
    /// e of §5.4 step 2: G = m · 2^e, −149 … 104.
    pub exponent: i32,
}

impl BaseStep {
    /// `step` and `gain` are finite and > 0 (checked when the stream was read).
    pub fn new(step: f32, gain: f32) -> Self {
        let g = step * gain;
        let bits = g.to_bits();
        let biased = ((bits >> 23) & 0xff) as i32;
        let frac = u64::from(bits & 0x7f_ffff);
        let (mantissa, exponent) = if biased == 0 {
            (frac, -149)
        } else {
            (frac | 1 << 23, biased - 150)
        };
        BaseStep {
            g,
            mantissa: mantissa.max(1),
            exponent,
        }
    }

    /// §5.5: the step in binary32, Δ = (G * factor) * 2^-16.
    pub fn delta(&self, factor: u32) -> f32 {
        (self.g * factor as f32) * (1.0 / 65536.0)
    }

    /// §5.4 step 3: the scale index threshold test. Returns whether
    /// sigma / Δ >= theta / 2^16, i.e. y_s 2^-frac >= theta 2^-16 * G * factor 2^-16,
    /// evaluated exactly as y_s * 2^(32 - frac - exponent) >= theta * mantissa * factor.
    #[inline]
    fn at_least(&self, y_s: u64, frac: i32, factor: u32, theta: u64) -> bool {
        let rhs = u128::from(theta) * u128::from(self.mantissa) * u128::from(factor);
        let sh = 32 - frac - self.exponent;
        if sh >= 0 {
            if sh >= 100 {
                return true;
            }
            (u128::from(y_s) << sh) >= rhs
        } else {
            let s = (-sh) as u32;
            if s >= 100 {
                return rhs == 0;
            }
            u128::from(y_s)
                >= rhs.checked_shl(s).map_or(
                    u128::MAX,
                    |v| {
                        if v >> s == rhs {
                            v
                        } else {
                            u128::MAX
                        }
                    },
                )
        }
    }

    /// §5.4 step 3: the scale index of a scale output `y` (units of 2^-frac) at step factor
    /// `factor`: the number of thresholds theta_j with theta_j <= 2^16 sigma / Δ, where
    /// sigma = max(y, 1) 2^-frac.
    pub fn scale_index(&self, y: i32, frac: i32, factor: u32, thresholds: &[u32]) -> u8 {
        let y_s = y.max(1) as u64;
        // Thresholds increase: binary search for the first one above sigma / Δ.
        let (mut lo, mut hi) = (0usize, thresholds.len());
        while lo < hi {
            let mid = (lo + hi) / 2;
            if self.at_least(y_s, frac, factor, thresholds[mid].into()) {
                lo = mid + 1;
            } else {
                hi = mid;
            }
        }
        lo as u8
    }
}

/// Number of scale thresholds (spec §6.3: 64 scale indices).
pub const THRESHOLDS: usize = 63;

impl BaseStep {
    /// The §5.4 step 3 thresholds moved into the domain of the scale outputs, for one anchor:
    /// `y << lift >= T[j]` holds exactly when `y 2^(32 - E - e) >= theta_j m factor`, where
    /// `lift = emax - E` (so every output of a group shares `emax`). Products stay in u64:
    /// theta < 2^21 and m factor < 2^41.
    pub fn y_thresholds(
        &self,
        factor: u32,
        emax: i32,
        theta: &[u32; THRESHOLDS],
    ) -> [u64; THRESHOLDS] {
        let d = self.mantissa * u64::from(factor);
        let sh = 32 - emax - self.exponent;
        theta.map(|t| {
            let p = u64::from(t) * d;
            if sh >= 0 {
                if sh >= 64 {
                    u64::from(p != 0)
                } else {
                    (p >> sh) + u64::from(p & ((1u64 << sh) - 1) != 0)
                }
            } else {
                let s = (-sh) as u32;
                if s >= 64 || p.leading_zeros() < s {
                    u64::MAX
                } else {
                    p << s
                }
            }
        })
    }
}

/// §5.5 step 1: the mean in binary32, μ = y 2^-frac rounded once.
#[inline]
pub fn mean_f32(y_mean: i32, frac: i32) -> f32 {
    (f64::from(y_mean) * super::mlp::pow2(-frac)) as f32
}

/// §5.5 steps 3-4: μ + Δ u in binary32, given μ from [`mean_f32`].
#[inline]
pub fn reconstruct_from(mu: f32, delta: f32, u: i64) -> f32 {
    canonical_nan(mu + delta * (u as f32))
}

/// The quiet NaN every reconstruction outputs for a NaN result (§5.5, §7.3): platforms differ
/// in the sign and payload of the NaN that `∞ − ∞` or `∞ · 0` produces.
pub const CANONICAL_NAN_BITS: u32 = 0x7FC0_0000;

/// `x`, or the canonical NaN if `x` is NaN.
#[inline]
pub fn canonical_nan(x: f32) -> f32 {
    if x.is_nan() {
        f32::from_bits(CANONICAL_NAN_BITS)
    } else {
        x
    }
}

/// §5.5: reconstruction of one attribute value in binary32: μ + Δ u, with μ = y 2^-frac.
#[inline]
pub fn reconstruct(y_mean: i32, frac: i32, delta: f32, u: i64) -> f32 {
    reconstruct_from(mean_f32(y_mean, frac), delta, u)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn factor_table_is_monotone_and_centred() {
        assert_eq!(STEP_FACTOR[64], 65536);
        assert!(STEP_FACTOR.windows(2).all(|w| w[0] < w[1]));
        // Annex: the table file in spec/tables is this table.
        let text = std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../..",
            "/spec/tables/step_factor.txt"
        ))
        .unwrap();
        let values: Vec<u32> = text
            .lines()
            .filter(|l| !l.starts_with('#'))
            .map(|l| l.split_whitespace().nth(1).unwrap().parse().unwrap())
            .collect();
        assert_eq!(values, STEP_FACTOR);
    }

    #[test]
    fn factor_index_rounds_and_clamps() {
        assert_eq!(factor_index(0, 10), 64);
        assert_eq!(factor_index(1 << 10, 10), 64 + 16); // adj = 1.0
        assert_eq!(factor_index(-(1 << 20), 10), 0);
        assert_eq!(factor_index(i32::MAX, 0), 128);
        // Exponents up to 68 (§5.3: 8 + a0 + a1 with a0, a1 ≤ 30): the exact rounded value.
        for frac in 30..=68 {
            for y in [i32::MIN, -1, 0, 1, i32::MAX] {
                let exact = ((i128::from(y) * 16 + (1i128 << (frac - 1))) >> frac).clamp(-64, 64);
                assert_eq!(
                    factor_index(y, frac),
                    (exact + 64) as usize,
                    "y {y}, E {frac}"
                );
            }
        }
    }

    #[test]
    fn base_step_decomposes_exactly() {
        for (s, g) in [(1.0f32, 1.0f32), (0.001, 1.7), (0.2, 3.3), (1e-30, 1e-10)] {
            let b = BaseStep::new(s, g);
            let back = b.mantissa as f64 * (b.exponent as f64).exp2();
            assert_eq!(back, f64::from(s * g));
        }
    }

    #[test]
    fn lifted_thresholds_match_the_exact_comparison() {
        let theta: [u32; THRESHOLDS] = std::array::from_fn(|k| {
            (((k as f64 + 1.0 - 24.5) / 8.0).exp2() * 65536.0).round() as u32
        });
        let mut seed = 12345u64;
        let mut next = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            seed >> 33
        };
        for _ in 0..20_000 {
            let step = f32::from_bits(0x3000_0000 + (next() as u32 % 0x1800_0000));
            let b = BaseStep::new(step, 1.0 + (next() % 100) as f32 / 37.0);
            let factor = STEP_FACTOR[(next() % 129) as usize];
            let e = (next() % 40) as i32;
            let lift = (next() % 20) as i32;
            let y = (next() as i32).wrapping_sub(1 << 29);
            let t = b.y_thresholds(factor, e + lift, &theta);
            let fast = t.partition_point(|&t| t <= (y.max(1) as u64) << lift) as u8;
            assert_eq!(
                fast,
                b.scale_index(y, e, factor, &theta),
                "{b:?} f {factor} e {e} y {y}"
            );
        }
    }

    #[test]
    fn scale_index_matches_real_division() {
        // thresholds 2^((k - 24.5) / 8) in Q16, as the entropy tables define them.
        let th: Vec<u32> = (1..64)
            .map(|k| ((k as f64 - 24.5) / 8.0).exp2() * 65536.0)
            .map(|t| t.round() as u32)
            .collect();
        let b = BaseStep::new(0.5, 1.25);
        for y in [1, 7, 100, 1000, 12345, 1 << 20, i32::MAX] {
            for factor in [44u32, 65536, 131028] {
                let frac = 12;
                let sigma_u = (y as f64 / 4096.0) / (0.625 * factor as f64 / 65536.0);
                let q16 = (sigma_u * 65536.0).floor() as u64;
                let expect = th.iter().filter(|&&t| u64::from(t) <= q16).count() as u8;
                assert_eq!(
                    b.scale_index(y, frac, factor, &th),
                    expect,
                    "y {y} f {factor}"
                );
            }
        }
    }
}
