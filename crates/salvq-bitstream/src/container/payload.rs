//! Model payload chunks (spec §1.6): `MLPS`, `QUAN`, `APOS`, `GRID`. Every payload opens with
//! a `coding_method` byte: method 0 stores values as they are (raw), method 1 is the coded
//! form a chunk type defines. Anchor attribute chunks are in [`crate::attributes`].

use crate::container::bytes::{packed_len, unpack_bits, PayloadReader};
use crate::container::chunk::ChunkTag;
use crate::par::*;

use crate::entropy::GaussianTables;
use crate::error::Field;
use crate::error::{Error, Result};
use crate::geometry::WalkScratch;
use crate::model::validate::{check_finite, check_positive, check_rate_steps};
use crate::model::{names, Basis, Dims, GroupQuantizer, HashGrid, Region};
use crate::tiles::{split_bodies, TileTable};

pub use super::method::{body, expect_len, METHOD_CODED, METHOD_RAW};

/// The little-endian binary32 values of `bytes`, 4 bytes each (§0.2); a trailing partial
/// value is ignored.
pub fn f32s(bytes: &[u8]) -> Vec<f32> {
    bytes
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect()
}

// ---- GRID (§1.6.1): method 1, touched entries only (§5.2) ----

/// Reads the touched entries' bits; untouched entries decode as +1 (§5.2).
pub fn read_grid(payload: &[u8], d: &Dims, touched: &[Vec<bool>; 4]) -> Result<HashGrid> {
    let tag = ChunkTag::GRID;
    let body = body(tag, payload, METHOD_CODED)?;
    let c = usize::from(d.grid_channels);
    let count: u64 = touched
        .iter()
        .map(|t| t.iter().filter(|&&u| u).count() as u64 * c as u64)
        .sum();
    expect_len(tag, body, packed_len(count))?;
    let mut bits = unpack_bits(tag, body, count as usize)?;
    let mut read = |used: &Vec<bool>| -> Vec<i8> {
        let mut t = vec![1i8; used.len() * c];
        for (e, _) in used.iter().enumerate().filter(|(_, &u)| u) {
            for v in &mut t[e * c..(e + 1) * c] {
                *v = if bits.next() == Some(true) { 1 } else { -1 };
            }
        }
        t
    };
    Ok(HashGrid {
        grid_3d: read(&touched[0]),
        grid_xy: read(&touched[1]),
        grid_xz: read(&touched[2]),
        grid_yz: read(&touched[3]),
    })
}

// ---- MLPS (§1.6.2): in its own module ----

pub use super::mlps::{context_bytes, read_mlps, ContextPrecision, ScaffoldPrecision};

// ---- QUAN (§1.6.3) ----

/// One basis of a group (§1.6.3): U, s, V, checked finite, then `s` without zeros.
fn read_basis(r: &mut PayloadReader<'_>, names: [&'static str; 3], dim: u64) -> Result<Basis> {
    let n = dim as usize;
    let u = f32s(r.take(4 * n * n)?);
    check_finite(names[0], &u, &[dim, dim])?;
    let s = f32s(r.take(4 * n)?);
    check_finite(names[1], &s, &[dim])?;
    let v = f32s(r.take(4 * n * n)?);
    check_finite(names[2], &v, &[dim, dim])?;
    // §7.2: B must be invertible; a zero singular value is the one defect a decoder
    // checks (the other basis rules of §2.6 bind encoders).
    if let Some(i) = s.iter().position(|&x| x == 0.0) {
        return Err(Error::BasisSingular {
            tensor: names[1],
            index: i as u64,
        });
    }
    Ok(Basis { u, s, v })
}

/// Shape of one group's quantizer in `QUAN`.
struct GroupShape<'a> {
    names: &'a [&'static str],
    region_names: &'a [&'static str; 4],
    /// §1.6.3: how errors name the computed matrix B of region 0 and of the other regions.
    matrix_names: [&'static str; 2],
    dim: u64,
    basis: bool,
    regions: u16,
}

fn read_group(
    r: &mut PayloadReader<'_>,
    g: &GroupShape<'_>,
    rates: u8,
    anchors: u32,
) -> Result<GroupQuantizer> {
    let names = g.names;
    let step = r.f32()?;
    check_positive(names[0], &[step])?;
    let gains = f32s(r.take(4 * usize::from(rates))?);
    check_positive(names[1], &gains)?;
    check_rate_steps(names[1], step, &gains)?;
    if !g.basis {
        return Ok(GroupQuantizer {
            step,
            gains,
            basis: None,
            regions: Vec::new(),
        });
    }
    // §7.6: region starts strictly increasing within 1 … N − 1 (R ≤ 65535, bounded by the
    // payload length checked before).
    let more = usize::from(g.regions.max(1)) - 1;
    let mut starts = Vec::with_capacity(more);
    let mut min = 1u64;
    for _ in 0..more {
        let s = r.u32()?;
        let max = u64::from(anchors).saturating_sub(1).min(i32::MAX as u64);
        if u64::from(s) < min || u64::from(s) > max {
            return Err(Error::FieldOutOfRange {
                field: Field::RegionStart,
                value: s.into(),
                min,
                max,
            });
        }
        min = u64::from(s) + 1;
        starts.push(s);
    }
    let basis = read_basis(r, [names[2], names[3], names[4]], g.dim)?;
    let mut regions = Vec::with_capacity(more);
    let rn = g.region_names;
    for start in starts {
        let basis = read_basis(r, [rn[1], rn[2], rn[3]], g.dim)?;
        regions.push(Region { start, basis });
    }
    // §1.6.3: each computed matrix B_r is finite.
    let n = g.dim as usize;
    for (r, b) in std::iter::once(&basis)
        .chain(regions.iter().map(|x| &x.basis))
        .enumerate()
    {
        if let Some((i, j)) = crate::quantizer::general_matrix_non_finite(n, b) {
            let (i, j) = (i as u64, j as u64);
            return Err(Error::NonFiniteValue {
                tensor: g.matrix_names[usize::from(r > 0)],
                index: if r == 0 {
                    vec![i, j]
                } else {
                    vec![r as u64 - 1, i, j]
                },
            });
        }
    }
    Ok(GroupQuantizer {
        step,
        gains,
        basis: Some(basis),
        regions,
    })
}

