//! Every part's rate-distortion curve (Annex A.8.2): for each trial step, the render error
//! of the part quantized alone and the bits the layer coder would pay for it. The bits are
//! counted on a spatial sample of a large scene ([`super::sample`]). The error is rendered
//! at every trial ([`Effort::Best`]) or predicted from one pass of sensitivities
//! ([`super::sensitivity`]), with each part's constant calibrated on two renders of the
//! sample ([`Effort::Default`]) or taken from the prior ([`Effort::Fast`]).

use super::grid::{grid, group_coordinates, Grid};
use super::layer::{group_bits, BitCost};
use super::plan::SizeClasses;
use super::prepare::PreparedGaussians;
use super::ratios::{parts, quantized, trial_exponents, Curve, Part};
use super::sample::Sample;
use super::{sensitivity, TrialSteps, Variant};
use crate::error::Result;
use crate::writers::DEFAULT_TILE_ANCHORS;
use salvq_bitstream::entropy::GaussianTables;
use salvq_bitstream::explicit::groups::GroupKind;
use salvq_bitstream::explicit::Gaussians;
use salvq_bitstream::tiles::TileTable;
use salvq_render::compare::RingTarget;

/// How hard the encoder searches (Annex A.8.2): how the curves' render errors are found.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Effort {
    /// Predicted from the sensitivities with the prior constants: no render besides the
    /// sensitivities' pass, and the rates are not landed by rendering.
    Fast,
    /// Predicted from the sensitivities with each part's constant calibrated on two renders
    /// of the scene's sample; each rate landed by rendering.
    #[default]
    Default,
    /// Rendered at every trial step, the whole scene; each rate landed by rendering.
    Best,
}

/// The errors the calibration aims at, per part, as MSE: the finest and coarsest default
/// targets (62 and 35 dB) shared among the parts.
const CALIBRATION_DB: [f64; 2] = [62.0, 35.0];

/// Work units (trial renders at the curves' size, of the whole scene) of the curves under
/// `effort`: what [`measure_curves`] reports progress in.
pub fn curve_units(p: &PreparedGaussians, effort: Effort) -> u64 {
    let parts = parts(p);
    match effort {
        Effort::Best => parts
            .iter()
            .map(|&part| trial_exponents(part).0.len() as u64)
            .sum(),
        // The sensitivities' pass, and per part its bits (and two sample renders).
        Effort::Default => 1 + 2 * parts.len() as u64,
        Effort::Fast => 1 + parts.len() as u64 / 2,
    }
}

/// Every part's curve (Annex A.8.2): `target` is the ring at the curves' size, `sample`
/// the scene's spatial sample (`None`: the scene is small enough to count on whole). `progress`
/// hears each part as it starts (its number from 1, and its description) and the work units
/// done so far ([`curve_units`]).
#[allow(clippy::too_many_arguments)]
pub fn measure_curves(
    g: &Gaussians,
    p: &PreparedGaussians,
    sample: Option<&Sample>,
    classes: &SizeClasses,
    variant: Variant,
    effort: Effort,
    target: &RingTarget,
    progress: &dyn Fn(usize, &str, u64),
) -> Result<Vec<(Part, Curve)>> {
    let (sg, sp) = match sample {
        Some(s) => (&s.gaussians, &s.prepared),
        None => (g, p),
    };
    let all = parts(p);
    let units = curve_units(p, effort);
    let per_part = (units - u64::from(effort != Effort::Best)) / all.len() as u64;
    progress(1, &all[0].describe(&p.kinds), 0);
    let model = match effort {
        Effort::Best => None,
        _ => Some(target.sensitivities(g)),
    };
    let calibration = match effort {
        Effort::Default => Some(Calibration::new(sg, sp, classes)?),
        _ => None,
    };
    let mut bits = Bits::new(sp, classes, variant);
    let start = TrialSteps::default_for(p);
    let class_of = classes.classes(p);
    let class_of = class_of.as_slice();
    let mut out = Vec::with_capacity(all.len());
    let done_before = u64::from(effort != Effort::Best);
    for (number, &part) in all.iter().enumerate() {
        let what = part.describe(&p.kinds);
        let before = done_before + number as u64 * per_part;
        progress(number + 1, &what, before);
        let base = part.base_step(&start);
        let (ks, scale) = trial_exponents(part);
        let members = part.members(class_of);
        let error: Box<dyn Fn(usize, f64) -> Result<f64>> = match &model {
            None => {
                let (group, class) = part.quantizes();
                Box::new(move |k_at, step| {
                    progress(number + 1, &what, before + k_at as u64);
                    Ok(target.mse(&quantized(g, p, group, class.map(|c| (c, class_of)), step))?)
                })
            }
            Some(sens) => {
                let u = sensitivity::weights(p, sens, part);
                let kappa = match &calibration {
                    Some(c) => c.kappa(part, base, &ks, scale)?,
                    None => Kappa::constant(sensitivity::prior(p, part)),
                };
                let members = members.clone();
                Box::new(move |_, step| {
                    let e = sensitivity::predicted_error(p, part, &members, &u, step);
                    Ok(kappa.at((step / base).log2()) * e)
                })
            }
        };
        let of = bits.part(part);
        let mut curve = Curve::new();
        if members.is_empty() {
            curve.push((0.0, 0.0, 0.0));
            out.push((part, curve));
            continue;
        }
        for (k_at, &k) in ks.iter().enumerate() {
            let log2 = f64::from(k) * scale;
            let step = base * log2.exp2();
            let mse = error(k_at, step)?;
            curve.push((log2, mse, bits.of(part, &of, k, step)?));
            if mse < 1e-10 {
                break;
            }
        }
        out.push((part, curve));
    }
    Ok(out)
}

