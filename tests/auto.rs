//! `--auto` (Annex A.5.3): the feature quantizer chosen by total bytes at equal
//! distortion, on two differently structured generated scenes.

use salvq::SceneModel;
use salvq_encoder::auto::{choose, FeatureQuantizer, DISTORTION_TOLERANCE};
use salvq_encoder::{encode_full, EncodeOptions};
use salvq_gen::{generate, GenParams};

/// A small scene whose feature residuals are mixed with singular values `decay^i` (Annex
/// B.4.3): 1 draws uncorrelated residuals, lower values strongly correlated ones.
fn scene(decay: f64) -> SceneModel {
    generate(&GenParams {
        feat_basis: false,
        feat_decay: decay,
        feat_dim: 16,
        ..GenParams::small(2000, 11)
    })
}

fn feature_mse(a: &SceneModel, b: &SceneModel) -> f64 {
    salvq_encoder::values_mse(&a.anchors.feat, &b.anchors.feat)
}

/// Every candidate is measured at the target distortion, the choice is the fewest bytes, and
/// the stream encoded with the choice has that distortion and (no sampling at 2 000 anchors)
/// those bytes.
fn check_choice(m: &SceneModel) -> FeatureQuantizer {
    let base = EncodeOptions::default();
    let choice = choose(m, &base).unwrap();
    assert_eq!(choice.sample_anchors, m.n());
    assert!(choice.candidates.len() >= 3, "{:?}", choice.candidates);
    for c in &choice.candidates {
        assert!(
            (c.mse / choice.target_mse - 1.0).abs() <= DISTORTION_TOLERANCE,
            "{c:?} not at the target MSE {}",
            choice.target_mse
        );
        assert!(
            choice.chosen().bytes <= c.bytes,
            "{c:?} is smaller than the choice"
        );
    }
    let (model, options) = choice.apply(m, &base);
    let e = encode_full(&model, &options).unwrap();
    let canonical = m.to_canonical_order();
    let mse = feature_mse(&canonical, e.expected());
    assert!((mse / choice.target_mse - 1.0).abs() <= DISTORTION_TOLERANCE);
    let bytes = e.stream.len() as f64;
    let predicted = choice.chosen().bytes as f64;
    assert!(
        (bytes / predicted - 1.0).abs() < 0.01,
        "stream {bytes} bytes, predicted {predicted}"
    );
    choice.chosen().quantizer
}

#[test]
fn auto_keeps_the_identity_when_features_are_uncorrelated() {
    // A basis would cost 2F² + F values and find nothing to decorrelate.
    assert_eq!(check_choice(&scene(1.0)), FeatureQuantizer::Identity);
}

#[test]
fn auto_fits_a_basis_when_features_are_correlated() {
    let q = check_choice(&scene(0.6));
    assert!(matches!(q, FeatureQuantizer::Fitted { .. }), "{q:?}");
}
