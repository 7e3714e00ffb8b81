//! The encoder's half of the stream's layers: each writer produces what a reader of
//! `salvq_bitstream` reads back, against the same definitions (spec §1.6, §3.3, §6, §8,
//! §10), and the stream surgery that tests and the automatic encoder use.

pub mod geometry;
pub mod gqua;
pub mod payload;
pub mod surgery;
pub mod symbols;
pub mod tile_cut;

pub use geometry::encode as encode_geometry;
pub use gqua::write_gqua;
pub use payload::{write_apos, write_grid, write_mlps, write_quan};
pub use symbols::SymbolWriter;
pub use tile_cut::{auto_tile_anchors, cut, cut_auto, DEFAULT_TILE_ANCHORS};
