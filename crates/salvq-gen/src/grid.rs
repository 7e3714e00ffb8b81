//! The binary hash grid (Annex B.4.1); its interpolation at an anchor (B.4.2) is the
//! encoder's float reference, [`salvq_encoder::float_grid::Interp`].

pub use salvq_encoder::float_grid::Interp;

use super::rng::{tag, Stream};
use salvq_bitstream::model::{Dims, HashGrid};

/// i.i.d. balanced +-1 values: bit b of draw k of stream GRID/t gives entry value 64k + b.
pub fn grid(d: &Dims, seed: u64) -> HashGrid {
    let c = u64::from(d.grid_channels);
    let make = |t: u64, len: u64| -> Vec<i8> {
        let mut s = Stream::new(seed, tag::GRID, t);
        let mut out = Vec::with_capacity(len as usize);
        while (out.len() as u64) < len {
            let w = s.next_u64();
            let take = (len - out.len() as u64).min(64);
            out.extend((0..take).map(|b| if (w >> b) & 1 == 1 { 1i8 } else { -1i8 }));
        }
        out
    };
    HashGrid {
        grid_3d: make(0, d.entries_3d() * c),
        grid_xy: make(1, d.entries_2d() * c),
        grid_xz: make(2, d.entries_2d() * c),
        grid_yz: make(3, d.entries_2d() * c),
    }
}
