//! The chunked container (spec §1): signature, chunk framing, preflight, chunk order.

pub mod bytes;
pub mod chunk;
pub mod method;
pub mod mlps;
pub mod payload;
pub mod preflight;
pub mod signature;
pub mod surgery;
pub mod tag;

pub use chunk::{Chunk, ChunkReader, ChunkTag};
pub use preflight::Preflight;
pub use signature::{Signature, FORMAT_MAJOR, FORMAT_MINOR};
