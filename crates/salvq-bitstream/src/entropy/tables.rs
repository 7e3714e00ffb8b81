//! Discretized-Gaussian frequency tables (spec §6.3.2 – §6.3.5), built by the normative integer
//! procedure: no floating point anywhere.

use std::fmt::Write as _;
use std::sync::OnceLock;

use super::ans::ScaleModel;
use super::ans::{COARSE_BITS, COARSE_LEN, MAX_PRECISION, MIN_PRECISION};
use super::scale::{wide_scale, SCALE_COUNT, SIGMA_Q16, THRESHOLD_Q16};

/// Longest Exp-Golomb prefix (leading zeros) an escape may have (§6.4).
pub const ESCAPE_MAX_PREFIX: u32 = 30;
/// Largest w = |u| − R_k an escape can carry: 2^31 − 1 (§6.4).
pub const ESCAPE_MAX_W: u64 = (1 << (ESCAPE_MAX_PREFIX + 1)) - 1;

/// The precision P of the format's tables (§6.5): frequencies sum to 2^P.
pub const PRECISION: u32 = 16;
/// TAIL in units of 1/16 (§6.3.2): R_k = min(⌈TAIL · σ_k⌉, R_MAX). TAIL = 5.
pub const TAIL_Q4: u32 = 80;
/// R_MAX (§6.3.2): the largest table radius.
pub const R_MAX: u32 = 127;

/// Largest radius any table may have (keeps every intermediate of §6.3.3 in range).
pub const RADIUS_LIMIT: u32 = 1023;

/// 2^64 / √(2π), floored (§6.3.3, constant C).
pub const INV_SQRT_2PI_Q64: u128 = 7_359_186_146_747_302_452;
/// The series argument limit X_MAX = 6 in Q32 (§6.3.3 step 2).
pub const X_MAX_Q32: u64 = 6 << 32;
/// ½ in Q64: the value of G at and beyond X_MAX.
pub const HALF_Q64: u64 = 1 << 63;

/// G(x) = Φ(x) − ½ in Q64 (floor), for x = b2 / (2σ) with `b2` = 2u + 1 odd and σ given in
/// Q16 as `sigma_q16` — spec §6.3.3 steps 1–5, verbatim.
pub fn half_cdf_q64(b2: u64, sigma_q16: u32) -> u64 {
    // Step 1: x in Q32, x = (u + ½)/σ = b2 · 2^15 / σ_q16 → floor(b2 · 2^47 / σ_q16).
    let x = (u128::from(b2) << 47) / u128::from(sigma_q16.max(1));
    // Step 2: beyond X_MAX the value is ½.
    if x >= u128::from(X_MAX_Q32) {
        return HALF_Q64;
    }
    // Step 3: T_0 = floor(x · C / 2^32), S = T_0.
    let mut t: u128 = (x * INV_SQRT_2PI_Q64) >> 32;
    let mut s: i128 = t as i128;
    // Step 4: T_n = floor(floor(T_(n−1) · x / 2^32) · x / (n · 2^33)),
    // S += (−1)^n · floor(T_n / (2n + 1)), until T_n = 0.
    let mut n: u128 = 1;
    loop {
        t = (((t * x) >> 32) * x) / (n << 33);
        if t == 0 {
            break;
        }
        let term = (t / (2 * n + 1)) as i128;
        if n % 2 == 1 {
            s -= term;
        } else {
            s += term;
        }
        n += 1;
    }
    // Step 5: clamp to [0, ½].
    s.clamp(0, i128::from(HALF_Q64)) as u64
}

/// One scale's table (§6.3.4): radius R, frequencies of the alphabet
/// u = −R … R then ESCAPE (A = 2R + 2 entries), and cumulative frequencies (A + 1 entries),
/// with the decoder's search table beside them (one scale's lookups then share one base).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ScaleTable {
    radius: u32,
    freq: Vec<u32>,
    /// The A + 1 cumulative frequencies, then [`SEARCH_PAD`] copies of 2^P: past the
    /// alphabet no symbol starts at or before a quantile, so a search may read a fixed
    /// window after any symbol without a bound of its own (`ScaleModel`).
    cum: Vec<u32>,
    /// See [`ScaleModel::coarse`].
    coarse: [u16; COARSE_LEN],
}

/// Entries of 2^P after a table's cumulative frequencies (see [`ScaleTable`]): a search
/// reads `cum[s .. s + 5]` for any symbol s ≤ A − 1.
pub const SEARCH_PAD: usize = 3;