/// A part's `κ` as a function of log2 of its step over the default: linear in log `κ`
/// between calibration points, constant beyond them.
struct Kappa(Vec<(f64, f64)>);

impl Kappa {
    fn constant(k: f64) -> Kappa {
        Kappa(vec![(0.0, k)])
    }

    fn at(&self, x: f64) -> f64 {
        let pts = &self.0;
        let (first, last) = (pts[0], pts[pts.len() - 1]);
        if x <= first.0 {
            return first.1;
        }
        if x >= last.0 {
            return last.1;
        }
        let k = pts.partition_point(|q| q.0 <= x);
        let (a, b) = (pts[k - 1], pts[k]);
        let t = (x - a.0) / (b.0 - a.0).max(1e-12);
        (a.1.ln() + t * (b.1.ln() - a.1.ln())).exp()
    }
}

/// The sample's own ring and sensitivities, on which each part's `κ` is measured.
struct Calibration<'a> {
    g: &'a Gaussians,
    p: &'a PreparedGaussians,
    class_of: Vec<u8>,
    target: RingTarget,
    sens: salvq_render::raster::Sensitivities,
}

impl<'a> Calibration<'a> {
    fn new(
        g: &'a Gaussians,
        p: &'a PreparedGaussians,
        classes: &SizeClasses,
    ) -> Result<Calibration<'a>> {
        use super::ratios::{CURVE_HEIGHT, CURVE_VIEWS, CURVE_WIDTH};
        let target = RingTarget::new(g, CURVE_VIEWS, CURVE_WIDTH, CURVE_HEIGHT)?;
        let sens = target.sensitivities(g);
        Ok(Calibration {
            g,
            p,
            class_of: classes.classes(p),
            target,
            sens,
        })
    }

    /// `part`'s `κ` at the trials whose predicted error (with the prior) is nearest to each
    /// of [`CALIBRATION_DB`]'s shares: rendered error over predicted error there.
    fn kappa(&self, part: Part, base: f64, ks: &[i32], scale: f64) -> Result<Kappa> {
        let prior = sensitivity::prior(self.p, part);
        let members = part.members(&self.class_of);
        let u = sensitivity::weights(self.p, &self.sens, part);
        let predicted: Vec<(f64, f64)> = ks
            .iter()
            .map(|&k| {
                let x = f64::from(k) * scale;
                let e = sensitivity::predicted_error(self.p, part, &members, &u, base * x.exp2());
                (x, e)
            })
            .collect();
        let shares = parts(self.p).len() as f64;
        let mut points: Vec<(f64, f64)> = Vec::new();
        for db in CALIBRATION_DB {
            let want = 10f64.powf(-db / 10.0) / shares;
            let Some(&(x, e)) = predicted.iter().filter(|t| t.1 > 0.0).min_by(|a, b| {
                let d = |t: &(f64, f64)| (prior * t.1 / want).ln().abs();
                d(a).total_cmp(&d(b))
            }) else {
                continue;
            };
            if points.iter().any(|q| q.0 == x) {
                continue;
            }
            let (group, class) = part.quantizes();
            let quantized = quantized(
                self.g,
                self.p,
                group,
                class.map(|c| (c, self.class_of.as_slice())),
                base * x.exp2(),
            );
            let rendered = self.target.mse(&quantized)?;
            points.push((x, (rendered / e).max(prior * 1e-3)));
        }
        if points.is_empty() {
            return Ok(Kappa::constant(prior));
        }
        points.sort_by(|a, b| a.0.total_cmp(&b.0));
        Ok(Kappa(points))
    }
}

