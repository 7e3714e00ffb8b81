//! Entropy coding (spec §6): discretized-Gaussian frequency tables, escapes, ANS.
//!
//! Anchor-attribute symbols are integers u = round((x − μ)/Δ), coded zero-mean with a
//! discretized Gaussian whose standard deviation in symbol units σ_u selects one of 64
//! integer frequency tables through a *scale index*. Everything that steers the decoder is
//! integer: the scale grid, the table construction, the index selection and the coder.
//!
//! | spec | what | here |
//! |---|---|---|
//! | §6.1 | events, chunk body | [`SymbolWriter`], [`SymbolReader`] |
//! | §6.2 | the ANS coder (`constriction`'s `AnsCoder<u32, u64>`), bit-exact | [`ans`], [`reference`](mod@reference) (a port from the text alone) |
//! | §6.3.1 | scale grid σ_k, thresholds θ_k, [`scale_index`] | [`scale`] |
//! | §6.3.2 – §6.3.5 | radius R_k, integer Φ, frequencies, the data file | [`tables`], `spec/tables/gaussian_tables.txt` |
//! | §6.3.6 | wide scales 64 … 127: a high part at a table scale and uniform low bits | [`scale`], [`symbols`] |
//! | §6.4 | escapes: Exp-Golomb order 0 with ½-probability bits | [`symbols`] |
//! | §6.5 | choice of P, TAIL, R_MAX (informative) | [`analysis`], `salvq_bench::coder`, `crates/salvq-bench/benches/entropy_precision.rs` |
//!
//! ## Use
//!
//! ```
//! use salvq::container::chunk::ChunkTag;
//! use salvq::entropy::{scale_index, GaussianTables, SymbolReader, SymbolWriter};
//!
//! let tables = GaussianTables::standard();
//! let k = scale_index(3 << 16); // σ_u = 3.0 in Q16
//! let mut w = SymbolWriter::new(ChunkTag::AFEA, tables);
//! w.symbol(-2, k)?;
//! w.bit(true, 1 << 14); // P(1) = 2^14 / 2^16
//! w.symbol(1_000_000, k)?; // escapes
//! let body = w.finish();
//!
//! let mut r = SymbolReader::new(ChunkTag::AFEA, &body, tables)?;
//! assert_eq!(r.symbol(k)?, -2);
//! assert!(r.bit(1 << 14)?);
//! assert_eq!(r.symbol(k)?, 1_000_000);
//! r.finish()?;
//! # Ok::<(), salvq::Error>(())
//! ```

pub mod analysis;
pub mod ans;
pub mod reference;
pub mod scale;
pub mod symbols;
pub mod tables;

pub use scale::{
    scale_index, wide_scale, SCALE_COUNT, SCALE_INDEX_COUNT, SIGMA_Q16, THRESHOLD_Q16,
};
pub use symbols::{checked_scale_index, SymbolReader, SymbolWriter};
pub use tables::{GaussianTables, ScaleTable, PRECISION, R_MAX, TAIL_Q4};
