//! `salvq bench rd`: the rate-distortion, search-method and stability measurements of the
//! lattice quantizers (spec §7) on one generated scene, written as SVG charts, a CSV of every
//! point and a text summary with the BD-rates.
//!
//! The scene is `GenParams::new(N, seed)` with F = 48 (so E8 products apply, as in the SALVQ
//! paper's E8 baseline). Every quantizer codes the same features; each gets scale rows fitted
//! to its own coordinates (Annex A.5), standing in for the training a real model would get
//! for it. Rate points come from scaling the feature group's base step; rate is the whole
//! stream's bits per anchor (the learned basis's factors included), distortion the feature
//! SNR `10 log10(var(x) / MSE)` in dB.

pub mod bdrate;
mod charts;
pub mod coder;
pub mod parsimony;
pub mod peers;
pub mod precision;
pub mod real;
pub mod render_psnr;
pub mod scale;

use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::bdrate::{bd_rate, Curve, Interpolation};
use salvq_bitstream::model::{Basis, LatticeKind, SceneModel};
use salvq_encoder::{encode_full, EncodeOptions, Search};
use salvq_encoder::{Error, Result};
use salvq_gen::linalg::orthogonal;
use salvq_gen::rng::Stream;
use salvq_gen::{generate, GenParams};
use salvq_render::error::IoOp;

/// Feature base-step factors giving the rate points (7 per curve).
pub const STEP_FACTORS: [f32; 7] = [0.35, 0.5, 0.71, 1.0, 1.41, 2.0, 2.83];
/// Residual correlations swept (Annex B.4.3's `feat_decay`; 1 = uncorrelated).
pub const DECAYS: [f64; 4] = [1.0, 0.95, 0.9, 0.8];
/// Basis condition numbers of the stability sweep.
pub const CONDITIONS: [f64; 9] = [1.0, 10.0, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8];
/// Stream tag of the stability sweep's bases (outside Annex B's tags 1–9).
const STABILITY_TAG: u64 = 0x5EED;
/// Extreme rate gains of the stability sweep.
pub const EXTREME_GAINS: [f32; 2] = [1e-3, 1e3];

/// What `salvq bench rd` is asked for.
#[derive(Debug, Clone)]
pub struct RdOptions {
    pub anchors: u32,
    pub seed: u64,
    pub out: PathBuf,
}

/// A feature quantizer as the encoder is asked for it.
#[derive(Debug, Clone, Copy)]
pub struct Quantizer {
    pub label: &'static str,
    pub lattice: Option<LatticeKind>,
    pub fit_basis: bool,
    pub search: Search,
    /// Spatial regions of a fitted basis (Sp-SALVQ, §7.6).
    pub regions: u16,
}

/// The quantizers of the R-D chart: USQ, D_n, E8⁶, the generator's (random, not adapted)
/// learned basis, SALVQ with a basis fitted to the scene (KLT, Annex A.5), USQ and SALVQ
/// with the rate-distortion optimised search, and Sp-SALVQ with 8 fitted regions (§7.6).
pub const QUANTIZERS: [Quantizer; 8] = [
    Quantizer {
        label: "USQ",
        lattice: Some(LatticeKind::Identity),
        fit_basis: false,
        search: Search::Auto,
        regions: 1,
    },
    Quantizer {
        label: "D48",
        lattice: Some(LatticeKind::Dn),
        fit_basis: false,
        search: Search::Auto,
        regions: 1,
    },
    Quantizer {
        label: "E8^6",
        lattice: Some(LatticeKind::E8Product),
        fit_basis: false,
        search: Search::Auto,
        regions: 1,
    },
    Quantizer {
        label: "random basis",
        lattice: Some(LatticeKind::General),
        fit_basis: false,
        search: Search::Auto,
        regions: 1,
    },
    Quantizer {
        label: "SALVQ (fitted)",
        lattice: None,
        fit_basis: true,
        search: Search::Auto,
        regions: 1,
    },
    Quantizer {
        label: "USQ + rdo",
        lattice: Some(LatticeKind::Identity),
        fit_basis: false,
        search: Search::Rdo { lambda_milli: 1000 },
        regions: 1,
    },
    Quantizer {
        label: "SALVQ + rdo",
        lattice: None,
        fit_basis: true,
        search: Search::Rdo { lambda_milli: 1000 },
        regions: 1,
    },
    Quantizer {
        label: "Sp-SALVQ (8)",
        lattice: None,
        fit_basis: true,
        search: Search::Auto,
        regions: 8,
    },
];

