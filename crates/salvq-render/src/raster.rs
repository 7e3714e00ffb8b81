//! A CPU preview rasterizer (spec Annex C.4): the forward pass of 3DGS's tile rasterizer
//! (Kerbl et al., SIGGRAPH 2023; `cuda_rasterizer/forward.cu` of graphdeco-inria's
//! diff-gaussian-rasterization), step for step:
//!
//! 1. `preprocessCUDA`: cull means with camera depth ≤ 0.2; 3D covariance `Σ = R S Sᵀ Rᵀ`
//!    from the normalised quaternion and `exp` of the log-scales; 2D covariance
//!    `J W Σ Wᵀ Jᵀ + 0.3 I` (EWA splatting, Zwicker et al. 2002) with the Jacobian evaluated
//!    at the mean clamped to 1.3× the field of view; its inverse (the conic); radius
//!    `ceil(3 √λ_max)`; the 16 × 16-pixel tiles the radius' square touches; colour from SH.
//! 2. Per tile, the Gaussians that touch it, sorted by depth (ties by index, as 3DGS's stable
//!    radix sort keeps them).
//! 3. `renderCUDA`: per pixel, front to back, `α = min(0.99, o · exp(power))`, skipped when
//!    below 1/255; compositing stops before the Gaussian that would take the transmittance
//!    below 10⁻⁴; the background fills what transmittance is left.
//!
//! Tiles render in parallel (rayon); the image does not depend on the thread count.

use rayon::prelude::*;

use super::camera::Camera;
use super::{sh, Gaussians, Image};

/// Tile side in pixels (3DGS `BLOCK_X`, `BLOCK_Y`).
pub const TILE: u32 = 16;
/// Means closer to the camera plane than this are culled (3DGS `in_frustum`).
pub const NEAR: f32 = 0.2;
/// Low-pass filter added to the 2D covariance's diagonal, pixels².
pub const LOW_PASS: f32 = 0.3;
/// Largest alpha of one Gaussian.
pub const MAX_ALPHA: f32 = 0.99;
/// Alphas below this are skipped.
pub const MIN_ALPHA: f32 = 1.0 / 255.0;
/// Compositing stops when the transmittance would fall below this.
pub const MIN_TRANSMITTANCE: f32 = 1e-4;

/// A Gaussian projected to the image.
#[derive(Debug, Clone, Copy)]
struct Splat {
    /// The Gaussian's index in the scene.
    index: u32,
    mean: [f32; 2],
    /// Inverse 2D covariance (a, b, c) of `[[a, b], [b, c]]`.
    conic: [f32; 3],
    opacity: f32,
    colour: [f32; 3],
    depth: f32,
    /// Pixels per scene unit at its depth (`f_x / z`).
    pixels_per_unit: f32,
    /// `power` below this gives `alpha < 1/255` for sure (with a margin for rounding).
    skip_below: f32,
    /// Half-extents in pixels of the ellipse `power ≥ skip_below` (plus a margin): pixels
    /// beyond them cannot be shaded by this Gaussian, so compositing does not visit them.
    reach: [f32; 2],
    /// Tiles touched: x in `tiles[0]..tiles[2]`, y in `tiles[1]..tiles[3]`.
    tiles: [u32; 4],
}

/// What a render drew.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct RenderStats {
    /// Gaussians that survived culling and touch at least one tile.
    pub splats: usize,
    /// (Gaussian, tile) pairs composited.
    pub tile_entries: usize,
}

/// Rotation matrix of the quaternion (w, x, y, z) after normalisation, as 3DGS's
/// `build_rotation` (a zero quaternion gives the identity).
fn rotation(q: [f32; 4]) -> [[f32; 3]; 3] {
    let n = (q.iter().map(|v| v * v).sum::<f32>()).sqrt().max(1e-12);
    let [r, x, y, z] = q.map(|v| v / n);
    [
        [
            1.0 - 2.0 * (y * y + z * z),
            2.0 * (x * y - r * z),
            2.0 * (x * z + r * y),
        ],
        [
            2.0 * (x * y + r * z),
            1.0 - 2.0 * (x * x + z * z),
            2.0 * (y * z - r * x),
        ],
        [
            2.0 * (x * z - r * y),
            2.0 * (y * z + r * x),
            1.0 - 2.0 * (x * x + y * y),
        ],
    ]
}

