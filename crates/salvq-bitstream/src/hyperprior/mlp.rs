//! The context MLP in fixed point (spec §5.3): i16 weights, i32 wrapping accumulation,
//! rounding shifts and a clamped ReLU. Every decoder computes bit-identical outputs.

use crate::model::Mlp;

/// Largest hidden activation (i16).
pub const HIDDEN_MAX: i32 = i16::MAX as i32;

/// The integer context MLP as a stream carries it (spec §5.3, Table 5-1).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct IntMlp {
    /// Input width Cin = C·(L3 + 3·L2): the grid features of §5.1.
    pub cin: usize,
    /// Hidden width H (`HEAD` `context_hidden`, 1 … 4096).
    pub hidden: usize,
    /// Output width Cout: the means, scales and three step adjustments of §5.3.
    pub cout: usize,
    /// Layer 0 weights [hidden, cin] in units of 2^-w0_frac_bits.
    pub w0: Vec<i16>,
    /// Layer 0 biases in units of 2^-(8 + w0_frac_bits).
    pub b0: Vec<i32>,
    /// a0 of Table 5-1: the fraction bits of the layer-0 weights, 0 … 30.
    pub w0_frac_bits: u8,
    /// Right shift from layer-0 sums to hidden activations.
    pub shift0: u8,
    /// Layer 1 weights [cout, hidden]; row o in units of `2^-w1_frac_bits[o]`.
    pub w1: Vec<i16>,
    /// Layer 1 biases; `b1[o]` in units of `2^-out_frac_bits(o)`.
    pub b1: Vec<i32>,
    /// Per output row: the fraction bits of its weights (per-channel scales keep outputs of
    /// very different magnitude, e.g. feature means and scaling steps, equally precise).
    pub w1_frac_bits: Vec<u8>,
}

/// 2^e exactly, for -1022 <= e <= 1023 (built from its bits: no library call).
pub fn pow2(e: i32) -> f64 {
    f64::from_bits(((1023 + e.clamp(-1022, 1023)) as u64) << 52)
}

/// Rounds `acc / 2^s` to nearest, ties toward +infinity (spec §0.5 `rshr`).
#[inline]
pub fn round_shift(acc: i32, s: u8) -> i32 {
    if s == 0 {
        acc
    } else {
        ((i64::from(acc) + (1i64 << (s - 1))) >> s) as i32
    }
}

/// Wrapping dot product of i16 vectors in i32 (spec §5.3: sums are modulo 2^32, so the
/// order of the terms does not matter). On x86-64 it is SSE2's multiply-add
/// ([`super::simd::dot`], the crate's one isolated `unsafe`); elsewhere the plain fold.
#[cfg(all(feature = "simd", target_arch = "x86_64"))]
#[inline]
fn dot(w: &[i16], x: &[i16]) -> i32 {
    super::simd::dot(w, x)
}

/// See the x86-64 version.
#[cfg(not(all(feature = "simd", target_arch = "x86_64")))]
#[inline]
fn dot(w: &[i16], x: &[i16]) -> i32 {
    w.iter().zip(x).fold(0i32, |a, (&w, &x)| {
        a.wrapping_add(i32::from(w) * i32::from(x))
    })
}

impl IntMlp {
    /// Fraction bits of the hidden activations: 8 + w0_frac_bits - shift0.
    pub fn hidden_frac_bits(&self) -> i32 {
        8 + i32::from(self.w0_frac_bits) - i32::from(self.shift0)
    }

    /// Fraction bits of output `o`: `hidden_frac_bits + w1_frac_bits[o]`.
    pub fn out_frac_bits(&self, o: usize) -> i32 {
        self.hidden_frac_bits() + i32::from(self.w1_frac_bits.get(o).copied().unwrap_or(0))
    }

    /// §5.3 steps 1-3: outputs `y` (`y[o]` in units of `2^-out_frac_bits(o)`) of input `x`
    /// (units of 2^-8).
    /// `h` is scratch of length `hidden`.
    pub fn eval(&self, x: &[i16], h: &mut [i16], y: &mut [i32]) {
        for ((hv, row), &b) in h
            .iter_mut()
            .zip(self.w0.chunks_exact(self.cin))
            .zip(&self.b0)
        {
            let acc = b.wrapping_add(dot(row, x));
            *hv = round_shift(acc, self.shift0).clamp(0, HIDDEN_MAX) as i16;
        }
        for ((yv, row), &b) in y
            .iter_mut()
            .zip(self.w1.chunks_exact(self.hidden))
            .zip(&self.b1)
        {
            *yv = b.wrapping_add(dot(row, h));
        }
    }

    /// The float MLP these integers stand for (the decoded model's `mlp_grid.*`), exactly:
    /// every value is an integer times a power of two.
    pub fn to_float(&self) -> Mlp {
        let s_w0 = pow2(-i32::from(self.w0_frac_bits));
        let s_b0 = pow2(-8 - i32::from(self.w0_frac_bits));
        let row = self.hidden.max(1);
        Mlp {
            w0: self
                .w0
                .iter()
                .map(|&w| (f64::from(w) * s_w0) as f32)
                .collect(),
            b0: self
                .b0
                .iter()
                .map(|&b| (f64::from(b) * s_b0) as f32)
                .collect(),
            w1: self
                .w1
                .iter()
                .enumerate()
                .map(|(i, &w)| {
                    let a = self.w1_frac_bits.get(i / row).copied().unwrap_or(0);
                    (f64::from(w) * pow2(-i32::from(a))) as f32
                })
                .collect(),
            b1: self
                .b1
                .iter()
                .enumerate()
                .map(|(o, &b)| (f64::from(b) * pow2(-self.out_frac_bits(o))) as f32)
                .collect(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_shift_rounds_half_up() {
        assert_eq!(round_shift(5, 1), 3);
        assert_eq!(round_shift(-5, 1), -2);
        assert_eq!(round_shift(-6, 2), -1);
        assert_eq!(round_shift(i32::MAX, 1), 1 << 30);
        assert_eq!(round_shift(7, 0), 7);
    }

    #[test]
    fn accumulation_wraps_instead_of_overflowing() {
        let m = IntMlp {
            cin: 2,
            hidden: 1,
            cout: 1,
            w0: vec![i16::MAX, i16::MAX],
            b0: vec![i32::MAX],
            w0_frac_bits: 0,
            shift0: 0,
            w1: vec![1],
            b1: vec![0],
            w1_frac_bits: vec![0],
        };
        let (mut h, mut y) = ([0i16; 1], [0i32; 1]);
        m.eval(&[i16::MAX, i16::MAX], &mut h, &mut y);
        let expect = i32::MAX.wrapping_add(2 * (32767 * 32767));
        assert_eq!(h[0] as i32, expect.clamp(0, HIDDEN_MAX));
    }
}
