//! One layer of an explicit-profile stream (spec §3.4, §3.5, Annex A.8.3): the coarse voxel
//! grid, the size classes with their position refinement and step shifts, the canonical
//! order, the tiles, the lattice coordinates, and the causal prior's tables fitted to them
//! by their exact coded cost.

use super::grid::grid;
use super::grid::Grid;
use super::plan::{RatePlan, SizeClasses};
use super::prepare::PreparedGaussians;
use super::prior::{
    bit_cost, entropy_bits, fit_prior, freq, group_histograms, Histograms, PRED_LEVEL_CANDIDATES,
};
pub use super::prior::{group_bits, BitCost, Variant};
use super::quantize::{quantize, Quantized};
use super::writer::{rest_count_freq, Writer};
use crate::error::Result;
use salvq_bitstream::container::chunk::{write_chunk, ChunkTag};
use salvq_bitstream::container::payload::METHOD_CODED;
use salvq_bitstream::entropy::GaussianTables;
use salvq_bitstream::explicit::attributes::{walk, TileSymbols};
use salvq_bitstream::explicit::groups::{Group, GroupKind};
use salvq_bitstream::explicit::layer::{
    rest_count_nodes, rest_values, Layer, CONTEXT_CLASSES, SIZE_CLASSES,
};
use salvq_bitstream::explicit::reconstruct::reconstruct_tile_into;
use salvq_bitstream::explicit::refinement::Precision;
use salvq_bitstream::explicit::Gaussians;
use salvq_bitstream::tiles::{join_bodies, TileTable};

/// What one layer cost and holds.
#[derive(Debug, Clone)]
pub struct LayerReport {
    /// The layer's rate.
    pub rate: u8,
    /// Bits per voxel coordinate.
    pub coord_bits: u8,
    /// Edge of a voxel in world units.
    pub voxel_size: f32,
    /// Octree levels a reference must share (§3.4).
    pub pred_level: u8,
    /// Position refinement bits per axis, per size class.
    pub refine: [u8; SIZE_CLASSES],
    /// Payload bytes of GLAY, TILS, APOS, GATT (framing excluded).
    pub glay_bytes: usize,
    /// Payload bytes of `TILS`.
    pub tils_bytes: usize,
    /// Payload bytes of `APOS`.
    pub apos_bytes: usize,
    /// Payload bytes of `GATT`.
    pub gatt_bytes: usize,
    /// Ideal bits per group under the fitted tables (the rotation index in its group).
    pub group_bits: Vec<f64>,
    /// Bits of the position refinement.
    pub refine_bits: f64,
    /// Whether each group is predicted from its reference.
    pub predict: Vec<bool>,
    /// Tiles in the layer.
    pub tiles: usize,
}

/// A coded layer: its chunks, what the decoder will output, and its report.
pub struct CodedLayer {
    /// The layer's chunks, framed.
    pub chunks: Vec<u8>,
    /// The Gaussians a conformant decoder outputs for this layer.
    pub expected: Gaussians,
    /// What it cost.
    pub report: LayerReport,
    /// What a decoder holds after it: what a refinement (§3.8) refines.
    pub state: LayerState,
}

/// The symbols of every Gaussian of a decoded layer, in canonical order, and their
/// precision: what a refinement layer (§3.8) starts from.
pub struct LayerState {
    /// The grid and the canonical order.
    pub grid: Grid,
    /// The tiles.
    pub tiles: TileTable,
    /// Lattice coordinates, every coded value of each Gaussian.
    pub coords: Vec<i32>,
    /// Size class of each Gaussian.
    pub size_class: Vec<u8>,
    /// Position bits below the voxel of each Gaussian, per axis.
    pub refinement: Vec<[u32; 3]>,
    /// Index of each Gaussian's largest rotation component.
    pub rotation: Vec<u8>,
    /// The precision they are at.
    pub precision: Precision,
}

