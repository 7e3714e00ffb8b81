//! The decoder (spec §1.5 decoding process): signature, then chunks in order, each payload
//! decoded against the preflight; the anchor attributes are decoded together once `SEND`
//! has been read (§6.6.2). It never panics on any input, sizes every allocation from a
//! preflight that passed [`Limits`], and reports the first broken rule.

use crate::par::*;

use crate::attributes::{
    layer_bodies, read_attributes, read_masks, Attributes, AttributesMut, Symbols,
};
use crate::builder::DecodeOptions;
#[cfg(feature = "test-hooks")]
use crate::builder::Fault;
use crate::container::chunk::{peek_critical, ChunkReader, ChunkTag};
use crate::container::payload;
use crate::container::preflight::Preflight;
use crate::container::signature::{Signature, SIGNATURE_LEN};
use crate::entropy::GaussianTables;
use crate::error::{Error, Result};
use crate::hyperprior::grid::GridRef;
use crate::hyperprior::prior::Prior;
use crate::hyperprior::{GridLayout, IntMlp};
use crate::limits::Limits;
use crate::model::{Anchors, GroupQuantizer, HashGrid, Mlp, SceneModel};
use crate::quantizer::GroupLattices;
use crate::scene::Scene;
use crate::tiles::TileTable;

/// The critical chunk expected at position `i` of a stream with `layers` symbol layers
/// (§1.5 Table 1-3 with §7.4: the layer chunks repeat once per layer).
pub(crate) fn expected_critical(i: usize, layers: usize) -> ChunkTag {
    const SHARED: usize = 7;
    const LAYER: [ChunkTag; 3] = [ChunkTag::AFEA, ChunkTag::ASCL, ChunkTag::AOFF];
    match i.checked_sub(SHARED) {
        None => ChunkTag::CRITICAL_ORDER[i],
        Some(j) if j < 3 * layers => LAYER[j % 3],
        Some(_) => ChunkTag::SEND,
    }
}

/// Parts of the model decoded so far, filled chunk by chunk.
#[derive(Default)]
struct Partial<'a> {
    head: Option<Preflight>,
    mlps: Option<(IntMlp, [Mlp; 3])>,
    quan: Option<[GroupQuantizer; 3]>,
    voxel: Option<Vec<[u32; 3]>>,
    touched: Option<[Vec<bool>; 4]>,
    grid: Option<HashGrid>,
    tiles: Option<TileTable>,
    selected: Vec<bool>,
    mask: Option<Vec<u8>>,
    /// `AMSK`'s outcome where it was decoded alongside `GRID` (see the `GRID` step), reported
    /// when its own position in the stream is reached.
    early_mask: Option<Result<Vec<u8>>>,
    attributes: [&'a [u8]; 3],
    /// The rate being decoded.
    rate: u8,
}

fn missing(tag: ChunkTag) -> Error {
    Error::ChunkOrder {
        found: ChunkTag::SEND,
        expected: tag,
    }
}

/// Decodes an anchors-profile stream's selected symbol layer (§7.4): every chunk's framing,
/// CRC and order is checked, the shared chunks and the selected layer are decoded, other
/// layers' payloads are not parsed. With `keep_symbols`, also the selected layer's symbols
/// (the lattice coordinates, §6.6.2), which the canonical decoded form hashes (§11.1);
/// keeping them needs `8·N·(F + S + 3K)` bytes more, checked against the allocation limit on
/// top of the decoded size.
pub(crate) fn decode_anchors(
    data: &[u8],
    options: &DecodeOptions,
    keep_symbols: bool,
) -> Result<(SceneModel, Option<Symbols>)> {
    decode_stream(data, options, keep_symbols)
}

