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
