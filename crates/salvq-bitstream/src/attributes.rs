//! Anchor attribute chunks (spec §6.6), decoder side: masks (`AMSK`) and the entropy-coded
//! features, scalings and offsets (`AFEA`, `ASCL`, `AOFF`), decoded anchor by anchor against
//! the integer prior (§5) and reconstructed in binary32 (§5.5).

use crate::par::*;

use crate::container::bytes::PayloadReader;
use crate::container::chunk::ChunkTag;
use crate::container::payload::{body, METHOD_CODED};
use crate::entropy::{GaussianTables, SymbolReader};
use crate::error::{Error, Result};
use crate::hyperprior::grid::GridRef;
use crate::hyperprior::prior::{Group, Prior, BATCH};
use crate::model::Dims;
use crate::quantizer::{reconstruct_value, GroupLattices};
use crate::tiles::{split_bodies, TileTable};

/// §6.6.1: the coder frequency of a mask bit being 1, from its 16-bit probability.
pub fn mask_freq(p_one: u16, precision: u32) -> u32 {
    let p = u32::from(p_one);
    let f = if precision <= 16 {
        p >> (16 - precision)
    } else {
        p << (precision - 16)
    };
    f.clamp(1, (1 << precision) - 1)
}

/// §6.6.1, §10.2: decodes `AMSK` for the selected tiles: K slot probabilities, then each
/// selected tile's N_t x K mask bits from its own body, anchor by anchor. Returns the masks
/// of the selected tiles' anchors, in order.
pub fn read_masks(
    payload: &[u8],
    d: &Dims,
    tables: &GaussianTables,
    tiles: &TileTable,
    selected: &[bool],
) -> Result<Vec<u8>> {
    let tag = ChunkTag::AMSK;
    let body = body(tag, payload, METHOD_CODED)?;
    let k = usize::from(d.offsets);
    let mut r = PayloadReader::new(tag, body);
    let mut freq = Vec::with_capacity(k);
    for slot in 0..k {
        let p = r.u16()?;
        if p == 0 {
            return Err(Error::ValueInvalid {
                tensor: "AMSK.p_one",
                index: vec![slot as u64],
                value: 0,
                allowed: "1..=65535",
            });
        }
        freq.push(mask_freq(p, tables.precision()));
    }
    let words = &body[r.consumed()..];
    let bodies = split_bodies(tag, 1 + r.consumed(), words, tiles.len())?;
    // Selected tiles in parallel; the lowest tile's error is reported (§10.3).
    let decoded: Vec<Result<Vec<u8>>> = bodies
        .into_par_iter()
        .enumerate()
        .filter(|(t, _)| selected.get(*t).copied().unwrap_or(false))
        .map(|(t, tile_body)| {
            let mut reader = SymbolReader::new(tag, tile_body, tables)?;
            let mut mask = Vec::with_capacity(tiles.range(t).len() * k);
            for _ in tiles.range(t) {
                for &f in &freq {
                    mask.push(u8::from(reader.bit(f)?));
                }
            }
            reader.finish()?;
            Ok(mask)
        })
        .collect();
    let mut mask = Vec::new();
    for m in decoded {
        mask.extend_from_slice(&m?);
    }
    Ok(mask)
}

/// §6.6.2, §10.2: the three layer chunks' tile bodies, `[tile][group]`, after their
/// `coding_method` checks and framing (AFEA, ASCL, AOFF in turn).
pub fn layer_bodies(payloads: [&[u8]; 3], tiles: usize) -> Result<Vec<[&[u8]; 3]>> {
    let tags = [ChunkTag::AFEA, ChunkTag::ASCL, ChunkTag::AOFF];
    let mut split = Vec::with_capacity(3);
    for (tag, payload) in tags.into_iter().zip(payloads) {
        split.push(split_bodies(
            tag,
            1,
            body(tag, payload, METHOD_CODED)?,
            tiles,
        )?);
    }
    Ok((0..tiles)
        .map(|t| [split[0][t], split[1][t], split[2][t]])
        .collect())
}