/// Codes layer `rate` of `p` with the quantizers `groups` (rate steps), `classes` and the
/// rate's `plan` (Annex A.8.3), in tiles of at most `tile_gaussians` (0: the reference's
/// automatic tiles, [`crate::writers::tile_cut::cut_auto`]).
#[allow(clippy::too_many_arguments)]
pub fn encode_layer(
    p: &PreparedGaussians,
    groups: &[Group],
    classes: &SizeClasses,
    plan: &RatePlan,
    origin: [f32; 3],
    rate: u8,
    tile_gaussians: u32,
    variant: Variant,
    tables: &GaussianTables,
) -> Result<CodedLayer> {
    let grid = grid(p, origin, plan.voxel);
    let tiles = match tile_gaussians {
        0 => crate::writers::cut_auto(&grid.voxels),
        per => crate::writers::cut(&grid.voxels, per),
    };
    let q = quantize(p, groups, classes, plan, &grid, origin, rate);
    let built;
    let cost = if std::ptr::eq(tables, GaussianTables::standard()) {
        BitCost::standard()
    } else {
        built = BitCost::new(tables);
        &built
    };
    let coder = LayerCoder {
        groups,
        q: &q,
        grid: &grid,
        tiles: &tiles,
        tables,
    };
    let prior = fit_layer_prior(&coder, plan, variant, cost);
    let (mut layer, mut group_bits) = layer_header(&grid, plan, &q, groups, prior);
    let refine_bits: f64 = q
        .size_class
        .iter()
        .map(|&c| 3.0 * f64::from(plan.refine[usize::from(c)]))
        .sum();
    if let Some(gi) = groups.iter().position(|g| g.kind == GroupKind::Rest) {
        let counts = coder.rest_counts(&layer)?;
        let (freq, bits) = rest_count_freq(&counts, groups[gi].dim);
        layer.rest_count_freq = freq;
        group_bits[gi] += bits;
    }
    let precision = Precision::of_layer(&layer, groups, rate);
    let coded = coder.code_tiles(&layer, &precision, origin, p.sh_degree)?;
    let (chunks, [glay_bytes, tils_bytes, apos_bytes, gatt_bytes]) =
        layer_chunks(&layer, &tiles, &coded);
    Ok(CodedLayer {
        chunks,
        expected: coded.expected,
        report: LayerReport {
            rate,
            coord_bits: grid.coord_bits,
            voxel_size: grid.voxel_size,
            pred_level: layer.pred_level,
            refine: plan.refine,
            glay_bytes,
            tils_bytes,
            apos_bytes,
            gatt_bytes,
            group_bits,
            refine_bits,
            predict: layer.predict,
            tiles: tiles.len(),
        },
        state: LayerState {
            grid,
            tiles,
            coords: q.coords,
            size_class: q.size_class,
            refinement: q.refinement,
            rotation: q.rotation,
            precision,
        },
    })
}

/// A quantized layer on its grid and tiles: what its prior is fitted to and its tiles are
/// coded from.
struct LayerCoder<'a> {
    groups: &'a [Group],
    q: &'a Quantized,
    grid: &'a Grid,
    tiles: &'a TileTable,
    tables: &'a GaussianTables,
}

/// GLAY's prior as fitted (Annex A.8.3).
struct FittedPrior {
    /// The reference level (§3.4).
    pred_level: u8,
    /// Whether each group is predicted from its reference.
    predict: Vec<bool>,
    /// The scale-index table of every value.
    scale_table: Vec<[u8; CONTEXT_CLASSES]>,
    /// Per group after the first, the scale-index offset of each size class.
    scale_offset: Vec<[i8; SIZE_CLASSES]>,
    /// Ideal bits per group under the fitted tables.
    group_bits: Vec<f64>,
}

