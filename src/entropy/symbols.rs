//! Symbols over the ANS coder (spec §6.1, §6.3.6, §6.4): table symbols with escapes, wide
//! scales, and binary events.
//!
//! [`SymbolWriter`] turns each event into one or more coder intervals at once (so errors are
//! reported at the call that caused them) and encodes them all, in reverse, at
//! [`SymbolWriter::finish`]. [`SymbolReader`] decodes them forward; each call consumes at most
//! one word per coded interval, and a symbol is at most 1 + 31 + 30 + 1 intervals (§6.4).

use super::ans::{
    self, clamp_freq_one, encode_intervals, with_precision, AnsReader, BinaryModel, Interval,
    UniformModel,
};
use super::scale::{wide_scale, SCALE_COUNT, SCALE_INDEX_COUNT};
use super::tables::{GaussianTables, PRECISION};

/// The widest uniform value a call reads or writes (at most the lowest precision, 12).
pub const UNIFORM_MAX_BITS: u32 = 12;
pub use super::tables::{ESCAPE_MAX_PREFIX, ESCAPE_MAX_W};
use crate::container::chunk::ChunkTag;
use crate::error::{AnsFault, Error, Result};

/// Checks a scale index (§6.3.1, §6.3.6): returns it as `u8` when a symbol can be coded with
/// it (a table's index 0 … 63 or a wide scale 64 … 127), else `ScaleIndexOutOfRange` naming
/// the chunk and the symbol's index.
pub fn checked_scale_index(tag: ChunkTag, symbol: u64, scale_index: i64) -> Result<u8> {
    if (0..SCALE_INDEX_COUNT as i64).contains(&scale_index) {
        Ok(scale_index as u8)
    } else {
        Err(Error::ScaleIndexOutOfRange {
            tag,
            symbol,
            scale_index,
            max: SCALE_INDEX_COUNT as u64 - 1,
        })
    }
}

/// Collects a chunk's symbols and binary events, then writes its entropy-coded body (§6.2.5).
#[derive(Debug, Clone)]
pub struct SymbolWriter<'t> {
    tag: ChunkTag,
    tables: &'t GaussianTables,
    intervals: Vec<Interval>,
    symbols: u64,
}

impl<'t> SymbolWriter<'t> {
    /// A writer for chunk `tag` (named in its errors) coding with `tables`.
    pub fn new(tag: ChunkTag, tables: &'t GaussianTables) -> Self {
        SymbolWriter {
            tag,
            tables,
            intervals: Vec::new(),
            symbols: 0,
        }
    }

    /// Symbols written so far (the index the next symbol's errors name).
    pub fn symbol_count(&self) -> u64 {
        self.symbols
    }

    /// Coder intervals collected so far (symbols, escape bits and binary events).
    pub fn interval_count(&self) -> usize {
        self.intervals.len()
    }

    fn half_bit(&mut self, bit: bool) {
        let p = self.tables.precision();
        self.intervals
            .push(BinaryModel::interval(p, 1 << (p - 1), bit));
    }

    /// Writes symbol `u` with scale index `k` (§6.4; a wide scale by §6.3.6).
    ///
    /// Errors: `ScaleIndexOutOfRange` if `k ≥ SCALE_INDEX_COUNT`; `EscapeOverflow` if the
    /// table symbol (`u`, or a wide scale's high part) passes its table's radius by 2^31 or
    /// more (the escape's prefix would exceed 30 bits). Nothing is written then.
    pub fn symbol(&mut self, u: i64, k: u8) -> Result<()> {
        let k = checked_scale_index(self.tag, self.symbols, i64::from(k))?;
        match wide_scale(k) {
            None => self.table_symbol(u, k)?,
            Some((table, low_bits)) => {
                // §6.3.6: the high part h = ⌊u / 2^b⌋ at the table scale, then u − h·2^b in b
                // uniform bits.
                let high = u >> low_bits;
                self.table_symbol(high, table)?;
                let low = (u - (high << low_bits)) as u32;
                let p = self.tables.precision();
                self.intervals
                    .push(UniformModel { bits: low_bits }.interval(p, low));
            }
        }
        self.symbols += 1;
        Ok(())
    }