/// The priors of a block of anchors: context MLP outputs, scale indices of every value
/// (masked offsets included), and the three group steps.
struct PriorBlock {
    ys: Vec<i32>,
    ks: Vec<u8>,
    deltas: Vec<[f32; 3]>,
}

impl PriorBlock {
    /// Computes the block's priors in parallel: every anchor's values are independent of the
    /// others and of the symbols, so the result does not depend on the thread count. Scale
    /// indices of offsets whose mask (`masks`, K per anchor of the block) is 0 are not needed
    /// and are left as they were.
    fn fill(
        &mut self,
        prior: &Prior,
        grid: GridRef<'_>,
        voxels: &[[u32; 3]],
        masks: &[u8],
        (f, s, k): (usize, usize, usize),
    ) {
        let cout = prior.mlp.cout;
        let width = f + s + 3 * k;
        let m = voxels.len();
        // Runs of anchors, each walked in order so that the next batch's grid entries are
        // requested while this one is computed.
        const RUN: usize = 64;
        self.ys[..m * cout]
            .par_chunks_mut(RUN * cout.max(1))
            .zip(self.ks[..m * width].par_chunks_mut(RUN * width.max(1)))
            .zip(self.deltas[..m].par_chunks_mut(RUN))
            .zip(voxels.par_chunks(RUN))
            .zip(masks.par_chunks(RUN * k.max(1)))
            .for_each_init(
                || prior.context(),
                |ctx, ((((ys, kks), deltas), vs), run_masks)| {
                    // §5.3 for BATCH anchors at a time, the next batch's grid entries
                    // requested first; a run's last, short batch anchor by anchor.
                    let batches = ys.chunks_mut(BATCH * cout.max(1)).zip(vs.chunks(BATCH));
                    for (b, (batch, v)) in batches.enumerate() {
                        for &next in vs.iter().skip((b + 1) * BATCH).take(BATCH) {
                            prior.prefetch(grid, next);
                        }
                        match v.first_chunk::<BATCH>() {
                            Some(v) if batch.len() == BATCH * cout => {
                                prior.eval_batch_into(grid, v, ctx, batch);
                            }
                            _ => {
                                for (&va, y) in v.iter().zip(batch.chunks_mut(cout.max(1))) {
                                    prior.eval_into(grid, va, ctx, y);
                                }
                            }
                        }
                    }
                    let anchors = ys
                        .chunks_mut(cout.max(1))
                        .zip(kks.chunks_mut(width.max(1)))
                        .zip(deltas.iter_mut())
                        .zip(run_masks.chunks(k.max(1)));
                    for (((y, kk), delta), mask) in anchors {
                        for (gi, (g, w)) in [(Group::Feature, f), (Group::Scaling, s)]
                            .into_iter()
                            .enumerate()
                        {
                            let step = prior.step(y, g);
                            delta[gi] = step.delta;
                            let at = gi * f;
                            prior.scale_indices(y, g, 0, &step, &mut kk[at..at + w]);
                        }
                        let step = prior.step(y, Group::Offsets);
                        delta[2] = step.delta;
                        prior.offset_scale_indices(y, &step, mask, &mut kk[f + s..]);
                    }
                },
            );
    }
}

/// The decoded attributes: features [N, F], scalings [N, S], offsets [N, K, 3].
pub struct Attributes {
    /// Latent features, row-major [N, F] (table 2-1 row 5).
    pub feat: Vec<f32>,
    /// Scalings, row-major [N, S] (table 2-1 row 6).
    pub scaling: Vec<f32>,
    /// Offsets, row-major [N, K, 3], in units of the anchor's scaling; 0.0 where masked.
    pub offsets: Vec<f32>,
}

/// The decoded symbols (lattice coordinates, §6.6.2) of one rate, for the canonical decoded
/// form (§11.1): features [N, F], scalings [N, S], offsets [N, K, 3] (0 where masked).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Symbols {
    /// Feature symbols (lattice coordinates `u`), row-major [N, F].
    pub feat: Vec<i64>,
    /// Scaling symbols (lattice coordinates `u`), row-major [N, S].
    pub scaling: Vec<i64>,
    /// Offset symbols, row-major [N, K, 3]; 0 where the offset is masked.
    pub offsets: Vec<i64>,
}

