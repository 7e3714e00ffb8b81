//! The events of a layer or refinement (spec §3.5, §3.8) as the encoder answers them: the
//! symbols it knows, written to one ANS body per tile.

use crate::writers::SymbolWriter;
use salvq_bitstream::container::chunk::ChunkTag;
use salvq_bitstream::entropy::GaussianTables;
use salvq_bitstream::explicit::attributes::{rest_count_of, BitEvent, Events};
use salvq_bitstream::explicit::layer::{rest_count_bits, rest_count_nodes};

use super::prior::{bit_cost, freq};

/// Answers a tile's events from its coordinates, rotation indices and position bits, and
/// writes them.
pub(super) struct Writer<'a, 't> {
    pub(super) out: SymbolWriter<'t>,
    coords: &'a [i32],
    rotation: &'a [u8],
    refinement: &'a [[u32; 3]],
    values: usize,
    /// The `sh_rest` count of the Gaussian at hand (§3.5): its values up to the last nonzero
    /// symbol.
    rest_count: usize,
    /// Every Gaussian's `sh_rest` count, in walk order.
    pub(super) rest_counts: Vec<usize>,
}

impl<'a, 't> Writer<'a, 't> {
    pub(super) fn new(
        tag: ChunkTag,
        tables: &'t GaussianTables,
        coords: &'a [i32],
        rotation: &'a [u8],
        refinement: &'a [[u32; 3]],
        values: usize,
    ) -> Self {
        Writer {
            out: SymbolWriter::new(tag, tables),
            coords,
            rotation,
            refinement,
            values,
            rest_count: 0,
            rest_counts: Vec::new(),
        }
    }
}

impl Events for Writer<'_, '_> {
    fn bit(&mut self, freq_one: u32, i: usize, what: BitEvent) -> salvq::Result<bool> {
        let bit = match what {
            BitEvent::RotationHigh => self.rotation[i] >> 1 == 1,
            BitEvent::RotationLow => self.rotation[i] & 1 == 1,
            BitEvent::Refine { axis, bit } => self.refinement[i][axis] >> bit & 1 == 1,
            BitEvent::RestCount { bit } => self.rest_count >> bit & 1 == 1,
        };
        self.out.bit(bit, freq_one);
        Ok(bit)
    }
    fn symbol(&mut self, k: u8, i: usize, v: usize, pred: i64) -> salvq::Result<i64> {
        let r = i64::from(self.coords[i * self.values + v]) - pred;
        self.out.symbol(r, k)?;
        Ok(r)
    }
    fn rest_predictions(&mut self, i: usize, first: usize, pred: impl Fn(usize) -> i64) {
        let row = &self.coords[i * self.values + first..(i + 1) * self.values];
        self.rest_count = rest_count_of(row, pred);
        self.rest_counts.push(self.rest_count);
    }
}

/// §3.4's `rest_count_freq` for `counts` (every Gaussian's `sh_rest` count) of a group of
/// `dim` values: each tree node's share of ones among the counts that pass it, and the cost
/// of coding them so, in bits.
pub(super) fn rest_count_freq(counts: &[usize], dim: usize) -> (Vec<u16>, f64) {
    let bits = rest_count_bits(dim);
    let nodes = rest_count_nodes(dim);
    let (mut ones, mut total) = (vec![0u64; nodes], vec![0u64; nodes]);
    for &n in counts {
        let mut node = 1usize;
        for bit in (0..bits).rev() {
            let b = n >> bit & 1;
            total[node - 1] += 1;
            ones[node - 1] += b as u64;
            node = 2 * node + b;
        }
    }
    let freq: Vec<u16> = ones.iter().zip(&total).map(|(&o, &t)| freq(o, t)).collect();
    let cost = (0..nodes)
        .map(|m| bit_cost(ones[m], total[m], freq[m]))
        .sum();
    (freq, cost)
}