impl ScaleTable {
    /// R_k: symbols with |u| ≤ R_k are coded directly; others take the escape (§6.4).
    pub fn radius(&self) -> u32 {
        self.radius
    }
    /// Frequencies f(−R) … f(R), f(ESCAPE): the alphabet index of u is u + R, ESCAPE is 2R + 1.
    pub fn frequencies(&self) -> &[u32] {
        &self.freq
    }
    /// Cumulative frequencies: `cum[i]` = Σ_(j<i) f(j), A + 1 entries ending in 2^P.
    pub fn cumulative(&self) -> &[u32] {
        &self.cum[..self.freq.len() + 1]
    }
    /// Alphabet index of ESCAPE (2R + 1).
    pub fn escape_index(&self) -> usize {
        2 * self.radius as usize + 1
    }
}

/// The 64 frequency tables at one precision (spec §6.3), with the decoder's coarse search table.
#[derive(Debug, Clone)]
pub struct GaussianTables {
    precision: u32,
    tail_q4: u32,
    r_max: u32,
    /// One per scale index: a fixed count, so that an index checked below [`SCALE_COUNT`]
    /// needs no other bound.
    scales: Box<[ScaleTable; SCALE_COUNT]>,
}

impl GaussianTables {
    /// The tables at precision `precision` with the format's TAIL and R_MAX (§6.3).
    ///
    /// # Panics
    /// If `precision` is outside `MIN_PRECISION..=MAX_PRECISION` (12 … 24): a configuration
    /// error, never a consequence of stream bytes.
    pub fn new(precision: u32) -> Self {
        Self::with_tail(precision, TAIL_Q4, R_MAX)
    }

    /// The format's tables (precision [`PRECISION`], §6.5), built on first use and cached.
    pub fn standard() -> &'static GaussianTables {
        static TABLES: OnceLock<GaussianTables> = OnceLock::new();
        TABLES.get_or_init(|| GaussianTables::new(PRECISION))
    }

    /// Tables with another TAIL (in 1/16 units) and R_MAX — for measurements (§6.5); streams
    /// use [`GaussianTables::standard`].
    ///
    /// # Panics
    /// If `precision` is unsupported, `tail_q4` is 0, or `r_max` is not in 1 … 1023.
    pub fn with_tail(precision: u32, tail_q4: u32, r_max: u32) -> Self {
        assert!(
            (MIN_PRECISION..=MAX_PRECISION).contains(&precision),
            "precision {precision} outside {MIN_PRECISION}..={MAX_PRECISION}"
        );
        assert!(tail_q4 >= 1, "TAIL must be positive");
        assert!(
            (1..=RADIUS_LIMIT).contains(&r_max),
            "R_MAX {r_max} outside 1..={RADIUS_LIMIT}"
        );
        GaussianTables {
            precision,
            tail_q4,
            r_max,
            scales: Box::new(core::array::from_fn(|k| {
                build_scale(SIGMA_Q16[k], precision, tail_q4, r_max)
            })),
        }
    }

    /// A deliberately wrong copy for conformance tests (a broken decoder must fail the
    /// vectors): in scale `k`'s table one unit of frequency moves from u = 0 to u = 1, so one
    /// cumulative entry is off by one while the table still sums to 2^P. `test-hooks` only.
    #[cfg(feature = "test-hooks")]
    pub fn with_one_wrong_entry(&self, k: u8) -> GaussianTables {
        let mut wrong = self.clone();
        if let Some(t) = wrong.scales.get_mut(usize::from(k)) {
            let zero = t.radius as usize;
            if t.freq[zero] > 1 {
                t.freq[zero] -= 1;
                t.freq[zero + 1] += 1;
                t.cum[zero + 1] -= 1;
                t.coarse = coarse_table(&t.cum, self.precision);
            }
        }
        wrong
    }

    /// Precision P: every table's frequencies sum to 2^P.
    pub fn precision(&self) -> u32 {
        self.precision
    }
    /// TAIL in 1/16 units.
    pub fn tail_q4(&self) -> u32 {
        self.tail_q4
    }
    /// R_MAX.
    pub fn r_max(&self) -> u32 {
        self.r_max
    }
    /// The table of scale index `k`.
    ///
    /// # Panics
    /// If `k ≥ SCALE_COUNT`.
    pub fn scale(&self, k: u8) -> &ScaleTable {
        &self.scales[usize::from(k)]
    }
    /// R_k of scale index `k` (panics if `k ≥ SCALE_COUNT`).
    pub fn radius(&self, k: u8) -> u32 {
        self.scales[usize::from(k)].radius
    }
    /// The decoding model of scale `k` (panics if `k ≥ SCALE_COUNT`).
    #[inline]
    pub(crate) fn model(&self, k: u8) -> ScaleModel<'_> {
        let t = &self.scales[usize::from(k)];
        ScaleModel {
            cum: &t.cum,
            coarse: &t.coarse,
        }
    }

    /// −log2 of the probability with which `u` is coded at scale index `k`, escape bits
    /// included (§6.4: each escape bit costs exactly 1 bit), and for a wide scale (§6.3.6)
    /// its high part ⌊u / 2^b⌋ and b uniform bits. Infinite for symbols that cannot be coded
    /// (|u| − R_k ≥ 2^31, or the high part's |h| − R_t ≥ 2^31).
    ///
    /// # Panics
    /// If `k ≥ SCALE_INDEX_COUNT`.
    pub fn ideal_bits(&self, k: u8, u: i64) -> f64 {
        if let Some((table, low_bits)) = wide_scale(k) {
            return self.ideal_bits(table, u >> low_bits) + f64::from(low_bits);
        }
        let t = self.scale(k);
        let p = f64::from(self.precision);
        let mag = u.unsigned_abs();
        let r = u64::from(t.radius);
        if mag <= r {
            let f = t.freq[(u + r as i64) as usize];
            return p - f64::from(f).log2();
        }
        let w = mag - r; // = v + 1 of §6.4
        if w > ESCAPE_MAX_W {
            return f64::INFINITY;
        }
        let prefix = 63 - w.leading_zeros(); // L = floor(log2(w))
        let f_esc = t.freq[t.escape_index()];
        p - f64::from(f_esc).log2() + f64::from(2 * prefix + 1) + 1.0
    }

    /// The data file `spec/tables/gaussian_tables.txt` for these tables (§6.3.5).
    pub fn to_text(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(
            s,
            "# SALVQ Gaussian frequency tables (spec section 6.3): precision P = {}, TAIL = {}/16, R_MAX = {}",
            self.precision, self.tail_q4, self.r_max
        );
        let _ = writeln!(
            s,
            "# k sigma_q16 threshold_q16 R_k f(-R_k) ... f(R_k) f(ESCAPE)"
        );
        for (k, t) in self.scales.iter().enumerate() {
            let _ = write!(s, "{k} {}", SIGMA_Q16[k]);
            if k == 0 {
                s.push_str(" -");
            } else {
                let _ = write!(s, " {}", THRESHOLD_Q16[k - 1]);
            }
            let _ = write!(s, " {}", t.radius);
            for f in &t.freq {
                let _ = write!(s, " {f}");
            }
            s.push('\n');
        }
        s
    }
}

