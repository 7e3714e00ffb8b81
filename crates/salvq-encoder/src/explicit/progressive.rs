//! Refinement layers of a progressive stream (spec §3.8, Annex A.8.3): a finer rate coded
//! as a refinement of the layer before it. The factors are the finer plan's steps measured
//! against the present ones; the prior (reference level, prediction per group, tables and
//! per-class offsets) is fitted to the exact coded cost, as for a full layer.

use std::ops::Range;

use rustc_hash::FxHashMap;

use super::grid::group_coordinates_at;
use super::layer::{CodedLayer, LayerReport, LayerState};
use super::plan::RatePlan;
use super::prepare::PreparedGaussians;
use super::prior::{entropy_bits, fit_prior, BitCost, Histograms, PRED_LEVEL_CANDIDATES};
use super::writer::{rest_count_freq, Writer};
use crate::error::Result;
use salvq_bitstream::container::chunk::{write_chunk, ChunkTag};
use salvq_bitstream::container::payload::METHOD_CODED;
use salvq_bitstream::entropy::GaussianTables;
use salvq_bitstream::explicit::attributes::{rest_count_of, BitEvent, Events, TileSymbols};
use salvq_bitstream::explicit::groups::{Group, GroupKind};
use salvq_bitstream::explicit::layer::{
    rest_count_nodes, rest_values, CONTEXT_CLASSES, MAX_POSITION_BITS, SIZE_CLASSES,
};
use salvq_bitstream::explicit::reconstruct::reconstruct_tile_into;
use salvq_bitstream::explicit::refinement::{refine_walk, Precision, Refinement, MAX_FACTOR};
use salvq_bitstream::explicit::Gaussians;
use salvq_bitstream::tiles::join_bodies;

/// The factor that takes a step `from` nearest (in ratio) to `to`: an odd integer, so that
/// the finer cells nest in the coarser one (§3.8), 1 where `to` is not finer.
pub fn step_factor(from: f64, to: f64) -> u8 {
    let ratio = from / to;
    if !(ratio.is_finite() && ratio > 1.0) {
        return 1;
    }
    (1..=MAX_FACTOR)
        .step_by(2)
        .min_by(|&a, &b| {
            let miss = |m: u8| (f64::from(m).ln() - ratio.ln()).abs();
            miss(a).total_cmp(&miss(b))
        })
        .unwrap_or(1)
}

/// The step `plan` gives group `gi` in size class `c`.
fn plan_step(plan: &RatePlan, gi: usize, c: usize) -> f64 {
    let shift = if gi == 0 { 0 } else { plan.shift[gi - 1][c] };
    plan.steps[gi] * f64::from(shift).exp2()
}

/// Records a refinement's residuals by value, context class and size class: the walk is
/// run with `scale_table[v][x] = x` and no offsets, so the scale index it asks with is the
/// context class.
struct Recorder<'a> {
    coords: &'a [i32],
    extra: &'a [[u32; 3]],
    classes: &'a [u8],
    values: usize,
    histograms: &'a mut Histograms,
    counts: &'a mut Vec<u64>,
    rest_count: usize,
}

impl Events for Recorder<'_> {
    fn bit(&mut self, _: u32, i: usize, what: BitEvent) -> salvq::Result<bool> {
        Ok(match what {
            BitEvent::Refine { axis, bit } => self.extra[i][axis] >> bit & 1 == 1,
            BitEvent::RestCount { bit } => self.rest_count >> bit & 1 == 1,
            BitEvent::RotationHigh | BitEvent::RotationLow => false,
        })
    }
    fn symbol(&mut self, k: u8, i: usize, v: usize, pred: i64) -> salvq::Result<i64> {
        let r = i64::from(self.coords[i * self.values + v]) - pred;
        let key = (r.unsigned_abs(), self.classes[i]);
        *self.histograms[v][usize::from(k)].entry(key).or_default() += 1;
        Ok(r)
    }
    fn rest_predictions(&mut self, i: usize, first: usize, pred: impl Fn(usize) -> i64) {
        let row = &self.coords[i * self.values + first..(i + 1) * self.values];
        self.rest_count = rest_count_of(row, pred);
        if self.counts.len() <= self.rest_count {
            self.counts.resize(self.rest_count + 1, 0);
        }
        self.counts[self.rest_count] += 1;
    }
}

/// What a refinement starts from and goes to.
struct Target<'a> {
    state: &'a LayerState,
    groups: &'a [Group],
    coords: &'a [i32],
    extra: &'a [[u32; 3]],
    values: usize,
}

