//! The explicit-Gaussians profile (spec §3): any trained 3DGS scene (the standard Inria PLY
//! layout) coded with the format's machinery — lattice quantizers with per-rate gains (§7),
//! octree geometry (§8), tiles (§10) and ANS with the normative tables (§6) — under a
//! causal integer prior fitted per scene and rate (§3.5). The decoded output is the
//! Gaussians themselves ([`Gaussians`]), reconstructed in binary32 exactly
//! (§3.6).
//!
//! | stream part | spec | module |
//! |---|---|---|
//! | `GHED` preflight | §3.2 | [`header`] |
//! | `GQUA` attribute groups, lattices, steps, gains | §3.3 | [`groups`] |
//! | `GLAY` a layer's grid and prior | §3.4 | [`layer`] |
//! | `GATT` attribute symbols per tile | §3.5 | [`attributes`] |
//! | reconstruction, the decoded Gaussians | §3.6 | [`reconstruct`], [`gaussians`] |
//! | `GATT` decoded tile by tile, in parallel | §3.5, §3.6 | [`gatt`] |
//! | progressive streams: `GREF`, `GRSY` | §3.8 | [`refinement`] |

pub mod attributes;
pub mod gatt;
pub mod gaussians;
pub mod groups;
pub mod header;
pub mod layer;
pub mod reconstruct;
pub mod refinement;

pub use gaussians::{rest_per_channel, Gaussians};
pub use groups::{Group, GroupKind, GROUP_KINDS};
pub use header::GaussianHeader;
pub use layer::{Layer, CONTEXT_CLASSES};