/// §6.3.2: R_k = min(⌈TAIL · σ_k⌉, R_MAX), TAIL = tail_q4 / 16, σ_k = σ_q16 / 2^16.
pub fn radius_for(sigma_q16: u32, tail_q4: u32, r_max: u32) -> u32 {
    let r = (u64::from(tail_q4) * u64::from(sigma_q16)).div_ceil(1 << 20);
    r.min(u64::from(r_max)) as u32
}

/// §6.3.3 – §6.3.4 for one scale.
fn build_scale(sigma_q16: u32, precision: u32, tail_q4: u32, r_max: u32) -> ScaleTable {
    // §6.3.2.
    let radius = radius_for(sigma_q16, tail_q4, r_max);
    let r = radius as usize;
    let a = 2 * r + 2;
    // §6.3.3 step 6: G̃_u = max(G((2u + 1)/(2σ)), G̃_(u−1)), u = 0 … R.
    let mut g = Vec::with_capacity(r + 1);
    let mut prev = 0u64;
    for u in 0..=radius {
        let v = half_cdf_q64(2 * u64::from(u) + 1, sigma_q16).max(prev);
        g.push(v);
        prev = v;
    }
    // §6.3.3 step 7: masses in Q64 (sum exactly 2^64).
    let mass = |i: usize| -> u128 {
        if i == a - 1 {
            (1u128 << 64) - 2 * u128::from(g[r])
        } else {
            let m = i.abs_diff(r); // |u|
            if m == 0 {
                2 * u128::from(g[0])
            } else {
                u128::from(g[m] - g[m - 1])
            }
        }
    };
    // §6.3.4 step 1: f = 1 + floor(m · W / 2^64), W = 2^P − A.
    let total = 1u32 << precision;
    let w = u128::from(total - a as u32);
    let mut freq: Vec<u32> = (0..a).map(|i| 1 + ((mass(i) * w) >> 64) as u32).collect();
    // §6.3.4 step 2: the remainder goes out from the centre, symmetrically.
    let mut rem = total - freq.iter().sum::<u32>();
    if rem % 2 == 1 {
        freq[r] += 1;
        rem -= 1;
    }
    let mut j = 1;
    while rem > 0 {
        freq[r - j] += 1;
        freq[r + j] += 1;
        rem -= 2;
        j += 1;
    }
    // §6.3.4 step 3.
    let mut cum = Vec::with_capacity(a + 1 + SEARCH_PAD);
    let mut c = 0u32;
    cum.push(0);
    for &f in &freq {
        c += f;
        cum.push(c);
    }
    cum.extend([total; SEARCH_PAD]);
    let coarse = coarse_table(&cum, precision);
    ScaleTable {
        radius,
        freq,
        cum,
        coarse,
    }
}

