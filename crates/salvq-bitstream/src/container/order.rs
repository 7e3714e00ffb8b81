//! The chunk order of both profiles as one walker (spec §1.5 Table 1-3 with §7.4; §3.7
//! Table 3-2 with §3.8): which critical chunk is due at each position, which layer it
//! belongs to, and the error a chunk out of place gives. The whole-buffer decoder, the
//! streaming decoder, extraction and the WebAssembly package walk streams with it, so they
//! apply the same rules in the same order.

use super::chunk::ChunkTag;
use crate::error::{Error, Result};

/// A stream's profile, named by its first chunk (§3).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Profile {
    /// Anchors: `HEAD`, the shared model chunks, `AFEA ASCL AOFF` per layer (§1.5, §7.4).
    Anchors,
    /// Explicit Gaussians: `GHED GQUA`, then `GLAY TILS APOS GATT` per layer, or in a
    /// progressive stream the first layer so and `GREF GRSY` per further one (§3.7, §3.8).
    Explicit,
}

/// §1.5 Table 1-3: the anchors profile's chunks before its layers.
const ANCHORS_SHARED: usize = 7;
/// §7.4: the chunks of one anchors layer.
const ANCHORS_LAYER: [ChunkTag; 3] = [ChunkTag::AFEA, ChunkTag::ASCL, ChunkTag::AOFF];

/// §3.7 Table 3-2: the explicit profile's critical chunk types.
pub const EXPLICIT_CRITICAL: [ChunkTag; 9] = [
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
/// §3.7: the position of an explicit stream's first layer chunk (`GLAY`, after `GHED GQUA`).
pub const EXPLICIT_FIRST_LAYER: usize = 2;
/// §3.7: the chunks of a full explicit layer.
const EXPLICIT_LAYER: [ChunkTag; 4] = [
    ChunkTag::GLAY,
    ChunkTag::TILS,
    ChunkTag::APOS,
    ChunkTag::GATT,
];
/// §3.8: the chunks of a refinement layer.
const EXPLICIT_REFINEMENT: [ChunkTag; 2] = [ChunkTag::GREF, ChunkTag::GRSY];

impl Profile {
    /// The profile's preflight chunk, the first of every stream (§1.4, §3.2).
    pub fn header(self) -> ChunkTag {
        match self {
            Profile::Anchors => ChunkTag::HEAD,
            Profile::Explicit => ChunkTag::GHED,
        }
    }

    /// Every critical chunk type of the profile (§1.5 rule 0, §3.7).
    pub fn critical(self) -> &'static [ChunkTag] {
        match self {
            Profile::Anchors => &ChunkTag::CRITICAL_ORDER,
            Profile::Explicit => &EXPLICIT_CRITICAL,
        }
    }

    /// The chunks that open a layer's section (§7.4: `AFEA`; §3.7: `GLAY`; §3.8: `GREF`).
    pub fn layer_start(self) -> &'static [ChunkTag] {
        match self {
            Profile::Anchors => &[ChunkTag::AFEA],
            Profile::Explicit => &[ChunkTag::GLAY, ChunkTag::GREF],
        }
    }

    /// The critical chunk due at position `i` (0 = the preflight) of a stream of `layers`
    /// layers, `progressive` or not (§3.8; the anchors profile has no progressive streams).
    pub fn expected(self, i: usize, layers: usize, progressive: bool) -> ChunkTag {
        match self {
            Profile::Anchors => match i.checked_sub(ANCHORS_SHARED) {
                None => ChunkTag::CRITICAL_ORDER[i],
                Some(j) if j < 3 * layers => ANCHORS_LAYER[j % 3],
                Some(_) => ChunkTag::SEND,
            },
            Profile::Explicit => match (i, self.layer_of(i, layers, progressive)) {
                (0, _) => ChunkTag::GHED,
                (1, _) => ChunkTag::GQUA,
                (_, None) => ChunkTag::SEND,
                (i, Some(_)) if i < EXPLICIT_FIRST_LAYER + 4 => {
                    EXPLICIT_LAYER[i - EXPLICIT_FIRST_LAYER]
                }
                (i, Some(_)) if progressive => {
                    EXPLICIT_REFINEMENT[(i - EXPLICIT_FIRST_LAYER - 4) % 2]
                }
                (i, Some(_)) => EXPLICIT_LAYER[(i - EXPLICIT_FIRST_LAYER) % 4],
            },
        }
    }

    /// The layer (in stream order) the critical chunk at position `i` belongs to: `None` for
    /// the chunks before the layers and for `SEND`.
    pub fn layer_of(self, i: usize, layers: usize, progressive: bool) -> Option<usize> {
        let l = match self {
            Profile::Anchors => i.checked_sub(ANCHORS_SHARED)? / 3,
            Profile::Explicit => match i.checked_sub(EXPLICIT_FIRST_LAYER)? {
                p if progressive && p >= 4 => 1 + (p - 4) / 2,
                p => p / 4,
            },
        };
        (l < layers).then_some(l)
    }
}

