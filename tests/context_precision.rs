//! The context MLP's weight storage (§1.6.2 Table 1-7, Annex A.5.4): i8 when it is
//! smaller at equal distortion, with the base steps refined to hold the distortion.

use salvq::SceneModel;
use salvq_bitstream::container::payload::ContextPrecision;
use salvq_encoder::context_precision::{MAX_REFINED_RATIO, MSE_TOLERANCE};
use salvq_encoder::{encode_full, values_mse as mse, EncodeOptions};
use salvq_gen::{generate, GenParams};

fn group_mse(m: &SceneModel, d: &SceneModel) -> [f64; 3] {
    [
        mse(&m.anchors.feat, &d.anchors.feat),
        mse(&m.anchors.scaling, &d.anchors.scaling),
        mse(&m.anchors.offsets, &d.anchors.offsets),
    ]
}

#[test]
fn i8_weights_are_chosen_when_smaller_at_equal_distortion() {
    let m = generate(&GenParams {
        feat_basis: false,
        ..GenParams::new(2000, 4)
    })
    .to_canonical_order();
    let auto = encode_full(&m, &EncodeOptions::default()).unwrap();
    let wide = encode_full(
        &m,
        &EncodeOptions {
            context_precision: Some(ContextPrecision::I16),
            ..Default::default()
        },
    )
    .unwrap();
    let c = auto.context;
    assert_eq!(c.precision, ContextPrecision::I8, "{c:?}");
    assert_eq!(c.sample_anchors, m.n());
    assert!(
        c.mse_ratio.iter().all(|&r| r <= 1.0 + MSE_TOLERANCE),
        "{c:?}"
    );
    let floor = 1.0 / MAX_REFINED_RATIO.sqrt();
    assert!(
        c.step_factors.iter().all(|&f| (floor..=1.0).contains(&f)),
        "{c:?}"
    );
    // Smaller, as measured, and the whole stream's distortion held within the tolerance
    // (here the sample is every anchor, so the measurement is the stream itself).
    assert!(auto.stream.len() < wide.stream.len());
    let (a, w) = (
        group_mse(&m, auto.expected()),
        group_mse(&m, wide.expected()),
    );
    for g in 0..3 {
        assert!(
            a[g] <= w[g] * (1.0 + MSE_TOLERANCE),
            "group {g}: {} vs {}",
            a[g],
            w[g]
        );
    }
    let d = &m.dims;
    let weights = (d.context_input() + d.context_output()) * u64::from(d.context_hidden);
    assert_eq!(c.model_bytes_saved, weights);
}

#[test]
fn weights_too_large_for_i8_stay_i16() {
    let mut m = generate(&GenParams {
        feat_basis: false,
        ..GenParams::small(300, 2)
    });
    // |w| = 200 cannot be an i8 at a0 = 0 (the coarsest unit is 1).
    m.mlp_grid.w0[0] = 200.0;
    let e = encode_full(&m, &EncodeOptions::default()).unwrap();
    assert_eq!(e.context.precision, ContextPrecision::I16);
    assert_eq!(e.context.sample_anchors, 0);
    let forced = encode_full(
        &m,
        &EncodeOptions {
            context_precision: Some(ContextPrecision::I8),
            ..Default::default()
        },
    );
    assert!(
        matches!(
            forced,
            Err(salvq_encoder::Error::Stream(
                salvq::Error::ValueInvalid { .. }
            ))
        ),
        "{forced:?}"
    );
}
