//! Each rate's steps fitted to its render-PSNR target (Annex A.8.2): the targets checked
//! (finest first, within what the scene can reach) before any work, the parts' curves
//! measured at the curves' size, an allocation per target, and each rate landed on its
//! target at the quality yardstick ([`ratios::QUALITY_WIDTH`]).

use super::curves::{self, Effort};
use super::layer;
use super::plan::{RatePlan, SizeClasses};
use super::prepare::PreparedGaussians;
use super::sample::{spatial_sample, Sample, SAMPLE_GAUSSIANS};
use super::{fit_groups, ratios, RateControl, Variant};
use crate::error::{Error, Result};
use crate::writers::write_gqua;
use salvq_bitstream::entropy::GaussianTables;
use salvq_bitstream::explicit::groups::{Group, GroupKind};
use salvq_bitstream::explicit::Gaussians;
use salvq_render::compare::RingTarget;

/// Allocations tried per rate after the first, before the closest to its target is kept
/// (Annex A.8.2), at [`Effort::Best`] and at [`Effort::Default`].
const CORRECTIONS: usize = 4;
const DEFAULT_CORRECTIONS: usize = 3;

/// A render at the yardstick's size counts as this many at the curves' (its pixels).
const QUALITY_RENDER_UNITS: u64 = 4;

/// Work units of the KLT choice (three codings of a layer).
const KLT_UNITS: u64 = 3;

/// How far an explicit encode is: the step a person reads, and the work done and in all,
/// in units of one trial render at the curves' size (the unit of its cost).
#[derive(Debug, Clone, Copy)]
pub struct Progress<'a> {
    /// What the encoder is doing.
    pub step: &'a str,
    /// Units done.
    pub done: u64,
    /// Units in all (at most; a curve that stops early counts its skipped trials as done).
    pub total: u64,
}

/// Work units of coding `rates` layers at the end.
pub fn coding_units(rates: usize) -> u64 {
    2 * rates as u64
}

/// Allocations tried per rate under `effort` (Annex A.8.2): none rendered at `Fast`.
fn landing_tries(effort: Effort) -> u64 {
    match effort {
        Effort::Fast => 0,
        Effort::Default => 1 + DEFAULT_CORRECTIONS as u64,
        Effort::Best => 1 + CORRECTIONS as u64,
    }
}

/// Each part's measured curve, as [`curves::measure_curves`] gives them.
type PartCurves = Vec<(ratios::Part, ratios::Curve)>;

/// Work units of a whole encode of `p` under `options` ([`Progress::total`]).
pub fn work_units(p: &PreparedGaussians, options: &super::ExplicitOptions) -> u64 {
    let coding = coding_units(options.rates.rate_count());
    let effort = options.effort;
    match &options.rates {
        RateControl::Plans(_) => coding,
        RateControl::Psnr(t) => {
            let landing = landing_tries(effort) * QUALITY_RENDER_UNITS;
            let ceiling = if effort == Effort::Fast {
                0
            } else {
                QUALITY_RENDER_UNITS
            };
            ceiling + curves::curve_units(p, effort) + KLT_UNITS + t.len() as u64 * landing + coding
        }
    }
}

/// Refuses targets that are not positive and finite, or not strictly falling (rate 0 is
/// the finest, Annex A.8.2).
fn check_order(targets: &[f64]) -> Result<()> {
    for (r, &db) in targets.iter().enumerate() {
        if !(db.is_finite() && db > 0.0) {
            return Err(Error::FitFailed {
                tensor: "psnr target",
                reason: format!("rate {r}: a target is a PSNR in dB above 0, not {db}"),
            });
        }
        if let Some(&finer) = r.checked_sub(1).and_then(|q| targets.get(q)) {
            if db >= finer {
                return Err(Error::FitFailed {
                    tensor: "psnr target",
                    reason: format!(
                        "rate {r}'s target {db} dB is not below rate {}'s {finer} dB: rate 0 is \
                         the finest, so targets fall from the first to the last",
                        r - 1
                    ),
                });
            }
        }
    }
    Ok(())
}

