//! Encoder-side fits (spec Annex A.5): a KLT basis and feature-scale rows refitted to the
//! coded lattice. Refitting the identity's scales reproduces the generator's true scales'
//! rate; refitting helps every other lattice; a fitted basis decorrelates the residuals; the
//! streams decode to what the encoder predicted; conflicting options are typed errors.

use salvq::{decode, SceneModel};
use salvq_bitstream::model::LatticeKind;
use salvq_bitstream::quantizer::GroupLattices;
use salvq_encoder::fit::{fit_feature_scales, fit_klt_basis};
use salvq_encoder::{encode_full, EncodeOptions};
use salvq_gen::{generate, GenParams};

fn model(n: u32) -> SceneModel {
    generate(&GenParams {
        feat_dim: 16,
        ..GenParams::small(n, 3)
    })
}

/// Feature bits per anchor of rate 0, checking the stream decodes to the encoder's oracle.
fn feature_bits(m: &SceneModel, lattice: Option<LatticeKind>, klt: bool, fit: bool) -> f64 {
    let e = encode_full(
        m,
        &EncodeOptions {
            feat_lattice: lattice,
            fit_basis: klt,
            fit_scales: fit,
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(
        &decode(&e.stream)
            .and_then(salvq::Scene::try_into_anchors)
            .unwrap(),
        e.expected()
    );
    let g = &e.report().groups[0];
    assert_eq!(g.group, "feature");
    g.coded_bytes as f64 * 8.0 / f64::from(m.dims.anchors)
}

#[test]
fn refitting_the_identity_recovers_the_true_scales() {
    // The generator draws features with exactly its context MLP's scales (Annex B.5.1): a fit
    // that works lands within 1 % of them, one that does not costs far more.
    let m = model(4000);
    let truth = feature_bits(&m, Some(LatticeKind::Identity), false, false);
    let fitted = feature_bits(&m, Some(LatticeKind::Identity), false, true);
    assert!(
        (fitted / truth - 1.0).abs() < 0.01,
        "true scales {truth:.2}, fitted {fitted:.2} bits/anchor"
    );
}

#[test]
fn refitting_helps_every_other_lattice() {
    let m = model(4000);
    for kind in [
        LatticeKind::Dn,
        LatticeKind::E8Product,
        LatticeKind::General,
    ] {
        let plain = feature_bits(&m, Some(kind), false, false);
        let fitted = feature_bits(&m, Some(kind), false, true);
        assert!(fitted < plain, "{kind:?}: {plain:.2} -> {fitted:.2}");
    }
}

#[test]
fn klt_basis_is_orthonormal_and_decorrelates() {
    let m = model(3000);
    let b = fit_klt_basis(&m).unwrap();
    let f = 16;
    assert!(b.s.iter().all(|&s| s == 1.0));
    for i in 0..f {
        for j in 0..f {
            let dot: f64 = (0..f)
                .map(|k| f64::from(b.u[k * f + i]) * f64::from(b.u[k * f + j]))
                .sum();
            let want = if i == j { 1.0 } else { 0.0 };
            assert!((dot - want).abs() < 1e-5, "UᵀU[{i}][{j}] = {dot}");
            assert_eq!(b.v[i * f + j], if i == j { 1.0 } else { 0.0 });
        }
    }
    // With the basis and fitted scales the features cost less than with USQ (the generated
    // features are correlated across dimensions, Annex B.4.3).
    let usq = feature_bits(&m, Some(LatticeKind::Identity), false, true);
    let klt = feature_bits(&m, None, true, true);
    assert!(klt < usq, "USQ {usq:.2}, KLT {klt:.2} bits/anchor");
}

#[test]
fn fitted_scales_change_only_the_feature_scale_rows() {
    let m = model(1500);
    let mut fitted = m.clone();
    let lattices = GroupLattices::new(LatticeKind::E8Product, 16, &m.quant_feat);
    let report = fit_feature_scales(&mut fitted, &lattices).unwrap();
    assert_eq!(report.anchors, 1500);
    assert!(
        report.mean_scale > 0.0 && report.low_fraction < 0.05,
        "{report:?}"
    );
    let (f, h) = (16, usize::from(m.dims.context_hidden));
    for (row, (a, b)) in m
        .mlp_grid
        .w1
        .chunks(h)
        .zip(fitted.mlp_grid.w1.chunks(h))
        .enumerate()
    {
        assert_eq!(a == b, !(f..2 * f).contains(&row), "row {row}");
    }
    assert_eq!(m.mlp_grid.w0, fitted.mlp_grid.w0);
    assert_eq!(m.anchors, fitted.anchors);
}

#[test]
fn a_fitted_basis_with_another_lattice_is_a_typed_error() {
    let m = model(200);
    let e = encode_full(
        &m,
        &EncodeOptions {
            feat_lattice: Some(LatticeKind::E8Product),
            fit_basis: true,
            ..Default::default()
        },
    )
    .unwrap_err();
    assert!(matches!(e, salvq_encoder::Error::FitFailed { .. }), "{e}");
}
