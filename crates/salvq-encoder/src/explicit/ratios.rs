//! The steps of each rate, fitted to what a viewer sees (Annex A.8.2): every part (the
//! positions of a size class, the scale group, each later group in each size class) alone
//! is quantized at trial steps, the scene rendered from the camera ring and compared with
//! the input's renders, and its bits counted as the layer coder would pay them; then for a
//! target error each part takes the step minimising `D + λ·R`, the equal-slope condition of
//! rate-distortion theory, with λ bisected until the parts' errors add up to the target.

use super::layer::{RatePlan, SizeClasses};
use super::prepare::PreparedGaussians;
use super::TrialSteps;
use crate::error::Result;
use salvq::explicit::groups::GroupKind;
use salvq::explicit::layer::SIZE_CLASSES;
use salvq::explicit::Gaussians;
use salvq_render::compare::RingTarget;

/// Views of the curves' renders.
pub const CURVE_VIEWS: u32 = 8;
/// Width of the curves' renders: small, since every trial renders every view; the curves
/// only rank the parts against each other, and the rates land on their targets at the
/// [`QUALITY_WIDTH`] yardstick.
pub const CURVE_WIDTH: u32 = 256;
/// Height of the curves' renders.
pub const CURVE_HEIGHT: u32 = 192;

/// Views of the render-PSNR yardstick (Annex A.8.2, C.2): every rate lands on its target
/// here, the encoder's summary reports it, and `salvq compare` and `salvq render` default
/// to it. 512 × 384 is the smallest size at which a viewer's window is no sharper than the
/// renders: at 256 × 192 a Gaussian smaller than a pixel hides its errors, and rates fitted
/// there measured up to 2.2 dB lower at 512 × 384 (donut, as trained).
pub const QUALITY_VIEWS: u32 = 8;
/// Width of the yardstick's renders.
pub const QUALITY_WIDTH: u32 = 512;
/// Height of the yardstick's renders.
pub const QUALITY_HEIGHT: u32 = 384;

/// Trial steps of a part's curve: octaves, half octaves for the scale group.
fn trial_exponents(part: Part) -> (Vec<i32>, f64) {
    match part {
        Part::Scale => ((-16..=10).rev().collect(), 0.5),
        _ => ((-10..=8).rev().collect(), 1.0),
    }
}

/// `g` with every part at the finest step its curve tries: the best render the
/// allocation can choose from (Annex A.8.2).
pub fn finest(g: &Gaussians, p: &PreparedGaussians) -> Gaussians {
    let start = TrialSteps::default_for(p);
    let finest_step = |part: Part, base: f64| {
        let (ks, scale) = trial_exponents(part);
        base * (f64::from(ks.iter().copied().min().unwrap_or(0)) * scale).exp2()
    };
    let mut out = quantized(
        g,
        p,
        None,
        None,
        finest_step(Part::Position(0), start.position),
    );
    for gi in 0..p.kinds.len() {
        let part = if gi == 0 {
            Part::Scale
        } else {
            Part::Group(gi, 0)
        };
        out = quantized(&out, p, Some(gi), None, finest_step(part, start.groups[gi]));
    }
    out
}

/// `g` with one part of the Gaussians of class `class` (all when `None`) uniformly
/// quantized at `step`: group `group`, or the positions (voxel centres) when `None`.
fn quantized(
    g: &Gaussians,
    p: &PreparedGaussians,
    group: Option<usize>,
    class: Option<(u8, &[u8])>,
    step: f64,
) -> Gaussians {
    let mut out = g.clone();
    let q = |x: f64| (step * (x / step).round()) as f32;
    let chosen = |i: usize| class.is_none_or(|(c, classes)| classes[i] == c);
    let Some(gi) = group else {
        for (i, pos) in out.positions.iter_mut().enumerate() {
            if !chosen(i) {
                continue;
            }
            for (a, v) in pos.iter_mut().enumerate() {
                let m = p.min[a];
                *v = (m + step * (((f64::from(*v) - m) / step).floor() + 0.5)) as f32;
            }
        }
        return out;
    };
    let d = p.dim(gi);
    let v = &p.values[gi];
    for i in (0..p.len()).filter(|&i| chosen(i)) {
        let x = &v[i * d..(i + 1) * d];
        match p.kinds[gi] {
            GroupKind::Opacity => out.opacity_logit[i] = q(x[0]),
            GroupKind::Scale => out.log_scales[i] = [q(x[0]), q(x[1]), q(x[2])],
            GroupKind::Dc => out.f_dc[i] = [q(x[0]), q(x[1]), q(x[2])],
            GroupKind::Rest => {
                for (o, &v) in out.f_rest[i * d..(i + 1) * d].iter_mut().zip(x) {
                    *o = q(v);
                }
            }
            GroupKind::Rotation => {
                let s = [q(x[0]), q(x[1]), q(x[2])];
                out.rotations[i] = salvq::explicit::reconstruct::quaternion(s, p.rotation_index[i]);
            }
        }
    }
    out
}

