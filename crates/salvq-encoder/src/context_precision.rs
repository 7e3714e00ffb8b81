//! Least sufficient precision for the integer context MLP (Annex A.5.4): its
//! weights stored as i8 instead of i16 (§1.6.2 Table 1-7) when the symbol bytes that costs,
//! measured, are fewer than the model bytes it saves, at equal distortion. The MLP's outputs
//! are the coder's scales, but also the means values are quantized around and the step
//! adjustments (§5.4): coarser weights add noise to the log-step, which raises the MSE (by
//! 0.5–1.5 % on generated scenes). A group whose MSE grows gets its base step scaled by
//! `1/sqrt(ratio)` (paid for in symbol bytes), and then each group's MSE must be within
//! [`MSE_TOLERANCE`] of the i16 one.

use serde::Serialize;

use crate::error::Result;
use salvq_bitstream::container::payload::{context_bytes, ContextPrecision, ScaffoldPrecision};
use salvq_bitstream::model::SceneModel;

use super::parsimony::subsample;
use super::values_mse as mse;
use super::{encode_full, EncodeOptions};

/// Anchors the two trial encodes use (every k-th canonical anchor above this).
pub const CONTEXT_SAMPLE: usize = 2048;

/// Largest relative growth of a group's reconstruction MSE that counts as equal distortion.
pub const MSE_TOLERANCE: f64 = 0.01;

/// Largest MSE ratio (i8 over i16) that a refined step may compensate; above it, i16.
pub const MAX_REFINED_RATIO: f64 = 1.05;

/// What the encoder chose for the context MLP's weights, and why.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ContextChoice {
    /// The precision chosen.
    pub precision: ContextPrecision,
    /// Model bytes i8 weights save against i16.
    pub model_bytes_saved: u64,
    /// Symbol bytes i8 weights cost over all anchors, estimated from the sample (negative
    /// when they save); 0 when not measured.
    pub symbol_bytes_cost: i64,
    /// Anchors measured on; 0 when the choice was not measured (asked for, or i8 cannot hold
    /// the weights).
    pub sample_anchors: usize,
    /// Reconstruction MSE with i8 (and the step factors) over that with i16, per group
    /// (feature, scaling, offsets), on the sample at rate 0; 1 when not measured.
    pub mse_ratio: [f64; 3],
    /// Factors on the groups' base steps (`quant.*.step`) that come with i8, to hold the
    /// distortion; all 1 with i16.
    pub step_factors: [f64; 3],
}

impl ContextChoice {
    /// `m` with the chosen step factors applied (a copy only when one is not 1).
    pub fn apply<'a>(&self, m: &'a SceneModel) -> std::borrow::Cow<'a, SceneModel> {
        if self.step_factors == [1.0; 3] {
            std::borrow::Cow::Borrowed(m)
        } else {
            std::borrow::Cow::Owned(with_step_factors(m, self.step_factors))
        }
    }
}

/// `m` with each group's base step multiplied by its factor (rounded to binary32).
fn with_step_factors(m: &SceneModel, f: [f64; 3]) -> SceneModel {
    let mut out = m.clone();
    for (q, f) in [
        &mut out.quant_feat,
        &mut out.quant_scaling,
        &mut out.quant_offsets,
    ]
    .into_iter()
    .zip(f)
    {
        q.step = (f64::from(q.step) * f) as f32;
    }
    out
}

