//! The steps of each rate, fitted to what a viewer sees (Annex A.8.2): every part (the
//! positions of a size class, the scale group, each later group in each size class) alone
//! is quantized at trial steps, the scene rendered from the camera ring and compared with
//! the input's renders, and its bits counted as the layer coder would pay them; then for a
//! target error each part takes the step minimising `D + λ·R`, the equal-slope condition of
//! rate-distortion theory, with λ bisected until the parts' errors add up to the target.

use super::plan::RatePlan;
use super::prepare::PreparedGaussians;
use super::TrialSteps;
use salvq_bitstream::explicit::groups::GroupKind;
use salvq_bitstream::explicit::layer::SIZE_CLASSES;
use salvq_bitstream::explicit::Gaussians;

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
pub(crate) fn trial_exponents(part: Part) -> (Vec<i32>, f64) {
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
    let mut out = g.clone();
    let position = finest_step(Part::Position(0), start.position);
    quantize_part(&mut out, p, None, &|_| Some(position));
    for gi in 0..p.kinds.len() {
        let part = if gi == 0 {
            Part::Scale
        } else {
            Part::Group(gi, 0)
        };
        let step = finest_step(part, start.groups[gi]);
        quantize_part(&mut out, p, Some(gi), &|_| Some(step));
    }
    out
}

/// `g` with one part of the Gaussians of class `class` (all when `None`) uniformly
/// quantized at `step`: group `group`, or the positions (voxel centres) when `None`.
pub(crate) fn quantized(
    g: &Gaussians,
    p: &PreparedGaussians,
    group: Option<usize>,
    class: Option<(u8, &[u8])>,
    step: f64,
) -> Gaussians {
    let mut out = g.clone();
    let chosen = |i: usize| class.is_none_or(|(c, classes)| classes[i] == c);
    quantize_part(&mut out, p, group, &|i| chosen(i).then_some(step));
    out
}

/// What a decoder outputs for `plan` with the quantizers `groups` (their means and bases;
/// the steps are the plan's), to the precision that matters for its render error: each
/// group's lattice point (§3.3) at the plan's step for the Gaussian's size class, the
/// class read from the quantized scales as §3.5 reads it, and each position at the centre
/// of its refined cell. Entropy coding and the binary32 rules of §3.6 are left out.
pub fn plan_output(
    g: &Gaussians,
    p: &PreparedGaussians,
    groups: &[salvq_bitstream::explicit::groups::Group],
    thresholds: &[f64],
    plan: &RatePlan,
) -> Gaussians {
    use nalgebra::DMatrix;
    let n = p.len();
    let mut out = g.clone();
    // Per group: B (row-major) and B⁻¹, or None for the identity.
    let bases: Vec<Option<(Vec<f64>, DMatrix<f64>)>> = groups
        .iter()
        .map(|gr| {
            gr.basis.as_ref().map(|_| {
                let b: Vec<f64> = gr.matrix().to_f64();
                let m = DMatrix::from_row_slice(gr.dim, gr.dim, &b);
                let inv = m
                    .try_inverse()
                    .unwrap_or_else(|| DMatrix::identity(gr.dim, gr.dim));
                (b, inv)
            })
        })
        .collect();
    // x̂ = mean + Δ·B·round(B⁻¹ (x − mean) / Δ), into `x`.
    let lattice = |gi: usize, x: &mut [f64], step: f64| {
        let gr = &groups[gi];
        let d = gr.dim;
        let t: Vec<f64> = (0..d)
            .map(|j| (x[j] - f64::from(gr.mean[j])) / step)
            .collect();
        match &bases[gi] {
            None => {
                for j in 0..d {
                    x[j] = f64::from(gr.mean[j]) + step * t[j].round();
                }
            }
            Some((b, inv)) => {
                let c: Vec<f64> = (0..d)
                    .map(|j| (0..d).map(|k| inv[(j, k)] * t[k]).sum::<f64>().round())
                    .collect();
                for j in 0..d {
                    let v: f64 = (0..d).map(|k| b[j * d + k] * c[k]).sum();
                    x[j] = f64::from(gr.mean[j]) + step * v;
                }
            }
        }
    };
    // §3.5: the size class compares the largest scale coordinate with the thresholds
    // rounded to the scale lattice.
    let (scale_mean, scale_step) = (f64::from(groups[0].mean[0]), plan.steps[0]);
    let threshold_u: Vec<f64> = thresholds
        .iter()
        .map(|t| ((t - scale_mean) / scale_step).round())
        .collect();
    let mut row = Vec::new();
    for i in 0..n {
        let scale = &p.values[0][3 * i..3 * i + 3];
        let largest = scale
            .iter()
            .map(|x| ((x - scale_mean) / scale_step).round())
            .fold(f64::NEG_INFINITY, f64::max);
        let class = threshold_u.iter().filter(|&&t| t <= largest).count();
        row.clear();
        row.extend_from_slice(scale);
        lattice(0, &mut row, scale_step);
        out.log_scales[i] = [row[0] as f32, row[1] as f32, row[2] as f32];
        let cell = plan.voxel * (-f64::from(plan.refine[class])).exp2();
        for a in 0..3 {
            let m = p.min[a];
            out.positions[i][a] =
                (m + cell * (((p.positions[i][a] - m) / cell).floor() + 0.5)) as f32;
        }
        for (gi, kind) in p.kinds.iter().enumerate().skip(1) {
            let d = p.dim(gi);
            row.clear();
            row.extend_from_slice(&p.values[gi][i * d..(i + 1) * d]);
            let step = plan.steps[gi] * f64::from(plan.shift[gi - 1][class]).exp2();
            lattice(gi, &mut row, step);
            let f = |k: usize| row[k] as f32;
            match kind {
                GroupKind::Opacity => out.opacity_logit[i] = f(0),
                GroupKind::Scale => out.log_scales[i] = [f(0), f(1), f(2)],
                GroupKind::Dc => out.f_dc[i] = [f(0), f(1), f(2)],
                GroupKind::Rest => {
                    for (k, o) in out.f_rest[i * d..(i + 1) * d].iter_mut().enumerate() {
                        *o = f(k);
                    }
                }
                GroupKind::Rotation => {
                    out.rotations[i] = salvq_bitstream::explicit::reconstruct::quaternion(
                        [f(0), f(1), f(2)],
                        p.rotation_index[i],
                    );
                }
            }
        }
    }
    out
}

