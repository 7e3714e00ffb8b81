//! What one decode does, as [`crate::DecoderBuilder`] set it: what the profiles' decoders
//! and the streaming decoder read, so that none of them imports the builder.

use crate::limits::Limits;
use crate::tiles::{RegionBox, TilePart};

/// What one decode does, as the builder set it.
#[derive(Debug, Clone, Default)]
pub(crate) struct DecodeOptions {
    pub(crate) limits: Limits,
    pub(crate) rate: Option<u8>,
    pub(crate) region: Option<RegionBox>,
    pub(crate) part: Option<TilePart>,
    pub(crate) gaussians_only: bool,
    pub(crate) accept_prefix: bool,
    #[cfg(feature = "test-hooks")]
    pub(crate) fault: Option<Fault>,
}

/// Deliberate decoder bugs ([`crate::DecoderBuilder::fault`]) that prove the conformance vectors
/// catch them (§11); only with the `test-hooks` feature, for the conformance tools.
#[cfg(feature = "test-hooks")]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Fault {
    /// One wrong entry in scale `scale`'s frequency table.
    FrequencyTable {
        /// The scale index whose table is wrong (§6.3).
        scale: u8,
    },
}
