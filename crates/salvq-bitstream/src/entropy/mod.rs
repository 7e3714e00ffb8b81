//! Entropy coding (spec §6): discretized-Gaussian frequency tables, escapes, ANS.
//!
//! Anchor-attribute symbols are integers u = round((x − μ)/Δ), coded zero-mean with a
//! discretized Gaussian whose standard deviation in symbol units σ_u selects one of 64
//! integer frequency tables through a *scale index*. Everything that steers the decoder is
//! integer: the scale grid, the table construction, the index selection and the coder.
//!
//! | spec | what | here |
//! |---|---|---|
//! | §6.1 | events, chunk body | `salvq_encoder::writers::SymbolWriter`, [`SymbolReader`] |
//! | §6.2 | the ANS coder (`constriction`'s `AnsCoder<u32, u64>`), bit-exact | [`ans`], `salvq_conformance::reference_coder` (a port from the text alone) |
//! | §6.3.1 | scale grid σ_k, thresholds θ_k, [`scale_index`] | [`scale`] |
//! | §6.3.2 – §6.3.5 | radius R_k, integer Φ, frequencies, the data file | [`tables`], `spec/tables/gaussian_tables.txt` |
//! | §6.3.6 | wide scales 64 … 127: a high part at a table scale and uniform low bits | [`scale`], [`symbols`] |
//! | §6.4 | escapes: Exp-Golomb order 0 with ½-probability bits | [`symbols`] |
//! | §6.5 | choice of P, TAIL, R_MAX (informative) | `salvq_encoder::entropy_analysis`, `salvq_bench::coder`, `crates/salvq-bench/benches/entropy_precision.rs` |
//!
//! ## Use
//!
//! [`SymbolReader`] reads a chunk body symbol by symbol; the encoder's writer
//! (`salvq_encoder::writers::SymbolWriter`) produces what it reads, and `tests/entropy_roundtrip.rs`
//! in the repository round-trips random streams with escapes and binary events through both.

pub mod ans;
pub mod scale;
pub mod symbols;
pub mod tables;

pub use scale::{
    scale_index, wide_scale, SCALE_COUNT, SCALE_INDEX_COUNT, SIGMA_Q16, THRESHOLD_Q16,
};
pub use symbols::{checked_scale_index, SymbolReader};
pub use tables::{GaussianTables, ScaleTable, PRECISION, R_MAX, TAIL_Q4};
