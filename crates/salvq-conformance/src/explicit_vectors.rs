//! The explicit profile's conformance vectors (spec §3, §11.6): valid streams of seeded
//! synthetic Gaussians (Annex B.6) coded with fixed plans (no rendering, so regenerating
//! gives the same bytes), and must-fail streams that each break one rule of §3.

use salvq_bitstream::explicit::Gaussians;
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

pub(crate) fn vector(
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
    let mut out = layered_vectors()?;
    out.extend(layered_edge_vectors()?);
    out.extend(progressive_vectors()?);
    Ok(out)
}

/// The options of a layered vector: tiles of at most `tiles` Gaussians, the rates `coded`
/// (all when `None`), KLT per group (the encoder's choice when `None`).
fn vector_options(tiles: u32, coded: Option<Vec<u8>>, klt: Option<Vec<bool>>) -> ExplicitOptions {
    ExplicitOptions {
        coded,
        klt,
        tile_gaussians: tiles,
        progressive: false,
        ..Default::default()
    }
}

/// Layered vectors of each SH degree (§3, §7.4): SH degree 0 at one rate, SH degree 3 at
/// three rates with KLT bases, one Gaussian of SH degree 1.
fn layered_vectors() -> Result<Vec<ExplicitVector>> {
    Ok(vec![
        vector(
            "g-sh0",
            "200 synthetic Gaussians, SH degree 0, one rate, identity lattices, size classes \
             with refinement and step shifts, 3 tiles",
            &[],
            encode_synthetic(
                &GaussianParams::new(200, 0, 3),
                vec![base_plan(false)],
                vector_options(80, None, Some(vec![false; 4])),
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
                vector_options(64, None, Some(vec![false, false, false, true, true])),
            )?,
        ),
        vector(
            "g-sh1-single",
            "one Gaussian, SH degree 1",
            &[],
            encode_synthetic(
                &GaussianParams::new(1, 1, 7),
                vec![base_plan(true)],
                vector_options(16_384, None, None),
            )?,
        ),
    ])
}

/// Layered vectors of edge cases (§3.5, §6.3.6, §7.4, §8.4): every group predicted, every
/// Gaussian in one voxel, wide scales.
fn layered_edge_vectors() -> Result<Vec<ExplicitVector>> {
    Ok(vec![
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
                    ..vector_options(16_384, None, None)
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
                vector_options(16_384, Some(vec![1]), None),
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
                vector_options(80, None, Some(vec![false; 4])),
            )?,
        ),
    ])
}

/// Progressive vectors (§3.8): three rates with steps doubling, and two coded rates of three
/// with a rate skipped.
fn progressive_vectors() -> Result<Vec<ExplicitVector>> {
    Ok(vec![
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
                    ..vector_options(64, None, Some(vec![false, false, false, true, true]))
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
                    ..vector_options(80, Some(vec![0, 2]), Some(vec![false; 4]))
                },
            )?,
        ),
    ])
}