/// Step 1 for Gaussian `i` (3DGS `preprocessCUDA`); `None` when culled.
fn preprocess(g: &Gaussians, i: usize, cam: &Camera, grid: [u32; 2]) -> Option<Splat> {
    let p = g.positions[i];
    let t = cam.to_camera(p);
    // `!(z > NEAR)` rather than `z <= NEAR`: a NaN depth is culled too.
    if t[2].partial_cmp(&NEAR) != Some(std::cmp::Ordering::Greater) {
        return None;
    }
    // Σ = M Mᵀ with M = R S.
    let r = rotation(g.rotations[i]);
    let s = g.log_scales[i].map(f32::exp);
    let m: [[f32; 3]; 3] = std::array::from_fn(|a| std::array::from_fn(|b| r[a][b] * s[b]));
    let sigma: [[f32; 3]; 3] =
        std::array::from_fn(|a| std::array::from_fn(|b| (0..3).map(|k| m[a][k] * m[b][k]).sum()));
    // computeCov2D: J at the mean clamped to 1.3× the half field of view.
    let [tan_x, tan_y] = cam.tan_half_fov();
    let (lim_x, lim_y) = (1.3 * tan_x, 1.3 * tan_y);
    let tz = t[2];
    let tx = (t[0] / tz).clamp(-lim_x, lim_x) * tz;
    let ty = (t[1] / tz).clamp(-lim_y, lim_y) * tz;
    let j = [
        [cam.fx / tz, 0.0, -(cam.fx * tx) / (tz * tz)],
        [0.0, cam.fy / tz, -(cam.fy * ty) / (tz * tz)],
    ];
    // T = J W (2 × 3), cov = T Σ Tᵀ.
    let w = &cam.rotation;
    let tm: [[f32; 3]; 2] =
        std::array::from_fn(|a| std::array::from_fn(|b| (0..3).map(|k| j[a][k] * w[k][b]).sum()));
    let ts: [[f32; 3]; 2] = std::array::from_fn(|a| {
        std::array::from_fn(|b| (0..3).map(|k| tm[a][k] * sigma[k][b]).sum())
    });
    let cov = |a: usize, b: usize| -> f32 { (0..3).map(|k| ts[a][k] * tm[b][k]).sum() };
    let (ca, cb, cc) = (cov(0, 0) + LOW_PASS, cov(0, 1), cov(1, 1) + LOW_PASS);
    let det = ca * cc - cb * cb;
    if det == 0.0 {
        return None;
    }
    let conic = [cc / det, -cb / det, ca / det];
    let mid = 0.5 * (ca + cc);
    let spread = (mid * mid - det).max(0.1).sqrt();
    let radius = (3.0 * (mid + spread).max(mid - spread).sqrt()).ceil();
    // The projected mean, as the projection matrix and ndc2Pix place it.
    let mean = [
        cam.fx * t[0] / tz + 0.5 * (cam.width as f32 - 1.0),
        cam.fy * t[1] / tz + 0.5 * (cam.height as f32 - 1.0),
    ];
    let finite =
        radius.is_finite() && mean.iter().chain(&conic).all(|v| v.is_finite()) && tz.is_finite();
    if !finite {
        return None;
    }
    // getRect: C's float-to-int conversion truncates toward zero.
    let tile = |v: f32, n: u32| -> u32 { (v / TILE as f32).max(0.0).min(n as f32) as u32 };
    let tiles = [
        tile(mean[0] - radius, grid[0]),
        tile(mean[1] - radius, grid[1]),
        tile(mean[0] + radius + (TILE - 1) as f32, grid[0]),
        tile(mean[1] + radius + (TILE - 1) as f32, grid[1]),
    ];
    if tiles[2] <= tiles[0] || tiles[3] <= tiles[1] {
        return None;
    }
    let dir = {
        let d: [f32; 3] = std::array::from_fn(|a| p[a] - cam.position[a]);
        let n = d.iter().map(|v| v * v).sum::<f32>().sqrt();
        d.map(|v| v / n)
    };
    let b = g.rest_per_channel();
    let rest = g.f_rest.get(i * 3 * b..(i + 1) * 3 * b).unwrap_or(&[]);
    let colour = if rest.len() == 3 * b {
        sh::colour(g.sh_degree, g.f_dc[i], rest, dir)
    } else {
        sh::colour(0, g.f_dc[i], &[], dir)
    };
    let opacity = 1.0 / (1.0 + (-g.opacity_logit[i]).exp());
    if !colour.iter().all(|c| c.is_finite()) || !opacity.is_finite() {
        return None;
    }
    // alpha = min(0.99, o exp(power)) < 1/255 wherever power < ln(1 / (255 o)); 10⁻³ below
    // that bound, skipping cannot change any pixel. `power = −dᵀ Σ'⁻¹ d / 2 ≥ skip_below` is
    // the ellipse `dᵀ Σ'⁻¹ d ≤ k`, whose bounding box is `|d_x| ≤ √(k Σ'_00)`,
    // `|d_y| ≤ √(k Σ'_11)`.
    let skip_below = (MIN_ALPHA / opacity).ln() - 1e-3;
    let k = (-2.0 * skip_below).max(0.0);
    let reach = [ca, cc].map(|v| (k * v).sqrt() * 1.001 + 0.01);
    Some(Splat {
        index: i as u32,
        mean,
        conic,
        opacity,
        colour,
        depth: tz,
        pixels_per_unit: cam.fx / tz,
        skip_below,
        reach,
        tiles,
    })
}

