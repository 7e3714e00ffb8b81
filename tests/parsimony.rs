//! Least sufficient structure: removing a hash-grid level from a model.

use salvq_bitstream::model::validate::validate_model;
use salvq_encoder::parsimony::{grid_levels, prune_grid_levels, without_level, GridLevel};
use salvq_encoder::{encode_full, EncodeOptions};
use salvq_gen::{generate, GenParams};

fn model() -> salvq::SceneModel {
    generate(&GenParams {
        feat_basis: false,
        ..GenParams::small(300, 4)
    })
    .to_canonical_order()
}

/// The model with zero `mlp_grid` weights on 3D level 1's inputs: that level carries nothing.
fn with_silent_level_1(mut m: salvq::SceneModel) -> salvq::SceneModel {
    let cin = m.mlp_grid.w0.len() / m.mlp_grid.b0.len();
    let c = usize::from(m.dims.grid_channels);
    for row in m.mlp_grid.w0.chunks_mut(cin) {
        row[c..2 * c].fill(0.0);
    }
    m
}

/// A level whose `mlp_grid` inputs have zero weight carries nothing: without it the prior is
/// the same (the folded bias adds 0), so every symbol and reconstruction is the same and the
/// stream is smaller by that level's `GRID` bits.
#[test]
fn a_level_with_zero_weights_goes_at_no_cost() {
    let m = with_silent_level_1(model());
    let c = usize::from(m.dims.grid_channels);
    let full = encode_full(&m, &EncodeOptions::default()).unwrap();
    let pruned = without_level(&m, GridLevel::ThreeD(1)).unwrap();
    validate_model(&pruned).unwrap();
    assert_eq!(pruned.dims.res_3d.len(), m.dims.res_3d.len() - 1);
    assert_eq!(
        pruned.mlp_grid.w0.len(),
        m.mlp_grid.w0.len() - c * m.mlp_grid.b0.len()
    );
    let smaller = encode_full(&pruned, &EncodeOptions::default()).unwrap();
    assert!(smaller.stream.len() < full.stream.len());
    assert_eq!(smaller.expected().anchors, full.expected().anchors);
    assert_eq!(
        salvq::decode(&smaller.stream)
            .and_then(salvq::Scene::try_into_anchors)
            .unwrap(),
        *smaller.expected()
    );
}

#[test]
fn every_level_can_be_removed_but_the_last() {
    let m = model();
    for level in grid_levels(&m) {
        let p = without_level(&m, level).unwrap();
        validate_model(&p).unwrap();
        let e = encode_full(&p, &EncodeOptions::default()).unwrap();
        assert_eq!(
            salvq::decode(&e.stream)
                .and_then(salvq::Scene::try_into_anchors)
                .unwrap(),
            *e.expected(),
            "{level}"
        );
    }
    let mut one = m.clone();
    while let Some(&level) = grid_levels(&one).first() {
        match without_level(&one, level) {
            Some(p) => one = p,
            None => break,
        }
    }
    assert_eq!(one.dims.res_3d.len() + one.dims.res_2d.len(), 1);
}

/// The greedy search only accepts removals that shrink the stream within the error slack,
/// and finds a level that carries nothing.
#[test]
fn pruning_never_grows_the_stream() {
    let m = with_silent_level_1(model());
    let before = encode_full(&m, &EncodeOptions::default())
        .unwrap()
        .stream
        .len() as u64;
    let (pruned, trials) = prune_grid_levels(&m, &EncodeOptions::default(), 0.01).unwrap();
    let after = encode_full(&pruned, &EncodeOptions::default())
        .unwrap()
        .stream
        .len() as u64;
    assert!(after <= before);
    let mut last = before;
    let mse0 = trials.first().map_or(0.0, |t| t.mse_with);
    for t in &trials {
        assert_eq!(t.bytes_with, last);
        assert!(t.bytes_without < t.bytes_with && t.mse_without <= mse0 * 1.01);
        last = t.bytes_without;
    }
    assert_eq!(last, after);
    assert!(
        trials.iter().any(|t| t.level == GridLevel::ThreeD(1)),
        "{trials:?}"
    );
}

/// Deciding on a sample of the anchors finds the silent level too, and the pruned structure
/// applies to every anchor.
#[test]
fn pruning_on_a_sample_applies_to_all_anchors() {
    use salvq_encoder::parsimony::prune_grid_levels_sampled;
    let m = with_silent_level_1(model());
    let (pruned, trials) =
        prune_grid_levels_sampled(&m, &EncodeOptions::default(), 0.01, 100).unwrap();
    assert!(trials.iter().all(|t| t.sample_anchors == 100));
    assert!(
        trials.iter().any(|t| t.level == GridLevel::ThreeD(1)),
        "{trials:?}"
    );
    assert_eq!(pruned.n(), m.n());
    validate_model(&pruned).unwrap();
    let e = encode_full(&pruned, &EncodeOptions::default()).unwrap();
    assert_eq!(
        salvq::decode(&e.stream)
            .and_then(salvq::Scene::try_into_anchors)
            .unwrap(),
        *e.expected()
    );
    let before = encode_full(&m, &EncodeOptions::default())
        .unwrap()
        .stream
        .len();
    assert!(e.stream.len() < before);
}
