//! The reference encoder's tiles (spec §10.3.1, informative): octree cells cut to a cap,
//! the default cap for a scene's size, and the default cut balanced for 2 threads.

use salvq_bitstream::model::morton3;
use salvq_bitstream::tiles::{bounding_box, enclosing_cell, part_plan, TileTable};

/// The reference encoder's largest tile (anchors per tile) when none is asked for.
pub const DEFAULT_TILE_ANCHORS: u32 = 16_384;

/// Tiles the reference encoder aims for in a scene too small to fill them at
/// [`DEFAULT_TILE_ANCHORS`].
pub const AUTO_TILES: u32 = 8;

/// The smallest tile [`auto_tile_anchors`] chooses.
pub const MIN_AUTO_TILE_ANCHORS: u32 = 2_048;

/// The reference encoder's tile size for a scene of `n` anchors (or Gaussians) when none is
/// asked for (informative, §10): `n / AUTO_TILES` rounded up, within
/// [`MIN_AUTO_TILE_ANCHORS`] … [`DEFAULT_TILE_ANCHORS`]. A scene below 8 · 16 384 would
/// otherwise be one or a few tiles and decode on one thread; smaller tiles cost bytes (each
/// restarts the octree and its contexts: 0.1 … 0.9 % of the real scenes' rate-0 streams at
/// 2 048 … 4 096 against 16 384, measured with `salvq encode --tile-anchors N`), so the floor
/// keeps a tile's cost small.
pub fn auto_tile_anchors(n: usize) -> u32 {
    let per = n.div_ceil(AUTO_TILES as usize);
    u32::try_from(per)
        .unwrap_or(u32::MAX)
        .clamp(MIN_AUTO_TILE_ANCHORS, DEFAULT_TILE_ANCHORS)
}

/// The smallest tile [`cut_auto`] goes down to when the tiles of
/// [`auto_tile_anchors`] leave 2 threads unevenly loaded.
pub const MIN_BALANCED_TILE_ANCHORS: u32 = 1_024;

/// The share of the anchors, as a fraction `NUM / DEN`, that the busier of 2 threads may
/// decode for [`cut_auto`] to call a cut balanced.
const BALANCED_SHARE: (u64, u64) = (13, 25);

/// The reference encoder's tiles when none are asked for (informative, §10.3):
/// [`cut`] at [`auto_tile_anchors`]; where that leaves the busier of 2 threads
/// (each taking the largest tile left, as the reference decoder does) more than 52 % of
/// the anchors, the cut at the largest cap, in steps of 7/8 down to
/// [`MIN_BALANCED_TILE_ANCHORS`], that does not. fruit_drops' 4 721 Gaussians cut at 2 048
/// were tiles of 1 382, 1 357 and 1 982 (58 % on one thread); at 1 568 they are 1 382,
/// 1 357, 946 and 1 036 (51 %). A scene of at most 2 048 stays one tile.
pub fn cut_auto(voxels: &[[u32; 3]]) -> TileTable {
    let mut per = auto_tile_anchors(voxels.len());
    let first = cut(voxels, per);
    if voxels.len() <= MIN_AUTO_TILE_ANCHORS as usize || balanced_on_two(&first) {
        return first;
    }
    while per > MIN_BALANCED_TILE_ANCHORS {
        per = (per / 8 * 7).max(MIN_BALANCED_TILE_ANCHORS);
        let table = cut(voxels, per);
        if balanced_on_two(&table) {
            return table;
        }
    }
    first
}

/// Whether the busier of 2 threads, each taking the largest tile left (§10.3.2's plan),
/// decodes at most [`BALANCED_SHARE`] of the anchors.
fn balanced_on_two(table: &TileTable) -> bool {
    let counts: Vec<u32> = (0..table.len())
        .map(|t| table.range(t).len() as u32)
        .collect();
    let mut load = [0u64; 2];
    for (t, part) in part_plan(&counts, &vec![true; counts.len()], 2)
        .into_iter()
        .enumerate()
    {
        load[part.unwrap_or(0) as usize & 1] += u64::from(counts[t]);
    }
    let (num, den) = BALANCED_SHARE;
    load[0].max(load[1]) * den <= num * u64::from(table.anchors)
}