/// Renders the Gaussians seen by `cam` over `background`.
pub fn render(g: &Gaussians, cam: &Camera, background: [f32; 3]) -> Image {
    render_with_stats(g, cam, background).0
}

/// Steps 1 and 2 for `cam`: the splats, and per 16 × 16 tile (row-major) the indices of the
/// splats touching it sorted front to back.
struct Binned {
    splats: Vec<Splat>,
    grid: [u32; 2],
    start: Vec<usize>,
    entries: Vec<u32>,
}

impl Binned {
    fn new(g: &Gaussians, cam: &Camera) -> Binned {
        let grid = [cam.width.div_ceil(TILE), cam.height.div_ceil(TILE)];
        let n = [
            g.positions.len(),
            g.f_dc.len(),
            g.opacity_logit.len(),
            g.log_scales.len(),
            g.rotations.len(),
        ]
        .into_iter()
        .min()
        .unwrap_or(0);
        let splats: Vec<Splat> = (0..n)
            .into_par_iter()
            .filter_map(|i| preprocess(g, i, cam, grid))
            .collect();
        // Bin (Gaussian, tile) pairs by tile, Gaussians in index order within a tile.
        let tiles = grid[0] as usize * grid[1] as usize;
        let mut start = vec![0usize; tiles + 1];
        for s in &splats {
            for ty in s.tiles[1]..s.tiles[3] {
                for tx in s.tiles[0]..s.tiles[2] {
                    start[ty as usize * grid[0] as usize + tx as usize + 1] += 1;
                }
            }
        }
        for t in 0..tiles {
            start[t + 1] += start[t];
        }
        let mut fill = start.clone();
        let mut entries = vec![0u32; start[tiles]];
        for (i, s) in splats.iter().enumerate() {
            for ty in s.tiles[1]..s.tiles[3] {
                for tx in s.tiles[0]..s.tiles[2] {
                    let t = ty as usize * grid[0] as usize + tx as usize;
                    entries[fill[t]] = i as u32;
                    fill[t] += 1;
                }
            }
        }
        let mut lists: Vec<&mut [u32]> = Vec::with_capacity(tiles);
        let mut rest = entries.as_mut_slice();
        for t in 0..tiles {
            let (list, tail) = rest.split_at_mut(start[t + 1] - start[t]);
            lists.push(list);
            rest = tail;
        }
        lists.into_par_iter().for_each(|list| {
            // Depths are > NEAR > 0, so their bit patterns sort as the numbers do.
            list.sort_unstable_by_key(|&i| (splats[i as usize].depth.to_bits(), i));
        });
        Binned {
            splats,
            grid,
            start,
            entries,
        }
    }

