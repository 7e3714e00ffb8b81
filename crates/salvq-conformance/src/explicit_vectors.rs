//! The explicit profile's conformance vectors (spec §3, §11.6): valid streams of seeded
//! synthetic Gaussians (Annex B.6) coded with fixed plans (no rendering, so regenerating
//! gives the same bytes), and must-fail streams that each break one rule of §3.

use salvq::container::chunk::ChunkTag;
use salvq::container::surgery;
use salvq::explicit::Gaussians;
use salvq_encoder::explicit::{
    encode_prepared, EncodedGaussians, ExplicitOptions, PreparedGaussians, RateControl, RatePlan,
};
use salvq_encoder::Result;
use salvq_gen::gaussians::{generate_gaussians, GaussianParams};

pub use super::explicit_must_fail::explicit_must_fail_vectors;

/// Sections every explicit valid vector exercises.
pub const EXPLICIT_SECTIONS: &[&str] = &[
    "§0.1", "§0.2", "§0.4", "§1.1", "§1.2", "§1.3", "§1.5", "§3.1", "§3.2", "§3.3", "§3.4", "§3.5",
    "§3.6", "§3.7", "§6.1", "§6.2", "§6.2.1", "§6.2.4", "§6.2.5", "§6.2.6", "§6.3", "§6.4", "§7.3",
    "§8.1", "§8.2", "§8.3", "§8.4", "§10.1", "§10.2", "§11.4", "§11.5", "§11.6",
];

/// An explicit-profile stream a conformant decoder must decode, at each of `rates`, to the
/// encoder's prediction `oracle`.
pub struct ExplicitVector {
    pub name: &'static str,
    pub description: &'static str,
    pub sections: &'static [&'static str],
    pub stream: Vec<u8>,
    pub rates: Vec<u8>,
    pub oracle: Vec<Gaussians>,
}

/// A plan: voxel edge, refinement per size class, base steps (scale, opacity, rotation,
/// DC, rest) and shifts per class for the groups after the scale.
fn plan(voxel: f64, refine: [u8; 4], steps: &[f64], shift: &[[i8; 4]]) -> RatePlan {
    RatePlan {
        voxel,
        refine,
        steps: steps.to_vec(),
        shift: shift.to_vec(),
    }
}

/// `plans` scaled by 2^k for rate k (coarser rates), shifts kept.
pub(crate) fn rates(first: &RatePlan, m: usize) -> Vec<RatePlan> {
    (0..m)
        .map(|k| {
            let f = (k as f64).exp2();
            RatePlan {
                voxel: first.voxel * f,
                steps: first.steps.iter().map(|s| s * f).collect(),
                ..first.clone()
            }
        })
        .collect()
}

/// Encodes the synthetic scene `params` with `plans` and `options`.
pub fn encode_synthetic(
    params: &GaussianParams,
    plans: Vec<RatePlan>,
    options: ExplicitOptions,
) -> Result<EncodedGaussians> {
    let g = generate_gaussians(params);
    let p = PreparedGaussians::new(&g)?;
    let options = ExplicitOptions {
        rates: RateControl::Plans(plans.clone()),
        ..options
    };
    encode_prepared(&p, &plans, &options)
}

fn vector(
    name: &'static str,
    description: &'static str,
    sections: &'static [&'static str],
    e: EncodedGaussians,
) -> ExplicitVector {
    ExplicitVector {
        name,
        description,
        sections,
        rates: e.layers.iter().map(|l| l.0.rate).collect(),
        oracle: e.layers.into_iter().map(|l| l.2).collect(),
        stream: e.stream,
    }
}

const SHIFTS_SH0: [[i8; 4]; 3] = [[1, 0, 0, -1], [2, 1, 0, 0], [1, 0, 0, 0]];
const SHIFTS_SH: [[i8; 4]; 4] = [[1, 0, 0, -1], [2, 1, 0, 0], [1, 0, 0, 0], [2, 1, 0, 0]];

/// The base plan of the vectors with SH rest (`sh` true) or without.
pub(crate) fn base_plan(sh: bool) -> RatePlan {
    if sh {
        plan(
            0.05,
            [3, 2, 1, 0],
            &[0.1, 0.25, 0.03, 0.03, 0.04],
            &SHIFTS_SH,
        )
    } else {
        plan(0.05, [3, 2, 1, 0], &[0.1, 0.25, 0.03, 0.03], &SHIFTS_SH0)
    }
}

