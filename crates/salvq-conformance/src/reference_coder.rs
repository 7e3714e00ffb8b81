//! The ANS coder and the symbol syntax written from the spec text (§6.2, §6.4) alone, with no
//! `constriction`: what a port in another language would write. Tests decode `constriction`'s
//! streams with [`Decoder`] and compare [`Encoder`]'s words with `constriction`'s, so the text
//! is proven to describe the bitstream. Plain, unoptimised code; it never panics on any bytes.

use salvq_bitstream::error::AnsFault;

/// §6.2.2: the initial (encoder) and final (decoder) state.
const L: u64 = 1 << 32;

/// §6.2.4: the decoder of a chunk body.
#[derive(Debug, Clone)]
pub struct Decoder<'a> {
    precision: u32,
    body: &'a [u8],
    next: usize,
    state: u64,
}

impl<'a> Decoder<'a> {
    /// §6.2.6 steps 1–3.
    pub fn new(body: &'a [u8], precision: u32) -> Result<Self, AnsFault> {
        if !body.len().is_multiple_of(4) || body.len() < 8 {
            return Err(AnsFault::Framing);
        }
        let mut d = Decoder {
            precision,
            body,
            next: 0,
            state: 0,
        };
        let high = d.word().unwrap_or(0);
        let low = d.word().unwrap_or(0);
        if high == 0 {
            return Err(AnsFault::ZeroTopWord);
        }
        d.state = (u64::from(high) << 32) | u64::from(low);
        Ok(d)
    }

    /// The next word, u32 little-endian, if any.
    fn word(&mut self) -> Option<u32> {
        let b = self.body.get(self.next..self.next + 4)?;
        self.next += 4;
        Some(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }

    /// §6.2.4: decodes one event of the distribution `freqs` (sum 2^P, each ≥ 1) and returns
    /// the index of the decoded symbol.
    pub fn decode(&mut self, freqs: &[u32]) -> Result<usize, AnsFault> {
        let p = self.precision;
        // Step 1.
        let q = (self.state & ((1u64 << p) - 1)) as u32;
        // Step 2: the symbol whose interval [c, c + f) holds q.
        let mut c = 0u32;
        let mut found = None;
        for (s, &f) in freqs.iter().enumerate() {
            if q < c + f {
                found = Some((s, c, f));
                break;
            }
            c += f;
        }
        let (s, c, f) = found.unwrap_or((0, 0, 1)); // unreachable: the freqs sum to 2^P > q
                                                    // Step 3.
        self.state = u64::from(f) * (self.state >> p) + u64::from(q - c);
        // Step 4.
        if self.state < L {
            match self.word() {
                Some(w) => self.state = (self.state << 32) | u64::from(w),
                None => return Err(AnsFault::OutOfWords),
            }
        }
        Ok(s)
    }

    /// §6.2.1: a binary event with frequency `freq_one` of 1 (clamped to 1 … 2^P − 1).
    pub fn decode_bit(&mut self, freq_one: u32) -> Result<bool, AnsFault> {
        let total = 1u32 << self.precision;
        let f1 = freq_one.clamp(1, total - 1);
        Ok(self.decode(&[total - f1, f1])? == 1)
    }

    /// §6.4: one symbol with table `freqs` (alphabet −R … R, ESCAPE) of radius `radius`.
    /// `Ok(Err(prefix))` reports an escape prefix over 30 bits.
    pub fn decode_symbol(
        &mut self,
        freqs: &[u32],
        radius: u32,
    ) -> Result<Result<i64, u32>, AnsFault> {
        let r = i64::from(radius);
        let s = self.decode(freqs)? as i64;
        if s <= 2 * r {
            return Ok(Ok(s - r));
        }
        let half = 1u32 << (self.precision - 1);
        let mut zeros = 0;
        while !self.decode_bit(half)? {
            zeros += 1;
            if zeros > 30 {
                return Ok(Err(zeros));
            }
        }
        let mut w: i64 = 1;
        for _ in 0..zeros {
            w = 2 * w + i64::from(self.decode_bit(half)?);
        }
        let negative = self.decode_bit(half)?;
        Ok(Ok(if negative { -(w + r) } else { w + r }))
    }

    /// §6.2.6 step 5.
    pub fn finish(&self) -> Result<(), AnsFault> {
        if self.next != self.body.len() {
            Err(AnsFault::WordsLeftOver)
        } else if self.state != L {
            Err(AnsFault::StateNotFinal)
        } else {
            Ok(())
        }
    }
}

/// §6.2.3: the encoder, fed events in decoding order.
#[derive(Debug, Clone)]
pub struct Encoder {
    precision: u32,
    events: Vec<(u32, u32)>,
}

impl Encoder {
    pub fn new(precision: u32) -> Self {
        Encoder {
            precision,
            events: Vec::new(),
        }
    }

    /// An event: the interval [cum, cum + freq) of 2^P.
    pub fn push(&mut self, cum: u32, freq: u32) {
        self.events.push((cum, freq));
    }

    /// §6.2.3 and §6.2.5: encode in reverse, then the state's two words, then the pushed words
    /// last-pushed first, all u32 little-endian.
    pub fn finish(self) -> Vec<u8> {
        let p = self.precision;
        let mut state = L;
        let mut pushed: Vec<u32> = Vec::new();
        for &(c, f) in self.events.iter().rev() {
            let f = u64::from(f);
            if (state >> (64 - p)) >= f {
                pushed.push(state as u32);
                state >>= 32;
            }
            state = ((state / f) << p) | (u64::from(c) + state % f);
        }
        let mut out = Vec::with_capacity(4 * (pushed.len() + 2));
        out.extend_from_slice(&((state >> 32) as u32).to_le_bytes());
        out.extend_from_slice(&(state as u32).to_le_bytes());
        for w in pushed.iter().rev() {
            out.extend_from_slice(&w.to_le_bytes());
        }
        out
    }
}
