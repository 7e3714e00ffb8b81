//! Conformance (spec §11): the canonical decoded form and its hashes, golden vectors, the
//! must-fail vectors, and a runner that tests any decoder through a command-line contract.
//!
//! | part | spec | module |
//! |---|---|---|
//! | canonical decoded form, integer and float hashes | §11.1, §11.2 | [`canonical`] |
//! | float tolerances | §11.3 | [`manifest::Tolerance`] |
//! | vectors and manifest | §11.4 | [`vectors`], [`must_fail`], [`explicit_vectors`], [`explicit_edited`], [`explicit_must_fail`], [`explicit_must_fail_bodies`], [`manifest`], [`generate`] |
//! | decoder contract and runner | §11.5 | [`runner`] |
//! | region decodes | §10.3.1, §11.7 | [`region_vectors`] |
//! | what the fuzz targets (`fuzz/`) check | §9 | [`fuzzing`] |

pub mod canonical;
pub mod explicit_edited;
pub mod explicit_must_fail;
pub mod explicit_must_fail_bodies;
pub mod explicit_vectors;
pub mod fuzzing;
pub mod generate;
pub mod manifest;
pub mod models;
pub mod must_fail;
pub mod reference_coder;
pub mod region_vectors;
pub mod runner;
pub mod vectors;
