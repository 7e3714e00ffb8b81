//! The explicit profile's prior as the encoder fits it (spec §3.5, Annex A.8.3): residual
//! histograms under §3.5's reference, prediction and context rules, scale-table entries and
//! per-class offsets chosen by the exact cost of §6.4, and the bit counts the rate fit uses.

use rustc_hash::FxHashMap;

use salvq_bitstream::entropy::{GaussianTables, SCALE_INDEX_COUNT};
use salvq_bitstream::explicit::attributes::{context_class, has_reference, offset_scale, rescale};
use salvq_bitstream::explicit::layer::{CONTEXT_CLASSES, MAX_SCALE_OFFSET, SIZE_CLASSES};
use salvq_bitstream::tiles::TileTable;

/// `pred_level` candidates the encoder tries, as offsets below `coord_bits`.
pub(super) const PRED_LEVEL_CANDIDATES: [u8; 5] = [0, 2, 4, 6, 8];

/// Ideal bits of |r| = m under scale k, cached for small m: the mean of +m's and −m's (they
/// differ only under a wide scale, §6.3.6, whose high part is ⌊r / 2^b⌋).
pub struct BitCost {
    small: Vec<[f64; SCALE_INDEX_COUNT]>,
}

fn magnitude_bits(tables: &GaussianTables, k: u8, m: i64) -> f64 {
    0.5 * (tables.ideal_bits(k, m) + tables.ideal_bits(k, -m))
}

const SMALL: usize = 4096;

impl BitCost {
    /// Costs under `tables`.
    pub fn new(tables: &GaussianTables) -> Self {
        BitCost {
            small: (0..SMALL)
                .map(|m| std::array::from_fn(|k| magnitude_bits(tables, k as u8, m as i64)))
                .collect(),
        }
    }
    /// The costs under the format's tables, built once per process (about 15 ms): every
    /// layer the encoder codes or tries uses them.
    pub fn standard() -> &'static BitCost {
        static COST: std::sync::OnceLock<BitCost> = std::sync::OnceLock::new();
        COST.get_or_init(|| BitCost::new(GaussianTables::standard()))
    }
    fn bits(&self, k: u8, m: u64) -> f64 {
        match self.small.get(m as usize) {
            Some(r) => r[usize::from(k)],
            None => magnitude_bits(GaussianTables::standard(), k, m as i64),
        }
    }
}

/// Per (value, context class), how often each (|residual|, size class) occurs.
pub(super) type Histograms = Vec<Vec<FxHashMap<(u64, u8), u64>>>;

/// The residual histograms of one group (values `[at, at + dim)` of `coords`, `values` per
/// Gaussian, each Gaussian with its size class and the group's step shift) under §3.5's
/// reference, prediction, rescaling and context rules.
#[allow(clippy::too_many_arguments)]
pub(super) fn group_histograms(
    coords: &[i32],
    values: usize,
    at: usize,
    dim: usize,
    classes: &[u8],
    shifts: &[i8],
    voxels: &[[u32; 3]],
    tiles: &TileTable,
    pred_level: u8,
    predict: bool,
    mut counts: Option<&mut Vec<u64>>,
) -> Histograms {
    let mut h: Histograms = vec![vec![FxHashMap::default(); CONTEXT_CLASSES]; dim];
    let mut r_row = vec![0i64; dim];
    for t in 0..tiles.len() {
        let range = tiles.range(t);
        let vox = &voxels[range.clone()];
        let mut prev_r = vec![0i64; dim];
        for (li, i) in range.enumerate() {
            let reference = has_reference(vox, li, pred_level);
            let s = shifts[i];
            let s_prev = if i > 0 { shifts[i - 1] } else { 0 };
            for (j, r) in r_row.iter_mut().enumerate() {
                let u = i64::from(coords[i * values + at + j]);
                let pred = if reference && predict {
                    rescale(i64::from(coords[(i - 1) * values + at + j]), s_prev, s)
                } else {
                    0
                };
                *r = u - pred;
            }
            // §3.5: a counted group (sh_rest) codes its values up to the last nonzero symbol.
            let coded = match counts.as_deref_mut() {
                Some(counts) => {
                    let n = r_row.iter().rposition(|&r| r != 0).map_or(0, |j| j + 1);
                    counts.resize(counts.len().max(dim + 1), 0);
                    counts[n] += 1;
                    n
                }
                None => dim,
            };
            for (j, &r) in r_row.iter().enumerate().take(coded) {
                let c = context_class(reference, rescale(prev_r[j], s_prev, s));
                *h[j][c].entry((r.unsigned_abs(), classes[i])).or_default() += 1;
            }
            prev_r.copy_from_slice(&r_row);
        }
    }
    h
}