    /// §6.4 for a table scale `k` (0 … 63): one interval, or the escape's.
    fn table_symbol(&mut self, u: i64, k: u8) -> Result<()> {
        let table = self.tables.scale(k);
        let r = u64::from(table.radius());
        let mag = u.unsigned_abs();
        let cum = table.cumulative();
        let interval = |i: usize| Interval {
            cum: cum[i],
            freq: core::num::NonZeroU32::new(cum[i + 1] - cum[i])
                .unwrap_or(core::num::NonZeroU32::MIN),
        };
        if mag <= r {
            // §6.4 step 1: |u| ≤ R_k: the alphabet index u + R_k.
            self.intervals.push(interval((u + r as i64) as usize));
        } else {
            // §6.4 step 2: ESCAPE, then w = |u| − R_k ≥ 1 in Exp-Golomb order 0, then the sign.
            let w = mag - r;
            let prefix = 63 - w.leading_zeros();
            if w > ESCAPE_MAX_W {
                return Err(Error::EscapeOverflow {
                    tag: self.tag,
                    symbol: self.symbols,
                    prefix_bits: prefix,
                });
            }
            self.intervals.push(interval(table.escape_index()));
            for _ in 0..prefix {
                self.half_bit(false);
            }
            // The L + 1 bits of w, most significant (the terminating 1) first.
            for i in (0..=prefix).rev() {
                self.half_bit((w >> i) & 1 == 1);
            }
            self.half_bit(u < 0);
        }
        Ok(())
    }

    /// Writes a binary event `bit` with P(1) = `freq_one` / 2^P (§6.2.1). `freq_one` is
    /// clamped to 1 … 2^P − 1, as the reader does.
    pub fn bit(&mut self, bit: bool, freq_one: u32) {
        let p = self.tables.precision();
        let f = clamp_freq_one(p, freq_one);
        self.intervals.push(BinaryModel::interval(p, f, bit));
    }

    /// Writes the low `bits` bits of `value` as one uniform value (§6.2.1 kind 4); `bits` is
    /// 1 … 12, which every precision the tables allow holds.
    pub fn uniform(&mut self, value: u32, bits: u32) {
        let p = self.tables.precision();
        let bits = bits.clamp(1, UNIFORM_MAX_BITS);
        let v = value & ((1 << bits) - 1);
        self.intervals.push(UniformModel { bits }.interval(p, v));
    }

    /// Encodes everything in reverse and returns the chunk body: the coder's words as u32
    /// little-endian, in reading order (§6.2.5). Never shorter than 8 bytes.
    pub fn finish(self) -> Vec<u8> {
        let words =
            with_precision!(self.tables.precision(), P => encode_intervals::<P>(&self.intervals));
        ans::words_to_bytes(&words)
    }
}

/// Reads a chunk's symbols and binary events back, in the order they were written.
///
/// Never panics on any bytes; every call reads at most 63 coder intervals, each at most one
/// word. After an error every further call returns that error.
#[derive(Debug, Clone)]
pub struct SymbolReader<'a> {
    tag: ChunkTag,
    tables: &'a GaussianTables,
    ans: AnsReader<'a>,
    symbols: u64,
    broken: Option<Error>,
    /// The tables are at the format's precision and nothing is broken: one flag, tested
    /// per call, for the two conditions of the inlined path.
    fast: bool,
}

