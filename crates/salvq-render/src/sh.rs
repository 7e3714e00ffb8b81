//! Spherical-harmonics colour, degree 0 … 3 (spec Annex C.4), as 3DGS evaluates it:
//! `computeColorFromSH` in diff-gaussian-rasterization's `cuda_rasterizer/forward.cu`
//! (Kerbl et al. 2023), with the real SH basis constants of `utils/sh_utils.py`.

/// Band 0: `1 / (2 √π)`.
pub const C0: f32 = 0.282_094_8;
/// Band 1.
pub const C1: f32 = 0.488_602_5;
/// Band 2.
pub const C2: [f32; 5] = [
    1.092_548_4,
    -1.092_548_4,
    0.315_391_57,
    -1.092_548_4,
    0.546_274_2,
];
/// Band 3.
pub const C3: [f32; 7] = [
    -0.590_043_6,
    2.890_611_4,
    -0.457_045_8,
    0.373_176_33,
    -0.457_045_8,
    1.445_305_7,
    -0.590_043_6,
];

/// The colour of one Gaussian seen along unit direction `dir` (from the camera centre to the
/// Gaussian): `Σ c_lm Y_lm(dir) + 0.5`, clamped at 0 as 3DGS clamps (no upper clamp).
///
/// `dc` is band 0; `rest` holds `3·B` coefficients channel-major (`rest[c·B + k]` is
/// coefficient `k + 1` of channel `c`), `B = (degree + 1)² − 1`.
pub fn colour(degree: u8, dc: [f32; 3], rest: &[f32], dir: [f32; 3]) -> [f32; 3] {
    let b = super::rest_per_channel(degree);
    let [x, y, z] = dir;
    let (xx, yy, zz) = (x * x, y * y, z * z);
    let (xy, yz, xz) = (x * y, y * z, x * z);
    // Basis values for coefficients 1 … 15, in 3DGS's order.
    let basis: [f32; 15] = [
        -C1 * y,
        C1 * z,
        -C1 * x,
        C2[0] * xy,
        C2[1] * yz,
        C2[2] * (2.0 * zz - xx - yy),
        C2[3] * xz,
        C2[4] * (xx - yy),
        C3[0] * y * (3.0 * xx - yy),
        C3[1] * xy * z,
        C3[2] * y * (4.0 * zz - xx - yy),
        C3[3] * z * (2.0 * zz - 3.0 * xx - 3.0 * yy),
        C3[4] * x * (4.0 * zz - xx - yy),
        C3[5] * z * (xx - yy),
        C3[6] * x * (xx - 3.0 * yy),
    ];
    let mut out = [0f32; 3];
    for (c, o) in out.iter_mut().enumerate() {
        let coefficients = &rest[c * b..(c + 1) * b];
        let higher: f32 = coefficients.iter().zip(&basis).map(|(k, y)| k * y).sum();
        *o = (C0 * dc[c] + higher + 0.5).max(0.0);
    }
    out
}

/// The SH band-0 coefficient whose colour is `rgb` (the inverse of degree-0 [`colour`]
/// without the clamp): `(rgb − 0.5) / C0`, as 3DGS's `RGB2SH`.
pub fn rgb_to_dc(rgb: [f32; 3]) -> [f32; 3] {
    rgb.map(|v| (v - 0.5) / C0)
}
