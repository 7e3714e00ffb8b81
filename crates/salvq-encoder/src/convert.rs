//! Converting a trained float context MLP into the integer MLP of spec §5.3 (an encoder
//! choice: any conversion that yields valid integers is conformant). The scales are chosen so
//! that, on this scene's anchors, no i32 sum wraps and no hidden activation saturates.

use rayon::prelude::*;

use crate::error::Result;
use salvq_bitstream::container::payload::ContextPrecision;
use salvq_bitstream::hyperprior::mlp::{pow2, HIDDEN_MAX};
use salvq_bitstream::hyperprior::{GridLayout, IntMlp};
use salvq_bitstream::model::{names, Mlp, SceneModel};

const I32_LIMIT: f64 = 2_147_483_647.0;
/// Headroom kept below i16 / i32 limits for values the scene did not exercise.
const MARGIN: f64 = 0.5;

fn quantize(v: &[f32], frac_bits: i32) -> Vec<i64> {
    v.iter()
        .map(|&w| (f64::from(w) * pow2(frac_bits)).round() as i64)
        .collect()
}

/// Largest `bits` in `0..=max_bits` for which `ok(bits)` holds (ok is monotone: true up to a point).
fn largest(max_bits: i32, ok: impl Fn(i32) -> bool) -> Option<i32> {
    (0..=max_bits).rev().find(|&b| ok(b))
}

/// Integer grid features of every anchor, row-major [N, Cin].
pub fn grid_inputs(m: &SceneModel, layout: &GridLayout) -> Vec<i16> {
    let cin = layout.features();
    let mut x = vec![0i16; m.n() * cin];
    x.par_chunks_mut(cin.max(1))
        .zip(m.anchors.voxel.par_iter())
        .for_each(|(row, &v)| layout.interpolate(&m.grid, v, row));
    x
}

/// Converts `mlp_grid` to fixed point with i16 weights, given the anchors' integer inputs `x`
/// ([N, Cin]).
pub fn convert_context_mlp(f: &Mlp, cin: usize, x: &[i16]) -> Result<IntMlp> {
    convert_context_mlp_for(f, cin, x, ContextPrecision::I16)
}

/// [`convert_context_mlp`] with every weight within what `precision` stores (§1.6.2
/// Table 1-7): the same scale search, bounded by ±127 for i8.
pub fn convert_context_mlp_for(
    f: &Mlp,
    cin: usize,
    x: &[i16],
    precision: ContextPrecision,
) -> Result<IntMlp> {
    let bound = WeightBound {
        weight_max: f64::from(precision.weight_max()),
        allowed: match precision {
            ContextPrecision::I16 => "weights whose fixed-point form fits i16 (|w| < 32768)",
            ContextPrecision::I8 => "weights whose fixed-point form fits i8 (|w| < 128)",
        },
    };
    let hidden = f.b0.len();
    let cout = f.b1.len();
    let a0 = layer0_frac_bits(f, cin, &bound)?;
    let w0: Vec<i16> = quantize(&f.w0, a0).into_iter().map(|v| v as i16).collect();
    let b0: Vec<i32> = quantize(&f.b0, 8 + a0)
        .into_iter()
        .map(|v| v as i32)
        .collect();
    let max_sum = max_layer0_sum(&w0, &b0, cin, x);
    // shift0: the smallest shift that keeps the largest activation within half of i16.
    let mut shift0 = 0u8;
    while (max_sum >> shift0) as f64 > f64::from(HIDDEN_MAX) * MARGIN && shift0 < 31 {
        shift0 += 1;
    }
    let int = IntMlp {
        cin,
        hidden,
        cout,
        w0,
        b0,
        w0_frac_bits: a0 as u8,
        shift0,
        w1: vec![],
        b1: vec![],
        w1_frac_bits: vec![],
    };
    let s_max = max_layer1_row_sums(&int, f, x);
    let qh = int.hidden_frac_bits();
    let w1_frac_bits = layer1_frac_bits(f, &s_max, qh, &bound)?;
    let w1 =
        f.w1.iter()
            .enumerate()
            .map(|(i, &w)| {
                (f64::from(w) * pow2(i32::from(w1_frac_bits[i / hidden.max(1)]))).round() as i16
            })
            .collect();
    let b1 =
        f.b1.iter()
            .zip(&w1_frac_bits)
            .map(|(&b, &a)| (f64::from(b) * pow2(qh + i32::from(a))).round() as i32)
            .collect();
    Ok(IntMlp {
        w1,
        b1,
        w1_frac_bits,
        ..int
    })
}

/// The bound the context precision puts on every fixed-point weight (§1.6.2 Table 1-7), and
/// the error's wording when a weight cannot meet it.
struct WeightBound {
    /// The largest weight magnitude stored.
    weight_max: f64,
    /// What the error reports as allowed.
    allowed: &'static str,
}

/// Largest magnitude in `v`.
fn max_abs(v: &[f32]) -> f64 {
    v.iter().fold(0f64, |a, &w| a.max(f64::from(w).abs()))
}

