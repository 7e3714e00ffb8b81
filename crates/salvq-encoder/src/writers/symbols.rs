//! Symbols as the encoder writes them (spec §6.1, §6.3.6, §6.4): [`SymbolWriter`] turns each
//! event into one or more coder intervals at once (so errors are reported at the call that
//! caused them) and encodes them all, in reverse, at [`SymbolWriter::finish`]. The reader, and
//! the intervals both sides share, are `salvq_bitstream::entropy`'s.

use salvq_bitstream::container::chunk::ChunkTag;
use salvq_bitstream::entropy::ans::{
    self, clamp_freq_one, encode_intervals, BinaryModel, Interval, UniformModel,
};
use salvq_bitstream::entropy::checked_scale_index;
use salvq_bitstream::entropy::symbols::{ESCAPE_MAX_W, UNIFORM_MAX_BITS};
use salvq_bitstream::entropy::{wide_scale, GaussianTables};
use salvq_bitstream::error::{Error, Result};
use salvq_bitstream::with_precision;

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
