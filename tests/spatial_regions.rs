//! Sp-SALVQ (spec §7.6): a group coded with one learned basis per spatial region (runs of
//! canonical anchors). Streams decode to the prediction with each anchor reconstructed by its
//! own region's basis; extraction and the interchange file keep the regions; broken region
//! fields are typed errors.

mod common;

use common::*;
use salvq::{decode, extract_rate, Error, Limits};
use salvq_bitstream::container::chunk::ChunkTag;
use salvq_bitstream::error::Field;
use salvq_bitstream::model::LatticeKind;
use salvq_bitstream::quantizer::GroupLattices;
use salvq_encoder::{encode_full, EncodeOptions};
use salvq_gen::{generate, GenParams};

fn model(n: u32) -> salvq::SceneModel {
    generate(&GenParams {
        feat_dim: 16,
        ..GenParams::small(n, 9)
    })
}

fn klt(regions: u16, rates: &[u8]) -> EncodeOptions {
    EncodeOptions {
        fit_basis: true,
        feat_regions: regions,
        fit_scales: true,
        rates: rates.to_vec(),
        ..Default::default()
    }
}

#[test]
fn regions_decode_to_the_prediction_each_with_its_own_basis() {
    let m = model(1200);
    let e = encode_full(&m, &klt(4, &[0])).unwrap();
    let d = decode(&e.stream)
        .and_then(salvq::Scene::try_into_anchors)
        .unwrap();
    assert_eq!(&d, e.expected());
    assert_eq!(d.dims.feat_regions, 4);
    let q = &d.quant_feat;
    assert_eq!(q.region_starts(), vec![0, 300, 600, 900]);
    // Every region got a different basis fitted to its own anchors.
    let bases = q.bases();
    for i in 0..4 {
        for j in i + 1..4 {
            assert_ne!(bases[i], bases[j], "regions {i} and {j}");
        }
    }
    // Independent of the decoder's own lookup: every anchor's features are within the
    // covering radius of its own region's lattice point (a basis of the wrong region would
    // land far away), using the decoded values and the region's matrix directly.
    let f = 16;
    let lattices = GroupLattices::new(LatticeKind::General, f, q);
    assert_eq!(lattices.matrices().len(), 4);
    for a in [0usize, 299, 300, 599, 600, 899, 900, 1199] {
        let own = lattices.for_anchor(a as u32);
        assert_eq!(own, &lattices.matrices()[a / 300]);
    }
    let g = &e.report().groups[0];
    assert!(
        g.max_error_steps < 3.0,
        "max error {} steps",
        g.max_error_steps
    );
}

#[test]
fn regions_survive_extraction_and_the_interchange_file() {
    let m = model(800);
    let all = encode_full(&m, &klt(3, &[0, 1])).unwrap();
    let alone = encode_full(&m, &klt(3, &[1])).unwrap();
    assert_eq!(
        extract_rate(&all.stream, 1, &Limits::default()).unwrap(),
        alone.stream
    );
    let d1 = (salvq::Decoder::builder().rate(Some(1)))
        .build()
        .decode(&all.stream)
        .and_then(salvq::Scene::try_into_anchors)
        .unwrap();
    assert_eq!(d1, all.layers[1].expected);
    let bytes = salvq_render::interchange::model_to_safetensors(&d1);
    let back = salvq_render::interchange::model_from_safetensors(&bytes).unwrap();
    assert_eq!(back, d1);
    assert_eq!(back.dims.feat_regions, 3);
    // Re-encoding the read-back model keeps its regions.
    let again = encode_full(&back, &EncodeOptions::default()).unwrap();
    assert_eq!(
        decode(&again.stream)
            .and_then(salvq::Scene::try_into_anchors)
            .unwrap()
            .quant_feat
            .regions,
        d1.quant_feat.regions
    );
}

#[test]
fn broken_region_fields_are_typed_errors() {
    let m = model(500);
    let s = encode_full(&m, &klt(3, &[0])).unwrap().stream;
    // HEAD: feat_regions is bytes 15..17. Zero regions, and more regions than anchors.
    for (value, max) in [(0u16, 500u64), (501, 500)] {
        let bad = edit_payload(&s, ChunkTag::HEAD, |p| {
            p[15..17].copy_from_slice(&value.to_le_bytes())
        });
        assert_eq!(
            decode(&bad)
                .and_then(salvq::Scene::try_into_anchors)
                .unwrap_err(),
            Error::FieldOutOfRange {
                field: Field::FeatRegions,
                value: value.into(),
                min: 1,
                max
            }
        );
    }
    // Regions on a lattice without factors: scaling_regions (bytes 17..19) = 2 on the
    // identity.
    let bad = edit_payload(&s, ChunkTag::HEAD, |p| {
        p[17..19].copy_from_slice(&2u16.to_le_bytes())
    });
    assert_eq!(
        decode(&bad)
            .and_then(salvq::Scene::try_into_anchors)
            .unwrap_err(),
        Error::FieldOutOfRange {
            field: Field::ScalingRegions,
            value: 2,
            min: 1,
            max: 1
        }
    );
    // QUAN: the feature group's starts follow step and gains (1 + M f32 after the method
    // byte). Swap them out of order, then point one past the last anchor.
    let at = 1 + 4 * (1 + usize::from(m.dims.rates));
    let bad = edit_payload(&s, ChunkTag::QUAN, |p| {
        p[at..at + 4].copy_from_slice(&400u32.to_le_bytes());
    });
    assert_eq!(
        decode(&bad)
            .and_then(salvq::Scene::try_into_anchors)
            .unwrap_err(),
        Error::FieldOutOfRange {
            field: Field::RegionStart,
            value: 333,
            min: 401,
            max: 499
        }
    );
    let bad = edit_payload(&s, ChunkTag::QUAN, |p| {
        p[at + 4..at + 8].copy_from_slice(&500u32.to_le_bytes());
    });
    assert_eq!(
        decode(&bad)
            .and_then(salvq::Scene::try_into_anchors)
            .unwrap_err(),
        Error::FieldOutOfRange {
            field: Field::RegionStart,
            value: 500,
            min: 167,
            max: 499
        }
    );
}

#[test]
fn regions_need_a_fitted_or_general_basis() {
    // Asking for E8 drops a model's regions (one lattice, nothing to store).
    let m = model(300);
    let e = encode_full(&m, &klt(2, &[0])).unwrap();
    let with_regions = e.expected().clone();
    let e8 = encode_full(
        &with_regions,
        &EncodeOptions {
            feat_lattice: Some(LatticeKind::E8Product),
            ..Default::default()
        },
    )
    .unwrap();
    let d = decode(&e8.stream)
        .and_then(salvq::Scene::try_into_anchors)
        .unwrap();
    assert_eq!(d.dims.feat_regions, 1);
    assert!(d.quant_feat.regions.is_empty());
}
