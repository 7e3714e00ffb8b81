//! Payload chunks of format 0.1 (spec §1.6). Every payload opens with a `coding_method`
//! byte; 0.1 defines method 0 only: values stored as they are (raw, lossless).

use crate::container::bytes::{pack_bits, packed_len, unpack_bits, PayloadReader, PayloadWriter};
use crate::container::chunk::ChunkTag;
use crate::container::preflight::Preflight;
use crate::error::{Error, Result};
use crate::model::validate::{check_finite, check_positive};
use crate::model::{
    morton3, names, Anchors, Basis, Dims, GroupQuantizer, HashGrid, Mlp, SceneModel,
};

/// `coding_method` 0: raw little-endian values (§1.6).
pub const METHOD_RAW: u8 = 0;

/// Splits off the method byte and checks it is a method of this version.
fn body(tag: ChunkTag, payload: &[u8]) -> Result<&[u8]> {
    match payload {
        [METHOD_RAW, rest @ ..] => Ok(rest),
        [method, ..] => Err(Error::UnknownCodingMethod {
            tag,
            method: *method,
        }),
        [] => Err(Error::ChunkSizeMismatch {
            tag,
            expected: 1,
            found: 0,
        }),
    }
}

/// Checks the body length before anything is allocated from it.
fn expect_len(tag: ChunkTag, body: &[u8], expected: u64) -> Result<()> {
    if body.len() as u64 != expected {
        return Err(Error::ChunkSizeMismatch {
            tag,
            expected: expected + 1,
            found: body.len() as u64 + 1,
        });
    }
    Ok(())
}

fn f32s(bytes: &[u8]) -> Vec<f32> {
    bytes
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect()
}

fn raw_payload(values: &[f32]) -> Vec<u8> {
    let mut w = PayloadWriter::default();
    w.u8(METHOD_RAW);
    w.f32s(values);
    w.buf
}

// ---- GRID (§1.6.1) ----

pub fn write_grid(grid: &HashGrid) -> Vec<u8> {
    let mut out = vec![METHOD_RAW];
    let all = [&grid.grid_3d, &grid.grid_xy, &grid.grid_xz, &grid.grid_yz];
    pack_bits(all.into_iter().flatten().map(|&v| v > 0), &mut out);
    out
}

pub fn read_grid(payload: &[u8], d: &Dims) -> Result<HashGrid> {
    let tag = ChunkTag::GRID;
    let body = body(tag, payload)?;
    let c = u64::from(d.grid_channels);
    let n3 = d.entries_3d() * c;
    let n2 = d.entries_2d() * c;
    let total = n3 + 3 * n2;
    expect_len(tag, body, packed_len(total))?;
    let mut bits = unpack_bits(tag, body, total as usize)?.map(|b| if b { 1i8 } else { -1 });
    let mut take = |n: u64| bits.by_ref().take(n as usize).collect::<Vec<i8>>();
    Ok(HashGrid {
        grid_3d: take(n3),
        grid_xy: take(n2),
        grid_xz: take(n2),
        grid_yz: take(n2),
    })
}

// ---- MLPS (§1.6.2) ----