/// A part's measured operating points: (log2 of the step over the part's default, render
/// MSE, bits per Gaussian of the whole scene).
pub type Curve = Vec<(f64, f64, f64)>;

/// The parts whose steps the allocation chooses (Annex A.8.2).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Part {
    /// The positions of one size class.
    Position(u8),
    /// The scale group (all classes: it defines them).
    Scale,
    /// Group `g ≥ 1` in one size class.
    Group(usize, u8),
}

impl Part {
    /// What the part is, in a person's words (`kinds`: the scene's groups).
    pub fn describe(self, kinds: &[GroupKind]) -> String {
        let class = |c: u8| {
            let which = ["smallest", "2nd smallest", "2nd largest", "largest"];
            format!(
                "{} quarter by size",
                which.get(usize::from(c)).unwrap_or(&"a")
            )
        };
        match self {
            Part::Position(c) => format!("positions, {}", class(c)),
            Part::Scale => "scales".into(),
            Part::Group(gi, c) => {
                let what = match kinds.get(gi) {
                    Some(GroupKind::Opacity) => "opacity",
                    Some(GroupKind::Rotation) => "rotations",
                    Some(GroupKind::Dc) => "base colour (SH DC)",
                    Some(GroupKind::Rest) => "view-dependent colour (SH rest)",
                    Some(GroupKind::Scale) | None => "values",
                };
                format!("{what}, {}", class(c))
            }
        }
    }
}

/// The parts of `p` in the order their curves are measured.
pub fn parts(p: &PreparedGaussians) -> Vec<Part> {
    let mut parts: Vec<Part> = (0..SIZE_CLASSES as u8).map(Part::Position).collect();
    parts.push(Part::Scale);
    for gi in 1..p.kinds.len() {
        for c in 0..SIZE_CLASSES as u8 {
            parts.push(Part::Group(gi, c));
        }
    }
    parts
}

/// Trial renders [`measure_curves`] makes at most.
pub fn curve_trials(p: &PreparedGaussians) -> u64 {
    parts(p)
        .into_iter()
        .map(|part| trial_exponents(part).0.len() as u64)
        .sum()
}

