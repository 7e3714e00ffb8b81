//! Synthetic explicit 3DGS scenes (Annex B.6, informative): Gaussians on a few spheres with
//! clustered sizes, anisotropic scales, random rotations (unnormalised, as trained files hold
//! them), smooth colours and decaying SH bands. For tests, conformance vectors, fuzz seeds
//! and scaling benches — never for compression claims, which use real scenes.

use salvq_render::{rest_per_channel, Gaussians};

use super::rng::Stream;

/// Stream tag of this generator (Annex B.1's seeding).
const TAG: u64 = 0x6761_7573_7331;

/// What to generate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GaussianParams {
    pub count: usize,
    pub sh_degree: u8,
    pub seed: u64,
    /// Put every Gaussian at the same position (a degenerate scene).
    pub one_point: bool,
}

impl GaussianParams {
    pub fn new(count: usize, sh_degree: u8, seed: u64) -> Self {
        GaussianParams {
            count,
            sh_degree,
            seed,
            one_point: false,
        }
    }
}

/// Generates the scene `p` asks for (deterministic in `p`).
pub fn generate_gaussians(p: &GaussianParams) -> Gaussians {
    let b = rest_per_channel(p.sh_degree);
    let mut g = Gaussians {
        sh_degree: p.sh_degree,
        ..Gaussians::default()
    };
    let spheres: Vec<([f64; 3], f64)> = (0..3)
        .map(|k| {
            let mut r = Stream::new(p.seed, TAG, 1_000_000 + k);
            (
                [r.range(-1.0, 1.0), r.range(-1.0, 1.0), r.range(-0.5, 0.5)],
                r.range(0.2, 0.6),
            )
        })
        .collect();
    for i in 0..p.count {
        let mut r = Stream::new(p.seed, TAG, i as u64);
        let (c, radius) = spheres[r.below(3) as usize];
        let d = r.unit3();
        let pos: [f64; 3] = if p.one_point {
            [0.25, -0.5, 0.125]
        } else {
            std::array::from_fn(|a| c[a] + radius * d[a] * (1.0 + 0.02 * r.normal()))
        };
        g.positions.push(pos.map(|v| v as f32));
        // Sizes cluster around a few levels, one axis often thinner (surfels).
        let level = -6.0 + 1.5 * r.below(3) as f64;
        let thin = if r.uniform() < 0.5 { -2.0 } else { 0.0 };
        g.log_scales.push([
            (level + 0.3 * r.normal()) as f32,
            (level + 0.3 * r.normal()) as f32,
            (level + thin + 0.3 * r.normal()) as f32,
        ]);
        g.opacity_logit.push((1.5 * r.normal() + 1.0) as f32);
        let q = [r.normal(), r.normal(), r.normal(), r.normal()];
        let scale = r.range(0.6, 2.0);
        g.rotations.push(q.map(|v| (v * scale) as f32));
        // Colour varies smoothly over the sphere.
        let dc: [f32; 3] = std::array::from_fn(|ch| (0.8 * d[ch] + 0.1 * r.normal()) as f32);
        g.f_dc.push(dc);
        for dc in d {
            for k in 0..b {
                let band = ((k + 1) as f64).sqrt().floor();
                let v = 0.15 / band * r.normal() + 0.05 * dc;
                g.f_rest.push(v as f32);
            }
        }
    }
    g
}