/// Bits of one histogram under table entry `k` with the size classes' `offsets`.
fn histogram_bits(
    hist: &FxHashMap<(u64, u8), u64>,
    k: u8,
    offsets: &[i8; SIZE_CLASSES],
    cost: &BitCost,
) -> f64 {
    hist.iter()
        .map(|(&(m, c), &count)| {
            count as f64 * cost.bits(offset_scale(k, offsets[usize::from(c)]), m)
        })
        .sum()
}

/// The best table entry of each (value, context class) under `offsets`, and the total ideal
/// bits; with `factorized`, one entry per value for every context (a position-free prior).
fn fit_tables(
    h: &Histograms,
    cost: &BitCost,
    factorized: bool,
    offsets: &[i8; SIZE_CLASSES],
) -> (Vec<[u8; CONTEXT_CLASSES]>, f64) {
    let mut total = 0.0;
    let merged: Histograms;
    let h = if factorized {
        merged = h
            .iter()
            .map(|classes| {
                let mut all: FxHashMap<(u64, u8), u64> = FxHashMap::default();
                for hist in classes {
                    for (&key, &count) in hist {
                        *all.entry(key).or_default() += count;
                    }
                }
                vec![all]
            })
            .collect();
        &merged
    } else {
        h
    };
    let rows = h
        .iter()
        .map(|contexts| {
            let mut row = [24u8; CONTEXT_CLASSES];
            for (c, hist) in contexts.iter().enumerate() {
                if hist.is_empty() {
                    continue;
                }
                let (k, b) = (0..SCALE_INDEX_COUNT as u8)
                    .map(|k| (k, histogram_bits(hist, k, offsets, cost)))
                    .fold((0, f64::INFINITY), |a, x| if x.1 < a.1 { x } else { a });
                row[c] = k;
                total += b;
            }
            if factorized {
                row = [row[0]; CONTEXT_CLASSES];
            }
            row
        })
        .collect();
    (rows, total)
}

/// The best offset of each size class given the table `rows`.
fn fit_offsets(
    h: &Histograms,
    rows: &[[u8; CONTEXT_CLASSES]],
    cost: &BitCost,
    start: [i8; SIZE_CLASSES],
) -> [i8; SIZE_CLASSES] {
    let mut out = start;
    for c in 0..SIZE_CLASSES as u8 {
        let bits = |o: i8| -> f64 {
            h.iter()
                .zip(rows)
                .flat_map(|(contexts, row)| {
                    contexts.iter().zip(row).map(move |(hist, &k)| (hist, k))
                })
                .map(|(hist, k)| {
                    hist.iter()
                        .filter(|((_, cc), _)| *cc == c)
                        .map(|(&(m, _), &count)| count as f64 * cost.bits(offset_scale(k, o), m))
                        .sum::<f64>()
                })
                .sum()
        };
        let (best, _) = (-MAX_SCALE_OFFSET..=MAX_SCALE_OFFSET)
            .map(|o| (o, bits(o)))
            .fold((out[usize::from(c)], f64::INFINITY), |a, x| {
                if x.1 < a.1 {
                    x
                } else {
                    a
                }
            });
        out[usize::from(c)] = best;
    }
    out
}

