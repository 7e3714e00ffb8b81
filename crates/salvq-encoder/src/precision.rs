//! Least sufficient precision (issue 10; DESIGN P7) for the Scaffold-GS MLPs: stored in
//! binary16 (§1.6.2 Table 1-6) when their activated outputs on this scene's anchors move by at
//! most [`OUTPUT_TOLERANCE`] (Annex A.5.2). They never steer the entropy decoder, so the
//! choice changes no symbol; it trades model bytes against the renderer's inputs.

use serde::Serialize;

use salvq::container::payload::ScaffoldPrecision;
use salvq::model::{Mlp, SceneModel};
use salvq_render::neural::{activate, forward, ScaffoldMlp};

/// Largest change of an activated output that binary16 may cause: a quarter of an 8-bit
/// colour level.
pub const OUTPUT_TOLERANCE: f64 = 1.0 / 512.0;

/// Anchors sampled for the measurement.
const SAMPLE: usize = 4096;

/// What the encoder chose for the Scaffold-GS MLPs, and why.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PrecisionChoice {
    /// The precision chosen.
    pub precision: ScaffoldPrecision,
    /// Largest change of an activated output with binary16 weights (∞ when a value does not
    /// fit binary16).
    pub max_output_change: f64,
    /// The largest change allowed.
    pub tolerance: f64,
    /// Model bytes saved against binary32.
    pub bytes_saved: u64,
}

/// The MLP with every value as `p` stores it.
pub fn rounded(mlp: &Mlp, p: ScaffoldPrecision) -> Mlp {
    let r = |v: &[f32]| v.iter().map(|&x| p.round(x)).collect();
    Mlp {
        w0: r(&mlp.w0),
        b0: r(&mlp.b0),
        w1: r(&mlp.w1),
        b1: r(&mlp.b1),
    }
}

/// The largest change of an activated output between `a` and `b` (the same MLPs at two
/// precisions) on the anchors' features and the view inputs of Annex A.5.2.
fn max_change(m: &SceneModel, a: [&Mlp; 3], b: [&Mlp; 3]) -> f64 {
    let f = usize::from(m.dims.feat_dim);
    let v = usize::from(m.dims.view_dims);
    let n = m.n();
    let p = n.min(SAMPLE);
    let mut views: Vec<Vec<f64>> = (0..v)
        .flat_map(|j| {
            [1.0, -1.0].map(|s| {
                let mut e = vec![0.0; v];
                e[j] = s;
                e
            })
        })
        .collect();
    if views.is_empty() {
        views.push(Vec::new());
    }
    let (mut ya, mut yb) = (Vec::new(), Vec::new());
    let mut worst = 0f64;
    for i in 0..p {
        let anchor = i * n / p;
        let feat = &m.anchors.feat[anchor * f..(anchor + 1) * f];
        for view in &views {
            let x: Vec<f64> = feat
                .iter()
                .map(|&x| f64::from(x))
                .chain(view.iter().copied())
                .collect();
            for (kind, which) in ScaffoldMlp::ALL.into_iter().enumerate() {
                forward(a[kind], &x, &mut ya);
                forward(b[kind], &x, &mut yb);
                activate(which, &mut ya);
                activate(which, &mut yb);
                for (p, q) in ya.iter().zip(&yb) {
                    let d = (p - q).abs();
                    worst = if d.is_nan() {
                        f64::INFINITY
                    } else {
                        worst.max(d)
                    };
                }
            }
        }
    }
    worst
}

/// Annex A.5.2: `requested` when given, else binary16 if every value fits and the outputs move
/// by at most [`OUTPUT_TOLERANCE`], else binary32.
pub fn choose(m: &SceneModel, requested: Option<ScaffoldPrecision>) -> PrecisionChoice {
    let mlps = [&m.mlp_opacity, &m.mlp_cov, &m.mlp_color];
    let values: u64 = mlps
        .iter()
        .map(|x| (x.w0.len() + x.b0.len() + x.w1.len() + x.b1.len()) as u64)
        .sum();
    let fits = mlps.iter().all(|x| {
        [&x.w0, &x.b0, &x.w1, &x.b1]
            .iter()
            .all(|v| v.iter().all(|w| w.abs() <= 65504.0))
    });
    let half = mlps.map(|x| rounded(x, ScaffoldPrecision::F16));
    let change = if fits {
        max_change(m, mlps, [&half[0], &half[1], &half[2]])
    } else {
        f64::INFINITY
    };
    let precision = requested.unwrap_or(if change <= OUTPUT_TOLERANCE {
        ScaffoldPrecision::F16
    } else {
        ScaffoldPrecision::F32
    });
    PrecisionChoice {
        precision,
        max_output_change: change,
        tolerance: OUTPUT_TOLERANCE,
        bytes_saved: (4 - precision.bytes()) * values,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use salvq_gen::{generate, GenParams};

    fn scene() -> SceneModel {
        generate(&GenParams {
            feat_basis: false,
            ..GenParams::small(60, 2)
        })
    }

    #[test]
    fn binary16_is_chosen_only_within_tolerance_and_range() {
        let mut m = scene();
        // Tiny Scaffold-GS weights: outputs barely move at any precision.
        for mlp in [&mut m.mlp_opacity, &mut m.mlp_cov, &mut m.mlp_color] {
            for v in mlp.w0.iter_mut().chain(mlp.w1.iter_mut()) {
                *v *= 1e-3;
            }
        }
        let c = choose(&m, None);
        assert_eq!(c.precision, ScaffoldPrecision::F16, "{c:?}");
        assert!(c.max_output_change <= OUTPUT_TOLERANCE && c.bytes_saved > 0);
        // A value beyond binary16's range forbids it.
        m.mlp_color.b1[0] = 1e6;
        let c = choose(&m, None);
        assert_eq!(c.precision, ScaffoldPrecision::F32);
        assert!(c.max_output_change.is_infinite());
        // An explicit request is honoured.
        assert_eq!(
            choose(&scene(), Some(ScaffoldPrecision::F16)).precision,
            ScaffoldPrecision::F16
        );
    }

    #[test]
    fn binary16_streams_decode_to_the_rounded_mlps() {
        let m = scene();
        for p in [ScaffoldPrecision::F32, ScaffoldPrecision::F16] {
            let options = crate::EncodeOptions {
                scaffold_precision: Some(p),
                ..Default::default()
            };
            let e = crate::encode_full(&m, &options).unwrap();
            let d = salvq::decode(&e.stream).unwrap();
            assert_eq!(&d, e.expected());
            assert_eq!(d.mlp_cov, rounded(&m.mlp_cov, p));
            if p == ScaffoldPrecision::F16 {
                assert_ne!(d.mlp_cov, m.mlp_cov, "binary16 rounds something");
            }
        }
    }
}
