//! The encoder's input for the explicit profile, validated and put in coding form once
//! (spec Annex A.8): finite values, clamped opacity logits, unit quaternions as their three
//! smallest components, each group's values side by side. Every trial encode reuses it.

use crate::error::{Error, Result};
use salvq_bitstream::explicit::groups::GroupKind;
use salvq_bitstream::explicit::Gaussians;

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
            return Err(Error::UnsupportedInput {
                found: format!("a scene of {n} Gaussians").into(),
                hint: "a stream holds 1 … 2^32 − 1 of them",
            });
        }
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
                    return Err(not_finite(i, ["x", "y", "z"][a].into()));
                }
                min[a] = min[a].min(f64::from(p[a]));
                max[a] = max[a].max(f64::from(p[a]));
            }
            for (gi, &kind) in kinds.iter().enumerate() {
                push_values(g, i, kind, &mut values[gi], &mut rotation_index)?;
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

    /// The Gaussians at `indices`, in that order, in the same box (`min`, `extent`).
    pub fn subset(&self, indices: &[usize]) -> PreparedGaussians {
        let values = self
            .values
            .iter()
            .enumerate()
            .map(|(gi, v)| {
                let d = self.dim(gi);
                indices
                    .iter()
                    .flat_map(|&i| v[i * d..(i + 1) * d].iter().copied())
                    .collect()
            })
            .collect();
        PreparedGaussians {
            sh_degree: self.sh_degree,
            positions: indices.iter().map(|&i| self.positions[i]).collect(),
            kinds: self.kinds.clone(),
            values,
            rotation_index: indices.iter().map(|&i| self.rotation_index[i]).collect(),
            min: self.min,
            extent: self.extent,
        }
    }
}

/// The error for Gaussian `vertex`'s `property` that is not finite (Annex A.8.1).
fn not_finite(vertex: usize, property: String) -> Error {
    salvq_render::Error::PlyValueNotFinite {
        vertex: vertex as u64,
        property,
    }
    .into()
}

/// Appends Gaussian `i`'s values of group `kind` to `out` in coding form (Annex A.8.1),
/// checking each is finite (opacity: not NaN, then clamped); a rotation also appends its
/// largest component's index to `rotation_index`.
fn push_values(
    g: &Gaussians,
    i: usize,
    kind: GroupKind,
    out: &mut Vec<f64>,
    rotation_index: &mut Vec<u8>,
) -> Result<()> {
    match kind {
        GroupKind::Opacity => {
            let o = g.opacity_logit[i];
            if o.is_nan() {
                return Err(not_finite(i, "opacity".into()));
            }
            let o = f64::from(o).clamp(-OPACITY_LOGIT_LIMIT, OPACITY_LOGIT_LIMIT);
            out.push(o);
        }
        GroupKind::Scale => {
            for a in 0..3 {
                let s = g.log_scales[i][a];
                if !s.is_finite() {
                    return Err(not_finite(i, format!("scale_{a}")));
                }
                out.push(f64::from(s));
            }
        }
        GroupKind::Rotation => {
            let q = g.rotations[i].map(f64::from);
            let Some(largest) = push_smallest_three(q, out) else {
                return Err(not_finite(i, "rot_0".into()));
            };
            rotation_index.push(largest);
        }
        GroupKind::Dc => {
            for c in 0..3 {
                let v = g.f_dc[i][c];
                if !v.is_finite() {
                    return Err(not_finite(i, format!("f_dc_{c}")));
                }
                out.push(f64::from(v));
            }
        }
        GroupKind::Rest => {
            let b = g.rest_per_channel();
            for k in 0..3 * b {
                let v = g.f_rest[i * 3 * b + k];
                if !v.is_finite() {
                    return Err(not_finite(i, format!("f_rest_{k}")));
                }
                out.push(f64::from(v));
            }
        }
    }
    Ok(())
}

/// Appends quaternion `q`, normalised, as its three smallest components with the largest made
/// positive (§3.6, Annex A.8.1), and returns the largest's index; `None` (nothing appended)
/// when its length is zero or not finite.
fn push_smallest_three(q: [f64; 4], out: &mut Vec<f64>) -> Option<u8> {
    let norm = q.iter().map(|v| v * v).sum::<f64>().sqrt();
    if !norm.is_finite() || norm == 0.0 {
        return None;
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
    Some(largest as u8)
}

/// Values the encoder changes on input (Annex A.8.1), one entry per property and kind of
/// change, so that nothing changes without a word.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ValueChange {
    /// The PLY property.
    pub property: &'static str,
    /// How many values.
    pub count: u64,
    /// What they were (`+inf`, `> 16`, …).
    pub was: &'static str,
    /// What they became.
    pub became: f64,
}

/// The values [`PreparedGaussians::new`] will change in `g`: opacity logits beyond
/// ±[`OPACITY_LOGIT_LIMIT`], infinite ones counted apart. Empty when it changes none.
pub fn value_changes(g: &Gaussians) -> Vec<ValueChange> {
    let limit = OPACITY_LOGIT_LIMIT;
    let mut counts = [0u64; 4];
    for &o in &g.opacity_logit {
        let o = f64::from(o);
        let kind = match o {
            f64::INFINITY => 0,
            o if o > limit => 1,
            f64::NEG_INFINITY => 2,
            o if o < -limit => 3,
            _ => continue,
        };
        counts[kind] += 1;
    }
    let kinds = [
        ("+inf", limit),
        ("> 16", limit),
        ("-inf", -limit),
        ("< -16", -limit),
    ];
    kinds
        .iter()
        .zip(counts)
        .filter(|&(_, count)| count > 0)
        .map(|(&(was, became), count)| ValueChange {
            property: "opacity",
            count,
            was,
            became,
        })
        .collect()
}

