//! A scene for the hyperprior's unit tests, built here rather than by the generator crate
//! (which depends on this one): HAC's grid dimensions, a pseudo-random ±1 hash grid, random
//! voxels and a random integer context MLP of the right shape.

use super::grid::GridLayout;
use super::mlp::IntMlp;
use crate::model::{Dims, GroupQuantizer, HashGrid, LatticeKind};

/// splitmix64: enough randomness for tests, and the same on every platform.
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Rng {
        Rng(seed)
    }

    pub fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in `lo..=hi`.
    pub fn range(&mut self, lo: i64, hi: i64) -> i64 {
        lo + (self.next() % (hi - lo + 1) as u64) as i64
    }
}

/// Test dimensions with these grid levels (`log2`: the 3D and 2D table sizes) and HAC's
/// attribute widths.
pub fn dims(
    anchors: u32,
    grid_channels: u8,
    res_3d: Vec<u16>,
    res_2d: Vec<u16>,
    (log2_size_3d, log2_size_2d): (u8, u8),
) -> Dims {
    Dims {
        anchors,
        feat_dim: 50,
        offsets: 10,
        scaling_dim: 6,
        rates: 1,
        grid_channels,
        res_3d,
        res_2d,
        log2_size_3d,
        log2_size_2d,
        context_hidden: 32,
        scaffold_hidden: 50,
        view_dims: 3,
        feat_lattice: LatticeKind::Identity,
        scaling_lattice: LatticeKind::Identity,
        feat_regions: 1,
        scaling_regions: 1,
    }
}

/// A hash grid of `d`'s shape with pseudo-random ±1 values.
pub fn random_grid(rng: &mut Rng, d: &Dims) -> HashGrid {
    let c = usize::from(d.grid_channels);
    let mut plane = |n: u64| -> Vec<i8> {
        (0..n as usize * c)
            .map(|_| if rng.next() & 1 == 1 { 1 } else { -1 })
            .collect()
    };
    HashGrid {
        grid_3d: plane(d.entries_3d()),
        grid_xy: plane(d.entries_2d()),
        grid_xz: plane(d.entries_2d()),
        grid_yz: plane(d.entries_2d()),
    }
}

pub struct TestScene {
    pub dims: Dims,
    pub coord_bits: u8,
    pub grid: HashGrid,
    pub voxels: Vec<[u32; 3]>,
    pub quant: GroupQuantizer,
}

impl TestScene {
    /// `anchors` random voxels in a 2^coord_bits cube, HAC's grid levels.
    pub fn new(anchors: u32, seed: u64) -> TestScene {
        let dims = dims(
            anchors,
            2,
            vec![12, 25, 50, 100, 200, 400],
            vec![12, 25, 50, 100, 200, 400, 800],
            (13, 15),
        );
        let mut rng = Rng::new(seed);
        let grid = random_grid(&mut rng, &dims);
        let coord_bits = 12;
        let voxels = (0..anchors)
            .map(|_| [0; 3].map(|_: u32| rng.range(0, (1 << coord_bits) - 1) as u32))
            .collect();
        let quant = GroupQuantizer {
            step: 1.0,
            gains: vec![1.0],
            basis: None,
            regions: Vec::new(),
        };
        TestScene {
            dims,
            coord_bits,
            grid,
            voxels,
            quant,
        }
    }

    /// A random context MLP with the shape §5.3 reads: the grid's features in, the three
    /// groups' means and scales out.
    pub fn mlp(&self, seed: u64) -> IntMlp {
        let mut rng = Rng::new(seed);
        let cin = GridLayout::new(&self.dims, self.coord_bits).features();
        let hidden = usize::from(self.dims.context_hidden);
        let (f, s, k3) = (
            usize::from(self.dims.feat_dim),
            usize::from(self.dims.scaling_dim),
            3 * usize::from(self.dims.offsets),
        );
        let cout = 2 * (f + s + k3);
        let mut v16 =
            |n: usize, m: i64| -> Vec<i16> { (0..n).map(|_| rng.range(-m, m) as i16).collect() };
        let (w0, w1) = (v16(hidden * cin, 2000), v16(cout * hidden, 2000));
        let mut rng = Rng::new(seed ^ 1);
        IntMlp {
            cin,
            hidden,
            cout,
            w0,
            b0: (0..hidden)
                .map(|_| rng.range(-1 << 16, 1 << 16) as i32)
                .collect(),
            w0_frac_bits: 12,
            shift0: 12,
            w1,
            b1: (0..cout)
                .map(|_| rng.range(-1 << 10, 1 << 10) as i32)
                .collect(),
            w1_frac_bits: (0..cout).map(|_| rng.range(8, 14) as u8).collect(),
        }
    }
}
