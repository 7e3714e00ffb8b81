//! §8.3's adaptive binary contexts: counts of 0s and 1s per context, and each context's
//! current P(1) computed from them without a division.

use super::ADAPT_LIMIT;

/// One adaptive binary context (§8.3): counts of 0s and 1s, both starting at 1, packed as
/// `c0 | c1 << 16` (both ≤ 256) so that an event reads and writes it whole.
#[derive(Debug, Clone, Copy)]
struct Counts(u32);

impl Counts {
    const START: Counts = Counts::new(1, 1);

    const fn new(c0: u32, c1: u32) -> Counts {
        Counts(c0 | c1 << 16)
    }

    /// P(1) in units of 2^−p, clamped to 1 … 2^p − 1: ⌊c1 · 2^p / (c0 + c1)⌋, computed as
    /// a product with a reciprocal (exact, see [`RECIPROCAL`]) rather than a division, which
    /// costs more than the rest of an event.
    #[cfg(test)]
    fn freq_one(self, p: u32) -> u32 {
        self.freq_one_at(Precision::new(p))
    }

    /// P(1) in units of 2^−p (as `freq_one` in the tests), its shift and bound worked out once
    /// per set of contexts.
    #[inline(always)]
    fn freq_one_at(self, p: Precision) -> u32 {
        let (c0, c1) = (self.0 & 0xffff, self.0 >> 16);
        let sum = ((c0 + c1) as usize).min(ADAPT_LIMIT as usize);
        let f = (u64::from(c1) * RECIPROCAL[sum]) >> p.shift;
        (f as u32).max(1).min(p.max)
    }

    #[inline]
    fn update(&mut self, bit: bool) {
        let v = self.0 + (1 << (16 * u32::from(bit)));
        let (c0, c1) = (v & 0xffff, v >> 16);
        *self = if c0 + c1 > ADAPT_LIMIT {
            Counts::new((c0 + 1) >> 1, (c1 + 1) >> 1)
        } else {
            Counts(v)
        };
    }
}

/// A precision `p` (§6.2, at most [`RECIPROCAL_BITS`]) as [`Counts::freq_one_at`] uses it: the
/// shift from the reciprocal product to units of 2^−p, and the largest P(1), 2^p − 1.
#[derive(Debug, Clone, Copy)]
struct Precision {
    shift: u32,
    max: u32,
}

impl Precision {
    fn new(p: u32) -> Precision {
        Precision {
            shift: RECIPROCAL_BITS - p,
            max: (1 << p) - 1,
        }
    }
}

/// A set of adaptive binary contexts, each one's current P(1) kept beside its counts: an
/// event reads its probability with one load, and the product that computes it runs at the
/// update, off the chain from one event's bit to the next event's context.
pub(super) struct Contexts<const N: usize> {
    counts: [Counts; N],
    freq_one: [u32; N],
    precision: Precision,
}

impl<const N: usize> Contexts<N> {
    /// `N` is a power of two, so that a context index masked to `N − 1` needs no bounds check.
    const MASK: usize = {
        assert!(N.is_power_of_two());
        N - 1
    };

    pub(super) fn new(precision: u32) -> Self {
        let precision = Precision::new(precision);
        Contexts {
            counts: [Counts::START; N],
            freq_one: [Counts::START.freq_one_at(precision); N],
            precision,
        }
    }

    /// P(1) of context `ctx` (below `N`), in 1 … 2^P − 1.
    #[inline(always)]
    pub(super) fn freq_one(&self, ctx: usize) -> u32 {
        self.freq_one[ctx & Self::MASK]
    }

    #[inline(always)]
    pub(super) fn update(&mut self, ctx: usize, bit: bool) {
        let ctx = ctx & Self::MASK;
        let c = &mut self.counts[ctx];
        c.update(bit);
        self.freq_one[ctx] = c.freq_one_at(self.precision);
    }
}

/// Bits of [`RECIPROCAL`]'s fixed point.
const RECIPROCAL_BITS: u32 = 48;

/// `⌈2^48 / s⌉` for every count sum `s` (2 … 256; the rest unused): for `c1 < s ≤ 256` and
/// `p ≤ 24`, `(c1 · ⌈2^48 / s⌉) >> (48 − p)` equals `⌊c1 · 2^p / s⌋` exactly. The product
/// exceeds `c1 · 2^p / s` by less than `c1 / 2^(48 − p) ≤ 2^−16`, and a quotient that is not
/// an integer is at least `1 / s ≥ 2^−8` below the next one. `c1 · ⌈2^48 / s⌉ < 2^56`.
const RECIPROCAL: [u64; ADAPT_LIMIT as usize + 1] = {
    let mut out = [0u64; ADAPT_LIMIT as usize + 1];
    let mut s = 1;
    while s <= ADAPT_LIMIT as usize {
        out[s] = (1u64 << RECIPROCAL_BITS).div_ceil(s as u64);
        s += 1;
    }
    out
};

#[cfg(test)]
mod tests {
    use super::*;
    use crate::entropy::ans::{MAX_PRECISION, MIN_PRECISION};

    /// The reciprocal product is the §8.3 quotient for every reachable count pair and every
    /// precision the tables allow.
    #[test]
    fn reciprocal_product_is_the_exact_quotient() {
        for p in MIN_PRECISION..=MAX_PRECISION {
            for sum in 2..=ADAPT_LIMIT {
                for c1 in 1..sum {
                    let counts = Counts::new(sum - c1, c1);
                    let exact = ((u64::from(c1) << p) / u64::from(sum)) as u32;
                    assert_eq!(
                        counts.freq_one(p),
                        exact.clamp(1, (1 << p) - 1),
                        "c1 {c1}, sum {sum}, P {p}"
                    );
                }
            }
        }
    }
}