impl Target<'_> {
    /// The tile's symbols before the refinement, to be refined in place.
    fn tile_before(&self, range: Range<usize>) -> TileSymbols {
        let s = self.state;
        TileSymbols {
            coords: s.coords[range.start * self.values..range.end * self.values].to_vec(),
            rotation_index: s.rotation[range.clone()].to_vec(),
            size_class: s.size_class[range.clone()].to_vec(),
            refinement: s.refinement[range].to_vec(),
        }
    }

    /// The writer of the Gaussians `range` (a tile).
    fn writer<'t>(&self, tables: &'t GaussianTables, range: Range<usize>) -> Writer<'_, 't> {
        Writer::new(
            ChunkTag::GRSY,
            tables,
            &self.coords[range.start * self.values..range.end * self.values],
            &self.state.rotation[range.clone()],
            &self.extra[range],
            self.values,
        )
    }

    /// Every Gaussian's `sh_rest` count under `r`, in walk order: what GREF's tree
    /// probabilities are fitted to.
    fn rest_counts(&self, r: &Refinement, tables: &GaussianTables) -> Result<Vec<usize>> {
        let tiles = &self.state.tiles;
        let mut counts = Vec::with_capacity(self.state.size_class.len());
        for t in 0..tiles.len() {
            let range = tiles.range(t);
            let mut w = self.writer(tables, range.clone());
            let mut tile = self.tile_before(range.clone());
            let voxels = &self.state.grid.voxels[range];
            refine_walk(r, self.groups, voxels, &mut w, &mut tile.as_mut())?;
            counts.extend(w.rest_counts);
        }
        Ok(counts)
    }

    /// Every tile's `GRSY` body under `r`, and the Gaussians a decoder reconstructs at
    /// `after`, the precision `r` refines to.
    fn code_tiles(
        &self,
        r: &Refinement,
        after: &Precision,
        origin: [f32; 3],
        tables: &GaussianTables,
        sh_degree: u8,
    ) -> Result<(Vec<Vec<u8>>, Gaussians)> {
        let (groups, grid, tiles) = (self.groups, &self.state.grid, &self.state.tiles);
        let values = self.values;
        let matrices: Vec<_> = groups.iter().map(Group::matrix).collect();
        let mut expected = Gaussians {
            sh_degree,
            ..Gaussians::default()
        };
        let mut bodies = Vec::with_capacity(tiles.len());
        for t in 0..tiles.len() {
            let range = tiles.range(t);
            let voxels = &grid.voxels[range.clone()];
            let mut w = self.writer(tables, range.clone());
            let mut tile = self.tile_before(range.clone());
            refine_walk(r, groups, voxels, &mut w, &mut tile.as_mut())?;
            debug_assert_eq!(
                tile.coords,
                self.coords[range.start * values..range.end * values]
            );
            bodies.push(w.out.finish());
            let out = expected.extend_zeroed(range.len());
            let (size, s) = (grid.voxel_size, tile.as_ref());
            reconstruct_tile_into(origin, size, after, groups, &matrices, voxels, s, out);
        }
        Ok((bodies, expected))
    }

    /// The residual histograms of every value (`[value][context class]`) and the `sh_rest`
    /// counts' histogram under `r` (whose tables are ignored).
    fn histograms(&self, r: &Refinement) -> Result<(Histograms, Vec<u64>)> {
        let mut probe = r.clone();
        probe.scale_table = vec![std::array::from_fn(|x| x as u8); self.values];
        probe.scale_offset = vec![[0; SIZE_CLASSES]; self.groups.len()];
        let mut h: Histograms = vec![vec![FxHashMap::default(); CONTEXT_CLASSES]; self.values];
        let mut counts = Vec::new();
        let tiles = &self.state.tiles;
        for t in 0..tiles.len() {
            let range = tiles.range(t);
            let mut before = self.tile_before(range.clone());
            let mut rec = Recorder {
                coords: &self.coords[range.start * self.values..range.end * self.values],
                extra: &self.extra[range.clone()],
                classes: &self.state.size_class[range.clone()],
                values: self.values,
                histograms: &mut h,
                counts: &mut counts,
                rest_count: 0,
            };
            let voxels = &self.state.grid.voxels[range];
            refine_walk(&probe, self.groups, voxels, &mut rec, &mut before.as_mut())?;
        }
        Ok((h, counts))
    }
}

