//! §5.2: the grid entries some anchor touches (a corner of its cell on some level). `GRID`
//! codes those entries only, so the set is known before the grid is read.

use crate::par::*;

use super::grid::GridLayout;
use super::simd::FastGrid;

impl GridLayout {
    /// §5.2: which entries of each grid tensor (3D, xy, xz, yz) some anchor touches. The
    /// anchors are split among the threads and the sets merged: the result is the same for
    /// every thread count, and with or without this target's kernel (`FastGrid`).
    pub fn touched(&self, voxels: &[[u32; 3]], entries_3d: u64, entries_2d: u64) -> [Vec<bool>; 4] {
        let empty = || {
            [
                vec![false; entries_3d as usize],
                vec![false; entries_2d as usize],
                vec![false; entries_2d as usize],
                vec![false; entries_2d as usize],
            ]
        };
        let kernel = FastGrid::new(self);
        let mark = |voxels: &[[u32; 3]]| {
            let mut t = empty();
            match &kernel {
                Some(k) => k.mark_touched(self, voxels, &mut t),
                None => self.mark_touched(voxels, &mut t),
            }
            t
        };
        // One part per thread (each part costs a set of flags), but small inputs stay whole.
        let part = voxels.len().div_ceil(current_num_threads()).max(16_384);
        voxels
            .par_chunks(part.max(1))
            .map(mark)
            .reduce_with(|mut a, b| {
                for (x, y) in a.iter_mut().zip(b) {
                    for (p, q) in x.iter_mut().zip(y) {
                        *p |= q;
                    }
                }
                a
            })
            .unwrap_or_else(empty)
    }
}
