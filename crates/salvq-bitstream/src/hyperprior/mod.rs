//! The integer hyperprior (spec §5): hash-grid interpolation with integer weights, the set of
//! grid entries anchors touch, the fixed-point context MLP, and the per-anchor steps and scale
//! indices that steer the entropy decoder. Nothing here uses floating point except the
//! binary32 reconstruction of §5.5, which does not steer decoding.

pub mod grid;
pub mod mlp;
pub mod prior;
// Always compiled: without the `simd` feature it holds only the kernel that is never made.
pub(crate) mod simd;
pub mod step;
#[cfg(test)]
mod test_scene;
mod threshold_search;
mod touched;

pub use grid::GridLayout;
pub use mlp::IntMlp;
pub use step::{BaseStep, STEP_FACTOR};
