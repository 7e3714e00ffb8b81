//! §6.6.2, §10: the anchors' attributes decoded tile by tile once every critical chunk has
//! been read, and the model built from the parts.

use crate::par::*;

use super::{missing, Partial};
use crate::attributes::{layer_bodies, read_attributes, Attributes, AttributesMut, Symbols};
use crate::container::chunk::ChunkTag;
use crate::entropy::GaussianTables;
use crate::error::{Error, Result};
use crate::hyperprior::grid::GridRef;
use crate::hyperprior::prior::Prior;
use crate::limits::{LimitKind, Limits};
use crate::model::{Anchors, Dims, GroupQuantizer, SceneModel};
use crate::quantizer::GroupLattices;
use crate::tiles::TileTable;

/// Decodes the attributes of the selected tiles and builds the model (the order rules
/// guarantee each part is present). `symbol_limits`: keep the symbols, within these limits.
pub(super) fn assemble(
    p: Partial<'_>,
    tables: &GaussianTables,
    symbol_limits: Option<&Limits>,
) -> Result<(SceneModel, Option<Symbols>)> {
    let head = p.head.ok_or(missing(ChunkTag::HEAD))?;
    let (int_mlp, [mlp_opacity, mlp_cov, mlp_color]) = p.mlps.ok_or(missing(ChunkTag::MLPS))?;
    let [quant_feat, quant_scaling, quant_offsets] = p.quan.ok_or(missing(ChunkTag::QUAN))?;
    let voxel = p.voxel.ok_or(missing(ChunkTag::APOS))?;
    let grid = p.grid.ok_or(missing(ChunkTag::GRID))?;
    let mask = p.mask.ok_or(missing(ChunkTag::AMSK))?;
    let tiles = p.tiles.ok_or(missing(ChunkTag::TILS))?;
    let d = &head.dims;
    let prior = Prior::new(
        d,
        head.coord_bits,
        int_mlp,
        [&quant_feat, &quant_scaling, &quant_offsets],
        usize::from(p.rate),
    );
    let lattices = group_lattices(d, &quant_feat, &quant_scaling);
    let chosen: Vec<usize> = (0..tiles.len()).filter(|&t| p.selected[t]).collect();
    let mut out = Output::allocate(d, &tiles, &chosen, symbol_limits, head.decoded_bytes)?;
    // §10: the selected tiles, each from its own bodies, in parallel; the lowest tile's
    // error is the one reported.
    let bodies = layer_bodies(p.attributes, tiles.len())?;
    let k = usize::from(d.offsets);
    // The grid's signs for the interpolation (kernel or scalar loop), made once for every tile.
    let signs = prior.grid_signs(&grid);
    let grid_ref = GridRef::new(&grid, signs.as_ref());
    let size = |j: usize| tiles.range(chosen[j]).len();
    let mask_starts = mask_starts(&tiles, &chosen, k);
    let decoded = map_largest_first(out.rows(d, &tiles, &chosen), size, |j, row| {
        let (t, m0) = (chosen[j], mask_starts[j]);
        let r = tiles.range(t);
        read_attributes(
            bodies[t],
            d,
            &voxel[r.clone()],
            &mask[m0..m0 + r.len() * k],
            r.start as u32,
            grid_ref,
            &prior,
            &lattices,
            tables,
            row,
        )
    });
    for result in decoded {
        result?;
    }
    // A region decode outputs the selected tiles' anchors only (§10.3.1 step 4).
    let (voxel, dims, quant_feat, quant_scaling) = if chosen.len() == tiles.len() {
        (voxel, head.dims, quant_feat, quant_scaling)
    } else {
        region_output(
            &voxel,
            &head.dims,
            &tiles,
            &chosen,
            quant_feat,
            quant_scaling,
        )
    };
    let model = SceneModel {
        origin: head.origin,
        voxel_size: head.voxel_size,
        anchors: Anchors {
            voxel,
            mask,
            feat: out.attrs.feat,
            scaling: out.attrs.scaling,
            offsets: out.attrs.offsets,
        },
        grid,
        mlp_grid: prior.mlp.to_float(),
        mlp_opacity,
        mlp_cov,
        mlp_color,
        quant_feat,
        quant_scaling,
        quant_offsets,
        dims,
    };
    Ok((model, out.symbols))
}