impl<'a> SymbolReader<'a> {
    /// Starts reading the entropy-coded `body` of chunk `tag` (§6.2.6 steps 1–3).
    ///
    /// Errors: `AnsStreamInvalid` with `Framing` (length not a multiple of 4, or < 8 bytes) or
    /// `ZeroTopWord`.
    pub fn new(tag: ChunkTag, body: &'a [u8], tables: &'a GaussianTables) -> Result<Self> {
        let ans = AnsReader::new(body).map_err(|fault| Error::AnsStreamInvalid { tag, fault })?;
        Ok(SymbolReader {
            tag,
            tables,
            ans,
            symbols: 0,
            broken: None,
            fast: tables.precision() == PRECISION,
        })
    }

    /// Symbols read so far (the index the next symbol's errors name).
    pub fn symbol_count(&self) -> u64 {
        self.symbols
    }

    /// Words of the body not read yet.
    pub fn remaining_words(&self) -> usize {
        self.ans.remaining_words()
    }

    #[cold]
    fn fail(&mut self, err: Error) -> Error {
        self.broken = Some(err.clone());
        self.fast = false;
        err
    }

    #[cold]
    fn ans_fault(&mut self, fault: AnsFault) -> Error {
        let tag = self.tag;
        self.fail(Error::AnsStreamInvalid { tag, fault })
    }

    /// Reads one symbol coded with scale index `k` (§6.4; a wide scale by §6.3.6).
    ///
    /// Errors: `ScaleIndexOutOfRange` if `k ≥ SCALE_INDEX_COUNT` (nothing is read);
    /// `AnsStreamInvalid { OutOfWords }`; `EscapeOverflow` if an escape's prefix exceeds 30 bits.
    #[inline(always)]
    pub fn symbol(&mut self, k: u8) -> Result<i64> {
        // The format's precision with nothing broken: the common case, inlined into the
        // caller's loop; the rest (other precisions for experiments, errors) out of line.
        if self.fast {
            const P: usize = PRECISION as usize;
            let u = if usize::from(k) < SCALE_COUNT {
                self.symbol_p::<P>(k)?
            } else if let Some((table, low_bits)) = wide_scale(k) {
                self.wide_p::<P>(table, low_bits)?
            } else {
                return self.symbol_any(k);
            };
            self.symbols += 1;
            return Ok(u);
        }
        self.symbol_any(k)
    }

    #[inline(never)]
    fn symbol_any(&mut self, k: u8) -> Result<i64> {
        if let Some(err) = &self.broken {
            return Err(err.clone());
        }
        let k = checked_scale_index(self.tag, self.symbols, i64::from(k))?;
        let u = match wide_scale(k) {
            None => with_precision!(self.tables.precision(), P => self.symbol_p::<P>(k))?,
            Some((table, low_bits)) => {
                with_precision!(self.tables.precision(), P => self.wide_p::<P>(table, low_bits))?
            }
        };
        self.symbols += 1;
        Ok(u)
    }

    /// §6.3.6: a wide scale's symbol, its high part at scale `table`, then `low_bits`
    /// uniform bits.
    #[inline(always)]
    fn wide_p<const P: usize>(&mut self, table: u8, low_bits: u32) -> Result<i64> {
        let high = self.symbol_p::<P>(table)?;
        let low = self
            .ans
            .decode_uniform::<P>(UniformModel { bits: low_bits })
            .map_err(|fault| self.ans_fault(fault))?;
        // |high| ≤ 2^31 − 1 + R_MAX and low_bits ≤ 8: no overflow.
        Ok((high << low_bits) + i64::from(low))
    }

    #[inline(always)]
    fn symbol_p<const P: usize>(&mut self, k: u8) -> Result<i64> {
        let table = self.tables.scale(k);
        // §6.4 step 1.
        let index = match self.ans.decode_scale::<P>(self.tables.model(k)) {
            Ok(i) => i,
            Err(fault) => return Err(self.ans_fault(fault)),
        };
        let r = table.radius();
        if index != table.escape_index() {
            return Ok(index as i64 - i64::from(r));
        }
        self.escape_p::<P>(r)
    }

