//! `GLAY` (spec §3.4): one layer's voxel grid, size classes and the tables of its causal
//! prior.

use crate::container::bytes::{PayloadReader, PayloadWriter};
use crate::container::chunk::ChunkTag;
use crate::container::payload::{body, expect_len, METHOD_RAW};
use crate::entropy::SCALE_INDEX_COUNT;
use crate::error::{Error, Field, Result};

/// §3.5: context classes per coded value.
pub const CONTEXT_CLASSES: usize = 8;

/// §3.5: size classes of a Gaussian (from its scale coordinates).
pub const SIZE_CLASSES: usize = 4;

/// Largest `coord_bits` (§3.4; as §1.4).
pub const MAX_COORD_BITS: u8 = 21;

/// `coord_bits` plus a size class's refinement bits is at most this (§3.6: every
/// refined coordinate is exact in binary32).
pub const MAX_POSITION_BITS: u8 = 24;

/// Largest magnitude of a step shift (§3.4).
pub const MAX_SHIFT: i8 = 16;

/// Largest magnitude of a scale-index offset (§3.4).
pub const MAX_SCALE_OFFSET: i8 = 63;

/// The decoded `GLAY` of one layer (Table 3-5).
#[derive(Debug, Clone, PartialEq)]
pub struct Layer {
    /// Every voxel coordinate is below `2^coord_bits`.
    pub coord_bits: u8,
    /// Edge length of a voxel.
    pub voxel_size: f32,
    /// A Gaussian's reference is the previous one of its tile when their voxels agree above
    /// this many low bits (§3.5).
    pub pred_level: u8,
    /// P(bit = 1) in units of 2^−16 of the rotation's largest-component index: its high
    /// bit, then its low bit after a high bit of 0, then after a high bit of 1.
    pub rotation_freq: [u16; 3],
    /// Size class thresholds on the largest scale coordinate, non-decreasing.
    pub size_threshold: [i32; SIZE_CLASSES - 1],
    /// Per size class: refinement bits of each position coordinate.
    pub refine: [u8; SIZE_CLASSES],
    /// Per group after the first (scale): per size class, the step's power-of-two shift.
    pub shift: Vec<[i8; SIZE_CLASSES]>,
    /// Per group after the first: per size class, the offset added to the scale table's
    /// entries (§3.5).
    pub scale_offset: Vec<[i8; SIZE_CLASSES]>,
    /// Per group: whether a value is predicted from the reference's (§3.5).
    pub predict: Vec<bool>,
    /// P(bit = 1) in units of 2^−16 of each node of the `sh_rest` count's tree (§3.5):
    /// node `m` (1 … 2^L − 1, its bits so far after a leading 1) at index `m − 1`. Empty
    /// without an `sh_rest` group.
    pub rest_count_freq: Vec<u16>,
    /// Scale index per coded value and context class: `[value][class]`, values in group
    /// order.
    pub scale_table: Vec<[u8; CONTEXT_CLASSES]>,
}

/// §3.4: the values of the `sh_rest` group (the fifth group, when there is one) of a
/// layer with `groups` groups and `values` coded values per Gaussian; 0 without it.
pub fn rest_values(groups: usize, values: usize) -> usize {
    if groups == 5 {
        values.saturating_sub(10)
    } else {
        0
    }
}

/// §3.5: L, the bits of a Gaussian's `sh_rest` count: `bitlen(d)` for the group's `d`
/// values (0 without the group).
pub fn rest_count_bits(rest_values: usize) -> u32 {
    usize::BITS - rest_values.leading_zeros()
}

/// §3.4: the nodes of the `sh_rest` count's tree, `2^L − 1`.
pub fn rest_count_nodes(rest_values: usize) -> usize {
    (1usize << rest_count_bits(rest_values)) - 1
}

/// The prior every layer and refinement ends with (§3.4, §3.8.1): `predict` per group, the
/// `sh_rest` count's tree, and the scale table.
pub(crate) type Prior = (Vec<bool>, Vec<u16>, Vec<[u8; CONTEXT_CLASSES]>);