/// Layer 0's weight scale `a0`: the largest for which the weights fit the bound, the biases
/// fit i32, and no row sum can wrap for |x| <= 256.
fn layer0_frac_bits(f: &Mlp, cin: usize, bound: &WeightBound) -> Result<i32> {
    let a0 = largest(30, |a| {
        let w = quantize(&f.w0, a);
        let b = quantize(&f.b0, 8 + a);
        max_abs(&f.w0) * pow2(a) <= bound.weight_max
            && w.chunks_exact(cin.max(1)).zip(&b).all(|(row, &b)| {
                let s: i64 = row.iter().map(|w| w.abs()).sum::<i64>() * 256 + b.abs();
                (s as f64) < I32_LIMIT
            })
    })
    .ok_or(salvq::Error::ValueInvalid {
        tensor: names::MLP_GRID[0],
        index: vec![],
        value: max_abs(&f.w0) as i64,
        allowed: bound.allowed,
    })?;
    Ok(a0)
}

/// Largest layer-0 sum over the scene's anchors `x` ([N, Cin]), in units of 2^-(8 + a0), at
/// least 1.
fn max_layer0_sum(w0: &[i16], b0: &[i32], cin: usize, x: &[i16]) -> i64 {
    let n = x.len() / cin.max(1);
    (0..n)
        .into_par_iter()
        .map(|i| {
            let xi = &x[i * cin..(i + 1) * cin];
            w0.chunks_exact(cin.max(1))
                .zip(b0)
                .map(|(row, &b)| {
                    let s: i64 = row
                        .iter()
                        .zip(xi)
                        .map(|(&w, &x)| i64::from(w) * i64::from(x))
                        .sum();
                    s + i64::from(b)
                })
                .max()
                .unwrap_or(0)
        })
        .max()
        .unwrap_or(0)
        .max(1)
}

/// Per output row o, the largest sum of `|w1[o]| h` over the scene's actual hidden activations
/// (layer 0 of `int` evaluated on every anchor of `x`): it bounds the row's sums.
fn max_layer1_row_sums(int: &IntMlp, f: &Mlp, x: &[i16]) -> Vec<f64> {
    let (cin, hidden, cout) = (int.cin, int.hidden, int.cout);
    let n = x.len() / cin.max(1);
    let abs_w1: Vec<f64> = f.w1.iter().map(|&w| f64::from(w).abs()).collect();
    let probe = IntMlp {
        cout: 0,
        ..int.clone()
    };
    let row_sums = |i: usize| -> Vec<f64> {
        let mut h = vec![0i16; hidden];
        probe.eval(&x[i * cin..(i + 1) * cin], &mut h, &mut []);
        abs_w1
            .chunks_exact(hidden.max(1))
            .map(|row| {
                row.iter()
                    .zip(&h)
                    .map(|(w, &h)| w * f64::from(h))
                    .sum::<f64>()
            })
            .collect()
    };
    (0..n).into_par_iter().map(row_sums).reduce(
        || vec![0f64; cout],
        |a, b| a.iter().zip(&b).map(|(x, y)| x.max(*y)).collect(),
    )
}

/// Layer 1's weight scale per output row: the largest that keeps the row's weights within the
/// bound and its sums (`s_max`, plus the bias at `qh` hidden fraction bits) within half of i32.
fn layer1_frac_bits(f: &Mlp, s_max: &[f64], qh: i32, bound: &WeightBound) -> Result<Vec<u8>> {
    let hidden = f.b0.len();
    let mut w1_frac_bits = Vec::with_capacity(f.b1.len());
    for (o, (&row_max, &bias)) in s_max.iter().zip(&f.b1).enumerate() {
        let row = &f.w1[o * hidden..(o + 1) * hidden];
        let b = f64::from(bias).abs();
        let a1 = largest(30, |a| {
            max_abs(row) * pow2(a) <= bound.weight_max
                && (row_max * pow2(a) + b * pow2(qh + a)) < I32_LIMIT * MARGIN
        })
        .ok_or(salvq::Error::ValueInvalid {
            tensor: names::MLP_GRID[2],
            index: vec![o as u64],
            value: max_abs(row) as i64,
            allowed: bound.allowed,
        })?;
        w1_frac_bits.push(a1 as u8);
    }
    Ok(w1_frac_bits)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn integer_outputs_track_the_float_mlp() {
        let m = salvq_gen::generate(&salvq_gen::GenParams::new(500, 3));
        let layout = GridLayout::new(&m.dims, m.coord_bits());
        let cin = layout.features();
        let x = grid_inputs(&m, &layout);
        let int = convert_context_mlp(&m.mlp_grid, cin, &x).unwrap();
        let (mut h, mut y) = (vec![0i16; int.hidden], vec![0i32; int.cout]);
        let f = &m.mlp_grid;
        let mut worst = 0f64;
        for i in 0..m.n() {
            let xi = &x[i * cin..(i + 1) * cin];
            int.eval(xi, &mut h, &mut y);
            let hf: Vec<f64> = (0..int.hidden)
                .map(|o| {
                    let s: f64 = (0..cin)
                        .map(|j| f64::from(f.w0[o * cin + j]) * f64::from(xi[j]) / 256.0)
                        .sum();
                    (s + f64::from(f.b0[o])).max(0.0)
                })
                .collect();
            for (o, &yo) in y.iter().enumerate() {
                let s: f64 = (0..int.hidden)
                    .map(|j| f64::from(f.w1[o * int.hidden + j]) * hf[j])
                    .sum();
                let yf = s + f64::from(f.b1[o]);
                let yi = f64::from(yo) * pow2(-int.out_frac_bits(o));
                worst = worst.max((yf - yi).abs() / (1.0 + yf.abs()));
            }
        }
        // 16-bit weights, half-range activations and a half-range i32 budget give ~12 bits of
        // output precision: far below what moves a scale index (8 per octave, §6.3).
        assert!(worst < 4e-3, "worst relative error {worst}");
    }
}
