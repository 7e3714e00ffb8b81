//! The progressive side of [`ExplicitDecoder`] (spec §3.8): which rate the full layer is
//! at, each layer's completion, the refinements decoded in place, and a stream's prefix.

use crate::par::*;

use super::{missing, DecodedGaussians, ExplicitDecoder};
use crate::container::chunk::ChunkTag;
use crate::container::payload::{body, METHOD_CODED};
use crate::entropy::GaussianTables;
use crate::error::Result;
use crate::explicit::gatt::refine_tile;
use crate::explicit::reconstruct::reconstruct_tile_into;
use crate::explicit::refinement::Precision;
use crate::explicit::Gaussians;
use crate::tiles::split_bodies;

impl ExplicitDecoder {
    /// §3.6: every decoded tile's Gaussians from its symbols at the present precision (a
    /// progressive stream cut before the selected layer, §3.8).
    pub(super) fn reconstruct_all(&mut self) -> Result<()> {
        let h = self.header.as_ref().ok_or(missing(ChunkTag::GHED))?;
        let precision = self.precision.as_ref().ok_or(missing(ChunkTag::GATT))?;
        let l = self.layer.as_ref().ok_or(missing(ChunkTag::GLAY))?;
        let g = self.groups.as_deref().ok_or(missing(ChunkTag::GQUA))?;
        let tiles = self.tiles.as_ref().ok_or(missing(ChunkTag::TILS))?;
        let voxels = self.voxels.as_deref().ok_or(missing(ChunkTag::APOS))?;
        let decoded = self.decoded.as_mut().ok_or(missing(ChunkTag::GATT))?;
        if !decoded.keep_symbols {
            return Ok(());
        }
        let kept = decoded.symbols.size_class.len();
        if decoded.gaussians.len() != kept {
            decoded.gaussians = Gaussians::zeroed(h.sh_degree, kept);
        }
        let values = g.iter().map(|g| g.dim).sum();
        let jobs = decoded.outputs(tiles, values);
        let size = |t: usize| tiles.range(t).len();
        let (origin, matrices) = (h.origin, &self.matrices[..]);
        map_largest_first(jobs, size, |t, output| {
            if let Some((Some(symbols), gaussians)) = output {
                let v = &voxels[tiles.range(t)];
                let s = symbols.as_ref();
                reconstruct_tile_into(
                    origin,
                    l.voxel_size,
                    precision,
                    g,
                    matrices,
                    v,
                    s,
                    gaussians,
                );
            }
        });
        self.gaussians_at = self.layers_done.checked_sub(1);
        Ok(())
    }

    /// The rate of the stream's first layer, the one `GLAY` … `GATT` code: the selected
    /// rate, or in a progressive stream the coarsest coded rate (§3.8).
    pub(crate) fn layer_rate(&self) -> u8 {
        match self.progressive {
            true => self
                .stream_rates
                .first()
                .copied()
                .unwrap_or(self.rate_chosen),
            false => self.rate_chosen,
        }
    }

    /// Whether the stream so far is a progressive stream's prefix holding a complete layer
    /// (§3.8).
    pub(crate) fn prefix_decodes(&self) -> bool {
        self.progressive && self.layers_done > 0
    }

    /// Records that the layer of the chunk just decoded (`GATT` or `GRSY`) is complete:
    /// its symbols are decoded and the precision is the layer's.
    pub(super) fn layer_decoded(&mut self) {
        let Some(l) = self.order.last_layer() else {
            return;
        };
        if let Some(r) = self.refinement.take() {
            self.precision = self.precision.as_ref().map(|p| p.refined(&r));
            self.refinements.push(r);
        } else if let (Some(layer), Some(groups)) = (&self.layer, &self.groups) {
            self.precision = Some(Precision::of_layer(layer, groups, self.layer_rate()));
            self.gaussians_at = Some(l);
        }
        self.layers_done = l + 1;
    }

    /// §3.8: the selected tiles' symbols refined by `GRSY` (`bytes`) in place, each tile in
    /// its own task; at the selected layer, its Gaussians reconstructed in the same task.
    pub(super) fn refine(&mut self, bytes: &[u8], tables: &GaussianTables) -> Result<()> {
        let h = self.header.as_ref().ok_or(missing(ChunkTag::GHED))?;
        let r = self.refinement.as_ref().ok_or(missing(ChunkTag::GREF))?;
        let before = self.precision.as_ref().ok_or(missing(ChunkTag::GATT))?;
        let l = self.layer.as_ref().ok_or(missing(ChunkTag::GLAY))?;
        let g = self.groups.as_deref().ok_or(missing(ChunkTag::GQUA))?;
        let tiles = self.tiles.as_ref().ok_or(missing(ChunkTag::TILS))?;
        let voxels = self.voxels.as_deref().ok_or(missing(ChunkTag::APOS))?;
        let decoded = self.decoded.as_mut().ok_or(missing(ChunkTag::GATT))?;
        // Where the first layer's tiles were reconstructed by the caller (a stream decoded
        // as it arrives), the refined Gaussians get their own room.
        let kept = decoded.symbols.size_class.len();
        if decoded.gaussians.len() != kept {
            decoded.gaussians = Gaussians::zeroed(h.sh_degree, kept);
        }
        let words = body(ChunkTag::GRSY, bytes, METHOD_CODED)?;
        let bodies = split_bodies(ChunkTag::GRSY, 1, words, tiles.len())?;
        let layer = self.order.last_layer();
        let last = layer == Some(self.selected_layer) || self.reconstruct_each_layer;
        let after = before.refined(r);
        let values = g.iter().map(|g| g.dim).sum();
        let outputs = decoded.outputs(tiles, values);
        let jobs: Vec<_> = bodies.into_iter().zip(outputs).collect();
        let size = |t: usize| tiles.range(t).len();
        let (origin, matrices) = (h.origin, &self.matrices[..]);
        let results = map_largest_first(jobs, size, |t, (b, output)| {
            let Some((Some(mut symbols), gaussians)) = output else {
                return Ok(());
            };
            let tile_voxels = &voxels[tiles.range(t)];
            refine_tile(r, g, tile_voxels, b, tables, &mut symbols)?;
            if last {
                let s = symbols.as_ref();
                reconstruct_tile_into(
                    origin,
                    l.voxel_size,
                    &after,
                    g,
                    matrices,
                    tile_voxels,
                    s,
                    gaussians,
                );
            }
            Ok(())
        });
        // §10.3: the lowest tile's error is reported.
        results.into_iter().collect::<Result<()>>()?;
        if last {
            self.gaussians_at = layer;
        }
        Ok(())
    }

    /// The Gaussians at the last refinement decoded and its rate, where they were
    /// reconstructed (the selected rate's, or each one's with `reconstruct_each_layer`).
    pub(crate) fn refined_gaussians(&self) -> Option<(u8, &Gaussians)> {
        let last = self.layers_done.checked_sub(1).filter(|&l| l > 0)?;
        let rate = *self.stream_rates.get(last)?;
        let decoded = self.decoded.as_ref()?;
        (self.gaussians_at == Some(last)).then_some((rate, &decoded.gaussians))
    }

    /// §3.8: a progressive stream that ended before `SEND`: the Gaussians of its last
    /// complete layer, marked as truncated.
    pub(crate) fn finish_prefix(mut self) -> Result<DecodedGaussians> {
        self.refinement = None;
        self.truncated = true;
        self.finish()
    }
}