    /// Tile `t`'s list and its top-left pixel.
    fn tile(&self, t: usize) -> (&[u32], [u32; 2]) {
        let x0 = (t % self.grid[0] as usize) as u32 * TILE;
        let y0 = (t / self.grid[0] as usize) as u32 * TILE;
        (&self.entries[self.start[t]..self.start[t + 1]], [x0, y0])
    }
}

/// [`render`], and what it drew. Gaussians whose vectors are shorter than `positions` are
/// not drawn.
pub fn render_with_stats(
    g: &Gaussians,
    cam: &Camera,
    background: [f32; 3],
) -> (Image, RenderStats) {
    let (w, h) = (cam.width, cam.height);
    let binned = Binned::new(g, cam);
    let tiles = binned.start.len() - 1;
    // Step 3: composite each tile.
    let tile_pixels: Vec<Vec<f32>> = (0..tiles)
        .into_par_iter()
        .map(|t| {
            let (list, origin) = binned.tile(t);
            composite_tile(
                &binned.splats,
                list,
                origin,
                [w, h],
                background,
                &mut |_, _| {},
            )
        })
        .collect();

    let mut image = Image::filled(w, h, background);
    for (t, pixels) in tile_pixels.iter().enumerate() {
        let (_, [x0, y0]) = binned.tile(t);
        for dy in 0..TILE.min(h - y0) {
            for dx in 0..TILE.min(w - x0) {
                let src = 3 * (dy * TILE + dx) as usize;
                let dst = 3 * ((y0 + dy) as usize * w as usize + (x0 + dx) as usize);
                image.rgb[dst..dst + 3].copy_from_slice(&pixels[src..src + 3]);
            }
        }
    }
    let stats = RenderStats {
        splats: binned.splats.len(),
        tile_entries: binned.entries.len(),
    };
    (image, stats)
}

/// How much `cam`'s image depends on each Gaussian, to first order: sums over the pixels it
/// shades of its squared blending weight `(α·T)²`, after occlusion, each times a factor.
#[derive(Debug, Clone, Default)]
pub struct Sensitivities {
    /// `Σ (α·T)²`: a change `δ` of its RGB changes a pixel by `α·T·δ`.
    pub colour: Vec<f32>,
    /// `Σ (α·T)² · (f/z)² · tr(Σ'⁻¹)/2`: a move of its footprint's edge by `δ` (scene
    /// units: of its mean, or of an axis' end by a change of its scale or rotation) moves
    /// it by `δ·f/z` pixels, which changes a pixel by about `α·T` times that over the
    /// footprint's width (low-pass filter included).
    pub position: Vec<f32>,
    /// `Σ (α·T)² · (f/z)²`: over [`Sensitivities::colour`], the mean square of the pixels
    /// per scene unit at its depth, which says which of its axes the image resolves.
    pub magnification: Vec<f32>,
}