/// Every explicit valid vector, in a fixed order.
pub fn explicit_valid_vectors() -> Result<Vec<ExplicitVector>> {
    let options = |tiles: u32, coded: Option<Vec<u8>>, klt: Option<Vec<bool>>| ExplicitOptions {
        coded,
        klt,
        tile_gaussians: tiles,
        progressive: false,
        ..Default::default()
    };
    Ok(vec![
        vector(
            "g-sh0",
            "200 synthetic Gaussians, SH degree 0, one rate, identity lattices, size classes \
             with refinement and step shifts, 3 tiles",
            &[],
            encode_synthetic(
                &GaussianParams::new(200, 0, 3),
                vec![base_plan(false)],
                options(80, None, Some(vec![false; 4])),
            )?,
        ),
        vector(
            "g-sh3-rates",
            "120 synthetic Gaussians, SH degree 3, three rates (all decoded), KLT bases \
             (lattice 4) for SH DC and SH rest, 2 tiles",
            &["§7.4"],
            encode_synthetic(
                &GaussianParams::new(120, 3, 5),
                rates(&base_plan(true), 3),
                options(64, None, Some(vec![false, false, false, true, true])),
            )?,
        ),
        vector(
            "g-sh1-single",
            "one Gaussian, SH degree 1",
            &[],
            encode_synthetic(
                &GaussianParams::new(1, 1, 7),
                vec![base_plan(true)],
                options(16_384, None, None),
            )?,
        ),
        vector(
            "g-sh1-predicted",
            "80 synthetic Gaussians, SH degree 1, every group predicted from its reference \
             (predict = 1, so the size class follows the predicted scale coordinates)",
            &[],
            encode_synthetic(
                &GaussianParams::new(80, 1, 13),
                vec![base_plan(true)],
                ExplicitOptions {
                    variant: salvq_encoder::explicit::Variant {
                        predict_all: true,
                        ..Default::default()
                    },
                    ..options(16_384, None, None)
                },
            )?,
        ),
        vector(
            "g-sh2-one-voxel",
            "40 Gaussians at one position (one voxel, counts of §8.4), SH degree 2, rate 1 of \
             two coded alone",
            &["§7.4"],
            encode_synthetic(
                &GaussianParams {
                    one_point: true,
                    ..GaussianParams::new(40, 2, 9)
                },
                rates(&base_plan(true), 2),
                options(16_384, Some(vec![1]), None),
            )?,
        ),
        vector(
            "g-wide-scales",
            "150 synthetic Gaussians, SH degree 0, steps 40 to 300 times finer than g-sh0's, so \
             that the residuals spread over hundreds to thousands of steps: wide scales \
             (scale indices 64 … 127, §6.3.6), 2 tiles",
            &["§6.3.6"],
            encode_synthetic(
                &GaussianParams::new(150, 0, 17),
                vec![plan(
                    0.05,
                    [3, 2, 1, 0],
                    &[0.0005, 0.05, 0.0001, 0.01],
                    &SHIFTS_SH0,
                )],
                options(80, None, Some(vec![false; 4])),
            )?,
        ),
        vector(
            "g-sh3-progressive",
            "600 synthetic Gaussians, SH degree 3, three rates with steps doubling per rate as a \
             progressive stream (§3.8): rate 2 a full layer, rates 1 and 0 refinements (step \
             factors 1 and 3, position bits added, predictions and the sh_rest count), KLT bases \
             for SH DC and SH rest, tiles of at most 64",
            &["§3.8", "§3.8.1", "§3.8.2", "§3.8.3", "§7.4"],
            encode_synthetic(
                &GaussianParams::new(600, 3, 23),
                rates(&base_plan(true), 3),
                ExplicitOptions {
                    progressive: true,
                    ..options(64, None, Some(vec![false, false, false, true, true]))
                },
            )?,
        ),
        vector(
            "g-sh0-progressive-skip",
            "300 synthetic Gaussians, SH degree 0, rates 0 and 2 of three coded as a progressive \
             stream (§3.8) whose steps shrink 16 times from rate 2 to rate 0 (step factors 5 and \
             more), identity lattices, 4 tiles",
            &["§3.8", "§3.8.1", "§3.8.2", "§3.8.3", "§7.4"],
            encode_synthetic(
                &GaussianParams::new(300, 0, 29),
                {
                    let base = base_plan(false);
                    (0..3)
                        .map(|k| {
                            let f = (2.0 * k as f64).exp2();
                            RatePlan {
                                voxel: base.voxel * f,
                                steps: base.steps.iter().map(|s| s * f).collect(),
                                ..base.clone()
                            }
                        })
                        .collect()
                },
                ExplicitOptions {
                    progressive: true,
                    ..options(80, Some(vec![0, 2]), Some(vec![false; 4]))
                },
            )?,
        ),
        rotation_near_sphere()?,
    ])
}

