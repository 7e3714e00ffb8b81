//! Anchor geometry (Annex B.3.3, B.3.4): the voxel size, then floaters and scene samples snapped
//! to the voxel grid until exactly N distinct voxels are occupied, in Morton order.

use std::collections::HashSet;
use std::hash::{BuildHasherDefault, Hasher};

use rayon::prelude::*;

use super::detmath::exp;
use super::linalg::fsum;
use super::rng::{mix, tag, Stream};
use super::scene::{Scene, BOX_MIN, BOX_SIZE, CLUSTER_EXTRA};
use salvq_bitstream::model::morton3;

/// Fraction of anchors that are floaters, uniform in the box (spec Annex B.3.4).
pub const FLOATER_FRACTION: f64 = 0.02;
/// Expected samples per surface voxel where the density is 1 when N is reached (tuned so that
/// NN distances and octree occupancy match the real Octree-GS anchors, Table B-2).
pub const DENSE_INTENSITY: f64 = 0.45;
/// Occupied voxels per unit surface area, in voxel^2 units (1.5 = mean over orientations of
/// |n_x| + |n_y| + |n_z|, raised slightly by the jitter).
pub const VOXELS_PER_AREA: f64 = 1.6;
/// Surface samples used to estimate the occupied area before sampling.
const AREA_PROBES: u64 = 4096;
/// Largest cell count per axis: coordinates fit in 21 bits (spec §1.4).
const MAX_CELLS: f64 = 2_097_151.0;

/// Hasher for voxel keys: one SplitMix64 mix (the set is never iterated, so order is irrelevant).
#[derive(Default)]
struct KeyHasher(u64);
impl Hasher for KeyHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = mix(self.0 ^ u64::from(b));
        }
    }
    fn write_u64(&mut self, x: u64) {
        self.0 = mix(x);
    }
}
type KeySet = HashSet<u64, BuildHasherDefault<KeyHasher>>;

fn key(v: [u64; 3]) -> u64 {
    v[0] | (v[1] << 21) | (v[2] << 42)
}
fn unkey(k: u64) -> [u32; 3] {
    let m = (1u64 << 21) - 1;
    [(k & m) as u32, ((k >> 21) & m) as u32, (k >> 42) as u32]
}

/// The generated geometry: voxels in Morton order, origin and voxel size.
pub struct Geometry {
    pub voxels: Vec<[u32; 3]>,
    pub origin: [f32; 3],
    pub voxel_size: f32,
}

/// Chooses the voxel size so that sampling reaches `n_surface` distinct voxels near intensity
/// DENSE_INTENSITY (Annex B.3.3): v^2 = VOXELS_PER_AREA * A * E / n with
/// E = mean over AREA_PROBES samples of accept * (1 - exp(-DENSE_INTENSITY w (1 + w CLUSTER_EXTRA / 2))).
fn voxel_size(seed: u64, n_surface: u64) -> f64 {
    let n = n_surface.max(1) as f64;
    let probe_scene = Scene::new(seed, 1.0);
    let v0 = (VOXELS_PER_AREA * probe_scene.area() * 0.3 / n).sqrt();
    let scene = Scene::new(seed, v0);
    let e = fsum((0..AREA_PROBES).map(|i| {
        let mut s = Stream::new(seed, tag::AREA_PROBE, i);
        scene.sample(&mut s, v0).map_or(0.0, |(_, _, w)| {
            // Points per voxel: accepted samples times the mean cluster size.
            1.0 - exp(-DENSE_INTENSITY * w * (1.0 + 0.5 * CLUSTER_EXTRA as f64 * w))
        })
    })) / AREA_PROBES as f64;
    (VOXELS_PER_AREA * scene.area() * e.max(1e-3) / n).sqrt()
}

/// Generates N distinct voxels (Annex B.3): floaters first, then surface samples in index order.
pub fn generate(seed: u64, n: u32) -> Geometry {
    let n_total = u64::from(n);
    let n_float = (n_total as f64 * FLOATER_FRACTION).floor() as u64;
    let n_surface = n_total - n_float;
    let min_voxel = BOX_SIZE / MAX_CELLS;
    let mut voxel = voxel_size(seed, n_surface).max(min_voxel);
    let mut keys: Vec<u64> = Vec::with_capacity(n as usize);
    for attempt in 0u64.. {
        let scene = Scene::new(seed, voxel);
        let cells = (BOX_SIZE / voxel).ceil().min(MAX_CELLS) as u64;
        let mut set = KeySet::with_capacity_and_hasher(n as usize, Default::default());
        keys.clear();
        // Floaters: uniform voxels of the box (stream FLOATER/attempt).
        let mut fs = Stream::new(seed, tag::FLOATER, attempt);
        let mut tries = 0u64;
        while (keys.len() as u64) < n_float && tries < 64 * n_float + 64 {
            tries += 1;
            let k = key([fs.below(cells), fs.below(cells), fs.below(cells)]);
            if set.insert(k) {
                keys.push(k);
            }
        }
        // Surface samples in batches computed in parallel, inserted in sample order.
        let expected = DENSE_INTENSITY * VOXELS_PER_AREA * scene.area() / (voxel * voxel);
        let budget = (6.0 * expected) as u64 + 8 * n_total + 4096;
        let batch = (n_total / 4).clamp(4096, 1 << 18);
        let mut next = 0u64;
        while (keys.len() as u64) < n_total && next < budget {
            let end = (next + batch).min(budget);
            let got: Vec<Vec<u64>> = (next..end)
                .into_par_iter()
                .map(|i| {
                    let mut s = Stream::new(seed, tag::SAMPLE, (attempt << 40) | i);
                    let mut pts = Vec::new();
                    if let Some((p, nrm, w)) = scene.sample(&mut s, voxel) {
                        if s.uniform() < w {
                            scene.cluster(&mut s, voxel, p, nrm, w, &mut pts);
                        }
                    }
                    pts.iter()
                        .map(|p| {
                            key(p.map(|x| {
                                (((x - BOX_MIN) / voxel).floor().max(0.0) as u64).min(cells - 1)
                            }))
                        })
                        .collect()
                })
                .collect();
            for k in got.into_iter().flatten() {
                if (keys.len() as u64) < n_total && set.insert(k) {
                    keys.push(k);
                }
            }
            next = end;
        }
        if keys.len() as u64 == n_total {
            break;
        }
        // The surfaces saturated: shrink the voxel and start again (attempt + 1).
        if voxel <= min_voxel || attempt >= 40 {
            // Unreachable for any N a u32 can hold; a deterministic scan of all 2^63 keys bounds the loop.
            let (mut t, m) = (0u64, (1u64 << 21) - 1);
            while (keys.len() as u64) < n_total {
                let k = key([t & m, (t >> 21) & m, (t >> 42) & m]);
                if set.insert(k) {
                    keys.push(k);
                }
                t += 1;
            }
            break;
        }
        voxel = (voxel * 0.8).max(min_voxel);
    }
    let mut voxels: Vec<[u32; 3]> = keys.into_iter().map(unkey).collect();
    let mut lo = [u32::MAX; 3];
    for v in &voxels {
        for a in 0..3 {
            lo[a] = lo[a].min(v[a]);
        }
    }
    for v in voxels.iter_mut() {
        for a in 0..3 {
            v[a] -= lo[a];
        }
    }
    voxels.par_sort_unstable_by_key(|&v| morton3(v));
    let voxel_size = voxel as f32;
    let origin = lo.map(|l| (BOX_MIN + (f64::from(l) + 0.5) * f64::from(voxel_size)) as f32);
    Geometry {
        voxels,
        origin,
        voxel_size,
    }
}
