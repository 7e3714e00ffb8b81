//! Least sufficient precision for the Scaffold-GS MLPs (Annex A.5.2):
//! stored in binary16 (§1.6.2 Table 1-6) when every value fits binary16 and the renders of
//! the scene's neural Gaussians with binary16 MLPs match those with binary32 MLPs at
//! [`PSNR_THRESHOLD_DB`] or more (the PSNR that rounding a render to 8 bits already costs).
//! A model that cannot be rendered neurally (not Scaffold-GS-shaped, Annex C.1) falls back
//! to a bound on the MLPs' activated outputs ([`OUTPUT_TOLERANCE`]). The MLPs never steer the
//! entropy decoder, so the choice changes no symbol; it trades model bytes against the
//! renderer's inputs.

use std::borrow::Cow;
use std::ops::Range;

use serde::Serialize;

use salvq_bitstream::container::payload::ScaffoldPrecision;
use salvq_bitstream::model::{Anchors, Mlp, SceneModel};
use salvq_render::camera::{Bounds, Ring};
use salvq_render::neural::ScaffoldMlp;
use salvq_render::neural::{
    activate, anchor_positions, check_model, neural_gaussians, PreparedMlp,
};
use salvq_render::raster::render;
use salvq_render::Image;

/// The least render PSNR (dB, peak 1) of binary16 MLPs against binary32 ones:
/// `10·log10(12·255²)` ≈ 58.92 dB, the PSNR of rounding an image uniformly to 8 bits (error
/// variance `(1/255)²/12`). Below it binary16 would move the render by more than storing it
/// as an 8-bit PNG does.
pub const PSNR_THRESHOLD_DB: f64 = 58.922_616_069_155_35;

/// Anchors the render rule renders at most: the whole scene up to this many, else
/// `RENDER_SAMPLE / RENDER_VIEWS` consecutive ones per view ([`view_anchors`]).
pub const RENDER_SAMPLE: usize = 32_768;

/// Views of the default ring (Annex C.2) the render rule compares.
pub const RENDER_VIEWS: u32 = 4;

/// Image width of the render rule's views.
pub const RENDER_WIDTH: u32 = 256;

/// Image height of the render rule's views.
pub const RENDER_HEIGHT: u32 = 192;

/// The fallback's largest change of an activated output that binary16 may cause: a quarter
/// of an 8-bit colour level.
pub const OUTPUT_TOLERANCE: f64 = 1.0 / 512.0;

/// Anchors the fallback samples at most.
const OUTPUT_SAMPLE: usize = 4096;

/// Which rule of Annex A.5.2 decided.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum PrecisionRule {
    /// The caller asked for a precision (`--scaffold-precision f32|f16`); nothing measured.
    Requested,
    /// A value is beyond binary16's range: binary32.
    Range,
    /// The render PSNR of binary16 against binary32 (Scaffold-GS-shaped models).
    Render,
    /// The fallback for models that cannot be rendered neurally: the activated outputs.
    Outputs,
}

/// What the encoder chose for the Scaffold-GS MLPs, and why.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PrecisionChoice {
    /// The precision chosen.
    pub precision: ScaffoldPrecision,
    /// The rule that decided.
    pub rule: PrecisionRule,
    /// PSNR (dB) of the binary16 renders against the binary32 renders over the covered
    /// pixels; `None` when not measured (requested, out of range, or not renderable),
    /// `+∞` (JSON `null`) when they are identical.
    pub render_psnr_db: Option<f64>,
    /// The least PSNR that allows binary16.
    pub psnr_threshold_db: f64,
    /// Anchors rendered (the sample).
    pub render_anchors: u64,
    /// Pixels (all views) that either render covers, over which the PSNR is taken.
    pub render_pixels: u64,
    /// Fallback only: largest change of an activated output with binary16 weights; `None`
    /// when not measured.
    pub max_output_change: Option<f64>,
    /// The fallback's largest change allowed.
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
/// precisions) on the anchors' features and the view inputs of Annex A.5.2 (the fallback).
pub fn max_change(m: &SceneModel, a: [&Mlp; 3], b: [&Mlp; 3]) -> f64 {
    let f = usize::from(m.dims.feat_dim);
    let v = usize::from(m.dims.view_dims);
    let n = m.n();
    let p = n.min(OUTPUT_SAMPLE);
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
    let (a, b) = (
        a.map(|m| PreparedMlp::new(m, f + v)),
        b.map(|m| PreparedMlp::new(m, f + v)),
    );
    let (mut ya, mut yb, mut hidden) = (Vec::new(), Vec::new(), Vec::new());
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
                a[kind].forward(&x, &mut hidden, &mut ya);
                b[kind].forward(&x, &mut hidden, &mut yb);
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

/// Anchors `range` of `m` (its order kept): `m` itself when that is all of them.
pub fn anchor_run(m: &SceneModel, range: Range<usize>) -> Cow<'_, SceneModel> {
    if range == (0..m.n()) {
        return Cow::Borrowed(m);
    }
    let (f, s, k) = (
        usize::from(m.dims.feat_dim),
        usize::from(m.dims.scaling_dim),
        usize::from(m.dims.offsets),
    );
    let rows = |v: &[f32], w: usize| v[range.start * w..range.end * w].to_vec();
    let a = &m.anchors;
    let anchors = Anchors {
        voxel: a.voxel[range.clone()].to_vec(),
        mask: a.mask[range.start * k..range.end * k].to_vec(),
        feat: rows(&a.feat, f),
        scaling: rows(&a.scaling, s),
        offsets: rows(&a.offsets, 3 * k),
    };
    let mut dims = m.dims.clone();
    dims.anchors = range.len() as u32;
    Cow::Owned(SceneModel {
        dims,
        origin: m.origin,
        voxel_size: m.voxel_size,
        anchors,
        grid: m.grid.clone(),
        mlp_grid: m.mlp_grid.clone(),
        mlp_opacity: m.mlp_opacity.clone(),
        mlp_cov: m.mlp_cov.clone(),
        mlp_color: m.mlp_color.clone(),
        quant_feat: m.quant_feat.clone(),
        quant_scaling: m.quant_scaling.clone(),
        quant_offsets: m.quant_offsets.clone(),
    })
}

