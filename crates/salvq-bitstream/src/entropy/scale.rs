//! The scale grid (spec §6.3.1): 64 standard deviations σ_k = 2^((k − 24)/8) in symbol
//! units, the 63 selection thresholds between them, and the scale-index selection rule.
//!
//! Both tables are *defined by the integers below* (Table 6-1 of the spec, also columns 2
//! and 3 of `spec/tables/gaussian_tables.txt`). They were computed once as
//! round(2^((k − 24)/8) · 2^16) and round(2^((k − 24.5)/8) · 2^16); a test checks them
//! against f64, but no decoder ever computes them.

/// Number of scale indices with a frequency table of their own (spec §6.3.1).
pub const SCALE_COUNT: usize = 64;

/// Number of scale indices a symbol may be coded with (spec §6.3.6): the 64 tables' indices
/// and the 64 wide scales 64 … 127, each coded as a high part at a table scale and uniform
/// low bits.
pub const SCALE_INDEX_COUNT: usize = 128;

/// A wide scale index k = 64 … 127 (spec §6.3.6) as its table scale k − 8·b (56 … 63) and
/// its number of low bits b = ⌊(k − 56) / 8⌋ (1 … 8); `None` below 64 or from 128 on.
#[inline]
pub fn wide_scale(k: u8) -> Option<(u8, u32)> {
    if (SCALE_COUNT..SCALE_INDEX_COUNT).contains(&usize::from(k)) {
        let low_bits = (k - 56) / 8;
        Some((k - 8 * low_bits, u32::from(low_bits)))
    } else {
        None
    }
}

/// σ_k in Q16 (σ_k · 2^16 rounded to the nearest integer), k = 0 … 63 (spec Table 6-1).
pub const SIGMA_Q16: [u32; SCALE_COUNT] = [
    8192, 8933, 9742, 10624, 11585, 12634, 13777, 15024, // k = 0..7   (0.125 … 0.229)
    16384, 17867, 19484, 21247, 23170, 25268, 27554, 30048, // k = 8..15  (0.25 …)
    32768, 35734, 38968, 42495, 46341, 50535, 55109, 60097, // k = 16..23 (0.5 …)
    65536, 71468, 77936, 84990, 92682, 101070, 110218, 120194, // k = 24..31 (1 …)
    131072, 142935, 155872, 169979, 185364, 202141, 220436, 240387, // k = 32..39 (2 …)
    262144, 285870, 311744, 339959, 370728, 404281, 440872, 480774, // k = 40..47 (4 …)
    524288, 571740, 623487, 679917, 741455, 808563, 881744, 961548, // k = 48..55 (8 …)
    1048576, 1143480, 1246974, 1359835, 1482910, 1617125, 1763488,
    1923097, // k = 56..63 (16 … 29.34)
];

/// θ_k in Q16 for k = 1 … 63 (θ_k = 2^((k − 24.5)/8) · 2^16 rounded; entry `k − 1`): the
/// smallest σ_u (Q16) that selects index k (spec Table 6-1). θ_k is the geometric midpoint of
/// σ_(k−1) and σ_k.
pub const THRESHOLD_Q16: [u32; SCALE_COUNT - 1] = [
    8555, 9329, 10173, 11094, 12098, 13193, 14387, // k = 1..7
    15689, 17109, 18658, 20347, 22188, 24196, 26386, 28774, // k = 8..15
    31379, 34219, 37316, 40693, 44376, 48393, 52773, 57549, // k = 16..23
    62757, 68438, 74632, 81386, 88752, 96785, 105545, 115098, // k = 24..31
    125515, 136875, 149263, 162773, 177505, 193571, 211090, 230195, // k = 32..39
    251030, 273750, 298527, 325546, 355010, 387141, 422180, 460391, // k = 40..47
    502060, 547500, 597053, 651091, 710020, 774282, 844361, 920782, // k = 48..55
    1004120, 1095000, 1194106, 1302182, 1420040, 1548564, 1688722, 1841564, // k = 56..63
];

/// The scale index for a symbol-unit standard deviation σ_u given in Q16 (spec §6.3.1):
/// the number of thresholds θ_1 … θ_63 that are ≤ `sigma_u_q16`, so 0 … 63.
///
/// Values below θ_1 select index 0 (σ = 0.125), values at or above θ_63 select index 63
/// (σ ≈ 29.3); symbols far outside the selected table are still coded, through the escape
/// (§6.4).
pub fn scale_index(sigma_u_q16: u64) -> u8 {
    // §6.3.1: k = #{ j in 1..=63 : θ_j ≤ σ_u }. THRESHOLD_Q16 is strictly increasing.
    let k = THRESHOLD_Q16.partition_point(|&t| u64::from(t) <= sigma_u_q16);
    // k ≤ 63 because the array has 63 entries.
    k as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sigma_and_thresholds_match_their_definition_within_one_q16_step() {
        for (k, &s) in SIGMA_Q16.iter().enumerate() {
            let exact = 2f64.powf((k as f64 - 24.0) / 8.0) * 65536.0;
            assert!(
                (s as f64 - exact).abs() <= 0.5 + 1e-6,
                "sigma {k}: {s} vs {exact}"
            );
        }
        for (j, &t) in THRESHOLD_Q16.iter().enumerate() {
            let k = j + 1;
            let exact = 2f64.powf((k as f64 - 24.5) / 8.0) * 65536.0;
            assert!(
                (t as f64 - exact).abs() <= 0.5 + 1e-6,
                "theta {k}: {t} vs {exact}"
            );
            // θ_k lies strictly between σ_(k−1) and σ_k.
            assert!(SIGMA_Q16[k - 1] < t && t < SIGMA_Q16[k]);
        }
    }

    #[test]
    fn scale_index_counts_thresholds() {
        assert_eq!(scale_index(0), 0);
        assert_eq!(scale_index(u64::MAX), 63);
        assert_eq!(wide_scale(63), None);
        assert_eq!(wide_scale(64), Some((56, 1)));
        assert_eq!(wide_scale(71), Some((63, 1)));
        assert_eq!(wide_scale(72), Some((56, 2)));
        assert_eq!(wide_scale(127), Some((63, 8)));
        assert_eq!(wide_scale(128), None);
        for k in 1..SCALE_COUNT {
            let t = u64::from(THRESHOLD_Q16[k - 1]);
            assert_eq!(scale_index(t), k as u8);
            assert_eq!(scale_index(t - 1), (k - 1) as u8);
        }
        for (k, &s) in SIGMA_Q16.iter().enumerate() {
            assert_eq!(scale_index(u64::from(s)), k as u8);
        }
    }
}