/// Where one tile's decoded attributes go: its anchors' rows of the output tensors, and of
/// the symbol tensors when they are kept.
pub struct AttributesMut<'a> {
    /// The tile's rows of [`Attributes::feat`], [n, F] for its n anchors.
    pub feat: &'a mut [f32],
    /// The tile's rows of [`Attributes::scaling`], [n, S].
    pub scaling: &'a mut [f32],
    /// The tile's rows of [`Attributes::offsets`], [n, K, 3].
    pub offsets: &'a mut [f32],
    /// Rows of [`Symbols`]' tensors, in the same order (`None`: symbols are not kept).
    pub symbols: Option<[&'a mut [i64]; 3]>,
}

/// What every anchor of a tile shares while its symbols are read (§6.6.2).
struct AnchorReader<'a> {
    prior: &'a Prior,
    lattices: &'a [GroupLattices; 2],
    masks: &'a [u8],
    first: u32,
    /// (F, S, K).
    dims: (usize, usize, usize),
}

impl AnchorReader<'_> {
    /// Reads the symbols of anchor `i`, the b-th of the block whose priors `current` holds,
    /// from the three `readers`, and writes its values, and its symbols where they are kept,
    /// into `out`; `u` and `z` have room for max(F, S) coordinates and lattice products.
    #[inline(always)]
    fn read(
        &self,
        readers: &mut [SymbolReader<'_>],
        current: &PriorBlock,
        b: usize,
        i: usize,
        out: &mut AttributesMut<'_>,
        (u, z): (&mut [i64], &mut [f32]),
    ) -> Result<()> {
        let (prior, lattices, masks, first) = (self.prior, self.lattices, self.masks, self.first);
        let (f, s, k) = self.dims;
        let cout = prior.mlp.cout;
        let width = f + s + 3 * k;
        let y = &current.ys[b * cout..(b + 1) * cout];
        let kk = &current.ks[b * width..(b + 1) * width];
        let delta = current.deltas[b];
        let [sym_f, sym_s, sym_o] = match out.symbols.as_mut() {
            Some([a, b, c]) => [Some(&mut **a), Some(&mut **b), Some(&mut **c)],
            None => [None, None, None],
        };
        for (g, w, at, dst, sym) in [
            (Group::Feature, f, 0, &mut *out.feat, sym_f),
            (Group::Scaling, s, f, &mut *out.scaling, sym_s),
        ] {
            let dst = &mut dst[i * w..(i + 1) * w];
            let reader = &mut readers[g as usize];
            let lattice = lattices[g as usize].for_anchor(first + i as u32);
            let delta = delta[g as usize];
            // §6.6.2: the group's w coordinates, in order.
            for (j, uj) in u[..w].iter_mut().enumerate() {
                *uj = reader.symbol(kk[at + j])?;
            }
            if let Some(sym) = sym {
                sym[i * w..(i + 1) * w].copy_from_slice(&u[..w]);
            }
            if lattice.is_identity() {
                prior.reconstruct_values(y, g, 0, delta, &u[..w], dst);
                continue;
            }
            // §7.3: μ + Δ·(B u).
            lattice.apply(&u[..w], &mut z[..w]);
            for (j, (x, &zj)) in dst.iter_mut().zip(&z[..w]).enumerate() {
                *x = reconstruct_value(prior.mean_f32(y, g, j), delta, zj);
            }
        }
        let reader = &mut readers[2];
        let row = &mut out.offsets[i * 3 * k..(i + 1) * 3 * k];
        let mut sym_row = sym_o.map(|o| &mut o[i * 3 * k..(i + 1) * 3 * k]);
        for slot in 0..k {
            if masks[i * k + slot] == 0 {
                row[3 * slot..3 * slot + 3].fill(0.0);
                continue;
            }
            let mut us = [0i64; 3];
            for (c, uc) in us.iter_mut().enumerate() {
                *uc = reader.symbol(kk[f + s + 3 * slot + c])?;
            }
            if let Some(sr) = sym_row.as_deref_mut() {
                sr[3 * slot..3 * slot + 3].copy_from_slice(&us);
            }
            let (dst, offsets) = (&mut row[3 * slot..3 * slot + 3], Group::Offsets);
            prior.reconstruct_values(y, offsets, 3 * slot, delta[2], &us, dst);
        }
        Ok(())
    }
}