/// The reference encoder's tiles over canonical `voxels` (informative, §10.3): octree
/// cells, split from the whole cube down until a cell holds at most `per_tile` anchors
/// (or is a single voxel), then consecutive sibling cells (same size, same parent)
/// merged while the run holds at most `per_tile` anchors. Each tile is a contiguous
/// Morton run (as §10 requires) inside one cell of twice its cells' size, so a region
/// selects few tiles.
pub fn cut(voxels: &[[u32; 3]], per_tile: u32) -> TileTable {
    let n = voxels.len() as u32;
    let per = per_tile.max(1) as usize;
    let codes: Vec<u64> = voxels.iter().map(|v| morton3(*v)).collect();
    // Cells as (first anchor, end, level): `level` = log2 of the cell's side.
    let mut cells: Vec<(usize, usize, u32)> = Vec::new();
    let mut stack = vec![(0usize, codes.len(), 21u32)];
    while let Some((a, b, level)) = stack.pop() {
        if b - a <= per || level == 0 {
            cells.push((a, b, level));
            continue;
        }
        // Children of the cell in Morton order: split on the 3 bits below `level`.
        let shift = 3 * (level - 1);
        let mut bounds = [a; 9];
        for (c, bound) in bounds.iter_mut().enumerate().skip(1) {
            let base = codes[a] >> (shift + 3) << (shift + 3);
            let limit = base + ((c as u64) << shift);
            *bound = a + codes[a..b].partition_point(|&m| m < limit);
        }
        bounds[8] = b;
        for c in (0..8).rev() {
            if bounds[c + 1] > bounds[c] {
                stack.push((bounds[c], bounds[c + 1], level - 1));
            }
        }
    }
    cells.sort_unstable();
    let mut starts: Vec<u32> = Vec::new();
    // Merge consecutive sibling cells (same level, same parent) while the run holds at
    // most `per_tile` anchors.
    let mut run: Option<(usize, usize, u32)> = None;
    for (a, b, level) in cells {
        let sibling = |ra: usize, rl: u32| {
            rl == level
                && level < 21
                && codes[ra] >> (3 * (level + 1)) == codes[a] >> (3 * (level + 1))
        };
        match run {
            Some((ra, _, rl)) if b - ra <= per && sibling(ra, rl) => run = Some((ra, b, rl)),
            _ => {
                if let Some((ra, _, _)) = run {
                    starts.push(ra as u32);
                }
                run = Some((a, b, level));
            }
        }
    }
    if let Some((ra, _, _)) = run {
        starts.push(ra as u32);
    }
    if starts.is_empty() {
        starts.push(0);
    }
    let mut table = TileTable {
        starts,
        cells: Vec::new(),
        boxes: Vec::new(),
        anchors: n,
    };
    table.boxes = (0..table.len())
        .map(|t| bounding_box(&voxels[table.range(t)]))
        .collect();
    table.cells = (0..table.len())
        .map(|t| {
            let r = table.range(t);
            enclosing_cell(voxels[r.start], voxels[r.end - 1])
        })
        .collect();
    table
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two dense clusters along a line, 3 000 and 1 500 voxels: cut at 2 048 (the automatic
    /// cap for 4 500) they make tiles that leave one of 2 threads more than 52 %; the
    /// automatic cut goes lower until they do not, and a scene of 2 048 stays one tile.
    #[test]
    fn automatic_tiles_balance_two_threads() {
        let cluster = |x0: u32, n: u32| (0..n).map(move |i| [x0 + i % 16, i / 16 % 16, i / 256]);
        let mut voxels: Vec<[u32; 3]> = cluster(0, 3_000).chain(cluster(1 << 12, 1_500)).collect();
        voxels.sort_by_key(|v| morton3(*v));
        let share = |t: &TileTable| {
            let counts: Vec<u32> = (0..t.len()).map(|i| t.range(i).len() as u32).collect();
            let plan = part_plan(&counts, &vec![true; t.len()], 2);
            let on_0: u32 = (0..t.len())
                .filter(|&i| plan[i] == Some(0))
                .map(|i| counts[i])
                .sum();
            f64::from(on_0.max(4_500 - on_0)) / 4_500.0
        };
        let fixed = cut(&voxels, auto_tile_anchors(voxels.len()));
        assert!(share(&fixed) > 0.52, "{}", share(&fixed));
        let auto = cut_auto(&voxels);
        assert!(share(&auto) <= 0.52, "{}", share(&auto));
        assert!(auto.len() > fixed.len());
        assert_eq!(auto.starts[0], 0);
        assert!(auto.starts.windows(2).all(|w| w[0] < w[1]));
        assert_eq!(cut_auto(&voxels[..2_048]).len(), 1);
    }
}
