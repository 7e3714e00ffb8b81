//! Encoder-side fits (spec Annex A.5, informative): what a trained SALVQ model learns for its
//! quantizer, estimated from the model's own anchors so that one scene can be coded with
//! lattices it was not trained for and the results compared.
//!
//! - [`fit_klt_basis`]: a learned basis for the feature group, `B = U` with `U` the
//!   eigenvectors of the covariance of the residuals `x − μ` (the Karhunen–Loève transform;
//!   `s = 1`, `V = I`, so the cells are rotated cubes of the same volume as USQ's).
//! - [`fit_feature_scales`]: the context MLP's feature-scale rows refitted so that output `j`
//!   predicts the spread of lattice coordinate `j` (`w = B⁻¹ (x − μ)`, in feature units)
//!   rather than of feature `j`. §6.6 codes each coordinate under its own Gaussian with that
//!   scale, and a model trained for one lattice has scales for that lattice's coordinates; a
//!   model re-quantized without this refit pays for the mismatch.
//!
//! Both look at an evenly spaced sample of anchors and run in binary64; only the stored
//! results (binary32 factors and weights) reach the stream, so decoding never depends on how
//! they were found.

use nalgebra::{DMatrix, DVector, SymmetricEigen};
use rayon::prelude::*;

use super::float_prior::FloatPrior;
use crate::error::{Error, Result};
use salvq_bitstream::model::{names, Basis, Region, SceneModel};
use salvq_bitstream::quantizer::GroupLattices;

/// At most this many anchors, evenly spaced in the model's order, enter a fit.
pub const FIT_SAMPLE: usize = 32_768;

/// Ridge added to the normal equations, relative to their mean diagonal (keeps hidden units
/// that are always 0 on the sample from making them singular).
const RIDGE: f64 = 1e-6;

/// `E|w| = σ · sqrt(2/π)` for a zero-mean Gaussian: the factor turning mean absolute
/// coordinates into standard deviations (less swayed by the heavy tail than squares).
const ABS_TO_SIGMA: f64 = 1.253_314_137_315_500_3;

/// What the fits saw and did.
#[derive(Debug, Clone, PartialEq)]
pub struct FitReport {
    /// Anchors sampled.
    pub anchors: usize,
    /// Mean fitted feature scale (feature units) over the sample and dimensions.
    pub mean_scale: f64,
    /// Fraction of sampled (anchor, dimension) scales the fit puts below 1/8 of the
    /// dimension's mean target (where a linear fit of a positive quantity runs thin).
    pub low_fraction: f64,
}

/// Hidden activations and feature residuals `x − μ` of the sampled anchors.
struct Sample {
    hidden: usize,
    h: Vec<f64>,
    r: Vec<f64>,
    rows: usize,
    /// The anchor of each row.
    anchors: Vec<usize>,
}

/// Up to [`FIT_SAMPLE`] anchors evenly spaced over `range`.
fn sample(m: &SceneModel, range: std::ops::Range<usize>) -> Sample {
    let f = usize::from(m.dims.feat_dim);
    let hidden = usize::from(m.dims.context_hidden);
    let prior = FloatPrior::new(m, m.coord_bits(), 0);
    let n = range.len();
    let rows = n.min(FIT_SAMPLE);
    let anchors: Vec<usize> = (0..rows)
        .map(|i| range.start + (i as u128 * n as u128 / rows as u128) as usize)
        .collect();
    let per: Vec<(Vec<f64>, Vec<f64>)> = anchors
        .par_iter()
        .map(|&a| {
            let h = prior.hidden(m, m.anchors.voxel[a]);
            let y = prior.outputs(&h);
            let r = (0..f)
                .map(|j| f64::from(m.anchors.feat[a * f + j]) - y[j])
                .collect();
            (h, r)
        })
        .collect();
    let mut s = Sample {
        hidden,
        h: Vec::with_capacity(rows * hidden),
        r: Vec::with_capacity(rows * f),
        rows,
        anchors,
    };
    for (h, r) in per {
        s.h.extend(h);
        s.r.extend(r);
    }
    s
}

/// The feature group's KLT basis (module docs), from the residuals of up to [`FIT_SAMPLE`]
/// anchors. Eigenvectors are ordered by decreasing eigenvalue, each signed so that its
/// largest-magnitude component (the first of equals) is positive.
pub fn fit_klt_basis(m: &SceneModel) -> Result<Basis> {
    klt(m, 0..m.n())
}

/// Sp-SALVQ (§7.6): `regions` runs of equal anchor count in canonical (Morton) order, region
/// `r` starting at anchor `⌊r·N/R⌋`, each with the KLT basis of its own anchors. `m` must be
/// in canonical order; `regions` is clamped to 1 … min(N, 65535).
pub fn fit_klt_regions(m: &SceneModel, regions: u16) -> Result<(Basis, Vec<Region>)> {
    let n = m.n();
    let r = usize::from(regions).clamp(1, n.clamp(1, usize::from(u16::MAX)));
    let start = |k: usize| (k as u128 * n as u128 / r as u128) as usize;
    let first = klt(m, 0..start(1))?;
    let rest = (1..r)
        .map(|k| {
            Ok(Region {
                start: start(k) as u32,
                basis: klt(m, start(k)..start(k + 1))?,
            })
        })
        .collect::<Result<_>>()?;
    Ok((first, rest))
}