/// §6.6.2: decodes `AFEA`, `ASCL` and `AOFF` together, anchor by anchor: for anchor i, its F
/// feature symbols from `AFEA`, its S scaling symbols from `ASCL`, then 3 symbols from `AOFF`
/// for each offset whose mask is 1 (masked offsets decode as 0.0).
///
/// One tile (§10): `bodies` are the tile's three bodies, `voxels` and `masks` its anchors',
/// `first` the canonical index of its first anchor (for spatial regions, §7.6); the values
/// are written into `out` (the tile's rows, zero where an offset is masked).
#[allow(clippy::too_many_arguments)]
pub fn read_attributes(
    bodies: [&[u8]; 3],
    d: &Dims,
    voxels: &[[u32; 3]],
    masks: &[u8],
    first: u32,
    grid: GridRef<'_>,
    prior: &Prior,
    lattices: &[GroupLattices; 2],
    tables: &GaussianTables,
    mut out: AttributesMut<'_>,
) -> Result<()> {
    let tags = [ChunkTag::AFEA, ChunkTag::ASCL, ChunkTag::AOFF];
    let mut readers = Vec::with_capacity(3);
    for (tag, body) in tags.into_iter().zip(bodies) {
        readers.push(SymbolReader::new(tag, body, tables)?);
    }
    let n = voxels.len();
    let f = usize::from(d.feat_dim);
    let s = usize::from(d.scaling_dim);
    let k = usize::from(d.offsets);
    if out.feat.len() != n * f || out.scaling.len() != n * s || out.offsets.len() != n * 3 * k {
        return Err(Error::DecodedSizeMismatch {
            stated: (n * (f + s + 3 * k)) as u64,
            computed: (out.feat.len() + out.scaling.len() + out.offsets.len()) as u64,
        });
    }
    // The prior of every anchor is independent of the symbols: it is computed for a block of
    // anchors in parallel (the same values whatever the thread count), then the symbols are
    // read anchor by anchor in the order of §6.6.2.
    const BLOCK: usize = 2048;
    let cout = prior.mlp.cout;
    let width = f + s + 3 * k;
    let blocks: Vec<&[[u32; 3]]> = voxels[..n.min(voxels.len())].chunks(BLOCK).collect();
    let new_block = || PriorBlock {
        ys: vec![0i32; BLOCK.min(n) * cout],
        ks: vec![0u8; BLOCK.min(n) * width],
        deltas: vec![[0f32; 3]; BLOCK.min(n)],
    };
    let (mut current, mut next) = (new_block(), new_block());
    let dims = (f, s, k);
    let anchor = AnchorReader {
        prior,
        lattices,
        masks,
        first,
        dims,
    };
    if let Some(first) = blocks.first() {
        current.fill(prior, grid, first, &masks[..first.len() * k], dims);
    }
    // Pipeline: while one thread reads block b's symbols, the others compute block b + 1's
    // priors. Symbols are still read in order, so errors are reported as §6.6.2 says.
    for (bi, block) in blocks.iter().enumerate() {
        let upcoming = blocks.get(bi + 1);
        let (_, decoded) = join(
            || {
                if let Some(vs) = upcoming {
                    let start = (bi + 1) * BLOCK * k;
                    next.fill(prior, grid, vs, &masks[start..start + vs.len() * k], dims);
                }
            },
            || -> Result<()> {
                let (mut u, mut z) = (vec![0i64; f.max(s)], vec![0f32; f.max(s)]);
                for b in 0..block.len() {
                    let i = bi * BLOCK + b;
                    anchor.read(&mut readers, &current, b, i, &mut out, (&mut u, &mut z))?;
                }
                Ok(())
            },
        );
        decoded?;
        std::mem::swap(&mut current, &mut next);
    }
    for r in readers {
        r.finish()?;
    }
    Ok(())
}