/// Quantizes in `out` group `group` (the positions, to voxel centres, when `None`) of each
/// Gaussian `i` for which `step_of(i)` gives a step.
fn quantize_part(
    out: &mut Gaussians,
    p: &PreparedGaussians,
    group: Option<usize>,
    step_of: &dyn Fn(usize) -> Option<f64>,
) {
    let Some(gi) = group else {
        for (i, pos) in out.positions.iter_mut().enumerate() {
            let Some(step) = step_of(i) else {
                continue;
            };
            for (a, v) in pos.iter_mut().enumerate() {
                let m = p.min[a];
                *v = (m + step * (((p.positions[i][a] - m) / step).floor() + 0.5)) as f32;
            }
        }
        return;
    };
    let d = p.dim(gi);
    let v = &p.values[gi];
    for i in 0..p.len() {
        let Some(step) = step_of(i) else {
            continue;
        };
        let q = |x: f64| (step * (x / step).round()) as f32;
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
                out.rotations[i] =
                    salvq_bitstream::explicit::reconstruct::quaternion(s, p.rotation_index[i]);
            }
        }
    }
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
    /// Which values it quantizes: the group (`None`: the positions) and the size class
    /// (`None`: all).
    pub fn quantizes(self) -> (Option<usize>, Option<u8>) {
        match self {
            Part::Position(c) => (None, Some(c)),
            Part::Scale => (Some(0), None),
            Part::Group(gi, c) => (Some(gi), Some(c)),
        }
    }

    /// Whether a Gaussian of size class `class` is one of its.
    pub fn holds(self, class: u8) -> bool {
        self.quantizes().1.is_none_or(|c| c == class)
    }

    /// Its Gaussians (ascending indices), given each one's size class.
    pub fn members(self, class_of: &[u8]) -> Vec<usize> {
        (0..class_of.len())
            .filter(|&i| self.holds(class_of[i]))
            .collect()
    }

    /// The step its trial exponents scale.
    pub fn base_step(self, start: &TrialSteps) -> f64 {
        match self {
            Part::Position(_) => start.position,
            Part::Scale => start.groups[0],
            Part::Group(gi, _) => start.groups[gi],
        }
    }

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

/// The plan of a rate coarser than `finer` that nests in it (§3.8): each group's step the
/// finer one's times its odd `factors`, each size class's position cell the finer one's
/// times `2^up[c]`. Shifts are kept, so the ratio of two nested plans' steps is the factor.
pub fn nested_plan(finer: &RatePlan, factors: &[u8], up: &[u8; SIZE_CLASSES]) -> RatePlan {
    let most = up.iter().copied().max().unwrap_or(0);
    RatePlan {
        voxel: finer.voxel * f64::from(most).exp2(),
        refine: std::array::from_fn(|c| finer.refine[c] + most - up[c]),
        steps: finer
            .steps
            .iter()
            .zip(factors)
            .map(|(s, &m)| s * f64::from(m))
            .collect(),
        shift: finer.shift.clone(),
    }
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
            let plan = nested_plan(finer, &factors_for(groups, gi, m), &[0; 4]);
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
            let plan = nested_plan(finer, &vec![1; groups], &up);
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
    nested_plan(finer, &factors, &up)
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
    use super::*;

    #[test]
    fn a_nested_plan_multiplies_steps_by_its_factors_and_cells_by_octaves() {
        let finer = RatePlan {
            voxel: 0.5,
            refine: [3, 2, 1, 0],
            steps: vec![0.1, 0.2, 0.3],
            shift: vec![[1, 0, 0, -1], [2, 1, 0, 0]],
        };
        let coarser = nested_plan(&finer, &[1, 3, 5], &[2, 0, 1, 0]);
        assert_eq!(coarser.steps, [0.1, 0.2 * 3.0, 0.3 * 5.0]);
        assert_eq!(coarser.shift, finer.shift);
        let cell = |p: &RatePlan, c: usize| p.voxel * (-f64::from(p.refine[c])).exp2();
        for (c, k) in [2, 0, 1, 0].into_iter().enumerate() {
            assert_eq!(
                cell(&coarser, c),
                cell(&finer, c) * f64::from(k).exp2(),
                "class {c}"
            );
        }
    }
}
