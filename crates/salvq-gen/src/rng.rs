//! Counter-based random streams (Annex B.1).
//!
//! Every random quantity is drawn from a *stream* named by `(seed, tag, index)`. A stream is the
//! SplitMix64 sequence started at a key derived by hashing the name, so any stream can be opened
//! on any thread in any order: anchor `a`'s attributes come from stream `(seed, ANCHOR, a)` with `a`
//! its index in the final Morton order, and parallel generation gives the same bytes as serial.
//!
//! ```text
//! mix(z):  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9
//!          z = (z ^ (z >> 27)) * 0x94D049BB133111EB
//!          return z ^ (z >> 31)                              (all arithmetic mod 2^64)
//! key(seed, tag, index) = mix(mix(mix(seed) ^ tag) ^ index)
//! draw k (k = 1, 2, 3, ...) = mix(key + k * 0x9E3779B97F4A7C15)
//! ```

use super::detmath;

/// The SplitMix64 increment (2^64 / golden ratio).
pub const GOLDEN: u64 = 0x9E37_79B9_7F4A_7C15;

/// Stream tags (Annex B.1, Table B-1). The index's meaning depends on the tag.
pub mod tag {
    /// Scene layout: primitive counts, shapes, poses (index 0) and the density field (index 1).
    pub const SCENE: u64 = 1;
    /// Surface samples for the voxel-size estimate (index = sample).
    pub const AREA_PROBE: u64 = 2;
    /// Floater voxels (index = attempt).
    pub const FLOATER: u64 = 3;
    /// Surface samples (index = attempt * 2^40 + sample).
    pub const SAMPLE: u64 = 4;
    /// Hash-grid values (index 0: grid_3d, 1: xy, 2: xz, 3: yz).
    pub const GRID: u64 = 5;
    /// Context MLP weights (index = part, see `prior.rs`).
    pub const CONTEXT_MLP: u64 = 6;
    /// Scaffold-GS MLPs (index 0: opacity, 1: cov, 2: color).
    pub const SCAFFOLD_MLP: u64 = 7;
    /// Quantizers (index 0: feat, 1: scaling, 2: offsets).
    pub const QUANT: u64 = 8;
    /// Per-anchor attributes (index = anchor in Morton order).
    pub const ANCHOR: u64 = 9;
}

/// The SplitMix64 output function.
pub fn mix(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// 2^-53.
const TWO_M53: f64 = 1.0 / 9_007_199_254_740_992.0;

/// One random stream: a key and a draw counter, plus the spare normal of Box-Muller.
#[derive(Debug, Clone)]
pub struct Stream {
    key: u64,
    counter: u64,
    spare: Option<f64>,
}

impl Stream {
    /// Opens stream `(seed, tag, index)` at its first draw.
    pub fn new(seed: u64, tag: u64, index: u64) -> Self {
        Stream {
            key: mix(mix(mix(seed) ^ tag) ^ index),
            counter: 0,
            spare: None,
        }
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.counter = self.counter.wrapping_add(1);
        mix(self.key.wrapping_add(self.counter.wrapping_mul(GOLDEN)))
    }

    /// Uniform on [0, 1): the top 53 bits times 2^-53.
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * TWO_M53
    }

    /// Uniform on (0, 1): (top 53 bits + 1/2) times 2^-53.
    pub fn open01(&mut self) -> f64 {
        ((self.next_u64() >> 11) as f64 + 0.5) * TWO_M53
    }

    /// Uniform on [lo, hi).
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.uniform()
    }

    /// Uniform integer in [0, n) (n >= 1): the high 64 bits of draw * n.
    pub fn below(&mut self, n: u64) -> u64 {
        ((u128::from(self.next_u64()) * u128::from(n)) >> 64) as u64
    }

    /// Standard normal by Box-Muller: u1 = open01(), u2 = uniform(),
    /// r = sqrt(-2 ln u1); returns r cos(2 pi u2) and keeps r sin(2 pi u2) for the next call.
    pub fn normal(&mut self) -> f64 {
        if let Some(z) = self.spare.take() {
            return z;
        }
        let u1 = self.open01();
        let u2 = self.uniform();
        let r = (-2.0 * detmath::ln(u1)).sqrt();
        let (s, c) = detmath::sincos_turns(u2);
        self.spare = Some(r * s);
        r * c
    }

    /// A uniformly random unit vector (three normals, normalised; +z if they are all ~0).
    pub fn unit3(&mut self) -> [f64; 3] {
        let v = [self.normal(), self.normal(), self.normal()];
        let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        if n < 1e-12 {
            [0.0, 0.0, 1.0]
        } else {
            [v[0] / n, v[1] / n, v[2] / n]
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn splitmix_reference_values() {
        // SplitMix64 seeded with 0 yields 0xE220A8397B1DCDAF first (Vigna's reference code).
        let mut s = Stream {
            key: 0,
            counter: 0,
            spare: None,
        };
        assert_eq!(s.next_u64(), 0xE220_A839_7B1D_CDAF);
        assert_eq!(s.next_u64(), 0x6E78_9E6A_A1B9_65F4);
    }

    #[test]
    fn streams_are_independent_of_opening_order() {
        let a: Vec<u64> = (0..4)
            .map(|_| Stream::new(7, tag::ANCHOR, 3).next_u64())
            .collect();
        assert!(a.windows(2).all(|w| w[0] == w[1]));
        assert_ne!(
            Stream::new(7, tag::ANCHOR, 3).next_u64(),
            Stream::new(7, tag::ANCHOR, 4).next_u64()
        );
    }

    #[test]
    fn normals_have_unit_variance() {
        let mut s = Stream::new(1, tag::ANCHOR, 0);
        let n = 200_000;
        let (mut m1, mut m2) = (0.0, 0.0);
        for _ in 0..n {
            let z = s.normal();
            m1 += z;
            m2 += z * z;
        }
        let mean = m1 / f64::from(n);
        let var = m2 / f64::from(n) - mean * mean;
        assert!(
            mean.abs() < 0.01 && (var - 1.0).abs() < 0.01,
            "{mean} {var}"
        );
    }
}