/// The decoder's search table of a scale at `precision` (see [`ScaleModel::coarse`]): bucket
/// b's first quantile is b << (P − COARSE_BITS); `cum` as [`ScaleTable`] holds it.
fn coarse_table(cum: &[u32], precision: u32) -> [u16; COARSE_LEN] {
    let shift = precision - COARSE_BITS;
    let last = cum.len() - SEARCH_PAD - 2;
    let mut search = [0u16; COARSE_LEN];
    let mut i = 0usize;
    for (b, entry) in (0u32..).zip(&mut search[..COARSE_LEN - 1]) {
        while cum[i + 1] <= b << shift {
            i += 1;
        }
        *entry = i as u16;
    }
    search[COARSE_LEN - 1] = last as u16;
    search
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The standard normal CDF.
    fn phi(x: f64) -> f64 {
        0.5 * libm::erfc(-x / std::f64::consts::SQRT_2)
    }

    #[test]
    fn half_cdf_matches_f64_within_2_pow_minus_33() {
        let mut worst = 0f64;
        for &s in &SIGMA_Q16 {
            for u in 0..200u64 {
                let g = half_cdf_q64(2 * u + 1, s) as f64 / 2f64.powi(64);
                let x = (u as f64 + 0.5) / (f64::from(s) / 65536.0);
                let exact = if x >= 6.0 { 0.5 } else { phi(x) - 0.5 };
                worst = worst.max((g - exact).abs());
            }
        }
        assert!(worst < 2f64.powi(-33), "worst error {worst:e}");
    }

    #[test]
    fn tables_sum_to_2_pow_p_and_are_symmetric() {
        for p in [12, 16, 20, 24] {
            let t = GaussianTables::new(p);
            for k in 0..SCALE_COUNT as u8 {
                let s = t.scale(k);
                assert_eq!(s.cumulative().last().copied(), Some(1 << p));
                // The search's window reads past the alphabet into entries of 2^P.
                assert_eq!(s.cum.len(), s.freq.len() + 1 + SEARCH_PAD);
                assert!(s.cum[s.freq.len()..].iter().all(|&c| c == 1 << p));
                assert!(s.freq.iter().all(|&f| f >= 1));
                let r = s.radius as usize;
                for j in 0..=r {
                    assert_eq!(s.freq[r - j], s.freq[r + j]);
                }
            }
        }
    }

    #[test]
    fn model_search_finds_the_symbol_of_every_quantile() {
        use constriction::stream::model::DecoderModel;
        // The format's tables, and wide ones (R up to 1023) whose tail buckets hold up to
        // 2^(P − COARSE_BITS) symbols of frequency 1: the search's widest bisections.
        let tables = [
            GaussianTables::new(12),
            GaussianTables::new(16),
            GaussianTables::new(20),
            GaussianTables::with_tail(16, 16 * 40, 1023),
        ];
        for t in &tables {
            let p = t.precision();
            for k in 0..SCALE_COUNT as u8 {
                let cum = t.scale(k).cumulative();
                let m = t.model(k);
                for q in 0..1u32 << p {
                    let (i, c, f) = crate::with_precision!(p, P => {
                        DecoderModel::<P>::quantile_function(&m, q)
                    });
                    assert!(cum[i] <= q && q < cum[i + 1]);
                    assert_eq!((c, f.get()), (cum[i], cum[i + 1] - cum[i]));
                }
            }
        }
    }
}