fn decode_stream(
    data: &[u8],
    options: &DecodeOptions,
    keep_symbols: bool,
) -> Result<(SceneModel, Option<Symbols>)> {
    let limits = &options.limits;
    // §1.2: signature and version.
    let (_sig, rest) = Signature::parse(data)?;
    let mut reader = ChunkReader::new(rest, SIGNATURE_LEN as u64, limits);
    let mut next_critical = 0usize;
    let mut p = Partial::default();
    // Layers in the stream and the index of the selected one, known once HEAD is read.
    let (mut layers, mut selected) = (0usize, 0usize);
    #[cfg(feature = "test-hooks")]
    let faulty;
    #[cfg(feature = "test-hooks")]
    let tables = match options.fault {
        Some(Fault::FrequencyTable { scale }) => {
            faulty = GaussianTables::standard().with_one_wrong_entry(scale);
            &faulty
        }
        None => GaussianTables::standard(),
    };
    #[cfg(not(feature = "test-hooks"))]
    let tables = GaussianTables::standard();
    loop {
        // §1.5 rule 4: the stream ends only with SEND.
        let chunk = reader.next_before_send()?;
        let tag = chunk.tag;
        if !tag.is_critical() {
            // §1.5 rules 1-2: ancillary chunks after HEAD are skipped.
            if p.head.is_none() {
                return Err(Error::ChunkOrder {
                    found: tag,
                    expected: ChunkTag::HEAD,
                });
            }
            continue;
        }
        // §3: an explicit-profile stream is not an anchors stream.
        if tag == ChunkTag::GHED && p.head.is_none() {
            return Err(Error::ChunkOrder {
                found: tag,
                expected: ChunkTag::HEAD,
            });
        }
        // §1.5 rules 0 and 3.
        if !ChunkTag::CRITICAL_ORDER.contains(&tag) {
            return Err(Error::UnknownCriticalChunk { tag });
        }
        let expected = if p.head.is_none() {
            ChunkTag::HEAD
        } else {
            expected_critical(next_critical, layers)
        };
        if tag != expected {
            return Err(Error::ChunkOrder {
                found: tag,
                expected,
            });
        }
        next_critical += 1;
        let bytes = chunk.payload;
        if tag == ChunkTag::HEAD {
            let head = Preflight::parse(bytes, limits)?;
            let rate;
            (rate, selected, layers) = head.select_layer(options.rate)?;
            p.rate = rate;
            p.head = Some(head);
            continue;
        }
        // §7.4: the layer this chunk belongs to, if it is a layer chunk.
        let layer = next_critical.checked_sub(8).map(|j| j / 3);
        let head = p.head.as_ref().ok_or(missing(ChunkTag::HEAD))?;
        let d = &head.dims;
        match tag {
            ChunkTag::MLPS => p.mlps = Some(payload::read_mlps(bytes, d)?),
            ChunkTag::QUAN => p.quan = Some(payload::read_quan(bytes, d)?),
            ChunkTag::APOS => {
                let tiles = p.tiles.as_ref().ok_or(missing(ChunkTag::TILS))?;
                let voxel = payload::read_apos(bytes, tiles, tables)?;
                // §5.2: the touched grid entries follow from the voxels.
                let layout = GridLayout::new(d, head.coord_bits);
                p.touched = Some(layout.touched(&voxel, d.entries_3d(), d.entries_2d()));
                p.voxel = Some(voxel);
            }
            ChunkTag::TILS => {
                let tiles = TileTable::parse(bytes, d.anchors, head.coord_bits)?;
                p.selected =
                    tiles.select(head.origin, head.voxel_size, options.region, options.part);
                p.tiles = Some(tiles);
            }
            ChunkTag::GRID => {
                let touched = p.touched.as_ref().ok_or(missing(ChunkTag::APOS))?;
                let tiles = p.tiles.as_ref().ok_or(missing(ChunkTag::TILS))?;
                // The grid is one coded body, decoded on one thread; the masks need only the
                // tiles (§6.6.1), so the next critical chunk, if it is a framed `AMSK`, is
                // decoded alongside. Its outcome waits for its own position (§1.5): this
                // chunk's error, and the chunks between, come first.
                let decode_grid = || payload::read_grid(bytes, d, touched);
                match peek_critical(reader.remaining(), ChunkTag::AMSK, limits) {
                    Some(amsk) => {
                        let (grid, mask) = join(decode_grid, || {
                            read_masks(amsk, d, tables, tiles, &p.selected)
                        });
                        p.grid = Some(grid?);
                        p.early_mask = Some(mask);
                    }
                    None => p.grid = Some(decode_grid()?),
                }
            }
            ChunkTag::AMSK => {
                let mask = match p.early_mask.take() {
                    Some(mask) => mask?,
                    None => {
                        let tiles = p.tiles.as_ref().ok_or(missing(ChunkTag::TILS))?;
                        read_masks(bytes, d, tables, tiles, &p.selected)?
                    }
                };
                p.mask = Some(mask);
            }
            ChunkTag::AFEA | ChunkTag::ASCL | ChunkTag::AOFF if layer != Some(selected) => {}
            ChunkTag::AFEA => p.attributes[0] = bytes,
            ChunkTag::ASCL => p.attributes[1] = bytes,
            ChunkTag::AOFF => p.attributes[2] = bytes,
            _ => {
                // SEND: empty, last, nothing after it (§1.5 rules 4-5).
                crate::container::chunk::check_send(bytes, reader.remaining())?;
                return assemble(p, tables, keep_symbols.then_some(&options.limits));
            }
        }
    }
}

/// Decodes a stream of either profile (§1.5, §3.7) with `options` on the caller's pool
/// (region and part apply to both; `fault` to the anchors profile).
pub(crate) fn decode_scene(data: &[u8], options: &DecodeOptions) -> Result<Scene> {
    if crate::container::is_explicit(data) {
        return crate::gaussians::decode_explicit(data, options)
            .map(|d| Scene::Gaussians(Box::new(d)));
    }
    decode_stream(data, options, false).map(|(m, _)| Scene::Anchors(Box::new(m)))
}

