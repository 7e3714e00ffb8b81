//! Progressive streams (spec §3.8): `GREF`, a refinement layer's header, and `GRSY`, its
//! symbols per tile. A refinement layer takes every Gaussian of the layer before it to a
//! finer rate in place: more position bits per size class, and each group's step divided
//! by an integer factor, the new coordinate coded as a residual within the old one's cell.
//! One traversal serves the encoder and the decoder, through [`Events`] as `GATT`'s does.

use crate::container::bytes::{PayloadReader, PayloadWriter};
use crate::container::chunk::ChunkTag;
use crate::container::payload::{body, expect_len, METHOD_RAW};
use crate::error::{Error, Field, Result};
use crate::explicit::attributes::{
    has_reference, offset_scale, read_rest_count, BitEvent, Events, TileSymbolsMut, MAX_COORDINATE,
    REFINE_FREQ,
};
use crate::explicit::groups::{Group, GroupKind};
use crate::explicit::layer::{
    read_prior, rest_count_bits, rest_count_nodes, rest_values, write_prior, Layer,
    CONTEXT_CLASSES, MAX_POSITION_BITS, MAX_SCALE_OFFSET, SIZE_CLASSES,
};

/// §3.8: the largest step factor of a refinement layer.
pub const MAX_FACTOR: u8 = 255;

/// 2^k as binary32, for |k| ≤ 126 (exact).
#[inline]
pub fn pow2(k: i32) -> f32 {
    f32::from_bits(((127 + k) as u32) << 23)
}

/// The precision every Gaussian of a decoded layer is at (§3.6, §3.8): per size class, the
/// position refinement bits below the voxel grid, and per group and size class, the step Δ.
#[derive(Debug, Clone, PartialEq)]
pub struct Precision {
    /// Per size class: the position bits below a voxel (`e` of §3.6 step 1).
    pub refine: [u8; SIZE_CLASSES],
    /// Per group (Table 3-3 order) and size class: Δ of §3.6 step 2.
    pub delta: Vec<[f32; SIZE_CLASSES]>,
}

impl Precision {
    /// §3.6: the precision of a full layer (`GLAY`) at `rate`:
    /// `Δ = (step ⊗ gain_r) ⊗ 2^shift`.
    pub fn of_layer(layer: &Layer, groups: &[Group], rate: u8) -> Precision {
        Precision {
            refine: layer.refine,
            delta: groups
                .iter()
                .enumerate()
                .map(|(gi, g)| {
                    let step = g.rate_step(rate);
                    std::array::from_fn(|c| step * pow2(layer.group_shift(gi, c).into()))
                })
                .collect(),
        }
    }

    /// §3.8: the precision after refinement `r`: `refine[c]` more position bits, and each
    /// Δ divided by its factor, `Δ ⊘ float32(factor)`.
    pub fn refined(&self, r: &Refinement) -> Precision {
        Precision {
            refine: std::array::from_fn(|c| self.refine[c] + r.refine[c]),
            delta: self
                .delta
                .iter()
                .zip(&r.factor)
                .map(|(d, f)| std::array::from_fn(|c| d[c] / f32::from(f[c])))
                .collect(),
        }
    }
}

/// The decoded `GREF` of one refinement layer (§3.8).
#[derive(Debug, Clone, PartialEq)]
pub struct Refinement {
    /// A Gaussian's reference is the previous one of its tile, of the same size class, when
    /// their voxels agree above this many low bits.
    pub pred_level: u8,
    /// Per size class: position bits added below the previous layer's.
    pub refine: [u8; SIZE_CLASSES],
    /// Per group and size class: the integer the step is divided by (1: not refined).
    pub factor: Vec<[u8; SIZE_CLASSES]>,
    /// Per group and size class: the offset added to the scale table's entries.
    pub scale_offset: Vec<[i8; SIZE_CLASSES]>,
    /// Per group: whether a value is predicted from the reference's refined value.
    pub predict: Vec<bool>,
    /// P(bit = 1) in units of 2^−16 of each node of the `sh_rest` count's tree, as §3.4.
    pub rest_count_freq: Vec<u16>,
    /// Scale index per coded value and context class: `[value][class]`.
    pub scale_table: Vec<[u8; CONTEXT_CLASSES]>,
}