/// Writes the prior's fields ([`Prior`]) as §3.4 orders them.
pub(crate) fn write_prior(
    w: &mut PayloadWriter,
    predict: &[bool],
    rest_count_freq: &[u16],
    scale_table: &[[u8; CONTEXT_CLASSES]],
) {
    for &p in predict {
        w.u8(u8::from(p));
    }
    for &f in rest_count_freq {
        w.u16(f);
    }
    for row in scale_table {
        w.buf.extend_from_slice(row);
    }
}

/// One row of `SIZE_CLASSES` signed bytes per group after the first, each within ±`max`
/// (`GLAY`'s `shift` and `scale_offset`, §3.4).
fn class_rows(
    r: &mut PayloadReader<'_>,
    groups: usize,
    tensor: &'static str,
    max: i8,
    allowed: &'static str,
) -> Result<Vec<[i8; SIZE_CLASSES]>> {
    let mut rows = Vec::with_capacity(groups - 1);
    for g in 1..groups {
        let mut row = [0i8; SIZE_CLASSES];
        for (c, v) in row.iter_mut().enumerate() {
            *v = r.u8()? as i8;
            if !(-max..=max).contains(v) {
                return Err(Error::ValueInvalid {
                    tensor,
                    index: vec![g as u64 - 1, c as u64],
                    value: (*v).into(),
                    allowed,
                });
            }
        }
        rows.push(row);
    }
    Ok(rows)
}

/// Reads and checks the prior's fields ([`Prior`]) of `groups` groups and `values` coded
/// values, each as it is read (§3.4 rules 9 – 11, §3.8.1 rules 5 – 7).
pub(crate) fn read_prior(r: &mut PayloadReader, groups: usize, values: usize) -> Result<Prior> {
    let out_of_range = |field, value: u64, min: u64, max: u64| Error::FieldOutOfRange {
        field,
        value,
        min,
        max,
    };
    let mut predict = Vec::with_capacity(groups);
    for _ in 0..groups {
        match r.u8()? {
            0 => predict.push(false),
            1 => predict.push(true),
            v => return Err(out_of_range(Field::PredictFlag, v.into(), 0, 1)),
        }
    }
    let nodes = rest_count_nodes(rest_values(groups, values));
    let mut rest_count_freq = Vec::with_capacity(nodes);
    for _ in 0..nodes {
        let f = r.u16()?;
        if f == 0 {
            return Err(out_of_range(Field::RestCountFreq, 0, 1, 65535));
        }
        rest_count_freq.push(f);
    }
    let mut scale_table = Vec::with_capacity(values);
    for _ in 0..values {
        let mut row = [0u8; CONTEXT_CLASSES];
        for k in &mut row {
            *k = r.u8()?;
            if usize::from(*k) >= SCALE_INDEX_COUNT {
                let max = SCALE_INDEX_COUNT as u64 - 1;
                return Err(out_of_range(Field::ScaleTable, (*k).into(), 0, max));
            }
        }
        scale_table.push(row);
    }
    Ok((predict, rest_count_freq, scale_table))
}

/// `GLAY`'s payload length for `groups` groups and `values` coded values per Gaussian.
pub fn glay_len(groups: usize, values: usize) -> u64 {
    let fixed = 1 + 1 + 4 + 1 + 6 + 4 * (SIZE_CLASSES - 1) + SIZE_CLASSES;
    let tree = 2 * rest_count_nodes(rest_values(groups, values));
    (fixed + 2 * SIZE_CLASSES * (groups - 1) + groups + tree + CONTEXT_CLASSES * values) as u64
}

impl Layer {
    /// The `GLAY` payload (§3.4), as the encoder writes it.
    pub fn to_payload(&self) -> Vec<u8> {
        let mut w = PayloadWriter::default();
        w.u8(METHOD_RAW);
        w.u8(self.coord_bits);
        w.f32(self.voxel_size);
        w.u8(self.pred_level);
        for f in self.rotation_freq {
            w.u16(f);
        }
        for t in self.size_threshold {
            w.u32(t as u32);
        }
        w.buf.extend_from_slice(&self.refine);
        for row in self.shift.iter().chain(&self.scale_offset) {
            w.buf.extend(row.iter().map(|&s| s as u8));
        }
        write_prior(
            &mut w,
            &self.predict,
            &self.rest_count_freq,
            &self.scale_table,
        );
        w.buf
    }