/// One coded point.
#[derive(Debug, Clone)]
pub struct Point {
    pub bits_per_anchor: f64,
    pub feature_bits_per_anchor: f64,
    pub mse: f64,
    pub snr_db: f64,
    pub escapes: u64,
    pub secs: f64,
    /// Render PSNR (dB) and SSIM of the decoded scene against the uncompressed one (Annex
    /// C.5); NaN where not measured.
    pub render_psnr_db: f64,
    pub render_ssim: f64,
}

fn options(q: &Quantizer, search: Search) -> EncodeOptions {
    let search = if search == Search::Auto {
        q.search
    } else {
        search
    };
    EncodeOptions {
        feat_lattice: q.lattice,
        fit_basis: q.fit_basis,
        feat_regions: q.regions,
        fit_scales: true,
        search,
        ..EncodeOptions::default()
    }
}

/// Variance of the feature values around their per-dimension means.
fn feature_variance(m: &SceneModel) -> f64 {
    let f = usize::from(m.dims.feat_dim);
    let n = m.n().max(1);
    let mut mean = vec![0.0; f];
    for row in m.anchors.feat.chunks_exact(f) {
        for (a, &v) in mean.iter_mut().zip(row) {
            *a += f64::from(v) / n as f64;
        }
    }
    let mut var = 0.0;
    for row in m.anchors.feat.chunks_exact(f) {
        for (a, &v) in mean.iter().zip(row) {
            var += (f64::from(v) - a).powi(2);
        }
    }
    var / (n * f) as f64
}

/// Encodes `m` with `o`, rate 0, and measures the point.
fn code(m: &SceneModel, o: &EncodeOptions, var: f64) -> Result<Point> {
    code_rendered(m, o, var, None)
}

/// [`code`], with render accuracy against `reference` when given.
fn code_rendered(
    m: &SceneModel,
    o: &EncodeOptions,
    var: f64,
    reference: Option<&render_psnr::RenderReference>,
) -> Result<Point> {
    let t = Instant::now();
    let e = encode_full(m, o)?;
    let secs = t.elapsed().as_secs_f64();
    let (render_psnr_db, render_ssim) = match reference {
        Some(r) => r.compare(e.expected())?,
        None => (f64::NAN, f64::NAN),
    };
    let g = &e.report().groups[0];
    let n = f64::from(m.dims.anchors);
    let mse = g.squared_error / g.symbols.max(1) as f64;
    Ok(Point {
        bits_per_anchor: e.stream.len() as f64 * 8.0 / n,
        feature_bits_per_anchor: g.coded_bytes as f64 * 8.0 / n,
        mse,
        snr_db: 10.0 * (var / mse).log10(),
        escapes: g.escapes,
        secs,
        render_psnr_db,
        render_ssim,
    })
}

fn with_step(m: &SceneModel, factor: f32) -> SceneModel {
    let mut m = m.clone();
    m.quant_feat.step *= factor;
    m
}

/// One R-D curve: the quantizer at every step factor.
fn curve(m: &SceneModel, q: &Quantizer, var: f64) -> Result<Vec<Point>> {
    rendered_curve(m, q, var, None)
}

/// [`curve`] with render accuracy against `reference`.
fn rendered_curve(
    m: &SceneModel,
    q: &Quantizer,
    var: f64,
    reference: Option<&render_psnr::RenderReference>,
) -> Result<Vec<Point>> {
    STEP_FACTORS
        .iter()
        .map(|&k| code_rendered(&with_step(m, k), &options(q, Search::Auto), var, reference))
        .collect()
}

/// BD-rate (percent) of `test` against `anchor`, whole-stream bits, for each method.
fn bd(anchor: &[Point], test: &[Point], feature_only: bool) -> Vec<(Interpolation, f64)> {
    let c = |p: &[Point]| {
        let rate = p
            .iter()
            .map(|x| {
                if feature_only {
                    x.feature_bits_per_anchor
                } else {
                    x.bits_per_anchor
                }
            })
            .collect();
        Curve::new(rate, p.iter().map(|x| x.snr_db).collect())
    };
    let (Ok(a), Ok(t)) = (c(anchor), c(test)) else {
        return Vec::new();
    };
    Interpolation::ALL
        .iter()
        .filter_map(|&i| bd_rate(&a, &t, i).ok().map(|v| (i, v)))
        .collect()
}

fn bd_text(v: &[(Interpolation, f64)]) -> String {
    if v.is_empty() {
        return "n/a (curves do not overlap)".into();
    }
    v.iter()
        .map(|(i, x)| format!("{} {x:+.2} %", i.name()))
        .collect::<Vec<_>>()
        .join(", ")
}