/// Every part's rate-distortion curve (Annex A.8.2): each part alone is quantized at trial
/// steps, its render error measured against `target` and its bits counted as the layer
/// coder would pay them (positions: the octree at that edge, shared by classes in
/// proportion to their Gaussians). `progress` hears each part as it starts (its number from
/// 1, and its description) and the trial renders done so far.
pub fn measure_curves(
    g: &Gaussians,
    p: &PreparedGaussians,
    classes: &SizeClasses,
    variant: super::Variant,
    effort: Effort,
    target: &RingTarget,
    progress: &dyn Fn(usize, &str, u64),
) -> Result<Vec<(Part, Curve)>> {
    use super::layer::{grid, group_bits, group_coordinates, BitCost};
    use salvq::entropy::GaussianTables;
    use salvq::tiles::{TileTable, DEFAULT_TILE_ANCHORS};
    let tables = GaussianTables::standard();
    let start = TrialSteps::default_for(p);
    let origin = p.min.map(|v| v as f32);
    let reference = grid(p, origin, start.position);
    let class_of = classes.classes(p);
    let n = p.len() as f64;
    let cost = BitCost::standard();
    let parts = parts(p);
    let mut trials_done = 0u64;
    // Octree bits per Gaussian at each trial edge, shared by the position parts.
    let mut octree_bits: rustc_hash::FxHashMap<i64, f64> = Default::default();
    let mut out = Vec::with_capacity(parts.len());
    for (number, part) in parts.into_iter().enumerate() {
        let (group, class, base) = match part {
            Part::Position(c) => (None, Some(c), start.position),
            Part::Scale => (Some(0), None, start.groups[0]),
            Part::Group(gi, c) => (Some(gi), Some(c), start.groups[gi]),
        };
        let (ks, scale) = trial_exponents(part);
        let what = part.describe(&p.kinds);
        let before = trials_done;
        progress(number + 1, &what, before);
        // Trials a curve skips (it stops once the error vanishes) count as done.
        trials_done += ks.len() as u64;
        let members: Vec<usize> = match class {
            Some(c) => reference
                .order
                .iter()
                .copied()
                .filter(|&i| class_of[i] == c)
                .collect(),
            None => reference.order.clone(),
        };
        let share = members.len() as f64 / n;
        let mut curve = Curve::new();
        if members.is_empty() {
            curve.push((0.0, 0.0, 0.0));
            out.push((part, curve));
            continue;
        }
        let subset_voxels: Vec<[u32; 3]> = {
            let mut at = vec![usize::MAX; p.len()];
            for (k, &i) in reference.order.iter().enumerate() {
                at[i] = k;
            }
            members.iter().map(|&i| reference.voxels[at[i]]).collect()
        };
        let tiles = TileTable::cut(&subset_voxels, DEFAULT_TILE_ANCHORS);
        let last = ks.len() - 1;
        // Each trial's bits, and its render error where it is rendered (None: interpolated).
        let mut trials: Vec<(f64, Option<f64>, f64)> = Vec::with_capacity(ks.len());
        for (k_at, k) in ks.into_iter().enumerate() {
            if k_at > 0 {
                progress(number + 1, &what, before + k_at as u64);
            }
            let log2 = f64::from(k) * scale;
            let step = base * log2.exp2();
            let rendered = k_at % effort.render_every() == 0 || k_at == last;
            let mse = if rendered {
                Some(target.mse(&quantized(
                    g,
                    p,
                    group,
                    class.map(|c| (c, class_of.as_slice())),
                    step,
                ))?)
            } else {
                None
            };
            let bits = match group {
                None => {
                    let key = k as i64;
                    let total = match octree_bits.get(&key) {
                        Some(&b) => b,
                        None => {
                            let gr = grid(p, origin, step);
                            let t = TileTable::cut(&gr.voxels, DEFAULT_TILE_ANCHORS);
                            let mut bytes = 0usize;
                            for i in 0..t.len() {
                                let (level, cell) = t.cells[i];
                                let local: Vec<[u32; 3]> = gr.voxels[t.range(i)]
                                    .iter()
                                    .map(|v| [0, 1, 2].map(|a| v[a] - (cell[a] << level)))
                                    .collect();
                                bytes += salvq::geometry::encode(&local, level, tables)?.len();
                            }
                            let b = bytes as f64 * 8.0 / n;
                            octree_bits.insert(key, b);
                            b
                        }
                    };
                    total * share
                }
                Some(gi) => {
                    let d = p.dim(gi);
                    let one = super::measurement_group(p, gi);
                    let c = group_coordinates(&p.values[gi], &one, step as f32, &|_| 0, &members);
                    group_bits(
                        &c,
                        d,
                        &subset_voxels,
                        reference.coord_bits,
                        &tiles,
                        cost,
                        variant,
                        one.kind == GroupKind::Rest,
                    ) * share
                }
            };
            trials.push((log2, mse, bits));
            if mse.is_some_and(|m| m < 1e-10) {
                break;
            }
        }
        // Trials after the last rendered one (none where every trial is rendered) are dropped.
        while trials.last().is_some_and(|t| t.1.is_none()) {
            trials.pop();
        }
        curve.extend(interpolated(&trials));
        out.push((part, curve));
    }
    Ok(out)
}

/// How hard the encoder searches (Annex A.8.2): which trial steps of a curve are rendered.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Effort {
    /// Every third trial step rendered (and the finest), the render error of the others
    /// interpolated: the curves cost about a third of the renders.
    #[default]
    Default,
    /// Every trial step rendered.
    Best,
}

impl Effort {
    fn render_every(self) -> usize {
        match self {
            Effort::Default => 3,
            Effort::Best => 1,
        }
    }
}

