//! Anchor geometry as the encoder writes it (spec §8): the octree of canonical-order voxels,
//! walked by `salvq_bitstream::geometry::walk` with every event's answer known, so that the
//! encoder and the decoder evolve the contexts identically.

use rustc_hash::FxHashMap;
use salvq_bitstream::container::chunk::ChunkTag;
use salvq_bitstream::entropy::GaussianTables;
use salvq_bitstream::error::Result;
use salvq_bitstream::geometry::{octant_of, walk, DirectOctant, Event, Events};
use salvq_bitstream::model::morton3;

use super::symbols::SymbolWriter;

/// The encoder's answers: each depth's occupied cells, with the number of distinct voxels
/// below each (up to 2) and one of them; and each voxel's anchor count.
struct KnownVoxels {
    depth: u32,
    cells: Vec<FxHashMap<u64, (u8, [u32; 3])>>,
    runs: Vec<usize>,
}

impl KnownVoxels {
    fn below(&self, depth: u32, cell: [u32; 3]) -> Option<(u8, [u32; 3])> {
        self.cells[depth as usize].get(&morton3(cell)).copied()
    }
}

/// The encoder records every event as the intervals of its body.
struct Recorder<'w, 't> {
    known: KnownVoxels,
    writer: &'w mut SymbolWriter<'t>,
}

impl Events for Recorder<'_, '_> {
    fn bit(&mut self, freq_one: u32, what: Event) -> Result<bool> {
        let bit = match what {
            Event::Occupancy { depth, cell } => self.known.below(depth, cell).is_some(),
            Event::Direct { depth, cell } => {
                matches!(self.known.below(depth, cell), Some((1, _)))
            }
            Event::Count { leaf, extra } => {
                extra + 1 < self.known.runs.get(leaf).copied().unwrap_or(1)
            }
        };
        self.writer.bit(bit, freq_one);
        Ok(bit)
    }

    fn octant(&mut self, what: DirectOctant) -> Result<u32> {
        let (_, voxel) = self.known.below(what.depth, what.cell).unwrap_or_default();
        let value = octant_of(voxel, self.known.depth - what.level) as u32;
        self.writer.uniform(value, 3);
        Ok(value)
    }
}

/// §8.1: the `APOS` body of canonical-order voxels (coordinates below `2^depth`).
pub fn encode(voxels: &[[u32; 3]], depth: u8, tables: &GaussianTables) -> Result<Vec<u8>> {
    // The occupied cells of every depth with their distinct voxels, and each voxel's anchor
    // count (voxels are sorted, so equal ones are adjacent).
    let mut runs: Vec<usize> = Vec::new();
    for (i, v) in voxels.iter().enumerate() {
        match runs.last_mut() {
            Some(r) if voxels[i - 1] == *v => *r += 1,
            _ => runs.push(1),
        }
    }
    let cells = (0..=u32::from(depth))
        .map(|k| {
            let shift = u32::from(depth) - k;
            let mut at: FxHashMap<u64, (u8, [u32; 3])> = FxHashMap::default();
            for (i, v) in voxels.iter().enumerate() {
                if i > 0 && voxels[i - 1] == *v {
                    continue;
                }
                let e = at.entry(morton3(v.map(|c| c >> shift))).or_insert((0, *v));
                e.0 = (e.0 + 1).min(2);
            }
            at
        })
        .collect();
    let known = KnownVoxels {
        depth: u32::from(depth),
        cells,
        runs,
    };
    let mut writer = SymbolWriter::new(ChunkTag::APOS, tables);
    let mut recorder = Recorder {
        known,
        writer: &mut writer,
    };
    let decoded = walk(
        depth,
        voxels.len() as u32,
        tables.precision(),
        &mut recorder,
    )?;
    debug_assert_eq!(decoded, voxels);
    Ok(writer.finish())
}

/// The order-0 entropy, in bits, of the octree's occupancy bytes over distinct `voxels`
/// (coordinates below `2^depth`), each depth with its own byte histogram: the baseline the
/// contexts of §8.3 are measured against (informative; benches and tests).
pub fn order0_occupancy_bits(voxels: &[[u32; 3]], depth: u8) -> f64 {
    let mut total = 0.0;
    for k in 0..u32::from(depth) {
        let shift = u32::from(depth) - k - 1;
        let mut bytes: FxHashMap<u64, u8> = FxHashMap::default();
        for v in voxels {
            let c = v.map(|x| x >> shift);
            let i = (c[0] & 1) | ((c[1] & 1) << 1) | ((c[2] & 1) << 2);
            *bytes.entry(morton3(c.map(|x| x >> 1))).or_default() |= 1 << i;
        }
        let mut hist = [0u64; 256];
        for b in bytes.values() {
            hist[usize::from(*b)] += 1;
        }
        let n = bytes.len() as f64;
        total += hist
            .iter()
            .filter(|&&h| h > 0)
            .map(|&h| -(h as f64) * (h as f64 / n).log2())
            .sum::<f64>();
    }
    total
}