fn scene(p: &RdOptions, decay: f64) -> SceneModel {
    generate(&GenParams {
        feat_dim: 48,
        feat_decay: decay,
        ..GenParams::new(p.anchors, p.seed)
    })
}

/// A general basis of condition number `cond` on `m`'s features: Haar `U`, `V`, singular
/// values geometric with geometric mean 1 (as Annex B.7, with the condition given).
fn with_condition(m: &SceneModel, cond: f64, seed: u64) -> SceneModel {
    let f = usize::from(m.dims.feat_dim);
    let mut s = Stream::new(seed, STABILITY_TAG, cond.to_bits());
    let u = orthogonal(&mut s, f);
    let v = orthogonal(&mut s, f);
    let sv = (0..f)
        .map(|i| (cond.ln() * (0.5 - i as f64 / (f - 1) as f64)).exp() as f32)
        .collect();
    let mut m = m.clone();
    m.quant_feat.basis = Some(Basis {
        u: u.iter().map(|&x| x as f32).collect(),
        s: sv,
        v: v.iter().map(|&x| x as f32).collect(),
    });
    m.dims.feat_lattice = LatticeKind::General;
    m
}

fn write(path: &Path, text: &str) -> Result<()> {
    Ok(salvq_render::io::write_bytes_atomic(path, text.as_bytes())?)
}

/// Runs every measurement, writes `rd.svg`, `search_speed.svg`, `stability.svg`, `rd.csv`
/// and `summary.txt` under `out`, and returns the summary text.
pub fn run(p: &RdOptions) -> Result<String> {
    std::fs::create_dir_all(&p.out).map_err(|e| Error::io(IoOp::Write, &p.out, e))?;
    let mut text = String::new();
    let mut csv = String::from(
        "part,series,x,bits_per_anchor,feature_bits_per_anchor,mse,snr_db,escapes,secs,render_psnr_db,render_ssim\n",
    );

    // 1. R-D of every quantizer on the default scene.
    let m = scene(p, salvq_gen::context::FEAT_DECAY);
    let var = feature_variance(&m);
    text.push_str(&format!(
        "Scene: GenParams::new({}, {}) with F = 48, feat_decay {}; feature variance {var:.3}.\n\
         Every quantizer with scale rows fitted to its coordinates (Annex A.5); rate = whole \
         stream bits/anchor; distortion = feature SNR (dB); step factors {STEP_FACTORS:?}.\n\n",
        p.anchors,
        p.seed,
        salvq_gen::context::FEAT_DECAY
    ));
    let curves = rd_curves(&m, var, &mut csv)?;
    text.push_str(&rd_summary(&curves));
    charts::rd(&p.out.join("rd.svg"), &curves)?;

    // 2. The SALVQ gain against the features' correlation.
    let by_decay = gain_by_correlation(p, &mut text, &mut csv)?;

    // 3. Search methods: encode time vs accuracy on the generator's learned basis.
    search_methods(p, &m, var, &mut text, &mut csv)?;

    // 4. Stability: condition numbers and extreme gains.
    stability(p, &mut text, &mut csv)?;
    charts::correlation(&p.out.join("rd_correlation.svg"), &by_decay)?;
    write(&p.out.join("rd.csv"), &csv)?;
    write(&p.out.join("summary.txt"), &text)?;
    Ok(text)
}

/// Appends one point to the CSV: its part of the run, series and x.
fn push_csv(csv: &mut String, part: &str, series: &str, x: f64, pt: &Point) {
    csv.push_str(&format!(
        "{part},{series},{x},{:.4},{:.4},{:.6},{:.4},{},{:.4},{:.4},{:.5}\n",
        pt.bits_per_anchor,
        pt.feature_bits_per_anchor,
        pt.mse,
        pt.snr_db,
        pt.escapes,
        pt.secs,
        pt.render_psnr_db,
        pt.render_ssim
    ));
}

/// The encoder's lattice searches the search and stability sweeps compare.
const SEARCH_METHODS: [(&str, Search); 5] = [
    ("rounding", Search::Rounding),
    ("nearest plane", Search::NearestPlane),
    ("closest ≤1k", Search::Closest { max_nodes: 1_000 }),
    ("closest ≤10k", Search::Closest { max_nodes: 10_000 }),
    ("rdo", Search::Rdo { lambda_milli: 1000 }),
];