/// §1.6.3: decodes `QUAN` (method 0) into the quantizers of the feature, scaling and offsets
/// groups, in that order, with the checks the section lists in stream order.
pub fn read_quan(payload: &[u8], d: &Dims) -> Result<[GroupQuantizer; 3]> {
    let tag = ChunkTag::QUAN;
    let body = body(tag, payload, METHOD_RAW)?;
    let basis_len = |dim: u64, on: bool, regions: u16| {
        let r = u64::from(regions.max(1));
        if on {
            (r - 1) + r * (2 * dim * dim + dim)
        } else {
            0
        }
    };
    let f = u64::from(d.feat_dim);
    let s = u64::from(d.scaling_dim);
    let feat = GroupShape {
        names: &names::QUANT_FEAT,
        region_names: &names::QUANT_FEAT_REGIONS,
        matrix_names: ["quant.feat.matrix", "quant.feat.regions.matrix"],
        dim: f,
        basis: d.feat_lattice.has_factors(),
        regions: d.feat_regions,
    };
    let scaling = GroupShape {
        names: &names::QUANT_SCALING,
        region_names: &names::QUANT_SCALING_REGIONS,
        matrix_names: ["quant.scaling.matrix", "quant.scaling.regions.matrix"],
        dim: s,
        basis: d.scaling_lattice.has_factors(),
        regions: d.scaling_regions,
    };
    let offsets = GroupShape {
        names: &names::QUANT_OFFSETS,
        region_names: &[""; 4],
        matrix_names: [""; 2],
        dim: 3,
        basis: false,
        regions: 1,
    };
    let count = 3 * (1 + u64::from(d.rates))
        + basis_len(f, feat.basis, feat.regions)
        + basis_len(s, scaling.basis, scaling.regions);
    expect_len(tag, body, 4 * count)?;
    let mut r = PayloadReader::new(tag, body);
    let feat = read_group(&mut r, &feat, d.rates, d.anchors)?;
    let scaling = read_group(&mut r, &scaling, d.rates, d.anchors)?;
    let offsets = read_group(&mut r, &offsets, d.rates, d.anchors)?;
    r.finish()?;
    Ok([feat, scaling, offsets])
}

// ---- APOS (§1.6.4, §8) ----

/// §8.1, §10: decodes `APOS` into the anchors' voxels, in canonical order: every tile's
/// octree in parallel (the lowest tile's error reported), then the tiles' boxes and order.
pub fn read_apos(
    payload: &[u8],
    tiles: &TileTable,
    tables: &GaussianTables,
) -> Result<Vec<[u32; 3]>> {
    read_apos_of(payload, tiles, tables, None)
}

/// [`read_apos`], decoding only the tiles `only` marks (all without it): an explicit-profile
/// part decode's (§10.3.2). Another tile's voxels are left as (0, 0, 0), never output, and
/// §10.1's pass checks the decoded tiles ([`TileTable::check_geometry_of`]).
pub fn read_apos_of(
    payload: &[u8],
    tiles: &TileTable,
    tables: &GaussianTables,
    only: Option<&[bool]>,
) -> Result<Vec<[u32; 3]>> {
    let bodies = apos_bodies(payload, tiles)?;
    // A pool for this call, not each thread's kept scratch: an anchors decode makes this
    // call once, and with its buffers freed at the end the rest of the decode page-faults
    // less (1 M anchors, `--measure`: 106 k page faults; 173 k with the buffers kept by each
    // thread, which glibc's allocator then does not reuse).
    let pool = Pool::<WalkScratch>::new();
    let size = |t: usize| tiles.range(t).len();
    let decoded = map_largest_first(bodies, size, |t, b| {
        if only.is_some_and(|o| !o.get(t).copied().unwrap_or(false)) {
            return Ok(vec![[0; 3]; tiles.range(t).len()]);
        }
        pool.with(|scratch| read_apos_tile(b, t, tiles, tables, scratch))
    });
    let mut voxels = Vec::with_capacity(tiles.anchors as usize);
    for d in decoded {
        voxels.extend_from_slice(&d?);
    }
    tiles.check_geometry_of(&voxels, only)?;
    Ok(voxels)
}

/// §8.1, §10: the body of each tile in `APOS`.
pub fn apos_bodies<'a>(payload: &'a [u8], tiles: &TileTable) -> Result<Vec<&'a [u8]>> {
    let tag = ChunkTag::APOS;
    let body = body(tag, payload, METHOD_CODED)?;
    split_bodies(tag, 1, body, tiles.len())
}

/// §8.1, §10: the voxels of tile `t` from its `APOS` body, in world voxel coordinates.
/// `scratch`: the octree walk's buffers, kept by a caller from tile to tile.
pub fn read_apos_tile(
    body: &[u8],
    t: usize,
    tiles: &TileTable,
    tables: &GaussianTables,
    scratch: &mut WalkScratch,
) -> Result<Vec<[u32; 3]>> {
    let (level, cell) = tiles.cells[t];
    let mut voxels = crate::geometry::decode_with(body, level, tiles.count(t), tables, scratch)?;
    for v in &mut voxels {
        *v = [0, 1, 2].map(|k| v[k] + (cell[k] << level));
    }
    Ok(voxels)
}
