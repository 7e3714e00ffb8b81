//! # salvq — reference encoder and decoder of the SALVQ scene format
//!
//! SALVQ streams carry compressed anchor-based 3D Gaussian Splatting scenes (Scaffold-GS
//! anchors with a HAC-style hash-grid hyperprior, quantized by scene-adaptive lattice vector
//! quantization with per-rate gains). The normative text is `spec/` in this repository; every
//! module cites the section it implements.
//!
//! This crate is the decoder: it reads a stream of either profile and nothing else. The
//! tools built on it are crates of their own (`crates/` in the repository): `salvq-encoder`
//! (the reference encoder and `info`), `salvq-render` (scene files, the Inria PLY, the CPU
//! preview renderer), `salvq-gen` (synthetic scenes), `salvq-conformance` (canonical form,
//! vectors, runner, fuzzing harness), `salvq-bench` (research benches) and `salvq-cli` (the
//! `salvq` command). Dependencies point one way, towards this crate.
//!
//! ## Map of a stream (format 0.15)
//!
//! | stream part | spec | module |
//! |---|---|---|
//! | signature: magic, major.minor, file flags | §1.2 | [`container::signature`] |
//! | chunk framing: length, tag, payload, CRC-32C | §1.3 | [`container::chunk`] |
//! | `HEAD` preflight: dimensions, geometry, decoded size | §1.4 | [`container::preflight`] |
//! | chunk order, critical / ancillary, `SEND` | §1.5 | [`decoder`] |
//! | model payload chunks `MLPS` `QUAN` `GRID` | §1.6 | [`container::mlps`], [`container::payload`] |
//! | the explicit-Gaussians profile: `GHED` `GQUA` `GLAY` `GATT` | §3 | [`explicit`] |
//! | anchor positions `APOS`: an octree per tile, adaptive contexts, voxel counts | §8 | [`geometry`] |
//! | tiles: `TILS`, per-tile bodies, parallel and region decoding | §10 | [`tiles`], [`decoder`] |
//! | integer hyperprior: grid features, fixed-point MLP, steps, scale indices | §5 | [`hyperprior`] |
//! | ANS, frequency tables, escapes | §6.1-§6.5 | [`entropy`] |
//! | anchor attribute chunks `AMSK` `AFEA` `ASCL` `AOFF` | §6.6 | [`attributes`] |
//! | the scene model: tensors, shapes, dtypes | §2 | [`model`] |
//! | model validation (finite, masks, bases, gains) | §2.3, §2.6 | [`model::validate`] |
//! | limits and errors | §9 | [`limits`], [`error`] |
//! | quantizers: lattices, reconstruction, rate layers, spatial regions | §7 | [`quantizer`], [`extract`] |
//!
//! ## Use
//!
//! ```
//! use salvq_gen::{generate, GenParams};
//! // A small synthetic scene with the identity basis (uniform scalar quantization).
//! let model = generate(&GenParams { feat_basis: false, ..GenParams::small(100, 1) });
//! let encoded = salvq_encoder::encode_full(&model, &Default::default())?;
//! let decoded = salvq::decode(&encoded.stream)?;
//! // Decoding reproduces, bit for bit, the reconstruction the encoder predicted; positions
//! // and masks are lossless, attributes lie within half a quantization step.
//! assert_eq!(&decoded, encoded.expected());
//! assert_eq!(decoded.anchors.mask, model.anchors.mask);
//! # Ok::<(), salvq_encoder::Error>(())
//! ```
//!
//! The decoder never panics on any input: every failure is an [`Error`] variant that names
//! the rule broken and its spec section, and [`Limits`] are checked against the preflight
//! before anything is allocated.

// No unsafe code, except the measured hot paths that are isolated and justified in
// `hyperprior::simd` (the context MLP's i16 dot products with SSE2 and AVX2, and the
// hash-grid corners with AVX2).
#![deny(unsafe_code)]
#![warn(missing_docs)]

mod builder;
pub mod decoder;
pub mod error;
pub mod explicit;
pub mod extract;
pub mod limits;
pub mod model;
mod par;
pub mod stream;

// The stream's layers, public for the workspace's encoder, conformance and tools crates
// (they write and inspect streams) but not part of the decoder's API: no stability promise.
#[doc(hidden)]
pub mod attributes;
#[doc(hidden)]
pub mod container;
#[doc(hidden)]
pub mod entropy;
#[doc(hidden)]
pub mod geometry;
#[doc(hidden)]
pub mod hyperprior;
#[doc(hidden)]
pub mod quantizer;
#[doc(hidden)]
pub mod tiles;

pub use builder::{Decoder, DecoderBuilder, Header};
pub use decoder::{
    decode, decode_any, decode_with_limits, decode_with_options, DecodeOptions, Decoded,
};
pub use error::{Error, Result};
pub use extract::extract_rate;
pub use limits::Limits;
pub use model::LatticeKind;
pub use model::SceneModel;
pub use stream::StreamDecoder;
pub use tiles::{InvalidRegion, RegionBox, TilePart};
