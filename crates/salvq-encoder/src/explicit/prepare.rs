//! The encoder's input for the explicit profile, validated and put in coding form once
//! (spec Annex A.8): finite values, clamped opacity logits, unit quaternions as their three
//! smallest components, each group's values side by side. Every trial encode reuses it.

use crate::error::{Error, Result};
use salvq::explicit::groups::GroupKind;
use salvq::explicit::Gaussians;

/// Opacity logits beyond ±this are clamped: sigmoid(16) differs from 1 by 1.1e-7, far below
/// what an 8-bit display or the renderer's 1/255 cut-off can tell.
pub const OPACITY_LOGIT_LIMIT: f64 = 16.0;

/// A scene in coding form (Annex A.8).
#[derive(Debug, Clone)]
pub struct PreparedGaussians {
    /// SH degree, 0 … 3.
    pub sh_degree: u8,
    /// The means.
    pub positions: Vec<[f64; 3]>,
    /// The groups of Table 3-3 present at this degree.
    pub kinds: Vec<GroupKind>,
    /// Per group, `n × dim` values (row per Gaussian).
    pub values: Vec<Vec<f64>>,
    /// Per Gaussian, the index of its largest quaternion component (0 … 3 = w x y z).
    pub rotation_index: Vec<u8>,
    /// Smallest corner of the positions' box, and the box's largest side.
    pub min: [f64; 3],
    /// The box's largest side.
    pub extent: f64,
}

impl PreparedGaussians {
    /// Number of Gaussians.
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// Values per Gaussian of group `g`.
    pub fn dim(&self, g: usize) -> usize {
        self.kinds[g].dim(self.sh_degree)
    }

    /// Validates `g` (Annex A.8) and puts it in coding form.
    pub fn new(g: &Gaussians) -> Result<PreparedGaussians> {
        let n = g.len();
        if n == 0 || n > u32::MAX as usize {
            return Err(Error::FitFailed {
                tensor: "gaussians",
                reason: format!("a scene has 1 … 2^32 − 1 Gaussians, this one has {n}"),
            });
        }
        let b = g.rest_per_channel();
        let bad = |vertex: usize, property: String| -> Error {
            salvq_render::Error::PlyValueNotFinite {
                vertex: vertex as u64,
                property,
            }
            .into()
        };
        let kinds = GroupKind::present(g.sh_degree);
        let mut values: Vec<Vec<f64>> = kinds
            .iter()
            .map(|k| Vec::with_capacity(n * k.dim(g.sh_degree)))
            .collect();
        let mut rotation_index = Vec::with_capacity(n);
        let mut min = [f64::INFINITY; 3];
        let mut max = [f64::NEG_INFINITY; 3];
        for i in 0..n {
            let p = g.positions[i];
            for a in 0..3 {
                if !p[a].is_finite() {
                    return Err(bad(i, ["x", "y", "z"][a].into()));
                }
                min[a] = min[a].min(f64::from(p[a]));
                max[a] = max[a].max(f64::from(p[a]));
            }
            for (gi, kind) in kinds.iter().enumerate() {
                let out = &mut values[gi];
                match kind {
                    GroupKind::Opacity => {
                        let o = g.opacity_logit[i];
                        if o.is_nan() {
                            return Err(bad(i, "opacity".into()));
                        }
                        let o = f64::from(o).clamp(-OPACITY_LOGIT_LIMIT, OPACITY_LOGIT_LIMIT);
                        out.push(o);
                    }
                    GroupKind::Scale => {
                        for a in 0..3 {
                            let s = g.log_scales[i][a];
                            if !s.is_finite() {
                                return Err(bad(i, format!("scale_{a}")));
                            }
                            out.push(f64::from(s));
                        }
                    }
                    GroupKind::Rotation => {
                        let q = g.rotations[i].map(f64::from);
                        let norm = q.iter().map(|v| v * v).sum::<f64>().sqrt();
                        if !norm.is_finite() || norm == 0.0 {
                            return Err(bad(i, "rot_0".into()));
                        }
                        let mut largest = 0;
                        for c in 1..4 {
                            if q[c].abs() > q[largest].abs() {
                                largest = c;
                            }
                        }
                        let sign = if q[largest] < 0.0 { -1.0 } else { 1.0 };
                        for (c, v) in q.iter().enumerate() {
                            if c != largest {
                                out.push(sign * v / norm);
                            }
                        }
                        rotation_index.push(largest as u8);
                    }
                    GroupKind::Dc => {
                        for c in 0..3 {
                            let v = g.f_dc[i][c];
                            if !v.is_finite() {
                                return Err(bad(i, format!("f_dc_{c}")));
                            }
                            out.push(f64::from(v));
                        }
                    }
                    GroupKind::Rest => {
                        for k in 0..3 * b {
                            let v = g.f_rest[i * 3 * b + k];
                            if !v.is_finite() {
                                return Err(bad(i, format!("f_rest_{k}")));
                            }
                            out.push(f64::from(v));
                        }
                    }
                }
            }
        }
        let extent = (0..3).map(|a| max[a] - min[a]).fold(0.0, f64::max);
        Ok(PreparedGaussians {
            sh_degree: g.sh_degree,
            positions: g.positions.iter().map(|p| p.map(f64::from)).collect(),
            kinds,
            values,
            rotation_index,
            min,
            extent,
        })
    }
}

/// `g` without the Gaussians whose used values are not all finite (an infinite opacity
/// logit is kept: it is an alpha of 0 or 1), and how many were dropped: what
/// `salvq encode --drop-invalid` encodes instead of failing (Annex A.8.1).
pub fn drop_invalid(g: &Gaussians) -> (Gaussians, usize) {
    let b = 3 * g.rest_per_channel();
    let ok = |i: usize| {
        g.positions[i].iter().all(|v| v.is_finite())
            && g.log_scales[i].iter().all(|v| v.is_finite())
            && g.rotations[i].iter().all(|v| v.is_finite())
            && g.rotations[i].iter().any(|&v| v != 0.0)
            && g.f_dc[i].iter().all(|v| v.is_finite())
            && !g.opacity_logit[i].is_nan()
            && g.f_rest[i * b..(i + 1) * b].iter().all(|v| v.is_finite())
    };
    let keep: Vec<usize> = (0..g.len()).filter(|&i| ok(i)).collect();
    let out = Gaussians {
        positions: keep.iter().map(|&i| g.positions[i]).collect(),
        sh_degree: g.sh_degree,
        f_dc: keep.iter().map(|&i| g.f_dc[i]).collect(),
        f_rest: keep
            .iter()
            .flat_map(|&i| g.f_rest[i * b..(i + 1) * b].iter().copied())
            .collect(),
        opacity_logit: keep.iter().map(|&i| g.opacity_logit[i]).collect(),
        log_scales: keep.iter().map(|&i| g.log_scales[i]).collect(),
        rotations: keep.iter().map(|&i| g.rotations[i]).collect(),
    };
    let dropped = g.len() - out.len();
    (out, dropped)
}