/// §6.6.2: decodes the attributes and builds the model once every critical chunk has been
/// read (the order rules guarantee each part is present).
/// `symbol_limits`: keep the symbols, within these limits.
fn assemble(
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
    let d = &head.dims;
    let prior = Prior::new(
        d,
        head.coord_bits,
        int_mlp,
        [&quant_feat, &quant_scaling, &quant_offsets],
        usize::from(p.rate),
    );
    // §7.2: the reconstruction matrices of the feature and scaling groups.
    // §7.6: one matrix per spatial region.
    let lattices = [
        GroupLattices::new(d.feat_lattice, usize::from(d.feat_dim), &quant_feat),
        GroupLattices::new(
            d.scaling_lattice,
            usize::from(d.scaling_dim),
            &quant_scaling,
        ),
    ];
    // §10: the selected tiles, each from its own bodies, in parallel; the lowest tile's
    // error is the one reported.
    let tiles = p.tiles.ok_or(missing(ChunkTag::TILS))?;
    let bodies = layer_bodies(p.attributes, tiles.len())?;
    let k = usize::from(d.offsets);
    let chosen: Vec<usize> = (0..tiles.len()).filter(|&t| p.selected[t]).collect();
    let mut mask_at = Vec::with_capacity(chosen.len());
    let mut at = 0usize;
    for &t in &chosen {
        mask_at.push(at);
        at += tiles.range(t).len() * k;
    }
    let (f, s) = (usize::from(d.feat_dim), usize::from(d.scaling_dim));
    let n_out: usize = chosen.iter().map(|&t| tiles.range(t).len()).sum();
    // The output tensors, allocated once and cut into each tile's rows.
    let mut attrs = Attributes {
        feat: vec![0f32; n_out * f],
        scaling: vec![0f32; n_out * s],
        offsets: vec![0f32; n_out * 3 * k],
    };
    let mut symbols = if let Some(limits) = symbol_limits {
        // The symbol tensors are extra to the decoded size the preflight checked (§1.4 step 6).
        let extra = (n_out as u64).saturating_mul((f + s + 3 * k) as u64 * 8);
        let requested = head.decoded_bytes.saturating_add(extra);
        if requested > limits.max_alloc_bytes {
            return Err(Error::LimitExceeded {
                limit: crate::limits::LimitKind::AllocationBytes,
                requested,
                allowed: limits.max_alloc_bytes,
            });
        }
        Some(Symbols {
            feat: vec![0; n_out * f],
            scaling: vec![0; n_out * s],
            offsets: vec![0; n_out * 3 * k],
        })
    } else {
        None
    };
    let mut rows = Vec::with_capacity(chosen.len());
    {
        let (mut fe, mut sc, mut of) = (
            &mut attrs.feat[..],
            &mut attrs.scaling[..],
            &mut attrs.offsets[..],
        );
        let mut sy = symbols
            .as_mut()
            .map(|sy| [&mut sy.feat[..], &mut sy.scaling[..], &mut sy.offsets[..]]);
        for &t in &chosen {
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
    }
    // The grid's signs for the interpolation (kernel or scalar loop), made once for every tile.
    let signs = prior.grid_signs(&grid);
    let grid_ref = GridRef::new(&grid, signs.as_ref());
    let size = |j: usize| tiles.range(chosen[j]).len();
    let decoded = map_largest_first(rows, size, |j, out| {
        let (t, m0) = (chosen[j], mask_at[j]);
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
            out,
        )
    });
    for result in decoded {
        result?;
    }
    // A region decode outputs the selected tiles' anchors only (§10.3.1 step 4).
    let (voxel, dims, quant_feat, quant_scaling) = if chosen.len() == tiles.len() {
        (voxel, head.dims, quant_feat, quant_scaling)
    } else {
        let kept: Vec<std::ops::Range<usize>> = chosen.iter().map(|&t| tiles.range(t)).collect();
        let voxel: Vec<[u32; 3]> = kept
            .iter()
            .flat_map(|r| voxel[r.clone()].iter().copied())
            .collect();
        let mut dims = head.dims.clone();
        dims.anchors = voxel.len() as u32;
        let quant_feat = rebase_regions(quant_feat, &kept);
        let quant_scaling = rebase_regions(quant_scaling, &kept);
        dims.feat_regions = (quant_feat.regions.len() + 1) as u16;
        dims.scaling_regions = (quant_scaling.regions.len() + 1) as u16;
        (voxel, dims, quant_feat, quant_scaling)
    };
    let model = SceneModel {
        origin: head.origin,
        voxel_size: head.voxel_size,
        anchors: Anchors {
            voxel,
            mask,
            feat: attrs.feat,
            scaling: attrs.scaling,
            offsets: attrs.offsets,
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
    Ok((model, symbols))
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