/// The input's renders at the yardstick, after checking that the scene reaches the first
/// target; `None` at [`Effort::Fast`], which renders nothing there.
fn yardstick(
    g: &Gaussians,
    p: &PreparedGaussians,
    effort: Effort,
    targets: &[f64],
    say: &dyn Fn(&str),
) -> Result<Option<RingTarget>> {
    if effort == Effort::Fast {
        return Ok(None);
    }
    say("checking what the scene can reach");
    let quality = RingTarget::new(
        g,
        ratios::QUALITY_VIEWS,
        ratios::QUALITY_WIDTH,
        ratios::QUALITY_HEIGHT,
    )?;
    check_ceiling(targets, ceiling_db(g, p, &quality)?)?;
    Ok(Some(quality))
}

/// Refuses a first target above `ceiling` (dB), what the scene reaches at best.
fn check_ceiling(targets: &[f64], ceiling: f64) -> Result<()> {
    match targets.first() {
        Some(&db) if db > ceiling => Err(Error::TargetUnreachable {
            rate: 0,
            target_db: db,
            ceiling_db: ceiling,
        }),
        _ => Ok(()),
    }
}

/// The render PSNR of `g` with every part at the finest step the curves try, at the
/// yardstick: no allocation renders better, so a target above it cannot be met.
pub fn ceiling_db(g: &Gaussians, p: &PreparedGaussians, quality: &RingTarget) -> Result<f64> {
    let mse = quality.mse(&ratios::finest(g, p))?;
    Ok(-10.0 * mse.max(1e-30).log10())
}

/// Which groups get a KLT basis (Annex A.8.3): SH DC, then SH rest, each kept when `size`
/// (the bytes of the shared model and one layer, coded with the quantizers it is given)
/// shrinks.
pub fn choose_klt(
    p: &PreparedGaussians,
    plans: &[RatePlan],
    size: &dyn Fn(&[Group]) -> Result<usize>,
) -> Result<Vec<bool>> {
    let mut klt = vec![false; p.kinds.len()];
    let mut best = size(&fit_groups(p, plans, &klt))?;
    for (gi, kind) in p.kinds.iter().enumerate() {
        if matches!(kind, GroupKind::Dc | GroupKind::Rest) {
            klt[gi] = true;
            let s = size(&fit_groups(p, plans, &klt))?;
            if s < best {
                best = s;
            } else {
                klt[gi] = false;
            }
        }
    }
    Ok(klt)
}