/// The anchors view `v` of the render rule renders: all `N` when `N ≤ RENDER_SAMPLE`, else
/// the `RENDER_SAMPLE / RENDER_VIEWS` consecutive anchors from `⌊v·N/RENDER_VIEWS⌋`.
pub fn view_anchors(n: usize, v: u32) -> Range<usize> {
    if n <= RENDER_SAMPLE {
        return 0..n;
    }
    let views = RENDER_VIEWS as usize;
    let start = v as usize * n / views;
    start..(start + RENDER_SAMPLE / views).min(n)
}

/// A render comparison: PSNR (dB) over the covered pixels and their number.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RenderMatch {
    /// PSNR (peak 1, values clamped to [0, 1] as Annex C.5) over the covered pixels; `+∞`
    /// when identical.
    pub psnr_db: f64,
    /// Anchors rendered.
    pub anchors: u64,
    /// Pixels, over all views, that either render covers (any channel above 0: the
    /// background is black).
    pub pixels: u64,
}

/// Squared error and covered pixels of `b` against `a` (Annex C.5 clamping).
fn covered_error(a: &Image, b: &Image) -> (f64, u64) {
    let unit = |v: f32| f64::from(v.clamp(0.0, 1.0));
    let (mut se, mut pixels) = (0.0, 0);
    for (p, q) in a.rgb.chunks_exact(3).zip(b.rgb.chunks_exact(3)) {
        if p.iter().chain(q).all(|&v| unit(v) == 0.0) {
            continue;
        }
        pixels += 1;
        se += p
            .iter()
            .zip(q)
            .map(|(&x, &y)| (unit(x) - unit(y)).powi(2))
            .sum::<f64>();
    }
    (se, pixels)
}

/// Renders view `v < RENDER_VIEWS` of [`view_anchors`] from view `v` of the
/// [`RENDER_VIEWS`]-view default ring (Annex C.2) around those anchors, with the MLPs `a`
/// and with `b`, and compares them over the pixels either covers. `None` when the model
/// cannot be rendered neurally (Annex C.1).
pub fn render_match(m: &SceneModel, a: [&Mlp; 3], b: [&Mlp; 3]) -> Option<RenderMatch> {
    check_model(m).ok()?;
    let ring = Ring {
        views: RENDER_VIEWS,
        ..Ring::default()
    };
    let (mut se, mut pixels, mut anchors) = (0.0, 0, 0);
    let mut whole: Option<Bounds> = None;
    for view in 0..RENDER_VIEWS {
        let range = view_anchors(m.n(), view);
        let part = anchor_run(m, range.clone());
        // Anchors rendered: the whole scene once, or each view's own run.
        if range.len() < m.n() || whole.is_none() {
            anchors += range.len() as u64;
        }
        let bounds = match whole {
            Some(b) if range.len() == m.n() => b,
            _ => Bounds::of_points(&anchor_positions(&part)),
        };
        if range.len() == m.n() {
            whole = Some(bounds);
        }
        let camera = ring
            .camera(&bounds, view, RENDER_WIDTH, RENDER_HEIGHT)
            .ok()?;
        let image = |mlps: [&Mlp; 3]| -> Option<Image> {
            let with = SceneModel {
                mlp_opacity: mlps[0].clone(),
                mlp_cov: mlps[1].clone(),
                mlp_color: mlps[2].clone(),
                ..part.as_ref().clone()
            };
            let g = neural_gaussians(&with, camera.position).ok()?;
            Some(render(&g, &camera, [0.0; 3]))
        };
        let (s, p) = covered_error(&image(a)?, &image(b)?);
        se += s;
        pixels += p;
    }
    let mse = if pixels == 0 {
        0.0
    } else {
        se / (3 * pixels) as f64
    };
    Some(RenderMatch {
        psnr_db: salvq_render::compare::psnr_of(mse),
        anchors,
        pixels,
    })
}