/// Annex A.5.4: `m` is the model as it will be coded (lattices chosen, canonical order) and
/// `options` the encode's own; `requested` wins when given.
pub fn choose(
    m: &SceneModel,
    options: &EncodeOptions,
    requested: Option<ContextPrecision>,
) -> Result<ContextChoice> {
    let saved = context_bytes(&m.dims, ContextPrecision::I16)
        - context_bytes(&m.dims, ContextPrecision::I8);
    let unmeasured = |precision| ContextChoice {
        precision,
        model_bytes_saved: saved,
        symbol_bytes_cost: 0,
        sample_anchors: 0,
        mse_ratio: [1.0; 3],
        step_factors: [1.0; 3],
    };
    if let Some(p) = requested {
        return Ok(unmeasured(p));
    }
    let k = m.n().div_ceil(CONTEXT_SAMPLE).max(1);
    let sample = if k > 1 { subsample(m, k) } else { m.clone() };
    let trial = |p| trial_options(options, p);
    let wide = encode_full(&sample, &trial(ContextPrecision::I16))?;
    // Weights too large for i8 at any scale (a0 = 0): i16 it is.
    let Ok(narrow) = encode_full(&sample, &trial(ContextPrecision::I8)) else {
        return Ok(unmeasured(ContextPrecision::I16));
    };
    let reference = group_mses(&sample, &wide);
    let first = ratio(group_mses(&sample, &narrow), reference);
    // Beyond this, i8 moves the reconstructions too much (or the sample is too small to
    // tell): no step refinement chases it.
    if first.iter().any(|&r| r > MAX_REFINED_RATIO) {
        return Ok(ContextChoice {
            symbol_bytes_cost: 0,
            sample_anchors: sample.n(),
            mse_ratio: first,
            ..unmeasured(ContextPrecision::I16)
        });
    }
    let step_factors = holding_step_factors(first);
    let (narrow, mse_ratio) = if step_factors == [1.0; 3] {
        (narrow, first)
    } else {
        let stepped = with_step_factors(&sample, step_factors);
        match encode_full(&stepped, &trial(ContextPrecision::I8)) {
            Ok(e) => {
                let r = ratio(group_mses(&sample, &e), reference);
                (e, r)
            }
            Err(_) => return Ok(unmeasured(ContextPrecision::I16)),
        }
    };
    let symbols_sample = narrow.stream.len() as i64 - wide.stream.len() as i64 + saved as i64;
    let scale = m.n() as f64 / sample.n().max(1) as f64;
    let cost = (symbols_sample as f64 * scale).round() as i64;
    let equal = mse_ratio.iter().all(|&r| r <= 1.0 + MSE_TOLERANCE);
    let narrow_wins = equal && cost < saved as i64;
    Ok(ContextChoice {
        precision: if narrow_wins {
            ContextPrecision::I8
        } else {
            ContextPrecision::I16
        },
        model_bytes_saved: saved,
        symbol_bytes_cost: cost,
        sample_anchors: sample.n(),
        mse_ratio,
        step_factors: if narrow_wins { step_factors } else { [1.0; 3] },
    })
}

/// The options of a trial encode at `precision`: the sample is coded with the model's
/// quantizers as they stand (no fits, notes or stats), at rate 0 whatever the stream codes, so
/// that the choice depends on the model alone and a rate extracted from a multi-rate stream
/// equals that rate encoded alone (§7.5).
fn trial_options(options: &EncodeOptions, precision: ContextPrecision) -> EncodeOptions {
    EncodeOptions {
        encoder_note: None,
        rates: vec![0],
        statistics: false,
        feat_lattice: None,
        fit_basis: false,
        fit_scales: false,
        scaffold_precision: Some(ScaffoldPrecision::F32),
        context_precision: Some(precision),
        ..options.clone()
    }
}

/// The reconstruction MSE per group (feature, scaling, offsets) of the encode `e` of `sample`.
fn group_mses(sample: &SceneModel, e: &super::Encoded) -> [f64; 3] {
    let d = e.expected();
    [
        mse(&sample.anchors.feat, &d.anchors.feat),
        mse(&sample.anchors.scaling, &d.anchors.scaling),
        mse(&sample.anchors.offsets, &d.anchors.offsets),
    ]
}

/// Per group, the MSE `a` over the MSE `b` (1 when both are 0, infinite when only `b` is).
fn ratio(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [0, 1, 2].map(|g| {
        if b[g] > 0.0 {
            a[g] / b[g]
        } else if a[g] > 0.0 {
            f64::INFINITY
        } else {
            1.0
        }
    })
}

/// The step factors that hold the distortion at the MSE ratios `first`: a group whose error
/// grew gets a finer base step (MSE ~ step²).
fn holding_step_factors(first: [f64; 3]) -> [f64; 3] {
    first.map(|r| {
        if r.is_finite() && r > 1.0 {
            1.0 / r.sqrt()
        } else {
            1.0
        }
    })
}