/// `trials` (log2 step, render error if rendered, bits) with each error that was not
/// rendered interpolated between the rendered ones around it, linearly in log error
/// against log step: the error of a quantizer grows as a power of its step.
fn interpolated(trials: &[(f64, Option<f64>, f64)]) -> Curve {
    let rendered: Vec<usize> = (0..trials.len())
        .filter(|&i| trials[i].1.is_some())
        .collect();
    let ln = |m: f64| m.max(1e-30).ln();
    trials
        .iter()
        .enumerate()
        .map(|(i, &(x, mse, bits))| {
            let mse = mse.unwrap_or_else(|| {
                let after = rendered.partition_point(|&r| r < i);
                let (a, b) = (
                    rendered[after.saturating_sub(1)],
                    rendered[after.min(rendered.len() - 1)],
                );
                let (xa, ma, xb, mb) = (
                    trials[a].0,
                    trials[a].1.unwrap_or(0.0),
                    trials[b].0,
                    trials[b].1.unwrap_or(0.0),
                );
                let t = if (xb - xa).abs() > 1e-12 {
                    (x - xa) / (xb - xa)
                } else {
                    0.0
                };
                (ln(ma) + t * (ln(mb) - ln(ma))).exp()
            });
            (x, mse, bits)
        })
        .collect()
}

