//! # salvq-bitstream — the layers of a SALVQ stream
//!
//! SALVQ streams carry compressed 3D Gaussian Splatting scenes in two profiles: anchors
//! (Scaffold-GS anchors under a HAC-style hash-grid hyperprior) and explicit Gaussians (any
//! trained 3DGS scene). The normative text is `spec/` in the repository; every module cites
//! the section it implements.
//!
//! This crate holds what the decoder (`salvq`) and the reference encoder (`salvq-encoder`)
//! share: the format's definitions, and for each part of a stream the reader that checks
//! and decodes it. The decoder crate walks the chunks and assembles a scene from these
//! readers; the encoder writes with its own writers against the same definitions, so both
//! sides compute every probability with the same integer code. A viewer depends on `salvq`,
//! not on this crate.
//!
//! ## Map of a stream (format 0.15)
//!
//! | stream part | spec | module |
//! |---|---|---|
//! | signature: magic, major.minor, file flags | §1.2 | [`container::signature`] |
//! | chunk framing: length, tag, payload, CRC-32C | §1.3 | [`container::chunk`] |
//! | `HEAD` preflight: dimensions, geometry, decoded size | §1.4 | [`container::preflight`] |
//! | chunk order of both profiles, layer of each chunk | §1.5, §3.7, §3.8 | [`container::order`] |
//! | model payload chunks `MLPS` `QUAN` `GRID` `APOS` | §1.6, §8 | [`container::mlps`], [`container::payload`] |
//! | the explicit-Gaussians profile: `GHED` `GQUA` `GLAY` `GATT` `GREF` `GRSY` | §3 | [`explicit`] |
//! | octree geometry: an octree per tile, adaptive contexts, voxel counts | §8 | [`geometry`] |
//! | tiles: `TILS`, per-tile bodies, region selection | §10 | [`tiles`] |
//! | integer hyperprior: grid features, fixed-point MLP, steps, scale indices | §5 | [`hyperprior`] |
//! | ANS, frequency tables, escapes | §6.1-§6.5 | [`entropy`] |
//! | anchor attribute chunks `AMSK` `AFEA` `ASCL` `AOFF` | §6.6 | [`attributes`] |
//! | the scene model: tensors, shapes, dtypes, validation | §2 | [`model`] |
//! | quantizers: lattices, reconstruction, spatial regions | §7 | [`quantizer`] |
//! | limits and errors | §9 | [`limits`], [`error`] |
//! | tiles and anchors in parallel, or in order without threads | §10.3 | [`par`] |
//!
//! Nothing that steers the entropy decoder is computed in floating point: probabilities,
//! scales and contexts are integers (§5, §6). Every reader returns an [`Error`] that names
//! the rule broken and never panics; [`Limits`] are checked before a length sizes a buffer.

// No unsafe code, except the measured hot paths isolated in `hyperprior::simd` (the context
// MLP's i16 dot products and the hash-grid corners), each with its `# Safety` contract.
#![deny(unsafe_code)]
#![warn(missing_docs)]

pub mod attributes;
pub mod container;
pub mod entropy;
pub mod error;
pub mod explicit;
pub mod geometry;
pub mod hyperprior;
pub mod limits;
pub mod model;
pub mod par;
pub mod quantizer;
pub mod tiles;

pub use error::{Error, Result};
pub use limits::Limits;