/// Annex A.5.2: `requested` when given; else binary32 when a value does not fit binary16;
/// else, for a model that renders neurally, binary16 when its binary16 renders match the
/// binary32 ones at [`PSNR_THRESHOLD_DB`] or more; for one that does not, binary16 when the
/// activated outputs move by at most [`OUTPUT_TOLERANCE`].
pub fn choose(m: &SceneModel, requested: Option<ScaffoldPrecision>) -> PrecisionChoice {
    let mlps = [&m.mlp_opacity, &m.mlp_cov, &m.mlp_color];
    let values: u64 = mlps
        .iter()
        .map(|x| (x.w0.len() + x.b0.len() + x.w1.len() + x.b1.len()) as u64)
        .sum();
    let mut c = PrecisionChoice {
        precision: ScaffoldPrecision::F32,
        rule: PrecisionRule::Requested,
        render_psnr_db: None,
        psnr_threshold_db: PSNR_THRESHOLD_DB,
        render_anchors: 0,
        render_pixels: 0,
        max_output_change: None,
        tolerance: OUTPUT_TOLERANCE,
        bytes_saved: 0,
    };
    let fits = mlps.iter().all(|x| {
        [&x.w0, &x.b0, &x.w1, &x.b1]
            .iter()
            .all(|v| v.iter().all(|w| w.abs() <= 65504.0))
    });
    if let Some(p) = requested {
        c.precision = p;
    } else if !fits {
        c.rule = PrecisionRule::Range;
    } else {
        let half = mlps.map(|x| rounded(x, ScaffoldPrecision::F16));
        let half = [&half[0], &half[1], &half[2]];
        let f16_if = |ok: bool| {
            if ok {
                ScaffoldPrecision::F16
            } else {
                ScaffoldPrecision::F32
            }
        };
        if let Some(r) = render_match(m, mlps, half) {
            c.rule = PrecisionRule::Render;
            c.render_psnr_db = Some(r.psnr_db);
            c.render_anchors = r.anchors;
            c.render_pixels = r.pixels;
            c.precision = f16_if(r.psnr_db >= PSNR_THRESHOLD_DB);
        } else {
            let change = max_change(m, mlps, half);
            c.rule = PrecisionRule::Outputs;
            c.max_output_change = Some(change);
            c.precision = f16_if(change <= OUTPUT_TOLERANCE);
        }
    }
    c.bytes_saved = (4 - c.precision.bytes()) * values;
    c
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

    /// Makes binary16 move every colour: hidden unit 0 of `mlp_color` a constant 1 whose
    /// weight −1000 cancels a bias of 1000.3 (binary32: 1000.29999…; binary16, spacing 0.5
    /// there: 1000.5), so each raw colour moves by 0.2 and its sigmoid by about 0.05, some
    /// twelve 8-bit levels.
    fn perturb(m: &mut SceneModel) {
        let c = &mut m.mlp_color;
        let (hidden, inp) = (c.b0.len(), c.w0.len() / c.b0.len());
        c.w0[..inp].fill(0.0);
        c.b0[0] = 1.0;
        for o in 0..c.b1.len() {
            c.w1[o * hidden] = -1000.0;
            c.b1[o] = 1000.3;
        }
        let f16 = rounded(c, ScaffoldPrecision::F16);
        assert_eq!((f16.b1[0], f16.w1[0]), (1000.5, -1000.0));
    }

    #[test]
    fn the_threshold_is_the_psnr_of_8_bit_rounding() {
        let expected = 10.0 * (12.0f64 * 255.0 * 255.0).log10();
        assert!((PSNR_THRESHOLD_DB - expected).abs() < 1e-12, "{expected}");
    }

    #[test]
    fn binary16_is_chosen_only_when_the_renders_match() {
        let mut m = scene();
        assert!(check_model(&m).is_ok(), "the generated scene renders");
        // Tiny Scaffold-GS weights: the renders barely move at any precision.
        for mlp in [&mut m.mlp_opacity, &mut m.mlp_cov, &mut m.mlp_color] {
            for v in mlp.w0.iter_mut().chain(mlp.w1.iter_mut()) {
                *v *= 1e-3;
            }
        }
        let c = choose(&m, None);
        assert_eq!(c.precision, ScaffoldPrecision::F16, "{c:?}");
        assert_eq!(c.rule, PrecisionRule::Render);
        let psnr = c.render_psnr_db.unwrap();
        assert!(psnr >= PSNR_THRESHOLD_DB, "{c:?}");
        assert!(c.render_pixels > 0 && c.render_anchors == 60 && c.bytes_saved > 0);
        assert_eq!(c.max_output_change, None);
        perturb(&mut m);
        let c = choose(&m, None);
        assert_eq!(c.rule, PrecisionRule::Render);
        assert!(c.render_psnr_db.unwrap() < PSNR_THRESHOLD_DB, "{c:?}");
        assert_eq!((c.precision, c.bytes_saved), (ScaffoldPrecision::F32, 0));
        // A value beyond binary16's range forbids it, without measuring.
        m.mlp_color.b1[0] = 1e6;
        let c = choose(&m, None);
        assert_eq!(
            (c.precision, c.rule),
            (ScaffoldPrecision::F32, PrecisionRule::Range)
        );
        assert_eq!(c.render_psnr_db, None);
        // An explicit request is honoured.
        let c = choose(&scene(), Some(ScaffoldPrecision::F16));
        assert_eq!(
            (c.precision, c.rule),
            (ScaffoldPrecision::F16, PrecisionRule::Requested)
        );
    }

    #[test]
    fn models_that_do_not_render_fall_back_to_the_outputs() {
        // View dims 0: not Scaffold-GS-shaped (Annex C.1), so nothing renders.
        let mut m = generate(&GenParams {
            feat_basis: false,
            view_dims: 0,
            ..GenParams::small(60, 2)
        });
        assert!(check_model(&m).is_err());
        for mlp in [&mut m.mlp_opacity, &mut m.mlp_cov, &mut m.mlp_color] {
            for v in mlp.w0.iter_mut().chain(mlp.w1.iter_mut()) {
                *v *= 1e-3;
            }
        }
        let c = choose(&m, None);
        assert_eq!(
            (c.precision, c.rule),
            (ScaffoldPrecision::F16, PrecisionRule::Outputs)
        );
        assert!(c.max_output_change.unwrap() <= OUTPUT_TOLERANCE);
        assert_eq!((c.render_psnr_db, c.render_pixels), (None, 0));
        perturb(&mut m);
        let c = choose(&m, None);
        assert_eq!(
            (c.precision, c.rule),
            (ScaffoldPrecision::F32, PrecisionRule::Outputs)
        );
        assert!(c.max_output_change.unwrap() > OUTPUT_TOLERANCE, "{c:?}");
    }

    #[test]
    fn each_view_renders_the_whole_scene_or_a_run_of_anchors() {
        assert_eq!(view_anchors(RENDER_SAMPLE, 3), 0..RENDER_SAMPLE);
        let run = RENDER_SAMPLE / RENDER_VIEWS as usize;
        let n = 1_000_001;
        let starts: Vec<usize> = (0..RENDER_VIEWS)
            .map(|v| view_anchors(n, v).start)
            .collect();
        assert_eq!(starts, [0, 250_000, 500_000, 750_000]);
        assert!((0..RENDER_VIEWS).all(|v| view_anchors(n, v).len() == run));
        let m = scene();
        assert!(matches!(anchor_run(&m, 0..60), Cow::Borrowed(_)));
        let s = anchor_run(&m, 10..17);
        let (f, k) = (usize::from(m.dims.feat_dim), usize::from(m.dims.offsets));
        assert_eq!(s.n(), 7);
        for i in 0..7 {
            let a = 10 + i;
            assert_eq!(s.anchors.voxel[i], m.anchors.voxel[a]);
            assert_eq!(
                s.anchors.feat[i * f..(i + 1) * f],
                m.anchors.feat[a * f..(a + 1) * f]
            );
            assert_eq!(
                s.anchors.mask[i * k..(i + 1) * k],
                m.anchors.mask[a * k..(a + 1) * k]
            );
            assert_eq!(
                s.anchors.offsets[i * 3 * k..(i + 1) * 3 * k],
                m.anchors.offsets[a * 3 * k..(a + 1) * 3 * k]
            );
            assert_eq!(
                s.anchors.scaling[i * 6..(i + 1) * 6],
                m.anchors.scaling[a * 6..(a + 1) * 6]
            );
        }
        assert!(check_model(&s).is_ok());
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
            let d = salvq::decode(&e.stream)
                .and_then(salvq::Scene::try_into_anchors)
                .unwrap();
            assert_eq!(&d, e.expected());
            assert_eq!(d.mlp_cov, rounded(&m.mlp_cov, p));
            if p == ScaffoldPrecision::F16 {
                assert_ne!(d.mlp_cov, m.mlp_cov, "binary16 rounds something");
            }
        }
    }
}