/// Each rate of `options.rates`, given or fitted to its PSNR target by rendering with
/// `options.effort` (Annex A.8.2), and the groups with a KLT basis (`options.klt` if given;
/// else chosen on the middle target's first allocation, so that every rate is fitted with
/// the quantizers it will be coded with). For a progressive stream (§3.8), each rate after
/// the finest is fitted as a [`ratios::nested_plan`] of the one before it. Targets above what the scene reaches fail at once
/// ([`Error::TargetUnreachable`]).
pub fn rate_plans(
    g: &Gaussians,
    p: &PreparedGaussians,
    options: &super::ExplicitOptions,
    progress: &dyn Fn(Progress<'_>),
) -> Result<(Vec<RatePlan>, Option<Vec<bool>>)> {
    let (rates, variant, effort) = (&options.rates, options.variant, options.effort);
    let (klt, nested) = (options.klt.as_deref(), options.progressive);
    let targets = match rates {
        RateControl::Plans(s) => return Ok((s.clone(), klt.map(<[bool]>::to_vec))),
        RateControl::Psnr(t) => t,
    };
    check_order(targets)?;
    let total = work_units(p, options);
    let say = |step: &str, done: u64| progress(Progress { step, done, total });
    let quality = yardstick(g, p, effort, targets, &|step| say(step, 0))?;
    let mut done = if quality.is_some() {
        QUALITY_RENDER_UNITS
    } else {
        0
    };
    let classes = SizeClasses::for_variant(p, variant);
    let (sample, curves) = measure_part_curves(g, p, &classes, options, &|step, units| {
        say(step, done + units)
    })?;
    done += curves::curve_units(p, effort);
    if quality.is_none() {
        // No render at the yardstick: the ceiling is the curves' finest points, summed.
        check_ceiling(targets, curves_ceiling_db(&curves))?;
    }
    let klt = match klt {
        Some(k) => k.to_vec(),
        None => {
            say("choosing a KLT basis for the colours", done);
            choose_klt_at_middle(p, &curves, targets, sample.as_ref(), variant)?
        }
    };
    done += KLT_UNITS;
    // The quantizers' means and bases, whose steps each plan sets.
    let quantizers = fit_groups(p, &[ratios::allocate(p, &curves, 1e-5)], &klt);
    // `Best` renders each try's layer as coded; `Default` what its quantizers give without
    // coding it.
    let output = |plan: &RatePlan| -> Result<Gaussians> {
        Ok(match effort {
            Effort::Best => {
                let groups = fit_groups(p, std::slice::from_ref(plan), &klt);
                code_trial(p, &groups, plan, variant)?.expected
            }
            _ => ratios::plan_output(g, p, &quantizers, &classes.thresholds, plan),
        })
    };
    // Each rate: allocate for the target, render what the decoder will output, and
    // correct the allocation's target by the error it missed by (the parts' errors do not
    // add up exactly, and the curves were found at another size).
    let mut out: Vec<RatePlan> = Vec::with_capacity(targets.len());
    for (r, &db) in targets.iter().enumerate() {
        let step = format!(
            "fitting rate {r} of {} to {db} dB ({} views at {}x{})",
            targets.len(),
            ratios::QUALITY_VIEWS,
            ratios::QUALITY_WIDTH,
            ratios::QUALITY_HEIGHT
        );
        let finer = out.last().filter(|_| nested);
        let on_try = |tries: u64| say(&step, done + tries * QUALITY_RENDER_UNITS);
        let plan = fit_rate(
            p,
            &curves,
            db,
            finer,
            quality.as_ref(),
            effort,
            &output,
            &on_try,
        )?;
        done += landing_tries(effort) * QUALITY_RENDER_UNITS;
        out.push(plan);
    }
    Ok((out, Some(klt)))
}

/// The sample of a large scene (Annex A.8.2) and the parts' curves measured on it (or on the
/// whole scene) at the curves' size; `report` gets each step and its units done so far.
fn measure_part_curves(
    g: &Gaussians,
    p: &PreparedGaussians,
    classes: &SizeClasses,
    options: &super::ExplicitOptions,
    report: &dyn Fn(&str, u64),
) -> Result<(Option<Sample>, PartCurves)> {
    let curve_target = RingTarget::new(
        g,
        ratios::CURVE_VIEWS,
        ratios::CURVE_WIDTH,
        ratios::CURVE_HEIGHT,
    )?;
    let parts = ratios::parts(p).len();
    let sample = spatial_sample(g, p, SAMPLE_GAUSSIANS);
    let curves = curves::measure_curves(
        g,
        p,
        sample.as_ref(),
        classes,
        options.variant,
        options.effort,
        &curve_target,
        &|number, what, units| {
            report(
                &format!("measuring what precision costs, part {number} of {parts}: {what}"),
                units,
            )
        },
    )?;
    Ok((sample, curves))
}

/// The render PSNR (dB) of the curves' finest points, their MSEs summed: the ceiling when
/// nothing renders at the yardstick.
fn curves_ceiling_db(curves: &[(ratios::Part, ratios::Curve)]) -> f64 {
    let finest: f64 = curves
        .iter()
        .filter_map(|(_, c)| c.last())
        .map(|t| t.1)
        .sum();
    -10.0 * finest.max(1e-30).log10()
}

/// `plan`'s layer of `p` coded with the quantizers `groups` (rate 0, automatic tiles): what a
/// trial measures.
fn code_trial(
    p: &PreparedGaussians,
    groups: &[Group],
    plan: &RatePlan,
    variant: Variant,
) -> Result<layer::CodedLayer> {
    let classes = SizeClasses::for_variant(p, variant);
    let origin = p.min.map(|v| v as f32);
    let tables = GaussianTables::standard();
    layer::encode_layer(p, groups, &classes, plan, origin, 0, 0, variant, tables)
}

/// The groups with a KLT basis ([`choose_klt`]), chosen on the middle target's allocation,
/// coded on `sample` of a large scene: so every rate is fitted with the quantizers it will be
/// coded with.
fn choose_klt_at_middle(
    p: &PreparedGaussians,
    curves: &[(ratios::Part, ratios::Curve)],
    targets: &[f64],
    sample: Option<&Sample>,
    variant: Variant,
) -> Result<Vec<bool>> {
    let middle = targets[targets.len() / 2];
    let plan = ratios::allocate(p, curves, 10f64.powf(-middle / 10.0));
    let on = sample.map_or(p, |s| &s.prepared);
    choose_klt(on, std::slice::from_ref(&plan), &|groups: &[Group]| {
        Ok(write_gqua(groups).len() + code_trial(on, groups, &plan, variant)?.chunks.len())
    })
}

/// The plan of the rate whose target is `db` (nested in `finer` if given): allocated on the
/// curves, then landed on `quality` (when given) by rendering `output` of the tries.
#[allow(clippy::too_many_arguments)]
fn fit_rate(
    p: &PreparedGaussians,
    curves: &[(ratios::Part, ratios::Curve)],
    db: f64,
    finer: Option<&RatePlan>,
    quality: Option<&RingTarget>,
    effort: Effort,
    output: &dyn Fn(&RatePlan) -> Result<Gaussians>,
    on_try: &dyn Fn(u64),
) -> Result<RatePlan> {
    let want = 10f64.powf(-db / 10.0);
    // The allocation is on a grid of steps; a common factor f on every step then lands on
    // the target (secant on log f against log MSE, which at high rate rises by 2 per unit
    // of log f). A nested rate has no common factor: f scales the MSE the allocation aims
    // at (MSE rises by about 1 per unit of its log), and the plan nests in the finer rate's.
    let alloc = ratios::allocate(p, curves, want);
    let plan_at = |f: f64| match finer {
        Some(finer) => ratios::allocate_nested(p, curves, finer, want * f),
        None => alloc.scaled(f),
    };
    let Some(quality) = quality else {
        return Ok(plan_at(1.0));
    };
    let tries = std::cell::Cell::new(0u64);
    let measure = |f: f64| -> Result<f64> {
        on_try(tries.get());
        tries.set(tries.get() + 1);
        Ok(quality.mse(&output(&plan_at(f))?)?.max(1e-30))
    };
    let slope = if finer.is_some() { 1.0 } else { 2.0 };
    let f = land(&measure, want, slope, landing_tries(effort) as usize - 1)?;
    Ok(plan_at(f))
}

/// The factor `f` whose `measure(f)` (an MSE) is nearest `want` after at most
/// `corrections` secant steps on log f from 1 (`slope`: the first guess of d log MSE /
/// d log f); it stops within 0.05 in log2 of the MSE.
fn land(
    measure: &dyn Fn(f64) -> Result<f64>,
    want: f64,
    slope: f64,
    corrections: usize,
) -> Result<f64> {
    let (mut lf, mut got) = (0.0f64, measure(1.0)?);
    let mut best = (((got / want).log2()).abs(), lf);
    let mut slope = slope;
    for _ in 0..corrections {
        if best.0 < 0.05 {
            break;
        }
        let next = (lf + (want.ln() - got.ln()) / slope).clamp(lf - 3.0, lf + 3.0);
        let g2 = measure(next.exp())?;
        if (next - lf).abs() > 1e-6 && g2 != got {
            slope = ((g2.ln() - got.ln()) / (next - lf)).clamp(0.5, 4.0);
        }
        (lf, got) = (next, g2);
        let miss = (got / want).log2().abs();
        if miss < best.0 {
            best = (miss, lf);
        }
    }
    Ok(best.1.exp())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn targets_fall_from_the_finest() {
        assert!(check_order(&[62.0, 50.0, 35.0]).is_ok());
        for bad in [
            &[30.0, 40.0][..],
            &[40.0, 40.0],
            &[f64::NAN],
            &[0.0],
            &[50.0, -1.0],
        ] {
            let e = check_order(bad).unwrap_err();
            assert_eq!(e.class(), "FitFailed", "{bad:?}");
        }
        let e = check_order(&[30.0, 40.0]).unwrap_err().to_string();
        assert!(
            e.contains("rate 1's target 40 dB is not below rate 0's 30 dB"),
            "{e}"
        );
    }
}
