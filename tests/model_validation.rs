//! Every model-validation error (spec §2.3, §2.6, Annex A): each names the tensor and index.

mod common;

use common::*;
use safetensors::tensor::TensorView;
use safetensors::{Dtype, SafeTensors};
use salvq::Error;
use salvq_bitstream::error::Field;
use salvq_bitstream::model::names;
use salvq_encoder::encode;
use salvq_render::interchange::{model_from_safetensors, model_to_safetensors};

/// The model file as (name, dtype, shape, bytes), editable.
type Entry = (String, Dtype, Vec<usize>, Vec<u8>);

fn entries() -> Vec<Entry> {
    let bytes = model_to_safetensors(&small_salvq_model());
    let st = SafeTensors::deserialize(&bytes).unwrap();
    let mut out: Vec<Entry> = st
        .tensors()
        .into_iter()
        .map(|(n, v)| (n, v.dtype(), v.shape().to_vec(), v.data().to_vec()))
        .collect();
    out.sort_by(|a, b| a.0.cmp(&b.0));
    out
}

fn file(entries: &[Entry]) -> Vec<u8> {
    let views: Vec<(String, TensorView<'_>)> = entries
        .iter()
        .map(|(n, d, s, b)| (n.clone(), TensorView::new(*d, s.clone(), b).unwrap()))
        .collect();
    safetensors::serialize(views, None).unwrap()
}

fn edit(name: &str, f: impl FnOnce(&mut Entry)) -> Error {
    let mut e = entries();
    let entry = e.iter_mut().find(|x| x.0 == name).expect("tensor present");
    f(entry);
    match model_from_safetensors(&file(&e)).expect_err("model must be rejected") {
        salvq_render::Error::Stream(e) => e,
        other => panic!("not a rule of the model (§2): {other}"),
    }
}

fn set_f32(bytes: &mut [u8], index: usize, v: f32) {
    bytes[4 * index..4 * index + 4].copy_from_slice(&v.to_le_bytes());
}

#[test]
fn valid_file_round_trips() {
    let m = small_salvq_model();
    assert_eq!(model_from_safetensors(&file(&entries())).unwrap(), m);
    assert_eq!(
        model_from_safetensors(&model_to_safetensors(&m)).unwrap(),
        m
    );
}

#[test]
fn interchange_format() {
    assert!(matches!(
        model_from_safetensors(b"not a safetensors file").unwrap_err(),
        salvq_render::Error::InterchangeFormat { .. }
    ));
}

#[test]
fn tensor_missing() {
    let mut e = entries();
    e.retain(|x| x.0 != "mlp_cov.2.bias");
    assert_eq!(
        model_from_safetensors(&file(&e)).unwrap_err(),
        Error::TensorMissing {
            tensor: "mlp_cov.2.bias"
        }
    );
}

#[test]
fn tensor_unexpected() {
    let mut e = entries();
    e.push(("extra.tensor".into(), Dtype::F32, vec![1], vec![0; 4]));
    assert_eq!(
        model_from_safetensors(&file(&e)).unwrap_err(),
        Error::TensorUnexpected {
            name: "extra.tensor".into()
        }
    );
}

#[test]
fn tensor_dtype() {
    let err = edit(names::SCALING, |x| x.1 = Dtype::I32);
    assert!(matches!(
        err,
        Error::TensorDtype {
            tensor: "anchor.scaling",
            ..
        }
    ));
}

#[test]
fn tensor_rank() {
    let err = edit(names::FEAT, |x| x.2 = vec![x.2[0] * x.2[1]]);
    assert_eq!(
        err,
        Error::TensorRank {
            tensor: "anchor.feat",
            expected: 2,
            found: 1
        }
    );
}

#[test]
fn tensor_shape() {
    let err = edit("mlp_color.0.bias", |x| {
        x.2 = vec![x.2[0] - 1];
        x.3.truncate(x.3.len() - 4);
    });
    assert!(matches!(
        err,
        Error::TensorShape {
            tensor: "mlp_color.0.bias",
            ..
        }
    ));
}

#[test]
fn dimension_out_of_range() {
    let err = edit(names::RES_3D, |x| {
        x.3[0..4].copy_from_slice(&70_000i32.to_le_bytes())
    });
    assert!(matches!(
        err,
        Error::FieldOutOfRange {
            field: Field::Resolution3d,
            value: 70_000,
            ..
        }
    ));
}

#[test]
fn non_finite_value_names_index() {
    // anchor.feat is [13, 8]: element [3, 2] is flat index 26.
    let err = edit(names::FEAT, |x| set_f32(&mut x.3, 26, f32::NAN));
    assert_eq!(
        err,
        Error::NonFiniteValue {
            tensor: "anchor.feat",
            index: vec![3, 2]
        }
    );
    let err = edit(names::OFFSETS, |x| {
        set_f32(&mut x.3, 4 * 3 + 3 + 1, f32::INFINITY)
    });
    assert_eq!(
        err,
        Error::NonFiniteValue {
            tensor: "anchor.offsets",
            index: vec![1, 1, 1]
        }
    );
}

#[test]
fn mask_and_grid_values() {
    let err = edit(names::MASK, |x| x.3[5] = 2);
    assert_eq!(
        err,
        Error::ValueInvalid {
            tensor: "anchor.mask",
            index: vec![1, 1],
            value: 2,
            allowed: "0 or 1"
        }
    );
    let err = edit(names::GRID_XZ, |x| x.3[3] = 0);
    assert!(matches!(
        err,
        Error::ValueInvalid {
            tensor: "hyperprior.grid_xz",
            value: 0,
            ..
        }
    ));
}

#[test]
fn coordinates() {
    let err = edit(names::VOXEL, |x| {
        x.3[4..8].copy_from_slice(&(-1i32).to_le_bytes())
    });
    assert!(matches!(
        err,
        Error::CoordinateOutOfRange {
            anchor: 0,
            axis: 1,
            value: -1,
            ..
        }
    ));
    let err = edit(names::VOXEL, |x| {
        x.3[0..4].copy_from_slice(&(1i32 << 21).to_le_bytes())
    });
    assert!(matches!(
        err,
        Error::CoordinateOutOfRange {
            anchor: 0,
            axis: 0,
            ..
        }
    ));
}

#[test]
fn gains_and_steps_must_be_positive() {
    let err = edit("quant.offsets.gains", |x| set_f32(&mut x.3, 1, 0.0));
    assert_eq!(
        err,
        Error::ValueNotPositive {
            tensor: "quant.offsets.gains",
            index: vec![1],
            value: 0.0
        }
    );
    let err = edit("quant.scaling.step", |x| set_f32(&mut x.3, 0, -0.5));
    assert!(matches!(
        err,
        Error::ValueNotPositive {
            tensor: "quant.scaling.step",
            ..
        }
    ));
}

#[test]
fn singular_basis() {
    let err = edit("quant.feat.basis_s", |x| set_f32(&mut x.3, 3, 0.0));
    assert_eq!(
        err,
        Error::BasisSingular {
            tensor: "quant.feat.basis_s",
            index: 3
        }
    );
}

#[test]
fn ill_conditioned_basis() {
    let err = edit("quant.feat.basis_s", |x| set_f32(&mut x.3, 0, 1e7));
    assert!(matches!(
        err,
        Error::BasisIllConditioned { tensor: "quant.feat.basis_s", max, .. } if max == 1e6
    ));
}

#[test]
fn non_orthogonal_basis() {
    let err = edit("quant.feat.basis_v", |x| {
        let v = f32::from_le_bytes(x.3[0..4].try_into().unwrap());
        set_f32(&mut x.3, 0, v * 1.5 + 0.1);
    });
    assert!(matches!(
        err,
        Error::BasisNotOrthogonal {
            tensor: "quant.feat.basis_v",
            index: [0, 0],
            ..
        }
    ));
}

#[test]
fn encoder_rejects_wrong_lengths_in_memory() {
    let mut m = small_salvq_model();
    m.anchors.feat.pop();
    assert!(matches!(
        encode(&m).unwrap_err(),
        salvq_encoder::Error::Stream(Error::TensorShape {
            tensor: "anchor.feat",
            ..
        })
    ));
    let mut m = small_salvq_model();
    m.quant_feat.basis = None;
    assert_eq!(
        encode(&m).unwrap_err(),
        Error::TensorMissing {
            tensor: "quant.feat.basis_u"
        }
    );
    let mut m = small_salvq_model();
    m.anchors.scaling[7] = f32::NEG_INFINITY;
    assert_eq!(
        encode(&m).unwrap_err(),
        Error::NonFiniteValue {
            tensor: "anchor.scaling",
            index: vec![1, 1]
        }
    );
}