/// The bits of each part at each trial step, counted on the (sampled) scene `p` as the
/// layer coder pays them (positions: the octree at that edge, shared by the size classes
/// in proportion to their Gaussians), per Gaussian of the scene.
struct Bits<'a> {
    p: &'a PreparedGaussians,
    class_of: Vec<u8>,
    variant: Variant,
    reference: Grid,
    /// Octree bits per Gaussian at each trial exponent, shared by the position parts.
    octree: rustc_hash::FxHashMap<i32, f64>,
}

/// One part's Gaussians of the sampled scene, in canonical order, their voxels and tiles.
struct PartBits {
    members: Vec<usize>,
    voxels: Vec<[u32; 3]>,
    tiles: TileTable,
    share: f64,
}

impl<'a> Bits<'a> {
    fn new(p: &'a PreparedGaussians, classes: &SizeClasses, variant: Variant) -> Bits<'a> {
        let reference = grid(
            p,
            p.min.map(|v| v as f32),
            TrialSteps::default_for(p).position,
        );
        Bits {
            p,
            class_of: classes.classes(p),
            variant,
            reference,
            octree: Default::default(),
        }
    }

    fn part(&self, part: Part) -> PartBits {
        let (mut members, mut voxels) = (Vec::new(), Vec::new());
        for (&i, &v) in self.reference.order.iter().zip(&self.reference.voxels) {
            if part.holds(self.class_of[i]) {
                members.push(i);
                voxels.push(v);
            }
        }
        let tiles = crate::writers::cut(&voxels, DEFAULT_TILE_ANCHORS);
        let share = members.len() as f64 / self.p.len() as f64;
        PartBits {
            members,
            voxels,
            tiles,
            share,
        }
    }

    /// Bits per Gaussian of `part` (its Gaussians `of`) at trial `k` (step `step`).
    fn of(&mut self, part: Part, of: &PartBits, k: i32, step: f64) -> Result<f64> {
        let p = self.p;
        if of.members.is_empty() {
            return Ok(0.0);
        }
        let tables = GaussianTables::standard();
        match part {
            Part::Position(_) => {
                if let Some(&b) = self.octree.get(&k) {
                    return Ok(b * of.share);
                }
                let gr = grid(p, p.min.map(|v| v as f32), step);
                let t = crate::writers::cut(&gr.voxels, DEFAULT_TILE_ANCHORS);
                let mut bytes = 0usize;
                for i in 0..t.len() {
                    let (level, cell) = t.cells[i];
                    let local: Vec<[u32; 3]> = gr.voxels[t.range(i)]
                        .iter()
                        .map(|v| [0, 1, 2].map(|a| v[a] - (cell[a] << level)))
                        .collect();
                    bytes += crate::writers::encode_geometry(&local, level, tables)?.len();
                }
                let b = bytes as f64 * 8.0 / p.len() as f64;
                self.octree.insert(k, b);
                Ok(b * of.share)
            }
            Part::Scale | Part::Group(..) => {
                let gi = part.quantizes().0.unwrap_or(0);
                let one = super::measurement_group(p, gi);
                let c = group_coordinates(&p.values[gi], &one, step as f32, &|_| 0, &of.members);
                Ok(group_bits(
                    &c,
                    p.dim(gi),
                    &of.voxels,
                    self.reference.coord_bits,
                    &of.tiles,
                    BitCost::standard(),
                    self.variant,
                    one.kind == GroupKind::Rest,
                ) * of.share)
            }
        }
    }
}
