//! The explicit encoder's rate control (Annex A.8.2): the sensitivities' first-order model,
//! the decoded output predicted without coding, the spatial sample, and the effort levels.

use salvq_bitstream::explicit::groups::GroupKind;
use salvq_encoder::explicit::layer::encode_layer;
use salvq_encoder::explicit::sample::{spatial_sample, subset};
use salvq_encoder::explicit::{
    curves::Effort, encode_gaussians, fit_groups, ratios, ExplicitOptions, PreparedGaussians,
    RateControl, RatePlan, SizeClasses, TrialSteps,
};
use salvq_gen::gaussians::{generate_gaussians, GaussianParams};
use salvq_render::compare::RingTarget;

/// A change of one Gaussian's colour alone moves the ring's error as its colour sensitivity
/// says: `colour[i] · |δ|² / 3` (the model is first order; one Gaussian is exact but for the
/// clamp at 0, which these colours stay clear of).
#[test]
fn colour_sensitivity_predicts_a_colour_change() {
    let g = generate_gaussians(&GaussianParams::new(400, 0, 7));
    let target = RingTarget::new(&g, 4, 96, 72).unwrap();
    let sens = target.sensitivities(&g);
    // The Gaussian that weighs most, and one of middling weight.
    let mut order: Vec<usize> = (0..g.len()).collect();
    order.sort_by(|&a, &b| sens.colour[b].total_cmp(&sens.colour[a]));
    let mut checked = 0;
    for &i in [order[0], order[order.len() / 4]].iter() {
        if sens.colour[i] <= 0.0 {
            continue;
        }
        let delta = 0.01f32;
        let mut h = g.clone();
        h.f_dc[i] = h.f_dc[i].map(|c| c + delta);
        // The rendered colour moves by C0·δ per channel (Table 3-4's SH DC constant).
        let rgb = 0.282_094_8 * f64::from(delta);
        let predicted = f64::from(sens.colour[i]) * rgb * rgb;
        let rendered = target.mse(&h).unwrap();
        assert!(
            (rendered / predicted - 1.0).abs() < 0.05,
            "Gaussian {i}: rendered {rendered:e}, predicted {predicted:e}"
        );
        checked += 1;
    }
    assert!(checked > 0, "no Gaussian is seen");
}

/// The decoded output the landing renders without coding errs as the coded layer does:
/// each value within half its step of the input (the coder may round a value to the other
/// neighbour, where its prediction offsets the lattice), and as much in all.
#[test]
fn the_predicted_output_errs_as_the_coded_layer() {
    let g = generate_gaussians(&GaussianParams::new(600, 1, 11));
    let p = PreparedGaussians::new(&g).unwrap();
    let start = TrialSteps::default_for(&p);
    let plan = RatePlan {
        voxel: start.position * 8.0,
        refine: [2, 1, 1, 0],
        steps: start.groups.clone(),
        shift: vec![[1, 0, 0, -1]; p.kinds.len() - 1],
    };
    let groups = fit_groups(&p, std::slice::from_ref(&plan), &vec![false; p.kinds.len()]);
    let classes = SizeClasses::quartiles(&p);
    let coded = encode_layer(
        &p,
        &groups,
        &classes,
        &plan,
        p.min.map(|v| v as f32),
        0,
        0,
        Default::default(),
        salvq_bitstream::entropy::GaussianTables::standard(),
    )
    .unwrap();
    let predicted = ratios::plan_output(&g, &p, &groups, &classes.thresholds, &plan);
    let out = &coded.expected;
    // (input, predicted, coded) of every value of a group, the step of its class.
    let mut sums = [0f64; 2];
    let mut check = |x: f32, a: f32, b: f32, step: f64, what: &str| {
        let half = 0.5 * step as f32 + 1e-5;
        assert!(
            (a - x).abs() <= half,
            "{what}: predicted {a} for {x} (step {step})"
        );
        assert!(
            (b - x).abs() <= half,
            "{what}: coded {b} for {x} (step {step})"
        );
        sums[0] += f64::from(a - x).powi(2);
        sums[1] += f64::from(b - x).powi(2);
    };
    // The coded layer's Gaussians are in canonical order.
    for (k, &i) in coded.state.grid.order.iter().enumerate() {
        let class = usize::from(coded.state.size_class[k]);
        let step = |gi: usize| plan.steps[gi] * f64::from(plan.shift[gi - 1][class]).exp2();
        check(
            g.opacity_logit[i],
            predicted.opacity_logit[i],
            out.opacity_logit[k],
            step(1),
            "opacity",
        );
        for c in 0..3 {
            check(
                g.f_dc[i][c],
                predicted.f_dc[i][c],
                out.f_dc[k][c],
                step(3),
                "dc",
            );
        }
        for j in 0..9 {
            let (x, a, b) = (
                g.f_rest[9 * i + j],
                predicted.f_rest[9 * i + j],
                out.f_rest[9 * k + j],
            );
            check(x, a, b, step(4), "rest");
        }
    }
    let ratio = sums[0] / sums[1];
    assert!((ratio - 1.0).abs() < 0.15, "squared errors {sums:?}");
    assert_eq!(p.kinds[1], GroupKind::Opacity);
    assert_eq!(p.kinds[3], GroupKind::Dc);
}

