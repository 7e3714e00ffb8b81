//! §3.7 Table 3-2 and §3.8: the order of an explicit-profile stream's critical chunks, and
//! which layer each belongs to.

use crate::container::chunk::ChunkTag;

/// The position in the chunk order of the first layer's first chunk (`GLAY`, after `GHED
/// GQUA`).
pub const FIRST_LAYER_CHUNK: usize = 2;

/// §3.7 Table 3-2: the explicit profile's critical chunk types.
pub const CRITICAL_CHUNKS: [ChunkTag; 9] = [
    ChunkTag::GHED,
    ChunkTag::GQUA,
    ChunkTag::GLAY,
    ChunkTag::TILS,
    ChunkTag::APOS,
    ChunkTag::GATT,
    ChunkTag::GREF,
    ChunkTag::GRSY,
    ChunkTag::SEND,
];

/// The chunks of a full layer (§3.7).
const LAYER: [ChunkTag; 4] = [
    ChunkTag::GLAY,
    ChunkTag::TILS,
    ChunkTag::APOS,
    ChunkTag::GATT,
];

/// The chunks of a refinement layer (§3.8).
const REFINEMENT: [ChunkTag; 2] = [ChunkTag::GREF, ChunkTag::GRSY];

/// §3.7 Table 3-2: the critical chunk due at position `i` (0 = `GHED`) of a stream with
/// `layers` layers, each a full layer, or in a `progressive` stream (§3.8) the first a full
/// layer and the others refinements.
pub fn expected_critical(i: usize, layers: usize, progressive: bool) -> ChunkTag {
    match (i, layer_of(i, layers, progressive)) {
        (0, _) => ChunkTag::GHED,
        (1, _) => ChunkTag::GQUA,
        (_, None) => ChunkTag::SEND,
        (i, Some(_)) if i < FIRST_LAYER_CHUNK + 4 => LAYER[i - FIRST_LAYER_CHUNK],
        (i, Some(_)) if progressive => REFINEMENT[(i - FIRST_LAYER_CHUNK - 4) % 2],
        (i, Some(_)) => LAYER[(i - FIRST_LAYER_CHUNK) % 4],
    }
}

/// The layer (in stream order) the critical chunk at position `i` belongs to: `None` for
/// `GHED`, `GQUA` and `SEND`.
pub fn layer_of(i: usize, layers: usize, progressive: bool) -> Option<usize> {
    let l = match i.checked_sub(FIRST_LAYER_CHUNK)? {
        p if progressive && p >= 4 => 1 + (p - 4) / 2,
        p => p / 4,
    };
    (l < layers).then_some(l)
}
