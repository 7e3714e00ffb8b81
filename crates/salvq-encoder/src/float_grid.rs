//! The hash grid's interpolation at voxel centres in binary64 (Annex B.4.2), indexed exactly
//! as the spec's hyperprior (§5) indexes it: the float reference the encoder fits the
//! context MLP against, and the generator's scene builder.

use salvq_bitstream::hyperprior::grid::{index2, index3, levels, Level};
use salvq_bitstream::model::{Dims, HashGrid};

/// Interpolation of the hash grid at voxel centres (Annex B.4.2).
#[derive(Debug, Clone)]
pub struct Interp {
    l3: Vec<Level>,
    l2: Vec<Level>,
    c: usize,
    scale: f64,
}

impl Interp {
    /// The interpolation for a scene of dimensions `d` on a `2^coord_bits` voxel grid.
    pub fn new(d: &Dims, coord_bits: u8) -> Self {
        Interp {
            l3: levels(&d.res_3d, 3, d.log2_size_3d),
            l2: levels(&d.res_2d, 2, d.log2_size_2d),
            c: d.grid_channels.into(),
            scale: 1.0 / (1u64 << coord_bits) as f64,
        }
    }

    /// Context features of voxel `v`: [3D levels, xy, xz, yz levels], C channels each.
    pub fn features(&self, g: &HashGrid, v: [u32; 3], out: &mut [f64]) {
        out.fill(0.0);
        let c = self.c;
        let p = v.map(|x| (f64::from(x) + 0.5) * self.scale);
        let corner = |q: f64, r: u32| {
            let x = q * f64::from(r);
            let i = x.floor();
            (i as u32, x - i)
        };
        for (l, lv) in self.l3.iter().enumerate() {
            let [(i, wx), (j, wy), (k, wz)] = p.map(|q| corner(q, lv.res));
            let o = &mut out[l * c..(l + 1) * c];
            for n in 0..8u32 {
                let (dx, dy, dz) = (n & 1, (n >> 1) & 1, n >> 2);
                let w = (if dx == 1 { wx } else { 1.0 - wx })
                    * (if dy == 1 { wy } else { 1.0 - wy })
                    * (if dz == 1 { wz } else { 1.0 - wz });
                let (a, b, cc) = (i + dx, j + dy, k + dz);
                let e = index3(lv, a, b, cc) as usize;
                let e = &g.grid_3d[e * c..(e + 1) * c];
                for (acc, &val) in o.iter_mut().zip(e) {
                    *acc += w * f64::from(val);
                }
            }
        }
        let base = self.l3.len() * c;
        let planes: [(&[i8], usize, usize); 3] =
            [(&g.grid_xy, 0, 1), (&g.grid_xz, 0, 2), (&g.grid_yz, 1, 2)];
        for (pi, (tensor, ax, ay)) in planes.iter().enumerate() {
            for (l, lv) in self.l2.iter().enumerate() {
                let (i, wx) = corner(p[*ax], lv.res);
                let (j, wy) = corner(p[*ay], lv.res);
                let start = base + (pi * self.l2.len() + l) * c;
                let o = &mut out[start..start + c];
                for n in 0..4u32 {
                    let (dx, dy) = (n & 1, n >> 1);
                    let w = (if dx == 1 { wx } else { 1.0 - wx })
                        * (if dy == 1 { wy } else { 1.0 - wy });
                    let (a, b) = (i + dx, j + dy);
                    let e = index2(lv, a, b) as usize;
                    let e = &tensor[e * c..(e + 1) * c];
                    for (acc, &val) in o.iter_mut().zip(e) {
                        *acc += w * f64::from(val);
                    }
                }
            }
        }
    }
}