impl LayerCoder<'_> {
    /// The histograms of group `gi`'s coded symbols (values from `at`) under `level` and
    /// `predict` and, for `sh_rest`, its counts' order-0 bits (§3.5: only the values up to
    /// the last nonzero symbol are coded).
    fn histograms(&self, gi: usize, at: usize, level: u8, predict: bool) -> (Histograms, f64) {
        let (q, g) = (self.q, &self.groups[gi]);
        let mut counts = Vec::new();
        let h = group_histograms(
            &q.coords,
            q.values,
            at,
            g.dim,
            &q.size_class,
            &q.shifts[gi],
            &self.grid.voxels,
            self.tiles,
            level,
            predict,
            (g.kind == GroupKind::Rest).then_some(&mut counts),
        );
        (h, entropy_bits(&counts))
    }

    /// The writer of the Gaussians `range` (a tile).
    fn writer(&self, range: std::ops::Range<usize>) -> Writer<'_, '_> {
        let (q, values) = (self.q, self.q.values);
        Writer::new(
            ChunkTag::GATT,
            self.tables,
            &q.coords[range.start * values..range.end * values],
            &q.rotation[range.clone()],
            &q.refinement[range],
            values,
        )
    }

    /// Every Gaussian's `sh_rest` count under `layer`'s predictions, in walk order: §3.5's
    /// counts follow from the coordinates and the predictions alone, so a first walk
    /// collects them and GLAY's tree probabilities are fitted to them.
    fn rest_counts(&self, layer: &Layer) -> Result<Vec<usize>> {
        let mut counts = Vec::with_capacity(self.q.size_class.len());
        for t in 0..self.tiles.len() {
            let range = self.tiles.range(t);
            let mut w = self.writer(range.clone());
            walk(layer, self.groups, &self.grid.voxels[range], &mut w)?;
            counts.extend(w.rest_counts);
        }
        Ok(counts)
    }

    /// Every tile's geometry (§8, cell-relative) and attributes (§3.5) under `layer`, and
    /// the Gaussians a decoder reconstructs from them.
    fn code_tiles(
        &self,
        layer: &Layer,
        precision: &Precision,
        origin: [f32; 3],
        sh_degree: u8,
    ) -> Result<CodedTiles> {
        let (groups, grid, tiles) = (self.groups, self.grid, self.tiles);
        let mut apos = Vec::with_capacity(tiles.len());
        let mut gatt = Vec::with_capacity(tiles.len());
        let matrices: Vec<_> = groups.iter().map(Group::matrix).collect();
        let mut expected = Gaussians {
            sh_degree,
            ..Gaussians::default()
        };
        for t in 0..tiles.len() {
            let range = tiles.range(t);
            let (level, cell) = tiles.cells[t];
            let local: Vec<[u32; 3]> = grid.voxels[range.clone()]
                .iter()
                .map(|v| [0, 1, 2].map(|a| v[a] - (cell[a] << level)))
                .collect();
            apos.push(crate::writers::encode_geometry(&local, level, self.tables)?);
            let mut w = self.writer(range.clone());
            let symbols: TileSymbols = walk(layer, groups, &grid.voxels[range.clone()], &mut w)?;
            debug_assert_eq!(symbols.size_class, self.q.size_class[range.clone()]);
            gatt.push(w.out.finish());
            let tile = expected.extend_zeroed(range.len());
            reconstruct_tile_into(
                origin,
                layer.voxel_size,
                precision,
                groups,
                &matrices,
                &grid.voxels[range],
                symbols.as_ref(),
                tile,
            );
        }
        Ok(CodedTiles {
            apos,
            gatt,
            expected,
        })
    }
}

/// The reference level and per-group prediction whose fitted tables cost least (Annex
/// A.8.3): for each candidate pred_level, each group with and without prediction, tables
/// fitted by exact cost under the shifts' offsets.
fn choose_prediction(
    coder: &LayerCoder,
    plan: &RatePlan,
    variant: Variant,
    cost: &BitCost,
) -> (u8, Vec<bool>) {
    let mut best: Option<(f64, u8, Vec<bool>)> = None;
    for offset in PRED_LEVEL_CANDIDATES {
        let Some(level) = coder.grid.coord_bits.checked_sub(offset) else {
            continue;
        };
        let mut total = 0.0;
        let mut predict = Vec::new();
        let mut at = 0;
        for (gi, g) in coder.groups.iter().enumerate() {
            let bits = |pr: bool| {
                let (h, count_bits) = coder.histograms(gi, at, level, pr);
                let shifts = plan.class_shifts(gi);
                let fit = fit_prior(&h, cost, variant.factorized_prior, shifts, false);
                fit.2 + count_bits
            };
            let off = bits(false);
            let on = if variant.factorized_prior {
                f64::INFINITY
            } else {
                bits(true)
            };
            let pr = variant.predict_all || on < off;
            predict.push(pr);
            total += if pr { on } else { off };
            at += g.dim;
        }
        if best.as_ref().is_none_or(|b| total < b.0) {
            best = Some((total, level, predict));
        }
    }
    let (_, pred_level, predict) = best.expect("at least one pred_level candidate fits");
    (pred_level, predict)
}