    /// §3.4: reads and checks `GLAY` for `groups` groups and `values` coded values.
    pub fn parse(payload: &[u8], groups: usize, values: usize) -> Result<Layer> {
        let tag = ChunkTag::GLAY;
        let b = body(tag, payload, METHOD_RAW)?;
        expect_len(tag, b, glay_len(groups, values) - 1)?;
        let mut r = PayloadReader::new(tag, b);
        let out_of_range = |field, value: i64, min: i64, max: i64| Error::FieldOutOfRange {
            field,
            value: value as u64,
            min: min as u64,
            max: max as u64,
        };
        let coord_bits = r.u8()?;
        if !(1..=MAX_COORD_BITS).contains(&coord_bits) {
            return Err(out_of_range(
                Field::CoordBits,
                coord_bits.into(),
                1,
                MAX_COORD_BITS.into(),
            ));
        }
        let voxel_size = r.f32()?;
        if !voxel_size.is_finite() {
            return Err(Error::NonFiniteValue {
                tensor: "GLAY.voxel_size",
                index: vec![],
            });
        }
        if voxel_size <= 0.0 {
            return Err(Error::ValueNotPositive {
                tensor: "GLAY.voxel_size",
                index: vec![],
                value: voxel_size,
            });
        }
        let pred_level = r.u8()?;
        if pred_level > coord_bits {
            return Err(out_of_range(
                Field::PredLevel,
                pred_level.into(),
                0,
                coord_bits.into(),
            ));
        }
        let mut rotation_freq = [0u16; 3];
        for f in &mut rotation_freq {
            *f = r.u16()?;
            if *f == 0 {
                return Err(out_of_range(Field::RotationFreq, 0, 1, 65535));
            }
        }
        let mut size_threshold = [0i32; SIZE_CLASSES - 1];
        for c in 0..SIZE_CLASSES - 1 {
            let t = r.u32()? as i32;
            if c > 0 && t < size_threshold[c - 1] {
                return Err(Error::ValueInvalid {
                    tensor: "GLAY.size_threshold",
                    index: vec![c as u64],
                    value: t.into(),
                    allowed: "not below the previous threshold (§3.4)",
                });
            }
            size_threshold[c] = t;
        }
        let mut refine = [0u8; SIZE_CLASSES];
        let most = MAX_POSITION_BITS - coord_bits;
        for e in &mut refine {
            *e = r.u8()?;
            if *e > most {
                return Err(out_of_range(Field::Refine, (*e).into(), 0, most.into()));
            }
        }
        let shift = class_rows(&mut r, groups, "GLAY.shift", MAX_SHIFT, "−16 … 16 (§3.4)")?;
        let scale_offset = class_rows(
            &mut r,
            groups,
            "GLAY.scale_offset",
            MAX_SCALE_OFFSET,
            "−63 … 63 (§3.4)",
        )?;
        let (predict, rest_count_freq, scale_table) = read_prior(&mut r, groups, values)?;
        r.finish()?;
        Ok(Layer {
            coord_bits,
            voxel_size,
            pred_level,
            rotation_freq,
            size_threshold,
            refine,
            shift,
            scale_offset,
            predict,
            rest_count_freq,
            scale_table,
        })
    }

    /// §3.5: the size class of a Gaussian whose largest scale coordinate is `largest`.
    pub fn size_class(&self, largest: i64) -> usize {
        self.size_threshold
            .iter()
            .filter(|&&t| i64::from(t) <= largest)
            .count()
    }

    /// The scale-index offset of group `g` in size class `c` (0 for the scale group).
    pub fn group_offset(&self, g: usize, c: usize) -> i8 {
        if g == 0 {
            0
        } else {
            self.scale_offset[g - 1][c]
        }
    }

    /// The step shift of group `g` (> 0) in size class `c`.
    pub fn group_shift(&self, g: usize, c: usize) -> i8 {
        if g == 0 {
            0
        } else {
            self.shift[g - 1][c]
        }
    }
}