/// §7.2: the reconstruction matrices of the feature and scaling groups; §7.6: one per
/// spatial region.
fn group_lattices(
    d: &Dims,
    quant_feat: &GroupQuantizer,
    quant_scaling: &GroupQuantizer,
) -> [GroupLattices; 2] {
    [
        GroupLattices::new(d.feat_lattice, usize::from(d.feat_dim), quant_feat),
        GroupLattices::new(d.scaling_lattice, usize::from(d.scaling_dim), quant_scaling),
    ]
}

/// Where each chosen tile's masks start in the selected tiles' masks (`k` per anchor).
fn mask_starts(tiles: &TileTable, chosen: &[usize], k: usize) -> Vec<usize> {
    let mut at = 0;
    chosen
        .iter()
        .map(|&t| {
            at += tiles.range(t).len() * k;
            at - tiles.range(t).len() * k
        })
        .collect()
}

/// The output tensors, allocated once and cut into each tile's rows.
struct Output {
    attrs: Attributes,
    symbols: Option<Symbols>,
}

impl Output {
    /// The tensors of the `chosen` tiles' anchors, and their symbols within `symbol_limits`
    /// (extra to the decoded size the preflight checked, §1.4 step 6).
    fn allocate(
        d: &Dims,
        tiles: &TileTable,
        chosen: &[usize],
        symbol_limits: Option<&Limits>,
        decoded_bytes: u64,
    ) -> Result<Output> {
        let (f, s, k) = (
            usize::from(d.feat_dim),
            usize::from(d.scaling_dim),
            usize::from(d.offsets),
        );
        let n_out: usize = chosen.iter().map(|&t| tiles.range(t).len()).sum();
        let attrs = Attributes {
            feat: vec![0f32; n_out * f],
            scaling: vec![0f32; n_out * s],
            offsets: vec![0f32; n_out * 3 * k],
        };
        let symbols = match symbol_limits {
            Some(limits) => {
                let extra = (n_out as u64).saturating_mul((f + s + 3 * k) as u64 * 8);
                let requested = decoded_bytes.saturating_add(extra);
                if requested > limits.max_alloc_bytes {
                    return Err(Error::LimitExceeded {
                        limit: LimitKind::AllocationBytes,
                        requested,
                        allowed: limits.max_alloc_bytes,
                    });
                }
                Some(Symbols {
                    feat: vec![0; n_out * f],
                    scaling: vec![0; n_out * s],
                    offsets: vec![0; n_out * 3 * k],
                })
            }
            None => None,
        };
        Ok(Output { attrs, symbols })
    }

    /// Each chosen tile's rows of the tensors, in order.
    fn rows<'o>(
        &'o mut self,
        d: &Dims,
        tiles: &TileTable,
        chosen: &[usize],
    ) -> Vec<AttributesMut<'o>> {
        let (f, s, k) = (
            usize::from(d.feat_dim),
            usize::from(d.scaling_dim),
            usize::from(d.offsets),
        );
        let a = &mut self.attrs;
        let (mut fe, mut sc, mut of) = (&mut a.feat[..], &mut a.scaling[..], &mut a.offsets[..]);
        let mut sy = self
            .symbols
            .as_mut()
            .map(|sy| [&mut sy.feat[..], &mut sy.scaling[..], &mut sy.offsets[..]]);
        let mut rows = Vec::with_capacity(chosen.len());
        for &t in chosen {
            let m = tiles.range(t).len();
            let (a, rest_f) = std::mem::take(&mut fe).split_at_mut(m * f);
            let (b, rest_s) = std::mem::take(&mut sc).split_at_mut(m * s);
            let (c, rest_o) = std::mem::take(&mut of).split_at_mut(m * 3 * k);
            (fe, sc, of) = (rest_f, rest_s, rest_o);
            let tile_symbols = sy.as_mut().map(|[sf, ss, so]| {
                let (x, rest_x) = std::mem::take(sf).split_at_mut(m * f);
                let (y, rest_y) = std::mem::take(ss).split_at_mut(m * s);
                let (z, rest_z) = std::mem::take(so).split_at_mut(m * 3 * k);
                (*sf, *ss, *so) = (rest_x, rest_y, rest_z);
                [x, y, z]
            });
            rows.push(AttributesMut {
                feat: a,
                scaling: b,
                offsets: c,
                symbols: tile_symbols,
            });
        }
        rows
    }
}

