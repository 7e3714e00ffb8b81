//! The per-anchor prior (spec §5.3-§5.5 together): features -> context MLP -> for each
//! attribute group the step factor, and for each coded value its mean and scale index.

use super::grid::{GridLayout, GridRef, GridSigns};
use super::mlp::IntMlp;
use super::simd::{FastGrid, FastMlp};
use super::step::{factor_index, BaseStep, STEP_FACTOR};
use super::threshold_search::ThresholdSearch;
use crate::entropy::scale::THRESHOLD_Q16;
use crate::model::{Dims, GroupQuantizer, HashGrid};

/// The attribute groups in coding order (spec §6.6).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Group {
    /// The latent features, F values per anchor (`AFEA`).
    Feature = 0,
    /// The scalings, S values per anchor (`ASCL`).
    Scaling = 1,
    /// The offsets, 3 values per unmasked offset slot (`AOFF`).
    Offsets = 2,
}

impl Group {
    /// The three groups in coding order.
    pub const ALL: [Group; 3] = [Group::Feature, Group::Scaling, Group::Offsets];

    /// The group's lower-case name (`feature`, `scaling`, `offsets`), as reports print it.
    pub fn name(self) -> &'static str {
        match self {
            Group::Feature => "feature",
            Group::Scaling => "scaling",
            Group::Offsets => "offsets",
        }
    }
}

/// Anchors [`Prior::eval_batch_into`] evaluates at once: two share each of the context MLP's
/// weight loads (`simd::avx2_batch`); four ran slower than two.
pub const BATCH: usize = 2;

/// Scratch space and outputs of one anchor's evaluation (of [`BATCH`] anchors' inputs and
/// hidden units, for [`Prior::eval_batch_into`]).
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
    /// The hash-grid layout the features are interpolated on (§2.4, §5.1).
    pub layout: GridLayout,
    /// The integer context MLP (§5.3).
    pub mlp: IntMlp,
    /// The same MLP in the layout of this target's kernel, where it has one (AVX2 on x86-64,
    /// `simd128` on WebAssembly; bit-identical).
    fast: Option<FastMlp>,
    /// The interpolation kernel where the target has one for this layout.
    fast_grid: Option<FastGrid>,
    /// The base steps G of the feature, scaling and offsets groups at the coded rate (§5.4).
    pub steps: [BaseStep; 3],
    /// Output offsets of (mean, scale) per group, and of the three adjustments.
    mean_at: [usize; 3],
    scale_at: [usize; 3],
    adj_at: usize,
    /// Fraction bits E_o of each output.
    frac: Vec<i32>,
    /// 2^-E_o of each output, exactly (§5.5 step 1's scale of a mean).
    unit: Vec<f64>,
    /// Per output: how far its scale output is shifted up to the group's largest E_o, the
    /// domain of `thresholds` (§5.4 step 3).
    lift: Vec<u32>,
    /// Per group and Table 5-2 factor (`g · 129 + factor index`): the binary32 step Δ and the
    /// scale thresholds in the group's output domain. A step factor takes one of 129 values,
    /// so these are computed once per decode, not once per anchor.
    deltas: Vec<f32>,
    thresholds: Vec<ThresholdSearch>,
}

/// A group's step at one anchor: the Table 5-2 factor, the binary32 step Δ, and the scale
/// thresholds in the domain of the group's scale outputs (§5.4 step 3).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GroupStep<'a> {
    /// The step factor of Table 5-2, in units of 2^−16 (44 … 131028).
    pub factor: u32,
    /// The anchor's binary32 step Δ = G · factor / 2^16 (§5.4 step 1).
    pub delta: f32,
    /// The thresholds, then a sentinel u64::MAX that no lifted output reaches.
    y_thresholds: &'a ThresholdSearch,
}

