//! Decoder limits (spec §9.1), checked against the preflight before anything is allocated.

use std::fmt;

/// Which limit a stream would exceed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LimitKind {
    /// `anchor_count` in `HEAD`.
    Anchors,
    /// The decoded model's total size (`decoded_bytes`), which bounds every allocation.
    AllocationBytes,
    /// One chunk's payload length.
    ChunkBytes,
}

impl fmt::Display for LimitKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            LimitKind::Anchors => "anchor count",
            LimitKind::AllocationBytes => "decoded size in bytes",
            LimitKind::ChunkBytes => "chunk payload length",
        })
    }
}

/// What a decoder is willing to allocate for one stream.
///
/// A stream that asks for more fails with [`Error::LimitExceeded`](crate::Error::LimitExceeded)
/// before any buffer is sized from it:
///
/// ```
/// use salvq_bitstream::{limits::LimitKind, Error, Limits};
/// let tiny = Limits { max_anchors: 10, ..Limits::default() };
/// let err = tiny.check(LimitKind::Anchors, 64).unwrap_err();
/// assert!(matches!(err, Error::LimitExceeded { limit: LimitKind::Anchors, requested: 64, allowed: 10 }));
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Limits {
    /// Largest `anchor_count` accepted.
    pub max_anchors: u64,
    /// Largest decoded model accepted, in bytes (the sum of every output tensor, §1.4).
    pub max_alloc_bytes: u64,
    /// Largest chunk payload accepted, in bytes.
    pub max_chunk_bytes: u64,
}

impl Default for Limits {
    /// 16 M anchors, 4 GiB decoded, 1 GiB per chunk: room for the largest scenes of the
    /// published benchmarks (a few million anchors) on a desktop machine.
    fn default() -> Self {
        Limits {
            max_anchors: 1 << 24,
            max_alloc_bytes: 4 << 30,
            max_chunk_bytes: 1 << 30,
        }
    }
}

impl Limits {
    /// Tight limits for fuzzing and untrusted input in tests: 64 k anchors, 64 MiB.
    pub fn tight() -> Self {
        Limits {
            max_anchors: 1 << 16,
            max_alloc_bytes: 64 << 20,
            max_chunk_bytes: 64 << 20,
        }
    }

    /// Checks `requested` against the limit `limit`; above it: **LimitExceeded**, naming the
    /// requested and allowed amounts (§9.1).
    pub fn check(&self, limit: LimitKind, requested: u64) -> crate::Result<()> {
        let allowed = match limit {
            LimitKind::Anchors => self.max_anchors,
            LimitKind::AllocationBytes => self.max_alloc_bytes,
            LimitKind::ChunkBytes => self.max_chunk_bytes,
        };
        if requested > allowed {
            return Err(crate::Error::LimitExceeded {
                limit,
                requested,
                allowed,
            });
        }
        Ok(())
    }
}
