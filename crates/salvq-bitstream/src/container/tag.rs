//! Chunk types (spec §1.3, Table 1-3): four bytes whose first letter's case says whether a
//! decoder must understand the chunk.

use std::fmt;

/// A four-byte chunk type (spec §1.3). The case of the first byte tells whether a decoder
/// must understand the chunk: upper case is critical, lower case is ancillary.
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
pub struct ChunkTag(
    /// The tag's bytes as they appear in the stream.
    pub [u8; 4],
);

impl ChunkTag {
    /// Preflight: dimensions, geometry and decoded size (§1.4). Critical, first.
    pub const HEAD: ChunkTag = ChunkTag(*b"HEAD");
    /// Binary hash grid (§1.6.1). Critical.
    pub const GRID: ChunkTag = ChunkTag(*b"GRID");
    /// MLP weights (§1.6.2). Critical.
    pub const MLPS: ChunkTag = ChunkTag(*b"MLPS");
    /// Quantizers: steps, gains, lattice bases (§1.6.3). Critical.
    pub const QUAN: ChunkTag = ChunkTag(*b"QUAN");
    /// Anchor voxel coordinates (§1.6.4). Critical.
    pub const APOS: ChunkTag = ChunkTag(*b"APOS");
    /// Tile table (§10.1).
    pub const TILS: ChunkTag = ChunkTag(*b"TILS");
    /// Anchor offset masks (§1.6.5). Critical.
    pub const AMSK: ChunkTag = ChunkTag(*b"AMSK");
    /// Anchor latent features (§1.6.6). Critical.
    pub const AFEA: ChunkTag = ChunkTag(*b"AFEA");
    /// Anchor scalings (§1.6.6). Critical.
    pub const ASCL: ChunkTag = ChunkTag(*b"ASCL");
    /// Anchor offsets (§1.6.6). Critical.
    pub const AOFF: ChunkTag = ChunkTag(*b"AOFF");
    /// End of stream (§1.5). Critical, last, empty.
    pub const SEND: ChunkTag = ChunkTag(*b"SEND");
    /// Explicit-Gaussians preflight (§3.2). Critical, first.
    pub const GHED: ChunkTag = ChunkTag(*b"GHED");
    /// Explicit-Gaussians attribute groups: lattices, means, steps, gains (§3.3). Critical.
    pub const GQUA: ChunkTag = ChunkTag(*b"GQUA");
    /// Explicit-Gaussians layer header: voxel grid and prior tables (§3.4). Critical.
    pub const GLAY: ChunkTag = ChunkTag(*b"GLAY");
    /// Explicit-Gaussians attribute symbols, one body per tile (§3.5). Critical.
    pub const GATT: ChunkTag = ChunkTag(*b"GATT");
    /// Explicit-Gaussians refinement layer header: position bits, step factors, prior
    /// tables (§3.8). Critical.
    pub const GREF: ChunkTag = ChunkTag(*b"GREF");
    /// Explicit-Gaussians refinement symbols, one body per tile (§3.8). Critical.
    pub const GRSY: ChunkTag = ChunkTag(*b"GRSY");
    /// Encoder identification, UTF-8 text (§1.7). Ancillary.
    pub const ENCD: ChunkTag = ChunkTag(*b"encd");
    /// Encoder statistics, JSON (§1.7). Ancillary.
    pub const ESTS: ChunkTag = ChunkTag(*b"ests");

    /// Critical chunks in the order a stream must carry them (spec Table 1-3).
    pub const CRITICAL_ORDER: [ChunkTag; 11] = [
        Self::HEAD,
        Self::MLPS,
        Self::QUAN,
        Self::TILS,
        Self::APOS,
        Self::GRID,
        Self::AMSK,
        Self::AFEA,
        Self::ASCL,
        Self::AOFF,
        Self::SEND,
    ];

    /// Whether a decoder must understand this chunk (first byte upper case).
    pub fn is_critical(self) -> bool {
        self.0[0].is_ascii_uppercase()
    }

    /// Whether the tag's bytes are allowed (§1.3): a letter, then letters or digits.
    pub fn is_valid(self) -> bool {
        self.0[0].is_ascii_alphabetic() && self.0[1..].iter().all(u8::is_ascii_alphanumeric)
    }

    /// The tag as text (only meaningful for valid tags).
    pub fn as_str(&self) -> &str {
        std::str::from_utf8(&self.0).unwrap_or("????")
    }
}

impl fmt::Display for ChunkTag {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.is_valid() {
            f.write_str(self.as_str())
        } else {
            write!(f, "{:02x?}", self.0)
        }
    }
}

impl fmt::Debug for ChunkTag {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "ChunkTag({self})")
    }
}