impl Prior {
    /// The prior of a stream of dimensions `dims` and voxel coordinates below
    /// 2^`coord_bits`, with its context MLP and the groups' quantizers, at rate `rate`
    /// (a quantizer without a gain for that rate takes 1.0); precomputes every step factor's
    /// Δ and scale thresholds (§5.4).
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
        let layout = GridLayout::new(dims, coord_bits);
        let fast = if layout.features() == mlp.cin {
            FastMlp::new(&mlp)
        } else {
            None
        };
        let fast_grid = FastGrid::new(&layout);
        let steps = quant.map(|q| BaseStep::new(q.step, gain(q)));
        let (mut deltas, mut thresholds) = (Vec::new(), Vec::new());
        for (g, base) in steps.iter().enumerate() {
            for &factor in &STEP_FACTOR {
                deltas.push(base.delta(factor));
                let t = base.y_thresholds(factor, emax[g], &THRESHOLD_Q16);
                thresholds.push(ThresholdSearch::new(std::array::from_fn(|i| {
                    t.get(i).copied().unwrap_or(u64::MAX)
                })));
            }
        }
        let unit = frac.iter().map(|&e| super::mlp::pow2(-e)).collect();
        Prior {
            layout,
            unit,
            fast,
            fast_grid,
            frac,
            lift,
            mlp,
            steps,
            deltas,
            thresholds,
            mean_at: [0, 2 * f, 2 * f + 2 * s],
            scale_at,
            adj_at: 2 * f + 2 * s + 2 * k3,
        }
    }

    /// Zeroed scratch and outputs for evaluating anchors with this prior, sized for its
    /// kernel (padded where the kernel reads or writes past the plain widths).
    pub fn context(&self) -> AnchorContext {
        // The kernel reads zero-padded inputs and writes padded hidden scratch.
        let (x_len, h_len) = (self.layout.features(), self.mlp.hidden);
        let (x_len, h_len) = match &self.fast {
            Some(k) => (
                BATCH * x_len.max(k.input_len()),
                h_len.max(k.hidden_len()).max(k.batch_hidden_len(BATCH)),
            ),
            None => (x_len, h_len),
        };
        AnchorContext {
            x: vec![0; x_len],
            h: vec![0; h_len],
            y: vec![0; self.mlp.cout],
        }
    }

    /// §5.1 + §5.3: evaluates the anchor at voxel `v` into `ctx.y`.
    pub fn eval(&self, grid: &HashGrid, v: [u32; 3], ctx: &mut AnchorContext) {
        let AnchorContext { x, h, y } = ctx;
        self.eval_parts(grid.into(), v, x, h, y);
    }

    /// Starts loading the grid entries that evaluating the anchor at voxel `v` reads (see
    /// [`GridLayout::prefetch`]).
    pub fn prefetch(&self, grid: GridRef<'_>, v: [u32; 3]) {
        match (&self.fast_grid, grid.signs) {
            // The signs fit this machine's L2 cache beside the rest of a decode: requesting
            // their words ahead cost more than waiting for them (the one-thread decode was
            // faster without the prefetch).
            (_, Some(_)) => {}
            (Some(k), None) => k.prefetch(&self.layout, grid.values, v),
            (None, None) => self.layout.prefetch(grid.values, v),
        }
    }

    /// The signs of `grid`'s values ([`GridSigns`]) where its entries have
    /// [`super::grid::SIGN_CHANNELS`] values (`None` otherwise): this target's kernel reads
    /// them, or the scalar loop where it has none ([`GridLayout::interpolate_signs`]).
    pub fn grid_signs(&self, grid: &HashGrid) -> Option<GridSigns> {
        GridSigns::new(grid, self.layout.channels)
    }

    /// §5.1: the grid features of the anchor at voxel `v` into `x` (length
    /// `layout.features()`), with this target's kernel where it has one: the same integers
    /// as [`GridLayout::interpolate`] for a grid of ±1 values (§2.4), which every decoded
    /// and every validated grid is.
    pub fn features(&self, grid: GridRef<'_>, v: [u32; 3], x: &mut [i16]) {
        match (&self.fast_grid, grid.signs) {
            (Some(k), Some(signs)) => k.interpolate_signs(&self.layout, grid.values, signs, v, x),
            (Some(k), None) => k.interpolate(&self.layout, grid.values, v, x),
            (None, Some(signs)) => self.layout.interpolate_signs(signs, v, x),
            (None, None) => self.layout.interpolate(grid.values, v, x),
        }
    }

    /// [`Prior::eval`] with the outputs written to `y` (length `cout`) instead of `ctx.y`.
    pub fn eval_into(
        &self,
        grid: GridRef<'_>,
        v: [u32; 3],
        ctx: &mut AnchorContext,
        y: &mut [i32],
    ) {
        self.eval_parts(grid, v, &mut ctx.x, &mut ctx.h, y);
    }

    /// [`Prior::eval_into`] of [`BATCH`] anchors, `ys` (`BATCH · cout`) holding their
    /// outputs one after the other: the same values, with the kernel's batch where this
    /// target has one.
    pub fn eval_batch_into(
        &self,
        grid: GridRef<'_>,
        v: &[[u32; 3]; BATCH],
        ctx: &mut AnchorContext,
        ys: &mut [i32],
    ) {
        let cout = self.mlp.cout;
        if let Some(k) = &self.fast {
            let (n, stride) = (self.layout.features(), k.input_len());
            for (&va, x) in v.iter().zip(ctx.x.chunks_exact_mut(stride)) {
                self.features(grid, va, &mut x[..n]);
            }
            k.eval_batch::<BATCH>(&ctx.x, &mut ctx.h, ys);
            return;
        }
        for (&va, y) in v.iter().zip(ys.chunks_exact_mut(cout)) {
            self.eval_into(grid, va, ctx, y);
        }
    }

    fn eval_parts(
        &self,
        grid: GridRef<'_>,
        v: [u32; 3],
        x: &mut [i16],
        h: &mut [i16],
        y: &mut [i32],
    ) {
        let n = self.layout.features();
        self.features(grid, v, &mut x[..n]);
        if let Some(k) = &self.fast {
            k.eval(x, h, y);
            return;
        }
        self.mlp.eval(&x[..n], &mut h[..self.mlp.hidden], y);
    }

    /// §5.4 step 1: the group's step at this anchor.
    pub fn step(&self, y: &[i32], g: Group) -> GroupStep<'_> {
        let o = self.adj_at + g as usize;
        let fi = factor_index(y[o], self.frac[o]);
        let at = g as usize * STEP_FACTOR.len() + fi;
        GroupStep {
            factor: STEP_FACTOR[fi],
            delta: self.deltas[at],
            y_thresholds: &self.thresholds[at],
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
        let mut k = [0u8];
        self.scale_indices(y, g, j, step, &mut k);
        k[0]
    }

    /// §5.4 step 3 for the values `first .. first + out.len()` of group `g`.
    #[inline]
    pub fn scale_indices(
        &self,
        y: &[i32],
        g: Group,
        first: usize,
        step: &GroupStep,
        out: &mut [u8],
    ) {
        let o = self.scale_at[g as usize] + first;
        let (ys, lifts) = (&y[o..o + out.len()], &self.lift[o..o + out.len()]);
        // lift <= 30 (Table 5-1 bounds the weight fraction bits) and y < 2^31, so the lifted
        // value stays below 2^61 < the sentinel.
        step.y_thresholds.counts_into(ys, lifts, out);
    }

    /// §5.4 step 3 for the offsets of the slots whose `mask` byte is not 0, into `out` (3
    /// per slot, K slots): the others' are not needed and are left as they were, or
    /// computed too where counting them with the rest costs nothing.
    #[inline]
    pub fn offset_scale_indices(&self, y: &[i32], step: &GroupStep, mask: &[u8], out: &mut [u8]) {
        if step.y_thresholds.vectorized() {
            return self.scale_indices(y, Group::Offsets, 0, step, &mut out[..3 * mask.len()]);
        }
        for (slot, _) in mask.iter().enumerate().filter(|(_, &m)| m != 0) {
            let at = 3 * slot;
            self.scale_indices(y, Group::Offsets, at, step, &mut out[at..at + 3]);
        }
    }

    /// §5.5 step 1: the binary32 mean μ of value `j` of group `g`.
    #[inline]
    pub fn mean_f32(&self, y: &[i32], g: Group, j: usize) -> f32 {
        let o = self.mean_at[g as usize] + j;
        super::step::mean_f32(y[o], self.frac[o])
    }

    /// §5.5: reconstruction of value `j` of group `g` from its symbol.
    #[inline]
    pub fn reconstruct(&self, y: &[i32], g: Group, j: usize, delta: f32, u: i64) -> f32 {
        let o = self.mean_at[g as usize] + j;
        super::step::reconstruct(y[o], self.frac[o], delta, u)
    }

    /// §5.5 for the values `first .. first + out.len()` of group `g` from their symbols `u`:
    /// [`Prior::reconstruct`] of each, with each output's 2^-E_o looked up instead of built.
    #[inline]
    pub fn reconstruct_values(
        &self,
        y: &[i32],
        g: Group,
        first: usize,
        delta: f32,
        u: &[i64],
        out: &mut [f32],
    ) {
        let o = self.mean_at[g as usize] + first;
        let (means, units) = (&y[o..o + out.len()], &self.unit[o..o + out.len()]);
        for (((x, &m), &unit), &u) in out.iter_mut().zip(means).zip(units).zip(u) {
            // μ = y 2^-E rounded once to binary32, as `step::mean_f32`.
            let mu = (f64::from(m) * unit) as f32;
            *x = super::step::reconstruct_from(mu, delta, u);
        }
    }

    /// Fraction bits E_o of output `o`.
    pub fn frac(&self, o: usize) -> i32 {
        self.frac[o]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hyperprior::test_scene::TestScene;

    /// The row reconstruction gives each value's [`Prior::reconstruct`], bit for bit, for
    /// every group, symbols from 0 to beyond 2^31, and steps that overflow to ∞ and NaN.
    #[test]
    fn row_reconstruction_equals_the_single_value() {
        let scene = TestScene::new(200, 9);
        let prior = Prior::new(
            &scene.dims,
            scene.coord_bits,
            scene.mlp(3),
            [&scene.quant; 3],
            0,
        );
        let mut ctx = prior.context();
        let symbols = [
            0i64,
            1,
            -1,
            7,
            -300,
            1 << 20,
            -(1 << 31) - 5,
            i64::MAX,
            i64::MIN,
        ];
        for &v in &scene.voxels {
            prior.eval(&scene.grid, v, &mut ctx);
            let d = &scene.dims;
            let widths = [d.feat_dim, d.scaling_dim, 3 * d.offsets].map(usize::from);
            for (g, width) in Group::ALL.into_iter().zip(widths) {
                for delta in [0.01f32, 3.5, f32::MAX, 0.0, f32::INFINITY] {
                    let u: Vec<i64> = (0..width).map(|j| symbols[j % symbols.len()]).collect();
                    let mut row = vec![0f32; width];
                    prior.reconstruct_values(&ctx.y, g, 0, delta, &u, &mut row);
                    for (j, (&x, &uj)) in row.iter().zip(&u).enumerate() {
                        let single = prior.reconstruct(&ctx.y, g, j, delta, uj);
                        assert_eq!(
                            x.to_bits(),
                            single.to_bits(),
                            "{g:?} value {j} delta {delta}"
                        );
                    }
                }
            }
        }
    }

    /// The SIMD kernel (where this CPU has one) and the portable §5.3 loop give the same
    /// outputs for every anchor of a random scene with HAC's dimensions and a random MLP
    /// (wrapping sums included: the weights are not fitted to keep them small).
    #[test]
    fn simd_and_portable_paths_agree_on_a_scene() {
        let scene = TestScene::new(3000, 5);
        let mlp = scene.mlp(7);
        let quant = [&scene.quant; 3];
        let fast = Prior::new(&scene.dims, scene.coord_bits, mlp, quant, 0);
        let mut portable = fast.clone();
        #[cfg(all(feature = "simd", target_arch = "x86_64"))]
        {
            let avx2 = crate::hyperprior::simd::avx2_or_skip(
                "hyperprior::prior::tests::simd_and_portable_paths_agree_on_a_scene",
            );
            assert_eq!(
                fast.fast.is_some(),
                avx2,
                "kernel chosen where AVX2 is present"
            );
            portable.fast = None;
        }
        let (mut a, mut b) = (fast.context(), portable.context());
        for &v in &scene.voxels {
            fast.eval(&scene.grid, v, &mut a);
            portable.eval(&scene.grid, v, &mut b);
            assert_eq!(a.y, b.y, "voxel {v:?}");
        }
    }
}
