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

    /// `n` Gaussians of SH degree `sh_degree`, every value +0, to be written in place
    /// ([`Gaussians::as_mut`], [`GaussiansMut::split_at`]). The buffers come zeroed from the allocator, so their pages
    /// are first touched by whichever thread writes them.
    pub fn zeroed(sh_degree: u8, n: usize) -> Gaussians {
        Gaussians {
            positions: vec![[0.0; 3]; n],
            sh_degree,
            f_dc: vec![[0.0; 3]; n],
            f_rest: vec![0.0; n * 3 * rest_per_channel(sh_degree)],
            opacity_logit: vec![0.0; n],
            log_scales: vec![[0.0; 3]; n],
            rotations: vec![[0.0; 4]; n],
        }
    }

    /// Every Gaussian, as one view to write in place.
    pub fn as_mut(&mut self) -> GaussiansMut<'_> {
        GaussiansMut {
            positions: &mut self.positions,
            rest_per_gaussian: 3 * rest_per_channel(self.sh_degree),
            f_dc: &mut self.f_dc,
            f_rest: &mut self.f_rest,
            opacity_logit: &mut self.opacity_logit,
            log_scales: &mut self.log_scales,
            rotations: &mut self.rotations,
        }
    }

    /// `n` more Gaussians, every value +0, as a view to write in place.
    pub fn extend_zeroed(&mut self, n: usize) -> GaussiansMut<'_> {
        let from = self.len();
        let rest = 3 * rest_per_channel(self.sh_degree);
        self.positions.resize(from + n, [0.0; 3]);
        self.f_dc.resize(from + n, [0.0; 3]);
        self.f_rest.resize((from + n) * rest, 0.0);
        self.opacity_logit.resize(from + n, 0.0);
        self.log_scales.resize(from + n, [0.0; 3]);
        self.rotations.resize(from + n, [0.0; 4]);
        self.as_mut().split_at(from).1
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

/// `n` Gaussians' fields as disjoint mutable slices (of a [`Gaussians`] made with
/// [`Gaussians::zeroed`]), so that tiles decoded on different threads write their Gaussians
/// straight into the output.
#[derive(Debug)]
pub struct GaussiansMut<'a> {
    /// [`Gaussians::positions`].
    pub positions: &'a mut [[f32; 3]],
    /// `3·B` (see [`Gaussians::f_rest`]).
    pub rest_per_gaussian: usize,
    /// [`Gaussians::f_dc`].
    pub f_dc: &'a mut [[f32; 3]],
    /// [`Gaussians::f_rest`].
    pub f_rest: &'a mut [f32],
    /// [`Gaussians::opacity_logit`].
    pub opacity_logit: &'a mut [f32],
    /// [`Gaussians::log_scales`].
    pub log_scales: &'a mut [[f32; 3]],
    /// [`Gaussians::rotations`].
    pub rotations: &'a mut [[f32; 4]],
}

impl<'a> GaussiansMut<'a> {
    /// Number of Gaussians.
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// The first `n` Gaussians and the rest (`n` ≤ [`Self::len`]).
    pub fn split_at(self, n: usize) -> (GaussiansMut<'a>, GaussiansMut<'a>) {
        let (positions, p) = self.positions.split_at_mut(n);
        let (f_dc, d) = self.f_dc.split_at_mut(n);
        let (f_rest, r) = self.f_rest.split_at_mut(n * self.rest_per_gaussian);
        let (opacity_logit, o) = self.opacity_logit.split_at_mut(n);
        let (log_scales, s) = self.log_scales.split_at_mut(n);
        let (rotations, q) = self.rotations.split_at_mut(n);
        let rest_per_gaussian = self.rest_per_gaussian;
        (
            GaussiansMut {
                positions,
                rest_per_gaussian,
                f_dc,
                f_rest,
                opacity_logit,
                log_scales,
                rotations,
            },
            GaussiansMut {
                positions: p,
                rest_per_gaussian,
                f_dc: d,
                f_rest: r,
                opacity_logit: o,
                log_scales: s,
                rotations: q,
            },
        )
    }
}
