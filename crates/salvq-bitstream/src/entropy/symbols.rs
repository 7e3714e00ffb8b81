//! Symbols over the ANS coder (spec §6.1, §6.3.6, §6.4): table symbols with escapes, wide
//! scales, and binary events.
//!
//! `salvq_encoder::writers::SymbolWriter` turns each event into one or more coder intervals at
//! once (so errors are reported at the call that caused them) and encodes them all, in
//! reverse, at `SymbolWriter::finish`. [`SymbolReader`] decodes them forward; each call
//! consumes at most one word per coded interval, and a symbol is at most 1 + 31 + 30 + 1
//! intervals (§6.4).

use super::ans::{clamp_freq_one, with_precision, AnsReader, BinaryModel, UniformModel};
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