/// What [`drop_invalid`] dropped: how many Gaussians, and per property how many were
/// dropped for it (the first value of each that is not finite, in PLY property order).
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct Dropped {
    /// Gaussians read.
    pub read: u64,
    /// Gaussians dropped.
    pub dropped: u64,
    /// `(property, Gaussians dropped for it)`, in the order properties are checked.
    pub by_property: Vec<(String, u64)>,
}

/// The first property of Gaussian `i` whose value the format cannot hold (NaN anywhere, an
/// infinity other than the opacity logit's, a zero-length quaternion), if any.
fn first_invalid(g: &Gaussians, i: usize) -> Option<String> {
    let b = 3 * g.rest_per_channel();
    let bad = |v: &f32| !v.is_finite();
    let names = |prefix: &str, k: usize| format!("{prefix}{k}");
    if let Some(a) = g.positions[i].iter().position(bad) {
        return Some(["x", "y", "z"][a].into());
    }
    if let Some(c) = g.f_dc[i].iter().position(bad) {
        return Some(names("f_dc_", c));
    }
    if let Some(k) = g.f_rest[i * b..(i + 1) * b].iter().position(bad) {
        return Some(names("f_rest_", k));
    }
    if g.opacity_logit[i].is_nan() {
        return Some("opacity".into());
    }
    if let Some(a) = g.log_scales[i].iter().position(bad) {
        return Some(names("scale_", a));
    }
    if let Some(c) = g.rotations[i].iter().position(bad) {
        return Some(names("rot_", c));
    }
    if g.rotations[i].iter().all(|&v| v == 0.0) {
        return Some("rot_0".into());
    }
    None
}

/// `g` without the Gaussians whose used values are not all finite (an infinite opacity
/// logit is kept: it is an alpha of 0 or 1, clamped as [`value_changes`] counts), and what
/// was dropped: what `salvq encode --drop-invalid` encodes instead of failing (Annex A.8.1).
pub fn drop_invalid(g: &Gaussians) -> (Gaussians, Dropped) {
    let b = 3 * g.rest_per_channel();
    let mut by_property: Vec<(String, u64)> = Vec::new();
    let mut keep = Vec::with_capacity(g.len());
    for i in 0..g.len() {
        match first_invalid(g, i) {
            None => keep.push(i),
            Some(p) => match by_property.iter_mut().find(|(q, _)| *q == p) {
                Some((_, n)) => *n += 1,
                None => by_property.push((p, 1)),
            },
        }
    }
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
    let dropped = Dropped {
        read: g.len() as u64,
        dropped: (g.len() - out.len()) as u64,
        by_property,
    };
    (out, dropped)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scene(opacity: &[f32]) -> Gaussians {
        let n = opacity.len();
        Gaussians {
            positions: (0..n).map(|i| [i as f32, 0.0, 0.0]).collect(),
            sh_degree: 0,
            f_dc: vec![[0.1; 3]; n],
            f_rest: Vec::new(),
            opacity_logit: opacity.to_vec(),
            log_scales: vec![[-3.0; 3]; n],
            rotations: vec![[1.0, 0.0, 0.0, 0.0]; n],
        }
    }

    #[test]
    fn every_clamped_opacity_is_counted_by_kind() {
        let g = scene(&[
            f32::INFINITY,
            20.0,
            3.0,
            f32::NEG_INFINITY,
            -17.0,
            -40.0,
            16.0,
        ]);
        let c = value_changes(&g);
        let got: Vec<(&str, u64, f64)> = c.iter().map(|v| (v.was, v.count, v.became)).collect();
        assert_eq!(
            got,
            [
                ("+inf", 1, 16.0),
                ("> 16", 1, 16.0),
                ("-inf", 1, -16.0),
                ("< -16", 2, -16.0)
            ]
        );
        // What the prepared form holds is what the count says.
        let p = PreparedGaussians::new(&g).unwrap();
        let at = p
            .kinds
            .iter()
            .position(|&k| k == GroupKind::Opacity)
            .unwrap();
        assert_eq!(p.values[at], [16.0, 16.0, 3.0, -16.0, -16.0, -16.0, 16.0]);
        assert!(value_changes(&scene(&[0.5, -2.0])).is_empty());
    }

    #[test]
    fn dropped_gaussians_are_counted_by_their_first_bad_property() {
        let mut g = scene(&[0.0, f32::INFINITY, f32::NAN, 1.0, 2.0]);
        g.log_scales[3][1] = f32::NEG_INFINITY;
        g.rotations[4] = [0.0; 4];
        let (kept, d) = drop_invalid(&g);
        assert_eq!(kept.len(), 2, "the infinite opacity is kept");
        assert_eq!(d.read, 5);
        assert_eq!(d.dropped, 3);
        assert_eq!(
            d.by_property,
            [
                ("opacity".into(), 1),
                ("scale_1".into(), 1),
                ("rot_0".into(), 1)
            ]
        );
    }
}
