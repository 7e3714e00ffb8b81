//! The render error of a part's quantization predicted without rendering it (Annex A.8.2):
//! one pass over the camera ring gives each Gaussian's first-order sensitivities
//! ([`salvq_render::raster::Sensitivities`]); a part quantized at a step then changes the
//! ring's mean squared error by about `κ · Σᵢ uᵢ · |xᵢ − Q(xᵢ)|²` over its Gaussians, with
//! `uᵢ` the Gaussian's weight for the part's kind of value and `κ` a constant of the part.
//! For colour `κ` follows from the spherical harmonics; for the geometry it stands for the
//! unknown contrast of a Gaussian against what lies behind it, and is either a prior
//! (measured once on the real scenes) or calibrated on one render of the part.

use super::prepare::PreparedGaussians;
use super::ratios::Part;
use salvq_bitstream::explicit::groups::GroupKind;
use salvq_render::raster::Sensitivities;

/// `1 / (12 π)`: a coefficient of an orthonormal real spherical harmonic has mean square
/// `1 / (4 π)` over the sphere, and the error is averaged over the three channels.
const COLOUR: f64 = 1.0 / (12.0 * std::f64::consts::PI);

/// Each Gaussian's weights for one part's values: one for all its values, or for the
/// scale group one per axis.
pub enum Weights {
    /// `uᵢ`, the same for each of the Gaussian's values.
    Each(Vec<f64>),
    /// `uᵢ` per axis of the scale group.
    PerAxis(Vec<[f64; 3]>),
}

/// Each Gaussian's weights for one part's values (Annex A.8.2). Positions and rotations
/// move the edge of a Gaussian's footprint, weighed by [`Sensitivities::position`]: a mean
/// by its error, a turn by `2 δ` (a quaternion component's error) by the differences of
/// the axes. An error `δ` of a log-scale stretches its axis by `δ` of its length, which
/// changes its pixels by about `α·T·δ` where the image resolves the axis (the low-pass
/// filter of 0.3 pixel² hides the rest).
pub fn weights(p: &PreparedGaussians, s: &Sensitivities, part: Part) -> Weights {
    let n = p.len();
    let colour = |i: usize| f64::from(s.colour[i]);
    // A move along the view axis shifts nothing on screen: two of three axes count.
    let moved = |i: usize| 2.0 / 3.0 * f64::from(s.position[i]);
    let axes = |i: usize| -> [f64; 3] {
        let l = &p.values[0][3 * i..3 * i + 3];
        [l[0].exp(), l[1].exp(), l[2].exp()]
    };
    let kind = match part {
        Part::Position(_) => return Weights::Each((0..n).map(moved).collect()),
        Part::Scale => GroupKind::Scale,
        Part::Group(gi, _) => p.kinds[gi],
    };
    Weights::Each(match kind {
        GroupKind::Dc | GroupKind::Rest => (0..n).map(|i| COLOUR * colour(i)).collect(),
        GroupKind::Opacity => {
            // dα/dl = α (1 − σ(l)) for the logit l: an opaque Gaussian hardly moves.
            let logits = &p.values[opacity_group(p)];
            (0..n)
                .map(|i| {
                    let sig = 1.0 / (1.0 + (-logits[i]).exp());
                    colour(i) * (1.0 - sig) * (1.0 - sig)
                })
                .collect()
        }
        GroupKind::Scale => {
            return Weights::PerAxis(
                (0..n)
                    .map(|i| {
                        let c = colour(i);
                        let zoom = f64::from(s.magnification[i]) / c.max(1e-30);
                        axes(i).map(|a| {
                            let px = a * a * zoom;
                            c * px / (px + f64::from(salvq_render::raster::LOW_PASS))
                        })
                    })
                    .collect(),
            )
        }
        GroupKind::Rotation => (0..n)
            .map(|i| {
                // A turn by θ about one axis moves the others' ends by θ times their
                // difference: a round Gaussian does not change.
                let [a, b, c] = axes(i);
                let spread = ((a - b).powi(2) + (b - c).powi(2) + (a - c).powi(2)) / 3.0;
                moved(i) * 4.0 * spread
            })
            .collect(),
    })
}

fn opacity_group(p: &PreparedGaussians) -> usize {
    p.kinds
        .iter()
        .position(|&k| k == GroupKind::Opacity)
        .unwrap_or(0)
}

/// The prior `κ` of a part (what [`super::curves::Effort::Fast`] uses): the geometric
/// mean over two as-trained scenes (fruit_drops, alti) of the median ratio of rendered to
/// predicted error, over the trials that render between 10⁻⁸ and 10⁻⁴ (Annex A.8.2;
/// `cargo run --release -p salvq-bench --example sensitivity_check -- SCENE.ply` prints
/// every ratio). Colour is above 1 because the errors of Gaussians that overlap and hold
/// nearly the same value are alike, and add in amplitude, not in power.
pub fn prior(p: &PreparedGaussians, part: Part) -> f64 {
    let kind = match part {
        Part::Position(_) => return 0.066,
        Part::Scale => GroupKind::Scale,
        Part::Group(gi, _) => p.kinds[gi],
    };
    match kind {
        GroupKind::Dc => 1.6,
        GroupKind::Rest => 2.0,
        GroupKind::Opacity => 0.1,
        GroupKind::Scale => 0.125,
        GroupKind::Rotation => 0.04,
    }
}

/// `Σᵢ uᵢ · |xᵢ − Q(xᵢ)|²` over `members` for the part's values quantized at `step` (as
/// [`super::ratios`] quantizes them: positions to voxel centres, other values to multiples
/// of the step).
pub fn predicted_error(
    p: &PreparedGaussians,
    part: Part,
    members: &[usize],
    u: &Weights,
    step: f64,
) -> f64 {
    let err = |x: f64| {
        let e = x - step * (x / step).round();
        e * e
    };
    let weight = |i: usize, k: usize| match u {
        Weights::Each(u) => u[i],
        Weights::PerAxis(u) => u[i][k],
    };
    match part {
        Part::Position(_) => members
            .iter()
            .map(|&i| {
                (0..3)
                    .map(|a| {
                        let x = p.positions[i][a] - p.min[a];
                        let e = x - step * ((x / step).floor() + 0.5);
                        weight(i, a) * e * e
                    })
                    .sum::<f64>()
            })
            .sum(),
        Part::Scale | Part::Group(..) => {
            let gi = part.quantizes().0.unwrap_or(0);
            let d = p.dim(gi);
            let v = &p.values[gi];
            members
                .iter()
                .map(|&i| {
                    v[i * d..(i + 1) * d]
                        .iter()
                        .enumerate()
                        .map(|(k, &x)| weight(i, k.min(2)) * err(x))
                        .sum::<f64>()
                })
                .sum()
        }
    }
}