/// `GREF`'s payload length for `groups` groups and `values` coded values per Gaussian.
pub fn gref_len(groups: usize, values: usize) -> u64 {
    let fixed = 1 + 1 + SIZE_CLASSES;
    let tree = 2 * rest_count_nodes(rest_values(groups, values));
    (fixed + 2 * SIZE_CLASSES * groups + groups + tree + CONTEXT_CLASSES * values) as u64
}

impl Refinement {
    /// The `GREF` payload (§3.8), as the encoder writes it.
    pub fn to_payload(&self) -> Vec<u8> {
        let mut w = PayloadWriter::default();
        w.u8(METHOD_RAW);
        w.u8(self.pred_level);
        w.buf.extend_from_slice(&self.refine);
        for row in &self.factor {
            w.buf.extend_from_slice(row);
        }
        for row in &self.scale_offset {
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

    /// §3.8: reads and checks `GREF` for `groups` groups and `values` coded values, refining
    /// a layer on a grid of `coord_bits` whose Gaussians are at `before`.
    pub fn parse(
        payload: &[u8],
        groups: usize,
        values: usize,
        coord_bits: u8,
        before: &Precision,
    ) -> Result<Refinement> {
        let tag = ChunkTag::GREF;
        let b = body(tag, payload, METHOD_RAW)?;
        expect_len(tag, b, gref_len(groups, values) - 1)?;
        let mut r = PayloadReader::new(tag, b);
        let out_of_range = |field, value: u64, min: u64, max: u64| Error::FieldOutOfRange {
            field,
            value,
            min,
            max,
        };
        let pred_level = r.u8()?;
        if pred_level > coord_bits {
            let (v, max) = (pred_level.into(), coord_bits.into());
            return Err(out_of_range(Field::PredLevel, v, 0, max));
        }
        let mut refine = [0u8; SIZE_CLASSES];
        for (c, e) in refine.iter_mut().enumerate() {
            *e = r.u8()?;
            let most = MAX_POSITION_BITS.saturating_sub(coord_bits + before.refine[c]);
            if *e > most {
                return Err(out_of_range(Field::Refine, (*e).into(), 0, most.into()));
            }
        }
        let mut factor = Vec::with_capacity(groups);
        for _ in 0..groups {
            let mut row = [0u8; SIZE_CLASSES];
            for f in &mut row {
                *f = r.u8()?;
                if *f == 0 {
                    return Err(out_of_range(Field::Factor, 0, 1, MAX_FACTOR.into()));
                }
            }
            factor.push(row);
        }
        let mut scale_offset = Vec::with_capacity(groups);
        for g in 0..groups {
            let mut row = [0i8; SIZE_CLASSES];
            for (c, o) in row.iter_mut().enumerate() {
                *o = r.u8()? as i8;
                if !(-MAX_SCALE_OFFSET..=MAX_SCALE_OFFSET).contains(o) {
                    return Err(Error::ValueInvalid {
                        tensor: "GREF.scale_offset",
                        index: vec![g as u64, c as u64],
                        value: (*o).into(),
                        allowed: "−63 … 63 (§3.8)",
                    });
                }
            }
            scale_offset.push(row);
        }
        let (predict, rest_count_freq, scale_table) = read_prior(&mut r, groups, values)?;
        r.finish()?;
        Ok(Refinement {
            pred_level,
            refine,
            factor,
            scale_offset,
            predict,
            rest_count_freq,
            scale_table,
        })
    }
}

/// §3.8: the context class of a refined value: without a reference 0 where the value's
/// previous coordinate is 0 and 1 elsewhere; with one, `2 + min(bitlen(|r'|), 5)` from the
/// reference's refinement symbol `r'`.
#[inline]
pub fn refinement_context(has_reference: bool, old: i64, r_ref: i64) -> usize {
    if has_reference {
        let bits = (u64::BITS - r_ref.unsigned_abs().leading_zeros()) as usize;
        2 + bits.min(CONTEXT_CLASSES - 3)
    } else {
        usize::from(old != 0)
    }
}

/// §3.8: walks the events of one tile of a refinement layer, refining the tile's symbols
/// `out` (the previous layer's, for the Gaussians at `voxels`) in place.
pub fn refine_walk(
    refinement: &Refinement,
    groups: &[Group],
    voxels: &[[u32; 3]],
    events: &mut impl Events,
    out: &mut TileSymbolsMut,
) -> Result<()> {
    let values: usize = groups.iter().map(|g| g.dim).sum();
    let n = voxels.len();
    debug_assert_eq!(out.coords.len(), n * values);
    let rest_bits = rest_count_bits(rest_values(groups.len(), values));
    let mut prev_r = vec![0i64; values];
    let mut r_row = vec![0i64; values];
    for i in 0..n {
        let class = usize::from(out.size_class[i]);
        let reference = has_reference(voxels, i, refinement.pred_level)
            && out.size_class[i - 1] == out.size_class[i];
        let mut v = 0;
        for (gi, g) in groups.iter().enumerate() {
            if gi == 1 {
                let e = refinement.refine[class];
                let w = &mut out.refinement[i];
                for (axis, wa) in w.iter_mut().enumerate() {
                    for bit in (0..e).rev() {
                        let b = events.bit(REFINE_FREQ, i, BitEvent::Refine { axis, bit })?;
                        *wa = 2 * *wa + u32::from(b);
                    }
                }
            }
            let range = v..v + g.dim;
            v += g.dim;
            let factor = i64::from(refinement.factor[gi][class]);
            if factor == 1 {
                r_row[range].fill(0);
                continue;
            }
            let half = factor / 2;
            let offset = refinement.scale_offset[gi][class];
            let predicted = reference && refinement.predict[gi];
            // The cell of each value's previous coordinate, and the prediction within it.
            let (before, now) = out.coords.split_at_mut(i * values);
            let previous = &before[before.len().saturating_sub(values)..];
            let row = &mut now[..values];
            let prediction = |v: usize, old: i64| {
                let centre = old * factor;
                match predicted {
                    true => i64::from(previous[v]).clamp(centre - half, centre + half),
                    false => centre,
                }
            };
            let mut coded = g.dim;
            if g.kind == GroupKind::Rest {
                events.rest_predictions(i, range.start, |j| {
                    prediction(range.start + j, i64::from(row[range.start + j]))
                });
                coded = read_rest_count(events, &refinement.rest_count_freq, rest_bits, i)?;
                if coded > g.dim {
                    return Err(Error::ValueInvalid {
                        tensor: "GRSY.rest_count",
                        index: vec![i as u64],
                        value: coded as i64,
                        allowed: "at most the sh_rest group's values (§3.8)",
                    });
                }
            }
            for (j, v) in range.enumerate() {
                let old = i64::from(row[v]);
                let pred = prediction(v, old);
                let r = if j < coded {
                    let x = refinement_context(reference, old, prev_r[v]);
                    let k = offset_scale(refinement.scale_table[v][x], offset);
                    events.symbol(k, i, v, pred)?
                } else {
                    0
                };
                let u = pred + r;
                if u.abs() > MAX_COORDINATE {
                    return Err(Error::ValueInvalid {
                        tensor: "GRSY.coordinate",
                        index: vec![i as u64, v as u64],
                        value: u,
                        allowed: "|u| ≤ 2^24 (§3.8)",
                    });
                }
                r_row[v] = r;
                row[v] = u as i32;
            }
        }
        // The reference of the next Gaussian: this one's refinement symbols.
        prev_r.copy_from_slice(&r_row);
    }
    Ok(())
}