/// The [`Sensitivities`] of `g` in `cam`'s image. Gaussians not drawn weigh 0.
pub fn sensitivities(g: &Gaussians, cam: &Camera) -> Sensitivities {
    let binned = Binned::new(g, cam);
    let tiles = binned.start.len() - 1;
    let per_tile: Vec<Vec<(u32, f32)>> = (0..tiles)
        .into_par_iter()
        .map(|t| {
            let (list, origin) = binned.tile(t);
            let mut sums: Vec<(u32, f32)> = list.iter().map(|&i| (i, 0.0)).collect();
            composite_tile(
                &binned.splats,
                list,
                origin,
                [cam.width, cam.height],
                [0.0; 3],
                &mut |k, w| sums[k].1 += w * w,
            );
            sums
        })
        .collect();
    let n = g.positions.len();
    let mut out = Sensitivities {
        colour: vec![0.0; n],
        position: vec![0.0; n],
        magnification: vec![0.0; n],
    };
    for (i, w) in per_tile.into_iter().flatten() {
        let s = &binned.splats[i as usize];
        let at = s.index as usize;
        let inverse_width = 0.5 * (s.conic[0] + s.conic[2]);
        out.colour[at] += w;
        let squared = s.pixels_per_unit * s.pixels_per_unit;
        out.position[at] += w * squared * inverse_width;
        out.magnification[at] += w * squared;
    }
    out
}

/// `renderCUDA` for one tile: front-to-back alpha compositing of the depth-sorted `list`.
/// Returns TILE × TILE RGB values (pixels outside the image are left at 0); `weight` hears
/// each splat's blending weight `α·T` (with its place in `list`) at each pixel it shades.
fn composite_tile(
    splats: &[Splat],
    list: &[u32],
    origin: [u32; 2],
    size: [u32; 2],
    background: [f32; 3],
    weight: &mut dyn FnMut(usize, f32),
) -> Vec<f32> {
    const N: usize = (TILE * TILE) as usize;
    let mut transmittance = [1f32; N];
    let mut colour = [[0f32; 3]; N];
    let mut active = [false; N];
    let mut remaining = 0usize;
    for (p, a) in active.iter_mut().enumerate() {
        let (x, y) = (origin[0] + p as u32 % TILE, origin[1] + p as u32 / TILE);
        *a = x < size[0] && y < size[1];
        remaining += usize::from(*a);
    }
    for (k, &i) in list.iter().enumerate() {
        if remaining == 0 {
            break;
        }
        let s = &splats[i as usize];
        // The pixels of this tile within the Gaussian's reach (`Splat::reach`).
        let span = |a: usize| -> (u32, u32) {
            let lo = (s.mean[a] - s.reach[a]).ceil().max(origin[a] as f32);
            let hi = (s.mean[a] + s.reach[a])
                .floor()
                .min((origin[a] + TILE - 1) as f32);
            if lo > hi {
                (1, 0)
            } else {
                (lo as u32 - origin[a], hi as u32 - origin[a])
            }
        };
        let ((x_lo, x_hi), (y_lo, y_hi)) = (span(0), span(1));
        for (ty, tx) in (y_lo..=y_hi).flat_map(|y| (x_lo..=x_hi).map(move |x| (y, x))) {
            let p = (ty * TILE + tx) as usize;
            if !active[p] {
                continue;
            }
            // Pixel (x, y) samples the image point (x, y) (3DGS `pixf`).
            let dx = s.mean[0] - (origin[0] + tx) as f32;
            let dy = s.mean[1] - (origin[1] + ty) as f32;
            let power = -0.5 * (s.conic[0] * dx * dx + s.conic[2] * dy * dy) - s.conic[1] * dx * dy;
            if power > 0.0 || power < s.skip_below {
                continue;
            }
            let alpha = MAX_ALPHA.min(s.opacity * power.exp());
            if alpha < MIN_ALPHA {
                continue;
            }
            let t = transmittance[p];
            let next = t * (1.0 - alpha);
            if next < MIN_TRANSMITTANCE {
                active[p] = false;
                remaining -= 1;
                continue;
            }
            for (sum, c) in colour[p].iter_mut().zip(s.colour) {
                *sum += c * alpha * t;
            }
            weight(k, alpha * t);
            transmittance[p] = next;
        }
    }
    colour
        .iter()
        .zip(transmittance)
        .flat_map(|(rgb, t)| [0, 1, 2].map(|c| rgb[c] + t * background[c]))
        .collect()
}
