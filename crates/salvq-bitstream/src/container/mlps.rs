//! `MLPS` (§1.6.2): the integer context MLP of §5.3, with its weights as i16 or i8 (Table 1-7),
//! then the Scaffold-GS MLPs as binary32 or binary16 (Table 1-6).

use super::bytes::PayloadReader;
use super::chunk::ChunkTag;
use super::payload::{body, expect_len, f32s, METHOD_CODED};
use crate::error::{Error, Field, Result};
use crate::hyperprior::IntMlp;
use crate::model::validate::check_finite;
use crate::model::{names, Dims, Mlp};

/// How the Scaffold-GS MLPs are stored (§1.6.2 Table 1-6).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
pub enum ScaffoldPrecision {
    /// Code 0: binary32.
    #[default]
    F32,
    /// Code 1: IEEE 754 binary16, decoded to binary32 exactly.
    F16,
}

impl ScaffoldPrecision {
    /// The `scaffold_precision` code stored in `MLPS` (Table 1-6).
    pub fn code(self) -> u8 {
        match self {
            ScaffoldPrecision::F32 => 0,
            ScaffoldPrecision::F16 => 1,
        }
    }

    /// Bytes per stored value.
    pub fn bytes(self) -> u64 {
        match self {
            ScaffoldPrecision::F32 => 4,
            ScaffoldPrecision::F16 => 2,
        }
    }

    /// `v` as this precision stores and decodes it (binary16: rounded to nearest even; a value
    /// beyond its range becomes infinite, which the encoder never writes).
    pub fn round(self, v: f32) -> f32 {
        match self {
            ScaffoldPrecision::F32 => v,
            ScaffoldPrecision::F16 => half::f16::from_f32(v).to_f32(),
        }
    }
}

/// How the integer context MLP's weights are stored (§1.6.2 Table 1-7); the values are the
/// same integers of §5.3 either way.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
pub enum ContextPrecision {
    /// Code 0: `w0` and `w1` as i16.
    #[default]
    I16,
    /// Code 1: `w0` and `w1` as i8 (each value in −128 … 127).
    I8,
}

impl ContextPrecision {
    /// The `context_precision` code stored in `MLPS` (Table 1-7).
    pub fn code(self) -> u8 {
        match self {
            ContextPrecision::I16 => 0,
            ContextPrecision::I8 => 1,
        }
    }

    /// Bytes per stored weight.
    pub fn bytes(self) -> u64 {
        match self {
            ContextPrecision::I16 => 2,
            ContextPrecision::I8 => 1,
        }
    }

    /// The largest weight magnitude the storage holds (the encoder's bound; −128 is never
    /// written, so the bound is symmetric).
    pub fn weight_max(self) -> i16 {
        match self {
            ContextPrecision::I16 => i16::MAX,
            ContextPrecision::I8 => i16::from(i8::MAX),
        }
    }
}

/// Bytes of `MLPS`'s context part (§1.6.2): `context_precision`, `w0_frac_bits`, `shift0`,
/// `w1_frac_bits[Cout]`, `w0`, `b0`, `w1`, `b1`.
pub fn context_bytes(d: &Dims, precision: ContextPrecision) -> u64 {
    let (cin, h, cout) = (
        d.context_input(),
        u64::from(d.context_hidden),
        d.context_output(),
    );
    let wb = precision.bytes();
    3 + cout + wb * (h * cin) + 4 * h + wb * (cout * h) + 4 * cout
}