fn klt(m: &SceneModel, range: std::ops::Range<usize>) -> Result<Basis> {
    let f = usize::from(m.dims.feat_dim);
    let s = sample(m, range);
    let fail = |reason: &str| Error::FitFailed {
        tensor: names::QUANT_FEAT[2],
        reason: reason.to_string(),
    };
    if s.rows == 0 {
        return Err(fail("no anchors to fit"));
    }
    let r = DMatrix::from_row_slice(s.rows, f, &s.r);
    let cov = (r.transpose() * &r) / s.rows as f64;
    let eig = SymmetricEigen::try_new(cov, 1e-14, 10_000)
        .ok_or_else(|| fail("eigendecomposition did not converge"))?;
    if eig.eigenvalues.iter().any(|v| !v.is_finite()) {
        return Err(fail("covariance is not finite"));
    }
    let mut order: Vec<usize> = (0..f).collect();
    order.sort_by(|&a, &b| eig.eigenvalues[b].total_cmp(&eig.eigenvalues[a]));
    let mut u = vec![0f32; f * f];
    for (k, &col) in order.iter().enumerate() {
        let v = eig.eigenvectors.column(col);
        let lead = (0..f).fold(
            0,
            |best, i| if v[i].abs() > v[best].abs() { i } else { best },
        );
        let sign = if v[lead] < 0.0 { -1.0 } else { 1.0 };
        for i in 0..f {
            u[i * f + k] = (sign * v[i]) as f32;
        }
    }
    let mut v = vec![0f32; f * f];
    for i in 0..f {
        v[i * f + i] = 1.0;
    }
    Ok(Basis {
        u,
        s: vec![1.0; f],
        v,
    })
}

/// Refits `m`'s feature-scale rows (context MLP layer 1, outputs F … 2F − 1) to the
/// coordinates of `lattice` (module docs): for each coordinate `j`, least squares of
/// `sqrt(π/2) |w_j|` on the hidden activations and a bias, over up to [`FIT_SAMPLE`]
/// anchors. The feature means and every other row stay as they are.
pub fn fit_feature_scales(m: &mut SceneModel, lattices: &GroupLattices) -> Result<FitReport> {
    let f = usize::from(m.dims.feat_dim);
    let fail = |reason: String| Error::FitFailed {
        tensor: names::MLP_GRID[2],
        reason,
    };
    let s = sample(m, 0..m.n());
    if s.rows == 0 {
        return Err(fail("no anchors to fit".into()));
    }
    let hd = s.hidden;
    let p = hd + 1;
    // Coordinates w = B⁻¹ r of every sampled anchor, B its region's.
    let mut inverses = Vec::new();
    for lattice in lattices.matrices() {
        inverses.push(if lattice.is_identity() {
            None
        } else {
            let b = DMatrix::from_row_slice(f, f, &lattice.to_f64());
            Some(
                b.try_inverse()
                    .ok_or_else(|| fail("lattice basis is singular".into()))?,
            )
        });
    }
    let starts = lattices.starts();
    let mut w = Vec::with_capacity(s.rows * f);
    for (row, &a) in s.anchors.iter().enumerate() {
        let region = starts.partition_point(|&st| st as usize <= a).max(1) - 1;
        let r = &s.r[row * f..(row + 1) * f];
        match &inverses[region] {
            None => w.extend_from_slice(r),
            Some(inv) => w.extend((0..f).map(|j| (0..f).map(|k| inv[(j, k)] * r[k]).sum::<f64>())),
        }
    }
    // Normal equations of [h, 1] against every coordinate's target at once.
    let mut design = DMatrix::<f64>::zeros(s.rows, p);
    for a in 0..s.rows {
        for k in 0..hd {
            design[(a, k)] = s.h[a * hd + k];
        }
        design[(a, hd)] = 1.0;
    }
    let target = DMatrix::from_fn(s.rows, f, |a, j| ABS_TO_SIGMA * w[a * f + j].abs());
    let mut normal = design.transpose() * &design;
    let ridge = RIDGE * normal.trace() / p as f64;
    for k in 0..p {
        normal[(k, k)] += ridge;
    }
    let rhs = design.transpose() * &target;
    let chol = normal
        .cholesky()
        .ok_or_else(|| fail("normal equations are not positive definite".into()))?;
    let coef = chol.solve(&rhs);
    if coef
        .iter()
        .any(|v| !v.is_finite() || v.abs() > f64::from(f32::MAX))
    {
        return Err(fail("fitted weights are not finite".into()));
    }
    for j in 0..f {
        let row = f + j;
        for k in 0..hd {
            m.mlp_grid.w1[row * hd + k] = coef[(k, j)] as f32;
        }
        m.mlp_grid.b1[row] = coef[(hd, j)] as f32;
    }
    // What the fit predicts on its own sample.
    let fitted = &design * &coef;
    let means: DVector<f64> = target.row_mean().transpose();
    let mut low = 0usize;
    for a in 0..s.rows {
        for j in 0..f {
            if fitted[(a, j)] < means[j] / 8.0 {
                low += 1;
            }
        }
    }
    let cells = (s.rows * f).max(1) as f64;
    Ok(FitReport {
        anchors: s.rows,
        mean_scale: fitted.sum() / cells,
        low_fraction: low as f64 / cells,
    })
}