/// §10.3.1 steps 4 – 5: the voxels, dimensions and quantizers of a region decode, which
/// outputs the `chosen` tiles' anchors only.
fn region_output(
    voxel: &[[u32; 3]],
    dims: &Dims,
    tiles: &TileTable,
    chosen: &[usize],
    quant_feat: GroupQuantizer,
    quant_scaling: GroupQuantizer,
) -> (Vec<[u32; 3]>, Dims, GroupQuantizer, GroupQuantizer) {
    let kept: Vec<std::ops::Range<usize>> = chosen.iter().map(|&t| tiles.range(t)).collect();
    let voxel: Vec<[u32; 3]> = kept
        .iter()
        .flat_map(|r| voxel[r.clone()].iter().copied())
        .collect();
    let mut dims = dims.clone();
    dims.anchors = voxel.len() as u32;
    let quant_feat = rebase_regions(quant_feat, &kept);
    let quant_scaling = rebase_regions(quant_scaling, &kept);
    dims.feat_regions = (quant_feat.regions.len() + 1) as u16;
    dims.scaling_regions = (quant_scaling.regions.len() + 1) as u16;
    (voxel, dims, quant_feat, quant_scaling)
}

/// §10.3.1 step 5: a quantizer's spatial regions (§7.6) re-based onto the anchors of the
/// `kept` ranges (in order): a region's new start counts the kept anchors below its start;
/// regions left empty are dropped, except region 0 when every region is.
fn rebase_regions(mut q: GroupQuantizer, kept: &[std::ops::Range<usize>]) -> GroupQuantizer {
    if q.regions.is_empty() {
        return q;
    }
    // New index of the first kept anchor at or after `a`, and the output size.
    let total: usize = kept.iter().map(|r| r.len()).sum();
    let new_index = |a: usize| -> usize {
        let mut before = 0usize;
        for r in kept {
            if a < r.end {
                return before + a.saturating_sub(r.start);
            }
            before += r.len();
        }
        before
    };
    let mut bases = Vec::with_capacity(q.regions.len() + 1);
    let starts: Vec<usize> = q
        .region_starts()
        .iter()
        .map(|&s| new_index(s as usize))
        .collect();
    if let Some(b) = q.basis.take() {
        bases.push(b);
    }
    bases.extend(q.regions.drain(..).map(|r| r.basis));
    // Region r covers new indices starts[r] .. starts[r + 1]; keep the non-empty ones, the
    // first of them as region 0.
    let mut kept_regions: Vec<(usize, crate::model::Basis)> = Vec::new();
    let mut first = None;
    for (r, b) in bases.into_iter().enumerate() {
        let end = starts.get(r + 1).copied().unwrap_or(total);
        if end > starts[r] {
            kept_regions.push((starts[r], b));
        } else if r == 0 {
            first = Some(b);
        }
    }
    // §10.3.1 step 5: with no anchor left (N' = 0), region 0 is kept alone.
    if kept_regions.is_empty() {
        kept_regions.extend(first.map(|b| (0, b)));
    }
    let mut it = kept_regions.into_iter();
    if let Some((_, b)) = it.next() {
        q.basis = Some(b);
    }
    q.regions = it
        .map(|(start, basis)| crate::model::Region {
            start: start as u32,
            basis,
        })
        .collect();
    q
}