/// Tables and offsets fitted by alternation (each step can only lower the cost), from
/// offsets of `−8·shift` (the step ratio in scale indices, §6.3.1); without
/// `with_offsets`, the tables alone under those offsets (a cheaper estimate).
pub(super) fn fit_prior(
    h: &Histograms,
    cost: &BitCost,
    factorized: bool,
    shifts: [i8; SIZE_CLASSES],
    with_offsets: bool,
) -> (Vec<[u8; CONTEXT_CLASSES]>, [i8; SIZE_CLASSES], f64) {
    let mut offsets = shifts.map(|s| (-8 * i32::from(s)).clamp(-63, 63) as i8);
    let (mut rows, mut bits) = fit_tables(h, cost, factorized, &offsets);
    if with_offsets {
        for _ in 0..2 {
            offsets = fit_offsets(h, &rows, cost, offsets);
            (rows, bits) = fit_tables(h, cost, factorized, &offsets);
        }
    }
    (rows, offsets, bits)
}

/// Encoder variants the ablations compare (Annex A.8.4); the default is the reference
/// encoder.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Variant {
    /// A position-free prior: no prediction, one scale index per value for every context.
    pub factorized_prior: bool,
    /// One size class: no per-class refinement or step shifts.
    pub single_class: bool,
    /// Predict every group from its reference, whatever it costs (conformance vectors and
    /// tests that need `predict = 1` everywhere).
    pub predict_all: bool,
}

/// Ideal bits per Gaussian of one group's coordinates (`coords`, `dim` per Gaussian, all at
/// one step) on `voxels` cut by `tiles`, with the prediction and `pred_level` that cost
/// least: what [`super::layer::encode_layer`] pays for the group, its tables aside. A
/// `counted` group (`sh_rest`, §3.5) codes only each Gaussian's values up to its last nonzero
/// symbol, and pays for the counts (their order-0 entropy, which the count's tree reaches
/// with fitted probabilities).
#[allow(clippy::too_many_arguments)]
pub fn group_bits(
    coords: &[i32],
    dim: usize,
    voxels: &[[u32; 3]],
    coord_bits: u8,
    tiles: &TileTable,
    cost: &BitCost,
    variant: Variant,
    counted: bool,
) -> f64 {
    let shifts = vec![0i8; voxels.len()];
    let classes = vec![0u8; voxels.len()];
    let mut best = f64::INFINITY;
    for offset in PRED_LEVEL_CANDIDATES {
        let Some(level) = coord_bits.checked_sub(offset) else {
            continue;
        };
        for predict in [false, true] {
            if predict && variant.factorized_prior {
                continue;
            }
            let mut counts = Vec::new();
            let h = group_histograms(
                coords,
                dim,
                0,
                dim,
                &classes,
                &shifts,
                voxels,
                tiles,
                level,
                predict,
                counted.then_some(&mut counts),
            );
            let tables = fit_tables(&h, cost, variant.factorized_prior, &[0; SIZE_CLASSES]).1;
            best = best.min(tables + entropy_bits(&counts));
        }
    }
    best / voxels.len().max(1) as f64
}

/// The order-0 entropy of a histogram, in bits (all its items together).
pub(super) fn entropy_bits(histogram: &[u64]) -> f64 {
    let total: u64 = histogram.iter().sum();
    histogram
        .iter()
        .filter(|&&c| c > 0)
        .map(|&c| c as f64 * (total as f64 / c as f64).log2())
        .sum()
}

/// Q16 probability of a 1 from counts, clamped to 1 … 65535.
pub(super) fn freq(ones: u64, total: u64) -> u16 {
    if total == 0 {
        return 32768;
    }
    ((ones as f64 / total as f64 * 65536.0).round() as u64).clamp(1, 65535) as u16
}

pub(super) fn bit_cost(ones: u64, total: u64, f: u16) -> f64 {
    let p1 = f64::from(f) / 65536.0;
    -(ones as f64) * p1.log2() - (total - ones) as f64 * (1.0 - p1).log2()
}
