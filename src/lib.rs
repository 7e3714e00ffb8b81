//! # salvq — decoder of the SALVQ scene format
//!
//! SALVQ streams carry compressed 3D Gaussian Splatting scenes in two profiles: explicit
//! Gaussians (any trained 3DGS scene, spec §3) and anchors (Scaffold-GS anchors under a
//! HAC-style hash-grid hyperprior, §1 – §2), quantized by scene-adaptive lattice vector
//! quantization with per-rate gains. The normative text is `spec/` in the repository.
//!
//! ## Use
//!
//! One way in for both profiles: [`Decoder::builder`] sets the limits, the rate, a region,
//! a part and the threads once; the decoder then reads a stream's [`Header`], decodes it
//! whole into a [`Scene`], or gives a [`StreamDecoder`] to feed as bytes arrive.
//! [`decode`] is the same with the defaults.
//!
//! ```
//! use salvq::{Decoder, Limits, Scene};
//! let path = concat!(env!("CARGO_MANIFEST_DIR"), "/conformance/vectors/g-sh3-rates.salvq");
//! let stream = std::fs::read(path).expect("a conformance vector");
//! let decoder = Decoder::builder().limits(Limits::default()).rate(1).build();
//! match decoder.decode(&stream)? {
//!     Scene::Gaussians(g) => println!("{} Gaussians at rate {}", g.gaussians.len(), g.rate),
//!     Scene::Anchors(m) => println!("{} anchors", m.anchors.voxel.len()),
//! }
//! # Ok::<(), salvq::Error>(())
//! ```
//!
//! The decoder never panics on any input: every failure is an [`Error`] variant that names
//! the rule broken and its spec section, and [`Limits`] are checked against the preflight
//! before anything is allocated.
//!
//! ## Map of `src/`
//!
//! `builder.rs` is the API ([`Decoder`], [`DecoderBuilder`], [`Header`], [`decode`]), and
//! `options.rs` what it hands the decoders below, so that none of them imports it. `scene.rs`
//! is what a decode returns ([`Scene`]) and which profile's decoder makes it (the first chunk
//! decides, §3.7). `anchors.rs` decodes an anchors-profile stream: the chunk walk and each
//! model chunk (§1.5, §1.6), then `anchors/assemble.rs` the attributes of the selected tiles in
//! parallel (§6.6, §10). `gaussians.rs`, with `gaussians/progressive.rs`, decodes an
//! explicit-profile stream (§3.7, §3.8); `stream.rs` decodes either as its bytes arrive, and
//! `extract.rs` cuts a stream down to one rate (§7.4, §7.5). `neural.rs` and `camera.rs` turn
//! an anchors scene into the Gaussians a camera sees (Annex C.1, C.2). Every layer they read
//! through (container and chunk order, ANS and tables, octree geometry, integer hyperprior,
//! quantizers, tiles, errors and limits) is the `salvq-bitstream` crate, which the reference
//! encoder shares.

// No unsafe code here: the SIMD kernels are the layer crate's.
#![forbid(unsafe_code)]
#![warn(missing_docs)]

mod anchors;
mod builder;
pub mod camera;
mod extract;
mod gaussians;
pub mod neural;
mod options;
mod scene;
mod stream;

// The layers, under the names the decoding steps cite them by (`crate::container::...`).
use salvq_bitstream::{
    attributes, container, entropy, error, explicit, geometry, hyperprior, limits, model, par,
    quantizer, tiles,
};

pub use builder::{decode, Decoder, DecoderBuilder, Header};
pub use extract::extract_rate;
pub use gaussians::DecodedGaussians;
#[cfg(feature = "test-hooks")]
pub use options::Fault;
pub use scene::Scene;
pub use stream::{DecodedTile, StreamDecoder};

pub use salvq_bitstream::attributes::Symbols;
pub use salvq_bitstream::container::preflight::Preflight;
pub use salvq_bitstream::error::Structure;
pub use salvq_bitstream::explicit::{GaussianHeader, Gaussians};
pub use salvq_bitstream::limits::LimitKind;
pub use salvq_bitstream::model::SceneModel;
pub use salvq_bitstream::tiles::{InvalidRegion, RegionBox, TilePart};
pub use salvq_bitstream::{Error, Limits, Result};
