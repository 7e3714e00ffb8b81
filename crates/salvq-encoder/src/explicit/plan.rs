//! What each rate's layer quantizes with (Annex A.8.2): the rate's plan and the scene's
//! size classes.

use super::prepare::PreparedGaussians;
use super::prior::Variant;
use salvq_bitstream::explicit::layer::SIZE_CLASSES;

/// What one rate's layer quantizes with (Annex A.8.2).
#[derive(Debug, Clone, PartialEq)]
pub struct RatePlan {
    /// Edge of the coarse voxel grid (the octree's).
    pub voxel: f64,
    /// Position refinement bits per size class.
    pub refine: [u8; SIZE_CLASSES],
    /// Per group (Table 3-3 order), the base step.
    pub steps: Vec<f64>,
    /// Per group after the first, the step shift of each size class.
    pub shift: Vec<[i8; SIZE_CLASSES]>,
}

impl RatePlan {
    /// Every step and the voxel edge times `f` (refinement and shifts kept).
    pub fn scaled(&self, f: f64) -> RatePlan {
        RatePlan {
            voxel: self.voxel * f,
            steps: self.steps.iter().map(|s| s * f).collect(),
            ..self.clone()
        }
    }

    /// The step shift of group `gi` per size class (the scale group, first, has none).
    pub(super) fn class_shifts(&self, gi: usize) -> [i8; SIZE_CLASSES] {
        if gi == 0 {
            [0i8; SIZE_CLASSES]
        } else {
            self.shift[gi - 1]
        }
    }
}

/// The size classes of a scene (Annex A.8.2): thresholds on a Gaussian's largest log-scale,
/// the same for every rate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SizeClasses {
    /// Upper bounds of classes 0 … 2 on the largest log-scale, increasing.
    pub thresholds: [f64; SIZE_CLASSES - 1],
}

impl SizeClasses {
    /// One class for every Gaussian (thresholds above any scale).
    pub fn single() -> SizeClasses {
        SizeClasses {
            thresholds: [f64::INFINITY; SIZE_CLASSES - 1],
        }
    }

    /// The reference encoder's classes: quartiles of the largest log-scale, or one class
    /// for [`Variant::single_class`].
    pub fn for_variant(p: &PreparedGaussians, variant: Variant) -> SizeClasses {
        if variant.single_class {
            SizeClasses::single()
        } else {
            SizeClasses::quartiles(p)
        }
    }

    /// Quartiles of the largest log-scale.
    pub fn quartiles(p: &PreparedGaussians) -> SizeClasses {
        let mut largest: Vec<f64> = p.values[0]
            .chunks_exact(3)
            .map(|s| s.iter().copied().fold(f64::NEG_INFINITY, f64::max))
            .collect();
        largest.sort_by(f64::total_cmp);
        let q = |f: f64| largest[((largest.len() - 1) as f64 * f) as usize];
        SizeClasses {
            thresholds: [q(0.25), q(0.5), q(0.75)],
        }
    }

    /// The class of each Gaussian (input order), by its unquantized scales.
    pub fn classes(&self, p: &PreparedGaussians) -> Vec<u8> {
        p.values[0]
            .chunks_exact(3)
            .map(|s| {
                let l = s.iter().copied().fold(f64::NEG_INFINITY, f64::max);
                self.thresholds.iter().filter(|&&t| t <= l).count() as u8
            })
            .collect()
    }
}
