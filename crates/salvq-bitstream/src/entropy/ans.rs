//! The ANS coder (spec §6.2), as `constriction`'s stack `AnsCoder<u32, u64>` implements it.
//!
//! This module is the only place that touches `constriction`. Every coded event — a table
//! symbol, an escape bit, a binary event — reaches the coder as an interval
//! (cumulative frequency, frequency) of a distribution whose frequencies sum to 2^P (§6.2.1).
//! The coder state is a `u64` that always lies in [2^32, 2^64) (§6.2.2); words are `u32`.
//!
//! * Encoding: [`encode_intervals`] starts `constriction`'s coder from the state 2^32
//!   (`AnsCoder::from_raw_parts`), encodes the intervals in reverse (§6.2.3), serializes it with
//!   `into_compressed` and reverses the word order, so that the chunk holds the words in the
//!   order the decoder reads them (§6.2.5).
//! * Decoding: [`AnsReader`] reads the two-word initial state itself (§6.2.6 steps 1–3) and
//!   hands `constriction`'s coder a [`LeWords`] backend that reads the remaining little-endian
//!   words front to back; after each symbol it checks the state invariant (§6.2.4 step 4).
//!
//! The decoding models ([`ScaleModel`], [`BinaryModel`]) implement `constriction`'s
//! `DecoderModel` for every precision; the arithmetic on the state stays `constriction`'s.

use core::convert::Infallible;
use core::num::NonZeroU32;

use constriction::backends::ReadWords;
use constriction::stream::model::{DecoderModel, EncoderModel, EntropyModel};
use constriction::stream::stack::AnsCoder;
use constriction::stream::{Code, Decode, Encode};
use constriction::{Stack, UnwrapInfallible};

use crate::error::AnsFault;

/// The state an encoder starts from and a decoder must end in (§6.2.2): 2^32.
pub const INITIAL_STATE: u64 = 1 << 32;

/// Smallest precision P (bits) the tables support (§6.2.1).
pub const MIN_PRECISION: u32 = 12;
/// Largest precision P (bits) the tables support (§6.2.1).
pub const MAX_PRECISION: u32 = 24;
/// The decoder finds a symbol from the top `COARSE_BITS` bits of the quantile: a table per
/// scale gives the symbols that hold the first quantiles of the quantile's bucket and of the
/// next one, and a binary search between them over the cumulative frequencies finishes the
/// search. Most buckets lie within one or two symbols; a bucket in a wide table's tails holds
/// up to 2^(P − COARSE_BITS) symbols of frequency 1, which a forward walk took one step each
/// (at rate 0 under format 0.13, fruit_drops and alti put 13 % and 7 % of their symbols in
/// the widest table, at 14.7 and 13.2 steps). This is an implementation choice: §6.2.4 step 2
/// defines the symbol whatever the search.
pub const COARSE_BITS: u32 = 8;
/// Entries of a scale's coarse table: one per bucket, then the last alphabet index.
pub const COARSE_LEN: usize = (1 << COARSE_BITS) + 1;
// Every precision has at least COARSE_BITS bits of quantile to cut into buckets.
const _: () = assert!(MIN_PRECISION >= COARSE_BITS);

/// Runs `$body` with `$p` (a runtime precision in `MIN_PRECISION..=MAX_PRECISION`) bound to
/// the const generic `$P`. `constriction` takes the precision as a const generic parameter.
/// The encoder's symbol writer and the benches that time the bare coder use it too.
#[macro_export]
macro_rules! with_precision {
    ($p:expr, $P:ident => $body:expr) => {
        match $p {
            12 => {
                const $P: usize = 12;
                $body
            }
            13 => {
                const $P: usize = 13;
                $body
            }
            14 => {
                const $P: usize = 14;
                $body
            }
            15 => {
                const $P: usize = 15;
                $body
            }
            16 => {
                const $P: usize = 16;
                $body
            }
            17 => {
                const $P: usize = 17;
                $body
            }
            18 => {
                const $P: usize = 18;
                $body
            }
            19 => {
                const $P: usize = 19;
                $body
            }
            20 => {
                const $P: usize = 20;
                $body
            }
            21 => {
                const $P: usize = 21;
                $body
            }
            22 => {
                const $P: usize = 22;
                $body
            }
            23 => {
                const $P: usize = 23;
                $body
            }
            24 => {
                const $P: usize = 24;
                $body
            }
            // `GaussianTables::new` rejects every other precision, and every reader and writer
            // takes its precision from a `GaussianTables`.
            p => unreachable!("precision {p} is not supported"),
        }
    };
}
pub use crate::with_precision;

