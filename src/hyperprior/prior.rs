//! The per-anchor prior (spec §5.3-§5.5 together): features -> context MLP -> for each
//! attribute group the step factor, and for each coded value its mean and scale index.

use super::grid::GridLayout;
use super::mlp::IntMlp;
use super::step::{factor_index, BaseStep, STEP_FACTOR, THRESHOLDS};
use crate::entropy::scale::THRESHOLD_Q16;
use crate::model::{Dims, GroupQuantizer, HashGrid};

/// The attribute groups in coding order (spec §6.6).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Group {
    Feature = 0,
    Scaling = 1,
    Offsets = 2,
}

impl Group {
    pub const ALL: [Group; 3] = [Group::Feature, Group::Scaling, Group::Offsets];

    pub fn name(self) -> &'static str {
        match self {
            Group::Feature => "feature",
            Group::Scaling => "scaling",
            Group::Offsets => "offsets",
        }
    }
}

/// Scratch space and outputs of one anchor's evaluation.
#[derive(Debug, Clone)]
pub struct AnchorContext {
    x: Vec<i16>,
    h: Vec<i16>,
    /// Context MLP outputs, units of 2^-E.
    pub y: Vec<i32>,
}

/// Everything fixed for a stream: layout, integer MLP, base steps of the coded rate.
#[derive(Debug, Clone)]
pub struct Prior {
    pub layout: GridLayout,
    pub mlp: IntMlp,
    pub steps: [BaseStep; 3],
    /// Output offsets of (mean, scale) per group, and of the three adjustments.
    mean_at: [usize; 3],
    scale_at: [usize; 3],
    adj_at: usize,
    /// Fraction bits E_o of each output.
    frac: Vec<i32>,
    /// Per group: the largest E_o of its scale outputs; per output: emax - E_o (§5.4 step 3).
    emax: [i32; 3],
    lift: Vec<u32>,
}

/// A group's step at one anchor: the Table 5-2 factor, the binary32 step Δ, and the scale
/// thresholds in the domain of the group's scale outputs (§5.4 step 3).
#[derive(Debug, Clone, PartialEq)]
pub struct GroupStep {
    pub factor: u32,
    pub delta: f32,
    y_thresholds: [u64; THRESHOLDS],
}

impl Prior {
    pub fn new(
        dims: &Dims,
        coord_bits: u8,
        mlp: IntMlp,
        quant: [&GroupQuantizer; 3],
        rate: usize,
    ) -> Prior {
        let f = usize::from(dims.feat_dim);
        let s = usize::from(dims.scaling_dim);
        let k3 = 3 * usize::from(dims.offsets);
        let gain = |q: &GroupQuantizer| q.gains.get(rate).copied().unwrap_or(1.0);
        let frac: Vec<i32> = (0..mlp.cout).map(|o| mlp.out_frac_bits(o)).collect();
        let scale_at = [f, 2 * f + s, 2 * f + 2 * s + k3];
        let widths = [f, s, k3];
        let emax: [i32; 3] = std::array::from_fn(|g| {
            frac[scale_at[g]..scale_at[g] + widths[g]]
                .iter()
                .copied()
                .max()
                .unwrap_or(0)
        });
        let mut lift = vec![0u32; mlp.cout];
        for g in 0..3 {
            for o in scale_at[g]..scale_at[g] + widths[g] {
                lift[o] = (emax[g] - frac[o]) as u32;
            }
        }
        Prior {
            layout: GridLayout::new(dims, coord_bits),
            frac,
            emax,
            lift,
            mlp,
            steps: quant.map(|q| BaseStep::new(q.step, gain(q))),
            mean_at: [0, 2 * f, 2 * f + 2 * s],
            scale_at,
            adj_at: 2 * f + 2 * s + 2 * k3,
        }
    }

    pub fn context(&self) -> AnchorContext {
        AnchorContext {
            x: vec![0; self.layout.features()],
            h: vec![0; self.mlp.hidden],
            y: vec![0; self.mlp.cout],
        }
    }

    /// §5.1 + §5.3: evaluates the anchor at voxel `v` into `ctx.y`.
    pub fn eval(&self, grid: &HashGrid, v: [u32; 3], ctx: &mut AnchorContext) {
        self.layout.interpolate(grid, v, &mut ctx.x);
        self.mlp.eval(&ctx.x, &mut ctx.h, &mut ctx.y);
    }

    /// §5.4 step 1: the group's step at this anchor.
    pub fn step(&self, y: &[i32], g: Group) -> GroupStep {
        let o = self.adj_at + g as usize;
        let factor = STEP_FACTOR[factor_index(y[o], self.frac[o])];
        let base = &self.steps[g as usize];
        GroupStep {
            factor,
            delta: base.delta(factor),
            y_thresholds: base.y_thresholds(factor, self.emax[g as usize], &THRESHOLD_Q16),
        }
    }

    /// The mean output of value `j` of group `g` (units of 2^-E).
    #[inline]
    pub fn mean(&self, y: &[i32], g: Group, j: usize) -> i32 {
        y[self.mean_at[g as usize] + j]
    }

    /// §5.4 step 3: the scale index of value `j` of group `g`.
    #[inline]
    pub fn scale_index(&self, y: &[i32], g: Group, j: usize, step: &GroupStep) -> u8 {
        let o = self.scale_at[g as usize] + j;
        let lifted = (y[o].max(1) as u64) << self.lift[o];
        // The number of thresholds <= lifted, by a branch-free binary search (the thresholds
        // increase; the comparisons become conditional moves, with no mispredictions).
        let t = &step.y_thresholds;
        let mut k = 0usize;
        for half in [32usize, 16, 8, 4, 2, 1] {
            let probe = k + half - 1;
            k += half * usize::from(probe < t.len() && t[probe] <= lifted);
        }
        k as u8
    }

    /// §5.5: reconstruction of value `j` of group `g` from its symbol.
    #[inline]
    pub fn reconstruct(&self, y: &[i32], g: Group, j: usize, delta: f32, u: i64) -> f32 {
        let o = self.mean_at[g as usize] + j;
        super::step::reconstruct(y[o], self.frac[o], delta, u)
    }

    /// Fraction bits E_o of output `o`.
    pub fn frac(&self, o: usize) -> i32 {
        self.frac[o]
    }
}