/// Every quantizer's R-D curve on `m`, each point's decoded scene rendered against the
/// uncompressed one (Annex C.5).
fn rd_curves(
    m: &SceneModel,
    var: f64,
    csv: &mut String,
) -> Result<Vec<(&'static str, Vec<Point>)>> {
    let reference = render_psnr::RenderReference::new(
        m,
        render_psnr::VIEWS,
        render_psnr::WIDTH,
        render_psnr::HEIGHT,
    )?;
    let mut curves = Vec::new();
    for q in &QUANTIZERS {
        let c = rendered_curve(m, q, var, Some(&reference))?;
        for (k, pt) in STEP_FACTORS.iter().zip(&c) {
            push_csv(csv, "rd", q.label, f64::from(*k), pt);
        }
        curves.push((q.label, c));
    }
    Ok(curves)
}

/// The summary's R-D points of every curve, their BD-rates against USQ, and the RDO search's
/// and Sp-SALVQ's against their base quantizers.
fn rd_summary(curves: &[(&'static str, Vec<Point>)]) -> String {
    let mut text = format!(
        "R-D points (bits/anchor / feature SNR dB / render PSNR dB, the decoded scene's renders \
         against the uncompressed scene's, {} ring views at {}x{}, Annex C.5):\n",
        render_psnr::VIEWS,
        render_psnr::WIDTH,
        render_psnr::HEIGHT
    );
    for (label, c) in curves {
        let pts: Vec<String> = c
            .iter()
            .map(|x| {
                format!(
                    "{:.1}/{:.2}/{:.2}",
                    x.bits_per_anchor, x.snr_db, x.render_psnr_db
                )
            })
            .collect();
        text.push_str(&format!("  {label:>15}: {}\n", pts.join("  ")));
    }
    text.push_str("\nBD-rate vs USQ (whole stream | feature chunk only):\n");
    for (label, c) in curves.iter().skip(1) {
        text.push_str(&format!(
            "  {label:>15}: {} | {}\n",
            bd_text(&bd(&curves[0].1, c, false)),
            bd_text(&bd(&curves[0].1, c, true))
        ));
    }
    text.push_str("\nRDO search vs the same quantizer's auto search, and Sp-SALVQ vs SALVQ (whole stream | feature chunk):\n");
    for (base, rdo) in [(0, 5), (4, 6), (4, 7)] {
        text.push_str(&format!(
            "  {:>15}: {} | {}\n",
            curves[rdo].0,
            bd_text(&bd(&curves[base].1, &curves[rdo].1, false)),
            bd_text(&bd(&curves[base].1, &curves[rdo].1, true))
        ));
    }
    text
}

/// SALVQ (fitted) against USQ at each residual correlation of [`DECAYS`]: the summary's
/// BD-rates, and the pchip BD-rate per decay for the correlation chart.
fn gain_by_correlation(
    p: &RdOptions,
    text: &mut String,
    csv: &mut String,
) -> Result<Vec<(f64, f64)>> {
    text.push_str(
        "\nSALVQ (fitted) vs USQ by residual correlation (feat_decay; 1 = uncorrelated), pchip:\n",
    );
    let mut by_decay = Vec::new();
    for &decay in &DECAYS {
        let m = scene(p, decay);
        let var = feature_variance(&m);
        let usq = curve(&m, &QUANTIZERS[0], var)?;
        let salvq = curve(&m, &QUANTIZERS[4], var)?;
        for (k, (a, b)) in STEP_FACTORS.iter().zip(usq.iter().zip(&salvq)) {
            push_csv(csv, &format!("decay {decay}"), "USQ", f64::from(*k), a);
            push_csv(
                csv,
                &format!("decay {decay}"),
                "SALVQ (fitted)",
                f64::from(*k),
                b,
            );
        }
        let v = bd(&usq, &salvq, false);
        let pchip = v
            .iter()
            .find(|(i, _)| *i == Interpolation::Pchip)
            .map(|x| x.1);
        text.push_str(&format!("  decay {decay:<5}: {}\n", bd_text(&v)));
        if let Some(x) = pchip {
            by_decay.push((decay, x));
        }
    }
    Ok(by_decay)
}

/// Encode time against accuracy of each of [`SEARCH_METHODS`] on the generator's learned
/// basis: the summary's rows and `search_speed.svg`.
fn search_methods(
    p: &RdOptions,
    m: &SceneModel,
    var: f64,
    text: &mut String,
    csv: &mut String,
) -> Result<()> {
    let gen_basis = &QUANTIZERS[3];
    let mut search_rows = Vec::new();
    for (label, s) in SEARCH_METHODS {
        // Warm once, then the best of two (the machine is shared; compare ratios).
        let o = options(gen_basis, s);
        code(m, &o, var)?;
        let a = code(m, &o, var)?;
        let b = code(m, &o, var)?;
        let pt = if a.secs <= b.secs { a } else { b };
        push_csv(csv, "search", label, 0.0, &pt);
        search_rows.push((label, pt));
    }
    let (t_round, mse_exact) = (search_rows[0].1.secs, search_rows[3].1.mse);
    text.push_str(&format!(
        "\nSearch methods on the generator's learned basis (F = 48, {} anchors; time = whole encode, \
         best of 2):\n",
        p.anchors
    ));
    for (label, pt) in &search_rows {
        text.push_str(&format!(
            "  {label:>14}: {:.2} µs/anchor  time/rounding {:.2}  MSE/closest≤10k {:.3}  bits/anchor {:.2}\n",
            pt.secs * 1e6 / f64::from(p.anchors),
            pt.secs / t_round,
            pt.mse / mse_exact,
            pt.bits_per_anchor
        ));
    }
    charts::search_speed(&p.out.join("search_speed.svg"), &search_rows, p.anchors)
}

/// Stability on a scene of at most 3000 anchors: each search method's MSE against the
/// closest search's as the basis's condition number grows (`stability.svg`), then
/// [`extreme_gains`].
fn stability(p: &RdOptions, text: &mut String, csv: &mut String) -> Result<()> {
    let small = RdOptions {
        anchors: p.anchors.min(3000),
        ..p.clone()
    };
    let ms = scene(&small, salvq_gen::context::FEAT_DECAY);
    let vs = feature_variance(&ms);
    text.push_str(&format!(
        "\nStability ({} anchors): basis condition number -> MSE / closest≤10k per method, escapes, refusals:\n",
        small.anchors
    ));
    let mut stab: Vec<(f64, Vec<Option<Point>>, String)> = Vec::new();
    for &cond in &CONDITIONS {
        let mc = with_condition(&ms, cond, p.seed);
        let mut pts = Vec::new();
        let mut note = String::new();
        for (label, s) in SEARCH_METHODS {
            match code(&mc, &options(&QUANTIZERS[3], s), vs) {
                Ok(pt) => {
                    push_csv(csv, &format!("cond {cond:e}"), label, cond, &pt);
                    pts.push(Some(pt));
                }
                Err(e) => {
                    if note.is_empty() {
                        note = format!("refused: {}", e.class());
                    }
                    pts.push(None);
                }
            }
        }
        let exact = pts[3].as_ref().map(|x| x.mse);
        let cells: Vec<String> = pts
            .iter()
            .zip(SEARCH_METHODS)
            .map(|(pt, (label, _))| match (pt, exact) {
                (Some(x), Some(e)) => format!("{label} {:.3} (esc {})", x.mse / e, x.escapes),
                _ => format!("{label} —"),
            })
            .collect();
        text.push_str(&format!(
            "  cond {cond:>7.0e}: {} {note}\n",
            cells.join(", ")
        ));
        stab.push((cond, pts, note));
    }
    let labels = SEARCH_METHODS.map(|m| m.0);
    charts::stability(&p.out.join("stability.svg"), &stab, &labels)?;
    extreme_gains(&ms, small.anchors, text);
    Ok(())
}

/// USQ and SALVQ on `ms` (`anchors` of them) with rate 0's gain replaced by each of
/// [`EXTREME_GAINS`]: the rate, the feature MSE, the escapes, and whether the decode is the
/// encoder's prediction, or why the encoder refused.
fn extreme_gains(ms: &SceneModel, anchors: u32, text: &mut String) {
    text.push_str("\nExtreme gains (rate 0's gain replaced; decode checked against the encoder's prediction):\n");
    for &g in &EXTREME_GAINS {
        for q in [&QUANTIZERS[0], &QUANTIZERS[4]] {
            let mut mg = ms.clone();
            mg.quant_feat.gains[0] = g;
            let o = options(q, Search::Auto);
            let line = match encode_full(&mg, &o) {
                Ok(e) => {
                    let decoded = salvq::decode(&e.stream).and_then(salvq::Scene::try_into_anchors);
                    let same = matches!(&decoded, Ok(d) if d == e.expected());
                    let gstats = &e.report().groups[0];
                    format!(
                        "{:.1} bits/anchor, feature MSE {:.3e}, escapes {} of {} symbols, decode {}",
                        e.stream.len() as f64 * 8.0 / f64::from(anchors),
                        gstats.squared_error / gstats.symbols.max(1) as f64,
                        gstats.escapes,
                        gstats.symbols,
                        if same { "== prediction" } else { "DIFFERS" }
                    )
                }
                Err(e) => format!("refused: {e}"),
            };
            text.push_str(&format!("  gain {g:e}, {:>15}: {line}\n", q.label));
        }
    }
}