    /// §6.4 step 2: the escape's Exp-Golomb value and sign.
    #[cold]
    fn escape_p<const P: usize>(&mut self, r: u32) -> Result<i64> {
        // §6.4 step 2a: count leading zeros up to the terminating 1.
        let mut prefix = 0u32;
        while !self.half_bit_p::<P>()? {
            prefix += 1;
            if prefix > ESCAPE_MAX_PREFIX {
                let err = Error::EscapeOverflow {
                    tag: self.tag,
                    symbol: self.symbols,
                    prefix_bits: prefix,
                };
                return Err(self.fail(err));
            }
        }
        // §6.4 step 2b: L more bits, most significant first; w in 1 … 2^31 − 1.
        let mut w: u64 = 1;
        for _ in 0..prefix {
            w = (w << 1) | u64::from(self.half_bit_p::<P>()?);
        }
        // §6.4 step 2c: the sign, 1 = negative.
        let negative = self.half_bit_p::<P>()?;
        let mag = (w + u64::from(r)) as i64;
        Ok(if negative { -mag } else { mag })
    }

    fn half_bit_p<const P: usize>(&mut self) -> Result<bool> {
        let model = BinaryModel {
            freq_zero: 1 << (P - 1),
        };
        self.ans
            .decode_binary::<P>(model)
            .map_err(|fault| self.ans_fault(fault))
    }

    /// Reads a binary event with P(1) = `freq_one` / 2^P, `freq_one` clamped to 1 … 2^P − 1
    /// (§6.2.1). Errors: `AnsStreamInvalid { OutOfWords }`.
    #[inline(always)]
    pub fn bit(&mut self, freq_one: u32) -> Result<bool> {
        // As in `symbol`: the format's precision inlined, the rest out of line.
        if self.fast {
            const P: usize = PRECISION as usize;
            let model = BinaryModel {
                freq_zero: (1u32 << P) - clamp_freq_one(P as u32, freq_one),
            };
            return match self.ans.decode_binary::<P>(model) {
                Ok(bit) => Ok(bit),
                Err(fault) => Err(self.ans_fault(fault)),
            };
        }
        self.bit_any(freq_one)
    }

    #[inline(never)]
    fn bit_any(&mut self, freq_one: u32) -> Result<bool> {
        if let Some(err) = &self.broken {
            return Err(err.clone());
        }
        let p = self.tables.precision();
        let model = BinaryModel {
            freq_zero: (1u32 << p) - clamp_freq_one(p, freq_one),
        };
        with_precision!(p, P => self.ans.decode_binary::<P>(model))
            .map_err(|fault| self.ans_fault(fault))
    }

    /// Reads one uniform value of `bits` bits (§6.2.1 kind 4), `bits` clamped to 1 … 12.
    /// Errors: `AnsStreamInvalid { OutOfWords }`.
    #[inline(always)]
    pub fn uniform(&mut self, bits: u32) -> Result<u32> {
        if let Some(err) = &self.broken {
            return Err(err.clone());
        }
        let model = UniformModel {
            bits: bits.clamp(1, UNIFORM_MAX_BITS),
        };
        let value = if self.tables.precision() == PRECISION {
            self.ans.decode_uniform::<{ PRECISION as usize }>(model)
        } else {
            with_precision!(self.tables.precision(), P => self.ans.decode_uniform::<P>(model))
        };
        value.map_err(|fault| self.ans_fault(fault))
    }

    /// Ends the chunk (§6.2.6 step 5). Errors: `AnsStreamInvalid` with `WordsLeftOver` if words
    /// were not read, `StateNotFinal` if the state is not 2^32 (or the error a call reported).
    pub fn finish(self) -> Result<()> {
        if let Some(err) = self.broken {
            return Err(err);
        }
        self.ans.finish().map_err(|fault| Error::AnsStreamInvalid {
            tag: self.tag,
            fault,
        })
    }
}