/// One coded event as the coder sees it: the interval [cum, cum + freq) of 2^P (§6.2.1).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Interval {
    /// Cumulative frequency of the symbols before this one.
    pub cum: u32,
    /// The symbol's frequency, ≥ 1.
    pub freq: NonZeroU32,
}

impl<const P: usize> EntropyModel<P> for Interval {
    type Symbol = ();
    type Probability = u32;
}

impl<const P: usize> EncoderModel<P> for Interval {
    #[inline(always)]
    fn left_cumulative_and_probability(
        &self,
        _symbol: impl core::borrow::Borrow<()>,
    ) -> Option<(u32, NonZeroU32)> {
        Some((self.cum, self.freq))
    }
}

/// Encodes `intervals` (given in decoding order) at precision `P` and returns the chunk's
/// words in the order the decoder reads them (§6.2.3, §6.2.5).
pub fn encode_intervals<const P: usize>(intervals: &[Interval]) -> Vec<u32> {
    // §6.2.3 step 1: the encoder starts from the state 2^32 with no words.
    let mut coder: AnsCoder<u32, u64> =
        AnsCoder::from_raw_parts(Vec::with_capacity(intervals.len() / 8 + 2), INITIAL_STATE);
    // §6.2.3 step 2: the last event is encoded first.
    for &iv in intervals.iter().rev() {
        Encode::<P>::encode_symbol(&mut coder, (), iv)
            .expect("an Interval model gives every symbol a nonzero frequency");
    }
    // §6.2.5: `into_compressed` appends the final state (low word, then high word) to the
    // pushed words; the chunk stores that sequence reversed.
    let mut words = coder.into_compressed().unwrap_infallible();
    words.reverse();
    words
}

/// Serializes words as u32 little-endian (§6.2.5).
pub fn words_to_bytes(words: &[u32]) -> Vec<u8> {
    words.iter().flat_map(|w| w.to_le_bytes()).collect()
}

/// `constriction` backend: the chunk's words after the initial state, read front to back as
/// u32 little-endian (§6.2.5). Its length is a multiple of 4 (checked by [`AnsReader::new`]).
#[derive(Debug, Clone)]
pub struct LeWords<'a> {
    rest: &'a [u8],
}

impl<'a> LeWords<'a> {
    /// Words not read yet.
    pub fn remaining(&self) -> usize {
        self.rest.len() / 4
    }
}

impl ReadWords<u32, Stack> for LeWords<'_> {
    type ReadError = Infallible;

    #[inline(always)]
    fn read(&mut self) -> Result<Option<u32>, Infallible> {
        match self.rest.split_first_chunk::<4>() {
            Some((w, rest)) => {
                self.rest = rest;
                Ok(Some(u32::from_le_bytes(*w)))
            }
            None => Ok(None),
        }
    }

    fn maybe_exhausted(&self) -> bool {
        self.rest.len() < 4
    }
}

/// Decoding model of one scale table: the alphabet indices 0 … A−1 with cumulative
/// frequencies `cum` (A + 1 entries, `cum[0] = 0`, `cum[A] = 2^P`, then entries of 2^P that
/// let the search read a window of five from any symbol), and the coarse table:
/// `coarse[b]` is the index of the symbol holding quantile `b · 2^(P − COARSE_BITS)`
/// (2^COARSE_BITS entries), then A − 1. The model serves the precision P its table was built
/// at; the bucket's shift is a constant of P, which the decoder's loops then need not load.
#[derive(Debug, Clone, Copy)]
pub struct ScaleModel<'t> {
    /// Cumulative frequencies in units of 2^−P, padded with 2^P (see the type's doc).
    pub cum: &'t [u32],
    /// The coarse table: bucket `b`'s first symbol, then A − 1 (see the type's doc).
    pub coarse: &'t [u16; COARSE_LEN],
}

impl<const P: usize> EntropyModel<P> for ScaleModel<'_> {
    type Symbol = usize;
    type Probability = u32;
}