/// Codes the refinement of `state` (a decoded layer of `p`) to `plan`, the plan of `rate`
/// (Annex A.8.3): its chunks (`GREF`, `GRSY`), the Gaussians it decodes to, and the state
/// after it.
#[allow(clippy::too_many_arguments)]
pub fn encode_refinement(
    p: &PreparedGaussians,
    groups: &[Group],
    state: &LayerState,
    plan: &RatePlan,
    origin: [f32; 3],
    rate: u8,
    tables: &GaussianTables,
) -> Result<CodedLayer> {
    let values: usize = groups.iter().map(|g| g.dim).sum();
    let grid = &state.grid;
    let mut refinement = start_refinement(groups, state, plan, values);
    let after = state.precision.refined(&refinement);
    let (extra, cumulative) = refined_positions(p, state, &refinement.refine, origin);
    let coords = refined_coordinates(p, groups, state, &refinement.factor, &after, values);
    let target = Target {
        state,
        groups,
        coords: &coords,
        extra: &extra,
        values,
    };
    let mut group_bits = fit_refinement_prior(&target, &mut refinement)?;

    // The counts' tree, then the symbols per tile and the Gaussians they decode to.
    if let Some(gi) = groups.iter().position(|g| g.kind == GroupKind::Rest) {
        let counts = target.rest_counts(&refinement, tables)?;
        let (freq, bits) = rest_count_freq(&counts, groups[gi].dim);
        refinement.rest_count_freq = freq;
        group_bits[gi] += bits;
    }
    let (bodies, expected) = target.code_tiles(&refinement, &after, origin, tables, p.sh_degree)?;
    let gref = refinement.to_payload();
    let mut grsy = vec![METHOD_CODED];
    grsy.extend(join_bodies(&bodies));
    let mut chunks = Vec::new();
    write_chunk(&mut chunks, ChunkTag::GREF, &gref);
    write_chunk(&mut chunks, ChunkTag::GRSY, &grsy);
    let refine_bits = state
        .size_class
        .iter()
        .map(|&c| 3.0 * f64::from(refinement.refine[usize::from(c)]))
        .sum();
    Ok(CodedLayer {
        chunks,
        expected,
        report: LayerReport {
            rate,
            coord_bits: grid.coord_bits,
            voxel_size: grid.voxel_size,
            pred_level: refinement.pred_level,
            refine: after.refine,
            glay_bytes: gref.len(),
            tils_bytes: 0,
            apos_bytes: 0,
            gatt_bytes: grsy.len(),
            group_bits,
            refine_bits,
            predict: refinement.predict.clone(),
            tiles: state.tiles.len(),
        },
        state: LayerState {
            grid: grid.clone(),
            tiles: state.tiles.clone(),
            coords,
            size_class: state.size_class.clone(),
            refinement: cumulative,
            rotation: state.rotation.clone(),
            precision: after,
        },
    })
}

/// The refinement of `state` to `plan` before its prior is fitted: the position bits (the
/// plan's fine edge per class, below the grid's voxel) and each group's step factors.
fn start_refinement(
    groups: &[Group],
    state: &LayerState,
    plan: &RatePlan,
    values: usize,
) -> Refinement {
    let (grid, before) = (&state.grid, &state.precision);
    let refine: [u8; SIZE_CLASSES] = std::array::from_fn(|c| {
        let h = plan.voxel * (-f64::from(plan.refine[c])).exp2();
        let total = (f64::from(grid.voxel_size) / h).log2().round();
        let most = MAX_POSITION_BITS.saturating_sub(grid.coord_bits + before.refine[c]);
        (total - f64::from(before.refine[c])).clamp(0.0, f64::from(most)) as u8
    });
    let factor: Vec<[u8; SIZE_CLASSES]> = (0..groups.len())
        .map(|gi| {
            std::array::from_fn(|c| {
                step_factor(f64::from(before.delta[gi][c]), plan_step(plan, gi, c))
            })
        })
        .collect();
    Refinement {
        pred_level: grid.coord_bits,
        refine,
        factor,
        scale_offset: vec![[0; SIZE_CLASSES]; groups.len()],
        predict: vec![false; groups.len()],
        rest_count_freq: vec![1 << 15; rest_count_nodes(rest_values(groups.len(), values))],
        scale_table: vec![[0; CONTEXT_CLASSES]; values],
    }
}

/// The new position bits of each Gaussian, `refine[class]` per axis nested in its old
/// cell, and its position bits below the voxel after them.
fn refined_positions(
    p: &PreparedGaussians,
    state: &LayerState,
    refine: &[u8; SIZE_CLASSES],
    origin: [f32; 3],
) -> (Vec<[u32; 3]>, Vec<[u32; 3]>) {
    let (grid, before) = (&state.grid, &state.precision);
    let n = state.size_class.len();
    let mut extra = Vec::with_capacity(n);
    let mut cumulative = Vec::with_capacity(n);
    for k in 0..n {
        let c = usize::from(state.size_class[k]);
        let (e_old, e) = (before.refine[c], refine[c]);
        let h = f64::from(grid.voxel_size) / f64::from(1u32 << (e_old + e));
        let q = p.positions[grid.order[k]];
        let w_old = state.refinement[k];
        let w: [u32; 3] = std::array::from_fn(|a| {
            let v = u64::from(grid.voxels[k][a]) << (e_old + e);
            let fine = ((q[a] - f64::from(origin[a])) / h).floor().max(0.0) as u64;
            let lo = v + (u64::from(w_old[a]) << e);
            (fine.clamp(lo, lo + (1u64 << e) - 1) - v) as u32
        });
        extra.push(std::array::from_fn(|a| w[a] - (w_old[a] << e)));
        cumulative.push(w);
    }
    (extra, cumulative)
}

