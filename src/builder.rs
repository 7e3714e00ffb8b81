//! The decoder as a viewer holds it: configured once ([`Decoder::builder`]), then asked for a
//! stream's preflight ([`Decoder::read_header`]), a whole decode ([`Decoder::decode`]) or a
//! decoder fed as bytes arrive ([`Decoder::stream`]).

#[cfg(feature = "parallel")]
use std::sync::Arc;

use crate::container::chunk::{ChunkReader, ChunkTag};
use crate::container::preflight::Preflight;
use crate::container::signature::{Signature, SIGNATURE_LEN};
use crate::decoder::{decode_any, DecodeOptions, Decoded};
use crate::error::{Error, Result, Structure};
use crate::explicit::GaussianHeader;
use crate::limits::Limits;
use crate::stream::StreamDecoder;

/// A stream's preflight (§1.4, §3.2): what a viewer needs to size its buffers before it
/// decodes anything.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum Header {
    /// An anchors-profile stream's `HEAD`.
    Anchors(Box<Preflight>),
    /// An explicit-profile stream's `GHED`.
    Gaussians(GaussianHeader),
}

/// A configured decoder: limits, rate, region and threads, set once.
///
/// ```
/// use salvq::{Decoder, Header};
/// let path = concat!(env!("CARGO_MANIFEST_DIR"), "/conformance/vectors/g-sh3-rates.salvq");
/// let stream = std::fs::read(path).expect("a conformance vector");
/// let decoder = Decoder::builder().rate(1).build();
/// let Header::Gaussians(header) = decoder.read_header(&stream)? else { panic!() };
/// let decoded = decoder.decode(&stream)?;
/// # let _ = (header, decoded);
/// # Ok::<(), salvq::Error>(())
/// ```
#[derive(Debug, Clone, Default)]
pub struct Decoder {
    options: DecodeOptions,
    #[cfg(feature = "parallel")]
    pool: Option<Arc<rayon::ThreadPool>>,
}

/// Sets up a [`Decoder`].
#[derive(Debug, Default)]
#[must_use]
pub struct DecoderBuilder {
    options: DecodeOptions,
    #[cfg(feature = "parallel")]
    pool: Option<Arc<rayon::ThreadPool>>,
}

impl DecoderBuilder {
    /// What the decoder may allocate (§9.1); default [`Limits::default`].
    pub fn limits(mut self, limits: Limits) -> Self {
        self.options.limits = limits;
        self
    }

    /// The rate to decode (§7.4); default: the lowest coded rate.
    pub fn rate(mut self, rate: u8) -> Self {
        self.options.rate = Some(rate);
        self
    }

    /// Decode only the tiles whose box meets this world box (min x, y, z, max x, y, z;
    /// §10.3); default: every tile.
    pub fn region(mut self, region: crate::tiles::RegionBox) -> Self {
        self.options.region = Some(region);
        self
    }

    /// Decode only `part` of the (region's) tiles (§10.3.2): one of several workers that
    /// share no memory, each with its own part; default: every tile.
    pub fn part(mut self, part: crate::tiles::TilePart) -> Self {
        self.options.part = Some(part);
        self
    }

    /// Explicit profile: keep only the Gaussians, not the symbols they were reconstructed
    /// from ([`crate::DecodeOptions::gaussians_only`]).
    pub fn gaussians_only(mut self) -> Self {
        self.options.gaussians_only = true;
        self
    }

    /// Decode tiles on a pool of `threads` threads, built once here (default: rayon's
    /// global pool). The output does not depend on the count (§10.3).
    #[cfg(feature = "parallel")]
    pub fn threads(mut self, threads: usize) -> Self {
        self.pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads.max(1))
            .build()
            .ok()
            .map(Arc::new);
        self
    }

    /// Decode tiles on the caller's pool: one the application shares, or one whose threads it
    /// has pinned to CPUs. Where the kernel packs threads onto few CPUs (virtual machines
    /// can), a pool thread woken by a busy thread may wait on that thread's CPU for a
    /// scheduler tick, milliseconds, which only a short decode notices (docs/speed).
    #[cfg(feature = "parallel")]
    pub fn thread_pool(mut self, pool: Arc<rayon::ThreadPool>) -> Self {
        self.pool = Some(pool);
        self
    }

    /// The decoder.
    pub fn build(self) -> Decoder {
        Decoder {
            options: self.options,
            #[cfg(feature = "parallel")]
            pool: self.pool,
        }
    }
}

impl Decoder {
    /// A builder with the defaults: [`Limits::default`], the lowest rate, every tile, rayon's
    /// global pool.
    pub fn builder() -> DecoderBuilder {
        DecoderBuilder::default()
    }

    /// The options this decoder applies.
    pub fn options(&self) -> &DecodeOptions {
        &self.options
    }

    /// The preflight of a stream of either profile, from its signature and first chunk only
    /// (§1.2 – §1.4, §3.2): checked against the limits, nothing else decoded.
    pub fn read_header(&self, data: &[u8]) -> Result<Header> {
        let (_, rest) = Signature::parse(data)?;
        let mut reader = ChunkReader::new(rest, SIGNATURE_LEN as u64, &self.options.limits);
        let chunk = reader.next_chunk()?.ok_or(Error::Truncated {
            structure: Structure::ChunkHeader,
            needed: 8,
            available: 0,
        })?;
        match chunk.tag {
            ChunkTag::GHED => {
                GaussianHeader::parse(chunk.payload, &self.options.limits).map(Header::Gaussians)
            }
            ChunkTag::HEAD => Preflight::parse(chunk.payload, &self.options.limits)
                .map(|p| Header::Anchors(Box::new(p))),
            found => Err(Error::ChunkOrder {
                found,
                expected: ChunkTag::HEAD,
            }),
        }
    }

    /// Decodes a whole stream of either profile (§1.5, §3.7).
    pub fn decode(&self, data: &[u8]) -> Result<Decoded> {
        #[cfg(feature = "parallel")]
        if let Some(pool) = &self.pool {
            return pool.install(|| decode_any(data, &self.options));
        }
        decode_any(data, &self.options)
    }

    /// A decoder to feed the stream in pieces as they arrive ([`StreamDecoder`]).
    pub fn stream(&self) -> StreamDecoder {
        StreamDecoder::new(self.options.clone())
    }
}