/// The rotation group's three values of `g-rotation-near-sphere`: a·a + b·b + c·c is 1 to
/// within a few binary32 units, where §3.6 step 3 evaluated in binary32 changes by 3.45e-4
/// when a multiply and an add are fused.
const NEAR_SPHERE: [f32; 3] = [0.577_296_9, 0.577_369_15, 0.577_384_7];

/// A valid stream whose decoded rotations sit where a decoder that evaluates §3.6 step 3 in
/// binary32 with a fused multiply-add fails §11.3's tolerance: `g-sh0`'s kind of stream with
/// the rotation group's mean moved onto the unit sphere and its step made tiny (`GQUA`
/// edited; every field stays valid). Its oracle is the reference decode, checked here to
/// differ from the fused binary32 form beyond the tolerance for most Gaussians.
fn rotation_near_sphere() -> Result<ExplicitVector> {
    let e = encode_synthetic(
        &GaussianParams::new(60, 0, 31),
        vec![base_plan(false)],
        ExplicitOptions {
            klt: Some(vec![false; 4]),
            progressive: false,
            ..Default::default()
        },
    )?;
    // GQUA (§3.3), SH degree 0, one rate, identity lattices: coding_method, then per group
    // lattice, step, one gain, d means: scale (d = 3) at 1, opacity (d = 1) at 22, rotation
    // (d = 3) at 35: its step at 36, its means at 44.
    let stream = surgery::edit_payload(&e.stream, ChunkTag::GQUA, |p| {
        assert_eq!(p[35], 0, "the rotation group's lattice is the identity");
        p[36..40].copy_from_slice(&1e-9f32.to_le_bytes());
        for (j, v) in NEAR_SPHERE.iter().enumerate() {
            p[44 + 4 * j..48 + 4 * j].copy_from_slice(&v.to_le_bytes());
        }
    })
    .expect("the stream has a GQUA");
    let decoded = salvq::explicit::decode_gaussians(&stream, &Default::default(), None)?;
    let g = decoded.gaussians;
    let beyond = g
        .rotations
        .iter()
        .filter(|q| {
            // m, near 0, is the component of least magnitude; a, b, c are the others in order.
            let k = (0..4)
                .min_by(|&i, &j| q[i].abs().total_cmp(&q[j].abs()))
                .unwrap_or(0);
            let mut abc = (0..4).filter(|&i| i != k).map(|i| q[i]);
            let (a, b, c) = (abc.next(), abc.next(), abc.next());
            let (Some(a), Some(b), Some(c)) = (a, b, c) else {
                return false;
            };
            let t = 1.0 - c.mul_add(c, a.mul_add(a, b * b));
            let fused32 = if t > 0.0 { t.sqrt() } else { 0.0 };
            let tolerance = 2f32.powi(-14) * (1.0 + q[k].abs());
            (fused32 - q[k]).abs() > tolerance
        })
        .count();
    assert!(
        2 * beyond > g.rotations.len(),
        "only {beyond} of {} rotations tell a fused binary32 evaluation apart",
        g.rotations.len()
    );
    Ok(ExplicitVector {
        name: "g-rotation-near-sphere",
        description: "60 synthetic Gaussians, SH degree 0, whose rotation values sit on the \
                      unit sphere to within a few binary32 units (GQUA's rotation mean moved \
                      there, its step 1e-9): §3.6 step 3 in binary64, which a fused \
                      multiply-add cannot change",
        sections: &[],
        rates: vec![0],
        oracle: vec![g],
        stream,
    })
}