/// The spatial sample takes whole runs of the canonical order, at most about the size asked,
/// with each Gaussian's values carried over.
#[test]
fn the_spatial_sample_is_a_subset_of_whole_runs() {
    let g = generate_gaussians(&GaussianParams::new(20_000, 0, 3));
    let p = PreparedGaussians::new(&g).unwrap();
    assert!(
        spatial_sample(&g, &p, 20_000).is_none(),
        "a small scene is its own sample"
    );
    let s = spatial_sample(&g, &p, 5_000).unwrap();
    assert!(s.indices.len() <= 5_000 + 2048, "{}", s.indices.len());
    assert!(s.indices.len() >= 2048);
    assert!(
        s.indices.windows(2).all(|w| w[0] < w[1]),
        "ascending, each once"
    );
    assert_eq!(s.prepared.len(), s.indices.len());
    assert_eq!((s.prepared.min, s.prepared.extent), (p.min, p.extent));
    let again = subset(&g, &s.indices);
    assert_eq!(again, s.gaussians);
    for (k, &i) in s.indices.iter().enumerate() {
        assert_eq!(
            s.prepared.values[0][3 * k..3 * k + 3],
            p.values[0][3 * i..3 * i + 3]
        );
    }
}

/// Every effort encodes a stream that decodes, the rates nested and falling in size; at
/// `Fast` nothing but the sensitivities is rendered, so the rates may land off their targets,
/// but not far from them on a scene like those the priors were measured on.
#[test]
#[cfg_attr(
    debug_assertions,
    ignore = "renders hundreds of images; run with --release"
)]
fn every_effort_encodes_a_stream_that_decodes() {
    let g = generate_gaussians(&GaussianParams::new(3_000, 1, 5));
    let quality = RingTarget::new(
        &g,
        ratios::QUALITY_VIEWS,
        ratios::QUALITY_WIDTH,
        ratios::QUALITY_HEIGHT,
    )
    .unwrap();
    let targets = vec![50.0, 40.0];
    for effort in [Effort::Fast, Effort::Default, Effort::Best] {
        let e = encode_gaussians(
            &g,
            &ExplicitOptions {
                rates: RateControl::Psnr(targets.clone()),
                effort,
                ..Default::default()
            },
            &|_| {},
        )
        .unwrap();
        let sizes = e.rate_stream_bytes();
        for ((report, _, expected), bytes) in e.layers.iter().zip(&sizes) {
            let decoded = salvq::Decoder::builder()
                .limits(salvq_bitstream::limits::Limits::default())
                .rate(Some(report.rate))
                .build()
                .decode(&e.stream)
                .and_then(salvq::Scene::try_into_gaussians)
                .unwrap();
            assert_eq!(
                &decoded.gaussians, expected,
                "{effort:?} rate {}",
                report.rate
            );
            let db = quality.psnr(expected).unwrap();
            let want = targets[usize::from(report.rate)];
            let off = if effort == Effort::Fast { 6.0 } else { 1.0 };
            assert!(
                (db - want).abs() < off,
                "{effort:?} rate {}: {db:.2} dB for {want} ({bytes} B)",
                report.rate
            );
        }
        // Layers in stream order, the coarsest first: each prefix holds more.
        assert!(
            sizes.windows(2).all(|w| w[0] < w[1]),
            "{effort:?}: {sizes:?}"
        );
    }
}
