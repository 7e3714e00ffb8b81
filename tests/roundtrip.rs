//! encode -> decode gives exactly the model the encoder predicts (its reconstruction, the
//! integer MLP's weights, +1 at untouched grid entries), attributes stay within half a step,
//! the interchange file round-trips, and the generator is deterministic.

mod common;

use common::*;
use salvq::{decode, SceneModel};
use salvq_encoder::{encode, encode_with_options};
use salvq_encoder::{encode_full, EncodeOptions};
use salvq_gen::{generate, GenParams};
use salvq_render::interchange::{model_from_safetensors, model_to_safetensors};

fn sha256(bytes: &[u8]) -> String {
    use sha2::{Digest, Sha256};
    Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

fn usq(p: GenParams) -> SceneModel {
    generate(&GenParams {
        feat_basis: false,
        ..p
    })
}

/// Decodes the stream of `m` and checks it against the encoder's prediction and the input.
fn check(m: &SceneModel) {
    let e = encode_full(m, &EncodeOptions::default()).unwrap();
    let decoded = decode(&e.stream)
        .and_then(salvq::Scene::try_into_anchors)
        .unwrap();
    assert_eq!(
        &decoded,
        e.expected(),
        "decoder output differs from the encoder's prediction"
    );
    let c = m.to_canonical_order();
    assert_eq!(decoded.anchors.voxel, c.anchors.voxel);
    assert_eq!(decoded.anchors.mask, c.anchors.mask);
    // The Scaffold-GS MLPs are lossless at the precision the encoder chose (§1.6.2).
    assert_eq!(
        decoded.mlp_color,
        salvq_encoder::precision::rounded(&c.mlp_color, e.scaffold.precision)
    );
    // Quantizers are lossless but for the base steps the encoder may refine to hold the
    // distortion with i8 context-MLP weights (Annex A.5.4): at most a factor 1/sqrt(1.05).
    let f = e.context.step_factors;
    let refined = salvq::SceneModel {
        quant_feat: salvq_bitstream::model::GroupQuantizer {
            step: (f64::from(c.quant_feat.step) * f[0]) as f32,
            ..c.quant_feat.clone()
        },
        quant_scaling: salvq_bitstream::model::GroupQuantizer {
            step: (f64::from(c.quant_scaling.step) * f[1]) as f32,
            ..c.quant_scaling.clone()
        },
        quant_offsets: salvq_bitstream::model::GroupQuantizer {
            step: (f64::from(c.quant_offsets.step) * f[2]) as f32,
            ..c.quant_offsets.clone()
        },
        ..c.clone()
    };
    assert!(f.iter().all(|&x| (0.975..=1.0).contains(&x)), "{f:?}");
    assert_eq!(decoded.quant_feat, refined.quant_feat);
    assert_eq!(decoded.quant_scaling, refined.quant_scaling);
    assert_eq!(decoded.quant_offsets, refined.quant_offsets);
    for g in &e.report().groups {
        assert!(
            g.max_error_steps <= 0.5 + 1e-4,
            "{}: {}",
            g.group,
            g.max_error_steps
        );
    }
    // Masked offsets decode as 0.
    let k = usize::from(m.dims.offsets);
    for (i, &b) in decoded.anchors.mask.iter().enumerate() {
        if b == 0 {
            assert_eq!(&decoded.anchors.offsets[3 * i..3 * i + 3], &[0.0; 3]);
        }
    }
    assert_eq!(decoded.anchors.offsets.len(), m.n() * k * 3);
}

#[test]
fn small_models_of_several_sizes() {
    for (n, seed) in [(1, 1), (2, 9), (13, 2), (500, 3)] {
        check(&usq(GenParams::small(n, seed)));
    }
}

#[test]
fn a_hac_size_model() {
    check(&usq(GenParams::new(2_000, 5)));
}

#[test]
fn every_rate() {
    let m = usq(GenParams::small(300, 8));
    let mut sizes = Vec::new();
    for rate in 0..m.dims.rates {
        let options = EncodeOptions {
            rates: vec![rate],
            ..Default::default()
        };
        let e = encode_full(&m, &options).unwrap();
        assert_eq!(
            &decode(&e.stream)
                .and_then(salvq::Scene::try_into_anchors)
                .unwrap(),
            e.expected()
        );
        sizes.push(e.stream.len());
    }
    // Larger gains are coarser steps: fewer bytes.
    assert!(sizes.windows(2).all(|w| w[0] > w[1]), "{sizes:?}");
}

#[test]
fn coded_size_is_within_half_a_percent_of_the_ideal() {
    let m = usq(GenParams::new(5_000, 2));
    let e = encode_full(&m, &EncodeOptions::default()).unwrap();
    for g in &e.report().groups {
        let ideal = g.ideal_bits_integer / 8.0;
        // One coder state (8 bytes) and the method byte per chunk on top of 0.5 %.
        assert!(
            (g.coded_bytes as f64) <= 1.005 * ideal + 16.0,
            "{}: coded {} ideal {ideal}",
            g.group,
            g.coded_bytes
        );
    }
}

#[test]
fn non_canonical_input_decodes_in_canonical_order() {
    let m = small_model();
    let mut shuffled = m.clone();
    let n = m.n();
    let d = &m.dims;
    let rev = |v: &[f32], w: usize| -> Vec<f32> {
        (0..n)
            .rev()
            .flat_map(|i| v[i * w..(i + 1) * w].to_vec())
            .collect()
    };
    let k = usize::from(d.offsets);
    shuffled.anchors.voxel.reverse();
    shuffled.anchors.mask = (0..n)
        .rev()
        .flat_map(|i| m.anchors.mask[i * k..(i + 1) * k].to_vec())
        .collect();
    shuffled.anchors.feat = rev(&m.anchors.feat, usize::from(d.feat_dim));
    shuffled.anchors.scaling = rev(&m.anchors.scaling, usize::from(d.scaling_dim));
    shuffled.anchors.offsets = rev(&m.anchors.offsets, 3 * k);
    assert!(!shuffled.is_canonical());
    assert_eq!(shuffled.to_canonical_order(), m.to_canonical_order());
    assert_eq!(
        decode(&encode(&shuffled).unwrap())
            .and_then(salvq::Scene::try_into_anchors)
            .unwrap(),
        small_expected()
    );
}

#[test]
fn shared_voxels_round_trip() {
    // Real Octree-GS models put several anchors in one voxel; the format keeps them all.
    let mut m = small_model();
    m.anchors.voxel[4] = m.anchors.voxel[3];
    m.anchors.voxel[5] = m.anchors.voxel[3];
    check(&m);
}

#[test]
fn all_zero_masks_round_trip() {
    let mut m = usq(GenParams::small(40, 4));
    for b in &mut m.anchors.mask[..12] {
        *b = 0;
    }
    check(&m);
}

#[test]
fn encoder_note_is_an_ancillary_chunk() {
    let m = small_model();
    let options = EncodeOptions {
        encoder_note: Some("salvq test".into()),
        ..Default::default()
    };
    let s = encode_with_options(&m, &options).unwrap();
    assert!(chunks(&s)
        .iter()
        .any(|(t, p)| t.0 == *b"encd" && p == b"salvq test"));
    assert_eq!(
        decode(&s).and_then(salvq::Scene::try_into_anchors).unwrap(),
        small_expected()
    );
}

#[test]
fn interchange_round_trip_is_exact() {
    let m = generate(&GenParams::new(300, 4));
    let bytes = model_to_safetensors(&m);
    assert_eq!(model_from_safetensors(&bytes).unwrap(), m);
    assert_eq!(
        model_to_safetensors(&model_from_safetensors(&bytes).unwrap()),
        bytes
    );
}

#[test]
fn generator_is_deterministic() {
    let a = model_to_safetensors(&generate(&GenParams::small(200, 11)));
    let b = model_to_safetensors(&generate(&GenParams::small(200, 11)));
    assert_eq!(a, b);
    let c = model_to_safetensors(&generate(&GenParams::small(200, 12)));
    assert_ne!(a, c);
}

/// Golden hashes: a change here means generated scenes or the coded stream changed on this
/// machine or build. Regenerate only for an intended change, and say so in the commit.
#[test]
fn golden_hashes() {
    let small = model_to_safetensors(&generate(&GenParams::small(64, 1)));
    let hac = model_to_safetensors(&generate(&GenParams::new(1_000, 1)));
    let stream = encode(&usq(GenParams::small(64, 1))).unwrap();
    let hac_stream = encode(&usq(GenParams::new(1_000, 1))).unwrap();
    let decoded = model_to_safetensors(
        &decode(&hac_stream)
            .and_then(salvq::Scene::try_into_anchors)
            .unwrap(),
    );
    let got = [
        ("small(64, 1) model", sha256(&small)),
        ("new(1000, 1) model", sha256(&hac)),
        ("small(64, 1) usq stream", sha256(&stream)),
        ("new(1000, 1) usq stream", sha256(&hac_stream)),
        ("new(1000, 1) usq decoded", sha256(&decoded)),
    ];
    let want = [
        "cf213b44c1b515e3b66c2cbb28b0b3d4525fbf1ea2ee7e8f6995bc2851a4b0c5",
        "817410082188887bc632e00b33196cce5000ffa50d6a537c3e07a87f38aef03f",
        "72b25fa7702eeba0a9095022f27827d8f32210d61564a4a79d8d4b5a77d75d8c",
        "baf101220375d5af57f3a6a69625c9d602266a1f591c503dc13eabb350b6394f",
        "ae2c4f3c2d96f482ccae0c598a54dc4dab3af7d292465af2ff58fdaef64818d9",
    ];
    for ((what, hash), want) in got.iter().zip(want) {
        assert_eq!(hash, want, "{what}");
    }
}

/// Threads come with the `parallel` feature; without it the decoder has one.
#[cfg(feature = "parallel")]
#[test]
fn decoded_output_does_not_depend_on_the_thread_count() {
    let m = usq(GenParams::new(5_000, 6));
    let e = encode_full(&m, &EncodeOptions::default()).unwrap();
    let with = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| {
                decode(&e.stream)
                    .and_then(salvq::Scene::try_into_anchors)
                    .unwrap()
            })
    };
    let one = with(1);
    assert_eq!(&one, e.expected());
    assert_eq!(with(2), one);
    assert_eq!(with(3), one);
}