impl<const P: usize> DecoderModel<P> for ScaleModel<'_> {
    #[inline(always)]
    fn quantile_function(&self, quantile: u32) -> (usize, u32, NonZeroU32) {
        // §6.2.4 step 2: the symbol s with cum[s] ≤ q < cum[s + 1]. The bucket's first
        // symbol starts at or before q, and the next bucket's (or A − 1) holds a quantile
        // above q: s lies between them, found by bisection (each step halves [lo, hi]).
        let bucket = (quantile >> (P as u32 - COARSE_BITS)) as usize;
        let mut lo = usize::from(self.coarse[bucket]);
        let mut hi = usize::from(self.coarse[bucket + 1]);
        if hi - lo <= 3 {
            // Most buckets: s is lo plus how many of the next three symbols start at or before
            // q, counted without a branch (whether q falls past a boundary in its bucket
            // follows the data), in a window of five entries read at once. Past hi, every
            // symbol starts above q (hi holds a quantile above q, or is A − 1, and cum[A] =
            // 2^P, as are the entries padding the table: `ScaleTable`), so the count stops at
            // hi by itself.
            if let Some(w) = self.cum.get(lo..lo + 5) {
                let starts_by_q = |t: usize| usize::from(w[t] <= quantile);
                let t = starts_by_q(1) + starts_by_q(2) + starts_by_q(3);
                let (cum, next) = (w[t], w[t + 1]);
                // Table frequencies are ≥ 1 by construction (§6.3.4); MIN is never taken.
                return (
                    lo + t,
                    cum,
                    NonZeroU32::new(next - cum).unwrap_or(NonZeroU32::MIN),
                );
            }
        }
        while lo < hi {
            let mid = (lo + hi).div_ceil(2);
            if self.cum[mid] <= quantile {
                lo = mid;
            } else {
                hi = mid - 1;
            }
        }
        let index = lo;
        let cum = self.cum[index];
        let freq = self.cum[index + 1] - cum;
        // Table frequencies are ≥ 1 by construction (§6.3.4); MIN is never taken.
        (index, cum, NonZeroU32::new(freq).unwrap_or(NonZeroU32::MIN))
    }
}

/// A binary event with P(1) = `freq_one` / 2^P (§6.2.1): symbol 0 is [0, 2^P − freq_one),
/// symbol 1 is [2^P − freq_one, 2^P).
#[derive(Debug, Clone, Copy)]
pub struct BinaryModel {
    /// 2^P − freq_one, in 1 … 2^P − 1.
    pub freq_zero: u32,
}

impl BinaryModel {
    /// The coded interval of `bit` at precision `precision`; `freq_one` must already be in
    /// 1 … 2^P − 1 (see `clamp_freq_one`).
    pub fn interval(precision: u32, freq_one: u32, bit: bool) -> Interval {
        let total = 1u32 << precision;
        let (cum, freq) = if bit {
            (total - freq_one, freq_one)
        } else {
            (0, total - freq_one)
        };
        Interval {
            cum,
            freq: NonZeroU32::new(freq).unwrap_or(NonZeroU32::MIN),
        }
    }
}

/// §6.2.1: a binary event's frequency of 1 is clamped to 1 … 2^P − 1.
pub fn clamp_freq_one(precision: u32, freq_one: u32) -> u32 {
    freq_one.clamp(1, (1u32 << precision) - 1)
}

impl<const P: usize> EntropyModel<P> for BinaryModel {
    type Symbol = bool;
    type Probability = u32;
}

impl<const P: usize> DecoderModel<P> for BinaryModel {
    #[inline(always)]
    fn quantile_function(&self, quantile: u32) -> (bool, u32, NonZeroU32) {
        if quantile < self.freq_zero {
            (
                false,
                0,
                NonZeroU32::new(self.freq_zero).unwrap_or(NonZeroU32::MIN),
            )
        } else {
            let freq_one = (1u32 << P) - self.freq_zero;
            (
                true,
                self.freq_zero,
                NonZeroU32::new(freq_one).unwrap_or(NonZeroU32::MIN),
            )
        }
    }
}

/// A uniform value of `bits` bits (§6.2.1 kind 4, 1 ≤ `bits` ≤ P): value v is
/// [v · 2^(P − bits), (v + 1) · 2^(P − bits)).
#[derive(Debug, Clone, Copy)]
pub struct UniformModel {
    /// Width of the value in bits, 1 … P.
    pub bits: u32,
}

impl UniformModel {
    /// The coded interval of `value` (below 2^bits) at precision `precision`.
    pub fn interval(self, precision: u32, value: u32) -> Interval {
        let shift = precision - self.bits;
        Interval {
            cum: value << shift,
            freq: NonZeroU32::new(1 << shift).unwrap_or(NonZeroU32::MIN),
        }
    }
}