/// The layer's prior: the cheapest reference level and predictions
/// ([`choose_prediction`]), then each group's tables and per-class offsets fitted together.
fn fit_layer_prior(
    coder: &LayerCoder,
    plan: &RatePlan,
    variant: Variant,
    cost: &BitCost,
) -> FittedPrior {
    let (pred_level, predict) = choose_prediction(coder, plan, variant, cost);
    let (mut scale_table, mut scale_offset) = (Vec::new(), Vec::new());
    let mut group_bits = Vec::new();
    let mut at = 0;
    for (gi, g) in coder.groups.iter().enumerate() {
        let (h, _) = coder.histograms(gi, at, pred_level, predict[gi]);
        let factorized = variant.factorized_prior;
        let (rows, offsets, bits) = fit_prior(&h, cost, factorized, plan.class_shifts(gi), gi > 0);
        scale_table.extend(rows);
        if gi > 0 {
            scale_offset.push(offsets);
        }
        group_bits.push(bits);
        at += g.dim;
    }
    FittedPrior {
        pred_level,
        predict,
        scale_table,
        scale_offset,
        group_bits,
    }
}

/// GLAY (§3.4) from the grid, the plan, the size thresholds and the fitted `prior`, with the
/// rotation probabilities fitted to `q` and the `sh_rest` counts' tree still flat; and the
/// ideal bits per group, the rotation indices' in their group.
fn layer_header(
    grid: &Grid,
    plan: &RatePlan,
    q: &Quantized,
    groups: &[Group],
    prior: FittedPrior,
) -> (Layer, Vec<f64>) {
    let mut group_bits = prior.group_bits;
    let (rotation_freq, rotation_bits) = rotation_probabilities(&q.rotation);
    if let Some(gi) = groups.iter().position(|g| g.kind == GroupKind::Rotation) {
        group_bits[gi] += rotation_bits;
    }
    let layer = Layer {
        coord_bits: grid.coord_bits,
        voxel_size: grid.voxel_size,
        pred_level: prior.pred_level,
        rotation_freq,
        size_threshold: q.size_threshold,
        refine: plan.refine,
        shift: plan.shift.clone(),
        scale_offset: prior.scale_offset,
        predict: prior.predict,
        rest_count_freq: vec![1 << 15; rest_count_nodes(rest_values(groups.len(), q.values))],
        scale_table: prior.scale_table,
    };
    (layer, group_bits)
}

/// GLAY's rotation index probabilities (§3.4: the high bit, then the low bit after each
/// high bit) fitted to `rotation`, and the bits the indices cost under them.
fn rotation_probabilities(rotation: &[u8]) -> ([u16; 3], f64) {
    let n = rotation.len() as u64;
    let (mut high, mut low, mut after) = (0u64, [0u64; 2], [0u64; 2]);
    for &r in rotation {
        let h = usize::from(r >> 1);
        high += h as u64;
        after[h] += 1;
        low[h] += u64::from(r & 1);
    }
    let freq = [
        freq(high, n),
        freq(low[0], after[0]),
        freq(low[1], after[1]),
    ];
    let bits = bit_cost(high, n, freq[0])
        + bit_cost(low[0], after[0], freq[1])
        + bit_cost(low[1], after[1], freq[2]);
    (freq, bits)
}

/// A layer's tiles, coded.
struct CodedTiles {
    /// Each tile's `APOS` body.
    apos: Vec<Vec<u8>>,
    /// Each tile's `GATT` body.
    gatt: Vec<Vec<u8>>,
    /// The Gaussians a conformant decoder outputs for them.
    expected: Gaussians,
}

/// The layer's chunks (GLAY, TILS, APOS, GATT), framed, and each one's payload bytes.
fn layer_chunks(layer: &Layer, tiles: &TileTable, coded: &CodedTiles) -> (Vec<u8>, [usize; 4]) {
    let glay = layer.to_payload();
    let tils = tiles.to_payload();
    let mut apos_payload = vec![METHOD_CODED];
    apos_payload.extend(join_bodies(&coded.apos));
    let mut gatt_payload = vec![METHOD_CODED];
    gatt_payload.extend(join_bodies(&coded.gatt));
    let mut chunks = Vec::new();
    write_chunk(&mut chunks, ChunkTag::GLAY, &glay);
    write_chunk(&mut chunks, ChunkTag::TILS, &tils);
    write_chunk(&mut chunks, ChunkTag::APOS, &apos_payload);
    write_chunk(&mut chunks, ChunkTag::GATT, &gatt_payload);
    let bytes = [glay, tils, apos_payload, gatt_payload].map(|p| p.len());
    (chunks, bytes)
}