/// Where a chunk stands in the order.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Position {
    /// An ancillary chunk after the preflight: skipped (§1.5 rules 1 – 2).
    Ancillary,
    /// The critical chunk due: its position (0 = the preflight) and the layer it belongs to.
    Critical {
        /// Its position among the critical chunks.
        index: usize,
        /// Its layer in stream order (`None` outside the layers).
        layer: Option<usize>,
    },
}

/// A walk through a stream's chunks: give it each chunk's tag in stream order
/// ([`ChunkOrder::step`]) and the layer count once the preflight is read
/// ([`ChunkOrder::set_layers`]); it says where the chunk stands or which rule it breaks.
///
/// ```
/// use salvq_bitstream::container::order::{ChunkOrder, Position, Profile};
/// use salvq_bitstream::container::ChunkTag;
/// let mut order = ChunkOrder::new(Profile::Explicit);
/// assert_eq!(order.step(ChunkTag::GHED)?, Position::Critical { index: 0, layer: None });
/// order.set_layers(2, false);
/// assert_eq!(order.step(ChunkTag::GQUA)?, Position::Critical { index: 1, layer: None });
/// assert_eq!(order.step(ChunkTag::GLAY)?, Position::Critical { index: 2, layer: Some(0) });
/// assert!(order.step(ChunkTag::GATT).is_err()); // TILS is due
/// # Ok::<(), salvq_bitstream::Error>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ChunkOrder {
    profile: Profile,
    next: usize,
    layers: usize,
    progressive: bool,
}

impl ChunkOrder {
    /// A walk from the start of a stream of `profile`.
    pub fn new(profile: Profile) -> Self {
        ChunkOrder {
            profile,
            next: 0,
            layers: 0,
            progressive: false,
        }
    }

    /// The profile walked.
    pub fn profile(&self) -> Profile {
        self.profile
    }

    /// The layer count and whether the stream is progressive (§3.8), from the preflight.
    pub fn set_layers(&mut self, layers: usize, progressive: bool) {
        self.layers = layers;
        self.progressive = progressive;
    }

    /// The position of the next critical chunk (0 = the preflight).
    pub fn next_index(&self) -> usize {
        self.next
    }

    /// The layer the next critical chunk belongs to, if any.
    pub fn next_layer(&self) -> Option<usize> {
        self.layer_at(self.next)
    }

    /// The layer the last critical chunk walked belongs to, if any.
    pub fn last_layer(&self) -> Option<usize> {
        self.layer_at(self.next.checked_sub(1)?)
    }

    /// The layer of the critical chunk at position `i`, if any.
    pub fn layer_at(&self, i: usize) -> Option<usize> {
        self.profile.layer_of(i, self.layers, self.progressive)
    }

    /// Where a chunk tagged `tag` would stand if it came next, or the rule it breaks: an
    /// ancillary chunk or another profile's preflight before the preflight, and a critical
    /// chunk out of its place, are **ChunkOrder** (§1.5 rules 1, 3; §3); a critical type
    /// the profile does not define is **UnknownCriticalChunk** (§1.5 rule 0).
    pub fn check(&self, tag: ChunkTag) -> Result<Position> {
        let header = self.profile.header();
        if self.next == 0 && tag != header {
            let other = [ChunkTag::HEAD, ChunkTag::GHED].contains(&tag);
            if !tag.is_critical() || other {
                return Err(Error::ChunkOrder {
                    found: tag,
                    expected: header,
                });
            }
        }
        if !tag.is_critical() {
            return Ok(Position::Ancillary);
        }
        if !self.profile.critical().contains(&tag) {
            return Err(Error::UnknownCriticalChunk { tag });
        }
        let expected = self
            .profile
            .expected(self.next, self.layers, self.progressive);
        if tag != expected {
            return Err(Error::ChunkOrder {
                found: tag,
                expected,
            });
        }
        Ok(Position::Critical {
            index: self.next,
            layer: self.next_layer(),
        })
    }

    /// [`Self::check`], and past the chunk if it is critical.
    pub fn step(&mut self, tag: ChunkTag) -> Result<Position> {
        let position = self.check(tag)?;
        if let Position::Critical { .. } = position {
            self.next += 1;
        }
        Ok(position)
    }

    /// The error of a stream that ends (or reaches `SEND`) while `tag` is still missing.
    pub fn missing(tag: ChunkTag) -> Error {
        Error::ChunkOrder {
            found: ChunkTag::SEND,
            expected: tag,
        }
    }
}