/// The Scaffold-GS MLPs in stream order with their tensor names and (in, hidden, out) widths.
fn scaffold_layout(d: &Dims) -> [([&'static str; 4], u64, u64, u64); 3] {
    let k = u64::from(d.offsets);
    let si = d.scaffold_input();
    let hs = u64::from(d.scaffold_hidden);
    [
        (names::MLP_OPACITY, si, hs, k),
        (names::MLP_COV, si, hs, 7 * k),
        (names::MLP_COLOR, si, hs, 3 * k),
    ]
}

fn shift_field(field: Field, value: u8, max: u8) -> Result<()> {
    if value > max {
        return Err(Error::FieldOutOfRange {
            field,
            value: value.into(),
            min: 0,
            max: max.into(),
        });
    }
    Ok(())
}

/// Reads `MLPS`: the integer context MLP and the three Scaffold-GS MLPs.
pub fn read_mlps(payload: &[u8], d: &Dims) -> Result<(IntMlp, [Mlp; 3])> {
    let tag = ChunkTag::MLPS;
    let body = body(tag, payload, METHOD_CODED)?;
    let layout = scaffold_layout(d);
    let scaffold: u64 = layout
        .iter()
        .map(|&(_, i, h, o)| h * i + h + o * h + o)
        .sum();
    let (context_precision, precision) = read_precisions(body, d, scaffold)?;
    let context = context_bytes(d, context_precision);
    expect_len(tag, body, context + 1 + precision.bytes() * scaffold)?;
    let mut r = PayloadReader::new(tag, body);
    r.u8()?; // context_precision, read above
    let ctx = read_context_mlp(&mut r, d, context_precision)?;
    r.u8()?; // scaffold_precision, read above
    let scaffold = read_scaffold(&mut r, layout, precision)?;
    r.finish()?;
    Ok((ctx, scaffold))
}

/// `context_precision` (the body's first byte), then `scaffold_precision` (its position
/// follows from the first): §1.6.2 checks them in this order, before the exact length.
fn read_precisions(
    body: &[u8],
    d: &Dims,
    scaffold: u64,
) -> Result<(ContextPrecision, ScaffoldPrecision)> {
    let tag = ChunkTag::MLPS;
    let Some(&context_code) = body.first() else {
        return Err(Error::ChunkSizeMismatch {
            tag,
            expected: 1 + context_bytes(d, ContextPrecision::I16) + 1 + 4 * scaffold,
            found: 1,
        });
    };
    let context_precision = match context_code {
        0 => ContextPrecision::I16,
        1 => ContextPrecision::I8,
        _ => {
            return Err(Error::FieldOutOfRange {
                field: Field::ContextPrecision,
                value: context_code.into(),
                min: 0,
                max: 1,
            })
        }
    };
    let context = context_bytes(d, context_precision);
    let Some(&code) = body.get(context as usize) else {
        return Err(Error::ChunkSizeMismatch {
            tag,
            expected: 1 + context + 1 + 4 * scaffold,
            found: 1 + body.len() as u64,
        });
    };
    let precision = match code {
        0 => ScaffoldPrecision::F32,
        1 => ScaffoldPrecision::F16,
        _ => {
            return Err(Error::FieldOutOfRange {
                field: Field::ScaffoldPrecision,
                value: code.into(),
                min: 0,
                max: 1,
            })
        }
    };
    Ok((context_precision, precision))
}

/// The integer context MLP (§1.6.2, Table 5-1), after `context_precision`.
fn read_context_mlp(
    r: &mut PayloadReader<'_>,
    d: &Dims,
    context_precision: ContextPrecision,
) -> Result<IntMlp> {
    let cin = d.context_input();
    let h = u64::from(d.context_hidden);
    let cout = d.context_output();
    let w0_frac_bits = r.u8()?;
    let shift0 = r.u8()?;
    let w1_frac_bits = r.take(cout as usize)?.to_vec();
    // Table 5-1: a0 <= 30; shift0 <= 31 and no more than 8 + a0 (Qh >= 0); each a1 <= 30.
    shift_field(Field::W0FracBits, w0_frac_bits, 30)?;
    shift_field(Field::Shift0, shift0, (8 + w0_frac_bits).min(31))?;
    for &a in &w1_frac_bits {
        shift_field(Field::W1FracBits, a, 30)?;
    }
    let i32s = |b: &[u8]| -> Vec<i32> {
        b.chunks_exact(4)
            .map(|c| i32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect()
    };
    // i8 weights are the same integers, sign-extended (§5.3 evaluates them as i16).
    let weights = |b: &[u8]| -> Vec<i16> {
        match context_precision {
            ContextPrecision::I16 => b
                .chunks_exact(2)
                .map(|c| i16::from_le_bytes([c[0], c[1]]))
                .collect(),
            ContextPrecision::I8 => b.iter().map(|&x| i16::from(x as i8)).collect(),
        }
    };
    let wb = context_precision.bytes();
    let w0 = weights(r.take((wb * h * cin) as usize)?);
    let b0 = i32s(r.take(4 * h as usize)?);
    let w1 = weights(r.take((wb * cout * h) as usize)?);
    let b1 = i32s(r.take(4 * cout as usize)?);
    Ok(IntMlp {
        cin: cin as usize,
        hidden: h as usize,
        cout: cout as usize,
        w0,
        b0,
        w0_frac_bits,
        shift0,
        w1,
        b1,
        w1_frac_bits,
    })
}

/// The three Scaffold-GS MLPs (§1.6.2) at `precision`, each value finite (§2.3).
fn read_scaffold(
    r: &mut PayloadReader<'_>,
    layout: [([&'static str; 4], u64, u64, u64); 3],
    precision: ScaffoldPrecision,
) -> Result<[Mlp; 3]> {
    let mut out = Vec::with_capacity(3);
    for (names, i, h, o) in layout {
        let shapes = [vec![h, i], vec![h], vec![o, h], vec![o]];
        let mut parts = Vec::with_capacity(4);
        for (name, shape) in names.iter().zip(shapes) {
            let n: u64 = shape.iter().product();
            let bytes = r.take((precision.bytes() * n) as usize)?;
            let values = match precision {
                ScaffoldPrecision::F32 => f32s(bytes),
                ScaffoldPrecision::F16 => bytes
                    .chunks_exact(2)
                    .map(|c| half::f16::from_le_bytes([c[0], c[1]]).to_f32())
                    .collect(),
            };
            check_finite(name, &values, &shape)?;
            parts.push(values);
        }
        let [w0, b0, w1, b1]: [Vec<f32>; 4] = parts
            .try_into()
            .map_err(|_| Error::TensorMissing { tensor: names[0] })?;
        out.push(Mlp { w0, b0, w1, b1 });
    }
    out.try_into().map_err(|_| Error::TensorMissing {
        tensor: names::MLP_OPACITY[0],
    })
}
