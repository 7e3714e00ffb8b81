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

/// What a decoder is willing to allocate for one stream (§9.1).
///
/// A stream that asks for more fails with [`Error::LimitExceeded`](crate::Error::LimitExceeded)
/// before any buffer is sized from it. Built from a preset and changed with the `with_`
/// setters; the fields are read-only outside this crate, and more limits may come:
///
/// ```
/// use salvq_bitstream::{limits::LimitKind, Error, Limits};
/// let tiny = Limits::default().with_max_anchors(10);
/// let err = tiny.check(LimitKind::Anchors, 64).unwrap_err();
/// assert!(matches!(err, Error::LimitExceeded { limit: LimitKind::Anchors, requested: 64, allowed: 10 }));
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub struct Limits {
    /// Largest `anchor_count` (anchors profile) or `gaussian_count` (explicit profile)
    /// accepted.
    pub max_anchors: u64,
    /// Largest decode accepted, in bytes: the decoded size (`decoded_bytes`, §1.4 step 5,
    /// §3.2 step 5) and what the decode holds besides it (§9.1).
    pub max_alloc_bytes: u64,
    /// Largest chunk payload accepted, in bytes (§1.3).
    pub max_chunk_bytes: u64,
}

impl Default for Limits {
    /// What a browser tab can live with (a wasm32 heap is at most 4 GiB, shared with the
    /// page): 2^24 anchors or Gaussians, 1 GiB decoded, 256 MiB per chunk. That decodes any
    /// scene of up to about 1.5 M Gaussians of SH degree 3, or 4 M of degree 0, with their
    /// symbols, and more with the Gaussians only. [`Limits::desktop`] is for larger scenes.
    fn default() -> Self {
        Limits {
            max_anchors: 1 << 24,
            max_alloc_bytes: 1 << 30,
            max_chunk_bytes: 256 << 20,
        }
    }
}

impl Limits {
    /// The spec's reference defaults (§9.1): 2^24 anchors or Gaussians, 4 GiB decoded,
    /// 1 GiB per chunk: room for the largest scenes of the published benchmarks (a few
    /// million anchors, 6 M Gaussians with the Gaussians only) on a desktop machine. What the
    /// `salvq` command uses.
    pub const fn desktop() -> Self {
        Limits {
            max_anchors: 1 << 24,
            max_alloc_bytes: 4 << 30,
            max_chunk_bytes: 1 << 30,
        }
    }

    /// Tight limits for fuzzing and untrusted input in tests: 64 k anchors, 64 MiB.
    pub const fn tight() -> Self {
        Limits {
            max_anchors: 1 << 16,
            max_alloc_bytes: 64 << 20,
            max_chunk_bytes: 64 << 20,
        }
    }

    /// These limits with at most `n` anchors or Gaussians.
    #[must_use]
    pub const fn with_max_anchors(mut self, n: u64) -> Self {
        self.max_anchors = n;
        self
    }

    /// These limits with at most `bytes` held by a decode.
    #[must_use]
    pub const fn with_max_alloc_bytes(mut self, bytes: u64) -> Self {
        self.max_alloc_bytes = bytes;
        self
    }

    /// These limits with chunks of at most `bytes`.
    #[must_use]
    pub const fn with_max_chunk_bytes(mut self, bytes: u64) -> Self {
        self.max_chunk_bytes = bytes;
        self
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