/// The coordinates after the refinement (`values` per Gaussian): recomputed at the refined
/// steps where a class's factor is above 1, kept elsewhere.
fn refined_coordinates(
    p: &PreparedGaussians,
    groups: &[Group],
    state: &LayerState,
    factor: &[[u8; SIZE_CLASSES]],
    after: &Precision,
    values: usize,
) -> Vec<i32> {
    let n = state.size_class.len();
    let mut coords = state.coords.clone();
    let mut at = 0;
    for (gi, g) in groups.iter().enumerate() {
        if factor[gi].iter().any(|&f| f > 1) {
            let step = |k: usize| after.delta[gi][usize::from(state.size_class[k])];
            let c = group_coordinates_at(&p.values[gi], g, &step, &state.grid.order);
            for k in 0..n {
                let class = usize::from(state.size_class[k]);
                if factor[gi][class] > 1 {
                    let row = &mut coords[k * values + at..k * values + at + g.dim];
                    row.copy_from_slice(&c[k * g.dim..(k + 1) * g.dim]);
                }
            }
        }
        at += g.dim;
    }
    coords
}

/// The refinement's prior fitted to `target` by exact cost (Annex A.8.3): for each
/// reference level, each group with and without prediction; the cheapest wins, and its
/// tables and per-class offsets are then fitted together.
fn fit_refinement_prior(target: &Target, r: &mut Refinement) -> Result<Vec<f64>> {
    let cost = BitCost::standard();
    let groups = target.groups;
    let ranges: Vec<std::ops::Range<usize>> = groups
        .iter()
        .scan(0, |at, g| {
            *at += g.dim;
            Some(*at - g.dim..*at)
        })
        .collect();
    // Start offsets: the factor's step ratio in scale indices (8 per octave, §6.3.1).
    let start = |gi: usize| -> [i8; SIZE_CLASSES] {
        r.factor[gi].map(|f| -(f64::from(f).log2().round() as i8))
    };
    let group_cost = |h: &Histograms, counts: &[u64], gi: usize, offsets: bool| {
        let hg: Histograms = h[ranges[gi].clone()].to_vec();
        let fit = fit_prior(&hg, cost, false, start(gi), offsets);
        let count_bits = match groups[gi].kind {
            GroupKind::Rest => entropy_bits(counts),
            _ => 0.0,
        };
        (fit, count_bits)
    };
    let coord_bits = target.state.grid.coord_bits;
    let mut best: Option<(f64, u8, Vec<bool>)> = None;
    for offset in PRED_LEVEL_CANDIDATES {
        let Some(level) = coord_bits.checked_sub(offset) else {
            continue;
        };
        r.pred_level = level;
        let mut bits = Vec::new();
        for predict in [false, true] {
            r.predict = vec![predict; groups.len()];
            let (h, counts) = target.histograms(r)?;
            bits.push(
                (0..groups.len())
                    .map(|gi| {
                        let ((_, _, b), c) = group_cost(&h, &counts, gi, false);
                        b + c
                    })
                    .collect::<Vec<f64>>(),
            );
        }
        let predict: Vec<bool> = (0..groups.len())
            .map(|gi| bits[1][gi] < bits[0][gi])
            .collect();
        let total = (0..groups.len())
            .map(|gi| bits[usize::from(predict[gi])][gi])
            .sum();
        if best.as_ref().is_none_or(|b| total < b.0) {
            best = Some((total, level, predict));
        }
    }
    let (_, level, predict) = best.expect("pred_level candidates include coord_bits");
    r.pred_level = level;
    r.predict = predict;
    let (h, counts) = target.histograms(r)?;
    let mut bits = Vec::with_capacity(groups.len());
    for (gi, range) in ranges.iter().enumerate() {
        let ((rows, offsets, b), _) = group_cost(&h, &counts, gi, true);
        r.scale_table[range.clone()].copy_from_slice(&rows);
        r.scale_offset[gi] = offsets;
        bits.push(b);
    }
    Ok(bits)
}