impl<const P: usize> EntropyModel<P> for UniformModel {
    type Symbol = u32;
    type Probability = u32;
}

impl<const P: usize> DecoderModel<P> for UniformModel {
    #[inline(always)]
    fn quantile_function(&self, quantile: u32) -> (u32, u32, NonZeroU32) {
        let shift = P as u32 - self.bits;
        let value = quantile >> shift;
        (
            value,
            value << shift,
            NonZeroU32::new(1 << shift).unwrap_or(NonZeroU32::MIN),
        )
    }
}

/// The decoder side of §6.2: `constriction`'s coder over a chunk body, plus the checks that
/// turn a word sequence the encoder could not have written into an [`AnsFault`].
#[derive(Clone)]
pub struct AnsReader<'a> {
    coder: AnsCoder<u32, u64, LeWords<'a>>,
}

impl core::fmt::Debug for AnsReader<'_> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("AnsReader")
            .field("state", &self.state())
            .field("remaining_words", &self.remaining_words())
            .finish()
    }
}

impl<'a> AnsReader<'a> {
    /// §6.2.6: checks the framing and reads the initial state (two words, high first).
    pub fn new(body: &'a [u8]) -> Result<Self, AnsFault> {
        // §6.2.6 step 1: a whole number of words, at least the two of the state.
        if body.len() % 4 != 0 {
            return Err(AnsFault::Framing);
        }
        let Some((head, rest)) = body.split_first_chunk::<8>() else {
            return Err(AnsFault::Framing);
        };
        let high = u32::from_le_bytes([head[0], head[1], head[2], head[3]]);
        let low = u32::from_le_bytes([head[4], head[5], head[6], head[7]]);
        // §6.2.6 step 2: the encoder's final state is ≥ 2^32, so its high word is not 0.
        if high == 0 {
            return Err(AnsFault::ZeroTopWord);
        }
        // §6.2.6 step 3.
        let state = (u64::from(high) << 32) | u64::from(low);
        Ok(AnsReader {
            coder: AnsCoder::from_raw_parts(LeWords { rest }, state),
        })
    }

    /// The current state (always in [2^32, 2^64) while no fault has been reported).
    pub fn state(&self) -> u64 {
        self.coder.state()
    }

    /// Words not read yet.
    pub fn remaining_words(&self) -> usize {
        self.coder.bulk().remaining()
    }

    /// §6.2.4 step 4: a state below 2^32 after the refill means a word was needed and none
    /// was left.
    #[inline(always)]
    fn check_state(&self) -> Result<(), AnsFault> {
        if self.coder.state() < INITIAL_STATE {
            Err(AnsFault::OutOfWords)
        } else {
            Ok(())
        }
    }

    /// Decodes one symbol of a scale table at precision `P` (§6.2.4).
    #[inline(always)]
    pub fn decode_scale<const P: usize>(
        &mut self,
        model: ScaleModel<'_>,
    ) -> Result<usize, AnsFault> {
        let index = Decode::<P>::decode_symbol(&mut self.coder, model).unwrap_infallible();
        self.check_state()?;
        Ok(index)
    }

    /// Decodes one binary event at precision `P` (§6.2.4).
    #[inline(always)]
    pub fn decode_binary<const P: usize>(&mut self, model: BinaryModel) -> Result<bool, AnsFault> {
        let bit = Decode::<P>::decode_symbol(&mut self.coder, model).unwrap_infallible();
        self.check_state()?;
        Ok(bit)
    }

    /// Decodes one uniform value at precision `P` (§6.2.4); `model.bits` must be 1 … P.
    #[inline(always)]
    pub fn decode_uniform<const P: usize>(&mut self, model: UniformModel) -> Result<u32, AnsFault> {
        let value = Decode::<P>::decode_symbol(&mut self.coder, model).unwrap_infallible();
        self.check_state()?;
        Ok(value)
    }

    /// §6.2.6 step 5: every word used, and the state back at 2^32.
    pub fn finish(&self) -> Result<(), AnsFault> {
        if self.remaining_words() != 0 {
            return Err(AnsFault::WordsLeftOver);
        }
        if self.coder.state() != INITIAL_STATE {
            return Err(AnsFault::StateNotFinal);
        }
        Ok(())
    }
}