/// The plan whose summed render error is `target_mse` at the least total bits (Annex
/// A.8.2): each part takes the point minimising `D + λ·R`, and λ is bisected.
pub fn allocate(p: &PreparedGaussians, curves: &[(Part, Curve)], target_mse: f64) -> RatePlan {
    let pick = |lambda: f64| -> Vec<(f64, f64, f64)> {
        curves
            .iter()
            .map(|(_, c)| {
                *c.iter()
                    .min_by(|a, b| (a.1 + lambda * a.2).total_cmp(&(b.1 + lambda * b.2)))
                    .expect("a curve has points")
            })
            .collect()
    };
    let (mut lo, mut hi) = (-20.0f64, 4.0f64);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        let d: f64 = pick(10f64.powf(mid)).iter().map(|x| x.1).sum();
        if d > target_mse {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    let chosen = pick(10f64.powf(lo));
    let start = TrialSteps::default_for(p);
    let mut position = [0f64; SIZE_CLASSES];
    let mut scale = 0.0;
    let mut group = vec![[0f64; SIZE_CLASSES]; p.kinds.len()];
    for ((part, _), x) in curves.iter().zip(&chosen) {
        match *part {
            Part::Position(c) => position[usize::from(c)] = x.0,
            Part::Scale => scale = x.0,
            Part::Group(gi, c) => group[gi][usize::from(c)] = x.0,
        }
    }
    // The coarse grid is the coarsest class's; the others refine it.
    let coarsest = position.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let refine = position.map(|l| (coarsest - l).round().clamp(0.0, 23.0) as u8);
    let mut steps = vec![start.groups[0] * scale.exp2()];
    let mut shift = Vec::new();
    for (gi, classes) in group.iter().enumerate().skip(1) {
        let base = classes[0];
        steps.push(start.groups[gi] * base.exp2());
        shift.push(classes.map(|l| (l - base).round().clamp(-16.0, 16.0) as i8));
    }
    RatePlan {
        voxel: start.position * coarsest.exp2(),
        refine,
        steps,
        shift,
    }
}

/// A part's (MSE, bits) at `x` (log2 of its step over the default), linear between the
/// curve's points and clamped at its ends.
fn curve_at(curve: &Curve, x: f64) -> (f64, f64) {
    let mut points: Vec<&(f64, f64, f64)> = curve.iter().collect();
    points.sort_by(|a, b| a.0.total_cmp(&b.0));
    let (Some(first), Some(last)) = (points.first(), points.last()) else {
        return (0.0, 0.0);
    };
    if x <= first.0 {
        return (first.1, first.2);
    }
    if x >= last.0 {
        return (last.1, last.2);
    }
    let k = points.partition_point(|q| q.0 <= x);
    let (a, b) = (points[k - 1], points[k]);
    let t = (x - a.0) / (b.0 - a.0).max(1e-12);
    (a.1 + t * (b.1 - a.1), a.2 + t * (b.2 - a.2))
}

/// Odd step factors a nested rate chooses among per group, and octaves its position cells
/// may grow by per size class (Annex A.8.2).
const NESTED_FACTORS: [u8; 3] = [1, 3, 5];
const NESTED_OCTAVES: [u8; 3] = [0, 1, 2];

/// The plan of a rate coarser than `finer` that nests in it (§3.8) whose render error, as
/// the parts' curves predict it, is at most `target_mse` at the fewest predicted bits:
/// every choice of an odd factor per group (1, 3 or 5) and of 0 to 2 more octaves per
/// size class's position cell is weighed; none within the target
/// gives the one of least error.
pub fn allocate_nested(
    p: &PreparedGaussians,
    curves: &[(Part, Curve)],
    finer: &RatePlan,
    target_mse: f64,
) -> RatePlan {
    let start = TrialSteps::default_for(p);
    let groups = p.kinds.len();
    // Per unit (each group, then each size class's positions), per option: (MSE, bits).
    let mut units: Vec<Vec<(f64, f64)>> = Vec::with_capacity(groups + SIZE_CLASSES);
    for gi in 0..groups {
        let options = NESTED_FACTORS.iter().map(|&m| {
            let plan = super::fit_rates::nested_plan(finer, &factors_for(groups, gi, m), &[0; 4]);
            predicted(curves, &start, &plan, |part| match part {
                Part::Scale => gi == 0,
                Part::Group(g, _) => g == gi,
                Part::Position(_) => false,
            })
        });
        units.push(options.collect());
    }
    for c in 0..SIZE_CLASSES {
        let options = NESTED_OCTAVES.iter().map(|&k| {
            let mut up = [0u8; SIZE_CLASSES];
            up[c] = k;
            let plan = super::fit_rates::nested_plan(finer, &vec![1; groups], &up);
            predicted(curves, &start, &plan, |part| {
                part == Part::Position(c as u8)
            })
        });
        units.push(options.collect());
    }
    // Every combination, as mixed-radix digits.
    let radix = 3usize;
    let combos = radix.pow(units.len() as u32);
    let mut best: Option<(bool, f64, usize)> = None;
    for combo in 0..combos {
        let (mut mse, mut bits, mut rest) = (0.0, 0.0, combo);
        for unit in &units {
            let (m, b) = unit[rest % radix];
            mse += m;
            bits += b;
            rest /= radix;
        }
        let fits = mse <= target_mse;
        let key = if fits { bits } else { mse };
        let better = match best {
            None => true,
            Some((f, k, _)) => (fits && !f) || (fits == f && key < k),
        };
        if better {
            best = Some((fits, key, combo));
        }
    }
    let mut rest = best.map_or(0, |b| b.2);
    let mut factors = Vec::with_capacity(groups);
    for _ in 0..groups {
        factors.push(NESTED_FACTORS[rest % radix]);
        rest /= radix;
    }
    let up: [u8; SIZE_CLASSES] = std::array::from_fn(|_| {
        let k = NESTED_OCTAVES[rest % radix];
        rest /= radix;
        k
    });
    super::fit_rates::nested_plan(finer, &factors, &up)
}

/// Factor `m` for group `gi` and 1 for the others.
fn factors_for(groups: usize, gi: usize, m: u8) -> Vec<u8> {
    (0..groups).map(|g| if g == gi { m } else { 1 }).collect()
}

/// The curves' (MSE, bits) of `plan`, summed over the parts `chosen` keeps.
fn predicted(
    curves: &[(Part, Curve)],
    start: &TrialSteps,
    plan: &RatePlan,
    chosen: impl Fn(Part) -> bool,
) -> (f64, f64) {
    let mut sum = (0.0, 0.0);
    for (part, curve) in curves.iter().filter(|(part, _)| chosen(*part)) {
        let x = match *part {
            Part::Position(c) => {
                let cell = plan.voxel * (-f64::from(plan.refine[usize::from(c)])).exp2();
                (cell / start.position).log2()
            }
            Part::Scale => (plan.steps[0] / start.groups[0]).log2(),
            Part::Group(gi, c) => {
                let shift = plan.shift[gi - 1][usize::from(c)];
                (plan.steps[gi] * f64::from(shift).exp2() / start.groups[gi]).log2()
            }
        };
        let (m, b) = curve_at(curve, x);
        sum = (sum.0 + m, sum.1 + b);
    }
    sum
}

#[cfg(test)]
mod tests {
    use super::interpolated;

    /// A render error that is a power of the step is interpolated exactly between rendered
    /// trials; rendered trials and every trial's bits are kept as they are.
    #[test]
    fn an_error_that_is_a_power_of_the_step_is_interpolated_exactly() {
        let mse = |x: f64| 0.01 * (2.0 * x).exp2();
        let trials: Vec<(f64, Option<f64>, f64)> = (0..10)
            .map(|i| {
                let x = 8.0 - f64::from(i);
                (x, (i % 3 == 0).then(|| mse(x)), 10.0 - x)
            })
            .collect();
        let curve = interpolated(&trials);
        assert_eq!(curve.len(), trials.len());
        for ((x, m, b), t) in curve.iter().zip(&trials) {
            assert_eq!((*x, *b), (t.0, t.2));
            assert!(
                (m / mse(*x) - 1.0).abs() < 1e-12,
                "at {x}: {m} against {}",
                mse(*x)
            );
        }
    }
}
