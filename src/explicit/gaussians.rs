//! Standard 3DGS Gaussians: what an explicit-profile stream decodes to (spec §3.6), laid out
//! as the Inria PLY stores them (Annex C.3).

/// A set of standard 3DGS Gaussians (Kerbl et al. 2023), stored as the Inria PLY stores them
/// (Annex C.3): activations are applied by the renderer, not here.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Gaussians {
    /// Means in world space.
    pub positions: Vec<[f32; 3]>,
    /// Spherical-harmonics degree, 0 … 3.
    pub sh_degree: u8,
    /// SH band-0 coefficient per colour channel (`f_dc_0..2`).
    pub f_dc: Vec<[f32; 3]>,
    /// The higher SH coefficients, `3·B` per Gaussian with `B = (degree + 1)² − 1`,
    /// channel-major as the PLY's `f_rest_{c·B + k}`.
    pub f_rest: Vec<f32>,
    /// Opacity as a logit (the renderer applies the sigmoid).
    pub opacity_logit: Vec<f32>,
    /// Natural logarithm of the three axis scales.
    pub log_scales: Vec<[f32; 3]>,
    /// Rotation quaternion (w, x, y, z), not necessarily of unit length.
    pub rotations: Vec<[f32; 4]>,
}

impl Gaussians {
    /// No Gaussians yet, with room for `n` of SH degree `sh_degree`.
    pub fn with_capacity(sh_degree: u8, n: usize) -> Gaussians {
        Gaussians {
            positions: Vec::with_capacity(n),
            sh_degree,
            f_dc: Vec::with_capacity(n),
            f_rest: Vec::with_capacity(n * 3 * rest_per_channel(sh_degree)),
            opacity_logit: Vec::with_capacity(n),
            log_scales: Vec::with_capacity(n),
            rotations: Vec::with_capacity(n),
        }
    }

    /// Moves `other`'s Gaussians (of the same SH degree) after these.
    pub fn append(&mut self, mut other: Gaussians) {
        self.positions.append(&mut other.positions);
        self.f_dc.append(&mut other.f_dc);
        self.f_rest.append(&mut other.f_rest);
        self.opacity_logit.append(&mut other.opacity_logit);
        self.log_scales.append(&mut other.log_scales);
        self.rotations.append(&mut other.rotations);
    }

    /// Number of Gaussians.
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// B: higher SH coefficients per colour channel, `(degree + 1)² − 1`.
    pub fn rest_per_channel(&self) -> usize {
        rest_per_channel(self.sh_degree)
    }
}

/// B of SH degree `d`: `(d + 1)² − 1` (0, 3, 8, 15 for degrees 0 … 3).
pub fn rest_per_channel(degree: u8) -> usize {
    let d = usize::from(degree);
    (d + 1) * (d + 1) - 1
}