/// The MLPs in stream order with their tensor names and (in, hidden, out) widths.
fn mlp_layout(d: &Dims) -> [([&'static str; 4], u64, u64, u64); 4] {
    let k = u64::from(d.offsets);
    let si = d.scaffold_input();
    let hs = u64::from(d.scaffold_hidden);
    [
        (
            names::MLP_GRID,
            d.context_input(),
            u64::from(d.context_hidden),
            d.context_output(),
        ),
        (names::MLP_OPACITY, si, hs, k),
        (names::MLP_COV, si, hs, 7 * k),
        (names::MLP_COLOR, si, hs, 3 * k),
    ]
}

pub fn write_mlps(m: &SceneModel) -> Vec<u8> {
    let mut w = PayloadWriter::default();
    w.u8(METHOD_RAW);
    for mlp in [&m.mlp_grid, &m.mlp_opacity, &m.mlp_cov, &m.mlp_color] {
        for part in [&mlp.w0, &mlp.b0, &mlp.w1, &mlp.b1] {
            w.f32s(part);
        }
    }
    w.buf
}

pub fn read_mlps(payload: &[u8], d: &Dims) -> Result<[Mlp; 4]> {
    let tag = ChunkTag::MLPS;
    let body = body(tag, payload)?;
    let layout = mlp_layout(d);
    let count: u64 = layout
        .iter()
        .map(|&(_, i, h, o)| h * i + h + o * h + o)
        .sum();
    expect_len(tag, body, 4 * count)?;
    let mut r = PayloadReader::new(tag, body);
    let mut out = Vec::with_capacity(4);
    for (names, i, h, o) in layout {
        let shapes = [vec![h, i], vec![h], vec![o, h], vec![o]];
        let mut parts = Vec::with_capacity(4);
        for (name, shape) in names.iter().zip(shapes) {
            let n: u64 = shape.iter().product();
            let values = f32s(r.take(4 * n as usize)?);
            check_finite(name, &values, &shape)?;
            parts.push(values);
        }
        let [w0, b0, w1, b1]: [Vec<f32>; 4] = parts
            .try_into()
            .map_err(|_| Error::TensorMissing { tensor: names[0] })?;
        out.push(Mlp { w0, b0, w1, b1 });
    }
    r.finish()?;
    out.try_into().map_err(|_| Error::TensorMissing {
        tensor: names::MLP_GRID[0],
    })
}

// ---- QUAN (§1.6.3) ----

pub fn write_quan(m: &SceneModel) -> Vec<u8> {
    let mut w = PayloadWriter::default();
    w.u8(METHOD_RAW);
    for q in [&m.quant_feat, &m.quant_scaling, &m.quant_offsets] {
        w.f32(q.step);
        w.f32s(&q.gains);
        if let Some(b) = &q.basis {
            w.f32s(&b.u);
            w.f32s(&b.s);
            w.f32s(&b.v);
        }
    }
    w.buf
}

fn read_group(
    r: &mut PayloadReader<'_>,
    names: &[&'static str],
    rates: u8,
    dim: u64,
    basis: bool,
) -> Result<GroupQuantizer> {
    let step = r.f32()?;
    check_positive(names[0], &[step])?;
    let gains = f32s(r.take(4 * usize::from(rates))?);
    check_positive(names[1], &gains)?;
    let basis = if basis {
        let n = dim as usize;
        let u = f32s(r.take(4 * n * n)?);
        check_finite(names[2], &u, &[dim, dim])?;
        let s = f32s(r.take(4 * n)?);
        check_finite(names[3], &s, &[dim])?;
        let v = f32s(r.take(4 * n * n)?);
        check_finite(names[4], &v, &[dim, dim])?;
        Some(Basis { u, s, v })
    } else {
        None
    };
    Ok(GroupQuantizer { step, gains, basis })
}

pub fn read_quan(payload: &[u8], d: &Dims) -> Result<[GroupQuantizer; 3]> {
    let tag = ChunkTag::QUAN;
    let body = body(tag, payload)?;
    let basis_len = |dim: u64, on: bool| if on { 2 * dim * dim + dim } else { 0 };
    let f = u64::from(d.feat_dim);
    let s = u64::from(d.scaling_dim);
    let count =
        3 * (1 + u64::from(d.rates)) + basis_len(f, d.feat_basis) + basis_len(s, d.scaling_basis);
    expect_len(tag, body, 4 * count)?;
    let mut r = PayloadReader::new(tag, body);
    let feat = read_group(&mut r, &names::QUANT_FEAT, d.rates, f, d.feat_basis)?;
    let scaling = read_group(&mut r, &names::QUANT_SCALING, d.rates, s, d.scaling_basis)?;
    let offsets = read_group(&mut r, &names::QUANT_OFFSETS, d.rates, 3, false)?;
    r.finish()?;
    Ok([feat, scaling, offsets])
}

// ---- APOS (§1.6.4) ----

pub fn write_apos(a: &Anchors) -> Vec<u8> {
    let mut w = PayloadWriter::default();
    w.u8(METHOD_RAW);
    for v in &a.voxel {
        for c in v {
            w.u32(*c);
        }
    }
    w.buf
}

pub fn read_apos(payload: &[u8], p: &Preflight) -> Result<Vec<[u32; 3]>> {
    let tag = ChunkTag::APOS;
    let body = body(tag, payload)?;
    expect_len(tag, body, 12 * u64::from(p.dims.anchors))?;
    let mut prev = 0u64;
    let mut out = Vec::with_capacity(p.dims.anchors as usize);
    for (i, c) in body.chunks_exact(12).enumerate() {
        let v = [
            u32::from_le_bytes([c[0], c[1], c[2], c[3]]),
            u32::from_le_bytes([c[4], c[5], c[6], c[7]]),
            u32::from_le_bytes([c[8], c[9], c[10], c[11]]),
        ];
        for (axis, &x) in v.iter().enumerate() {
            if x >> p.coord_bits != 0 {
                return Err(Error::CoordinateOutOfRange {
                    anchor: i as u64,
                    axis: axis as u8,
                    value: x.into(),
                    coord_bits: p.coord_bits,
                });
            }
        }
        // §2.2: anchors are in non-decreasing Morton order.
        let code = morton3(v);
        if code < prev {
            return Err(Error::AnchorOrder { anchor: i as u64 });
        }
        prev = code;
        out.push(v);
    }
    Ok(out)
}

// ---- AMSK (§1.6.5) ----

pub fn write_amsk(a: &Anchors) -> Vec<u8> {
    let mut out = vec![METHOD_RAW];
    pack_bits(a.mask.iter().map(|&b| b != 0), &mut out);
    out
}

pub fn read_amsk(payload: &[u8], d: &Dims) -> Result<Vec<u8>> {
    let tag = ChunkTag::AMSK;
    let body = body(tag, payload)?;
    let count = u64::from(d.anchors) * u64::from(d.offsets);
    expect_len(tag, body, packed_len(count))?;
    Ok(unpack_bits(tag, body, count as usize)?
        .map(u8::from)
        .collect())
}

// ---- AFEA, ASCL, AOFF (§1.6.6) ----

pub fn write_f32_chunk(values: &[f32]) -> Vec<u8> {
    raw_payload(values)
}

/// Reads a raw float tensor of `shape` from a payload.
pub fn read_f32_chunk(
    tag: ChunkTag,
    tensor: &'static str,
    payload: &[u8],
    shape: &[u64],
) -> Result<Vec<f32>> {
    let body = body(tag, payload)?;
    let count: u64 = shape.iter().product();
    expect_len(tag, body, 4 * count)?;
    let values = f32s(body);
    check_finite(tensor, &values, shape)?;
    Ok(values)
}
