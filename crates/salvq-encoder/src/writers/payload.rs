//! The model payload chunks as the encoder writes them (spec §1.6): `GRID`, `QUAN`, `APOS`,
//! `MLPS`. Their readers, and the layouts both sides share, are `salvq_bitstream::container`'s.

use rayon::prelude::*;
use salvq_bitstream::container::bytes::{pack_bits, PayloadWriter};
use salvq_bitstream::container::method::{METHOD_CODED, METHOD_RAW};
use salvq_bitstream::container::mlps::{ContextPrecision, ScaffoldPrecision};
use salvq_bitstream::entropy::GaussianTables;
use salvq_bitstream::hyperprior::IntMlp;
use salvq_bitstream::model::{Anchors, HashGrid, SceneModel};
use salvq_bitstream::tiles::{join_bodies, TileTable};
use salvq_bitstream::Result;

/// The grid's bits at the touched entries, tensor by tensor, entry by entry, C channels each.
pub fn write_grid(grid: &HashGrid, touched: &[Vec<bool>; 4], c: usize) -> Vec<u8> {
    let mut out = vec![METHOD_CODED];
    let tensors = [&grid.grid_3d, &grid.grid_xy, &grid.grid_xz, &grid.grid_yz];
    let bits = tensors.into_iter().zip(touched).flat_map(|(t, used)| {
        used.iter()
            .enumerate()
            .filter(|(_, &u)| u)
            .flat_map(move |(e, _)| t[e * c..(e + 1) * c].iter().map(|&v| v > 0))
    });
    pack_bits(bits, &mut out);
    out
}

/// `QUAN` (§1.6.3): each group's step, gains, regions and bases, as stored (method 0).
pub fn write_quan(m: &SceneModel) -> Vec<u8> {
    let mut w = PayloadWriter::default();
    w.u8(METHOD_RAW);
    for q in [&m.quant_feat, &m.quant_scaling, &m.quant_offsets] {
        w.f32(q.step);
        w.f32s(&q.gains);
        if q.basis.is_some() {
            for r in &q.regions {
                w.u32(r.start);
            }
            for b in q.bases() {
                w.f32s(&b.u);
                w.f32s(&b.s);
                w.f32s(&b.v);
            }
        }
    }
    w.buf
}

/// §8.1, §10: `APOS` of canonical-order anchors, one octree per tile, each in its tile's
/// cell.
pub fn write_apos(a: &Anchors, tiles: &TileTable, tables: &GaussianTables) -> Result<Vec<u8>> {
    let bodies: Vec<Vec<u8>> = (0..tiles.len())
        .into_par_iter()
        .map(|t| {
            let (level, cell) = tiles.cells[t];
            let local: Vec<[u32; 3]> = a.voxel[tiles.range(t)]
                .iter()
                .map(|v| [0, 1, 2].map(|k| v[k] - (cell[k] << level)))
                .collect();
            super::geometry::encode(&local, level, tables)
        })
        .collect::<Result<_>>()?;
    let mut out = vec![METHOD_CODED];
    out.extend_from_slice(&join_bodies(&bodies));
    Ok(out)
}

/// Writes `MLPS`; the Scaffold-GS values are stored in `precision` (the caller has checked
/// that they fit it).
pub fn write_mlps(
    ctx: &IntMlp,
    context: ContextPrecision,
    m: &SceneModel,
    precision: ScaffoldPrecision,
) -> Vec<u8> {
    let mut w = PayloadWriter::default();
    w.u8(METHOD_CODED);
    w.u8(context.code());
    w.u8(ctx.w0_frac_bits);
    w.u8(ctx.shift0);
    w.buf.extend_from_slice(&ctx.w1_frac_bits);
    // The caller converted the MLP for `context` (every weight within its range).
    let weights = |w: &mut PayloadWriter, v: &[i16]| match context {
        ContextPrecision::I16 => v
            .iter()
            .for_each(|x| w.buf.extend_from_slice(&x.to_le_bytes())),
        ContextPrecision::I8 => v.iter().for_each(|&x| w.buf.push(x as i8 as u8)),
    };
    weights(&mut w, &ctx.w0);
    for v in &ctx.b0 {
        w.buf.extend_from_slice(&v.to_le_bytes());
    }
    weights(&mut w, &ctx.w1);
    for v in &ctx.b1 {
        w.buf.extend_from_slice(&v.to_le_bytes());
    }
    w.u8(precision.code());
    for mlp in [&m.mlp_opacity, &m.mlp_cov, &m.mlp_color] {
        for part in [&mlp.w0, &mlp.b0, &mlp.w1, &mlp.b1] {
            match precision {
                ScaffoldPrecision::F32 => w.f32s(part),
                ScaffoldPrecision::F16 => {
                    for &v in part.iter() {
                        w.buf
                            .extend_from_slice(&half::f16::from_f32(v).to_le_bytes());
                    }
                }
            }
        }
    }
    w.buf
}
