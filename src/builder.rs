//! The one way in: a decoder configured once ([`Decoder::builder`]), then asked for a
//! stream's preflight ([`Decoder::read_header`]), a whole decode ([`Decoder::decode`]) or a
//! decoder fed as bytes arrive ([`Decoder::stream`]), for either profile.

#[cfg(feature = "parallel")]
use std::sync::Arc;

use crate::anchors::decode_anchors;
use crate::attributes::Symbols;
use crate::container::chunk::{ChunkReader, ChunkTag};
use crate::container::is_explicit;
use crate::container::preflight::Preflight;
use crate::container::signature::{Signature, SIGNATURE_LEN};
use crate::error::{Error, Result, Structure};
use crate::explicit::GaussianHeader;
use crate::limits::Limits;
use crate::model::SceneModel;
use crate::options::DecodeOptions;
#[cfg(feature = "test-hooks")]
use crate::options::Fault;
use crate::scene::{decode_scene, Scene};
use crate::stream::StreamDecoder;
use crate::tiles::{RegionBox, TilePart};

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

/// A configured decoder: limits, rate, region, part and threads, set once; cheap to clone.
///
/// ```
/// use salvq::{Decoder, Header, Scene};
/// let path = concat!(env!("CARGO_MANIFEST_DIR"), "/conformance/vectors/g-sh3-rates.salvq");
/// let stream = std::fs::read(path).expect("a conformance vector");
/// let decoder = Decoder::builder().rate(1).build();
/// let Header::Gaussians(header) = decoder.read_header(&stream)? else { panic!() };
/// let Scene::Gaussians(scene) = decoder.decode(&stream)? else { panic!() };
/// assert_eq!(scene.gaussians.len(), header.count as usize);
/// # Ok::<(), salvq::Error>(())
/// ```
#[derive(Debug, Clone, Default)]
pub struct Decoder {
    options: DecodeOptions,
    #[cfg(feature = "parallel")]
    pool: Option<Arc<rayon::ThreadPool>>,
}

/// Sets up a [`Decoder`]; every setting has a default, so `Decoder::builder().build()`
/// decodes any stream within [`Limits::default`].
#[derive(Debug, Clone, Default)]
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

    /// The rate to decode (§7.4); default (or `None`): the lowest coded rate.
    pub fn rate(mut self, rate: impl Into<Option<u8>>) -> Self {
        self.options.rate = rate.into();
        self
    }

    /// Decode only the tiles whose box meets this world box (§10.3); default (or `None`):
    /// every tile.
    pub fn region(mut self, region: impl Into<Option<RegionBox>>) -> Self {
        self.options.region = region.into();
        self
    }

    /// Decode only `part` of the (region's) tiles (§10.3.2): one of several workers that
    /// share no memory, each with its own part; default (or `None`): every tile.
    pub fn part(mut self, part: impl Into<Option<TilePart>>) -> Self {
        self.options.part = part.into();
        self
    }

    /// Explicit profile: keep only the Gaussians, not the lattice coordinates and other
    /// symbols they were reconstructed from ([`crate::DecodedGaussians::symbols`] is then
    /// empty). What a viewer needs: less memory written, and about a third less at the peak.
    /// The conformance output (§11.6) needs the symbols. Default: off.
    pub fn gaussians_only(mut self, on: bool) -> Self {
        self.options.gaussians_only = on;
        self
    }

    /// Explicit profile, progressive streams (§3.8): a stream that ends before `SEND`, after
    /// at least one complete layer, decodes to its last complete layer
    /// ([`crate::DecodedGaussians::truncated`]) instead of failing with the truncation.
    /// Default: off.
    pub fn accept_prefix(mut self, on: bool) -> Self {
        self.options.accept_prefix = on;
        self
    }

    /// Decode tiles on a pool of `threads` threads, built once here; default (or `None`):
    /// rayon's global pool. The output does not depend on the count (§10.3). Without the
    /// `parallel` feature every decode runs on the caller's thread and this does nothing.
    #[cfg_attr(not(feature = "parallel"), allow(unused_mut))]
    pub fn threads(mut self, threads: impl Into<Option<usize>>) -> Self {
        let threads = threads.into();
        #[cfg(feature = "parallel")]
        {
            self.pool = threads.and_then(|n| {
                rayon::ThreadPoolBuilder::new()
                    .num_threads(n.max(1))
                    .build()
                    .ok()
                    .map(Arc::new)
            });
        }
        #[cfg(not(feature = "parallel"))]
        let _ = threads;
        self
    }

    /// Decode tiles on the caller's pool: one the application shares, or one whose threads it
    /// has pinned to CPUs. Where the kernel packs threads onto few CPUs (virtual machines
    /// can), a pool thread woken by a busy thread may wait on that thread's CPU for a
    /// scheduler tick, milliseconds, which only a short decode notices.
    #[cfg(feature = "parallel")]
    pub fn thread_pool(mut self, pool: Arc<rayon::ThreadPool>) -> Self {
        self.pool = Some(pool);
        self
    }

    /// A deliberate decoder bug (`test-hooks` feature, conformance tools only).
    #[cfg(feature = "test-hooks")]
    pub fn fault(mut self, fault: Option<Fault>) -> Self {
        self.options.fault = fault;
        self
    }

    /// The decoder.
    pub fn build(&self) -> Decoder {
        Decoder {
            options: self.options.clone(),
            #[cfg(feature = "parallel")]
            pool: self.pool.clone(),
        }
    }
}

impl Decoder {
    /// A builder with the defaults: [`Limits::default`], the lowest rate, every tile, rayon's
    /// global pool.
    pub fn builder() -> DecoderBuilder {
        DecoderBuilder::default()
    }

    /// The limits this decoder applies.
    pub fn limits(&self) -> &Limits {
        &self.options.limits
    }

    /// The rate this decoder asks for (`None`: the lowest coded rate).
    pub fn rate(&self) -> Option<u8> {
        self.options.rate
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
    pub fn decode(&self, data: &[u8]) -> Result<Scene> {
        self.in_pool(|| decode_scene(data, &self.options))
    }

    /// Decodes an anchors-profile stream and the selected layer's symbols, the lattice
    /// coordinates (§6.6.2) that the canonical decoded form hashes (§11.1). Keeping them
    /// needs `8·N·(F + S + 3K)` bytes more, checked against the allocation limit on top of
    /// the decoded size. An explicit-profile stream keeps its symbols in
    /// [`crate::DecodedGaussians::symbols`]; here it fails as an anchors stream would
    /// (`ChunkOrder`, §3).
    pub fn decode_with_symbols(&self, data: &[u8]) -> Result<(SceneModel, Symbols)> {
        if is_explicit(data) {
            return Err(Error::ChunkOrder {
                found: ChunkTag::GHED,
                expected: ChunkTag::HEAD,
            });
        }
        self.in_pool(|| decode_anchors(data, &self.options, true))
            .map(|(m, sy)| (m, sy.unwrap_or_default()))
    }

    /// A decoder to feed the stream in pieces as they arrive ([`StreamDecoder`]); it decodes
    /// on the caller's thread.
    pub fn stream(&self) -> StreamDecoder {
        StreamDecoder::new(self.options.clone())
    }

    #[cfg(feature = "parallel")]
    fn in_pool<T: Send>(&self, f: impl FnOnce() -> T + Send) -> T {
        match &self.pool {
            Some(pool) => pool.install(f),
            None => f(),
        }
    }

    #[cfg(not(feature = "parallel"))]
    fn in_pool<T>(&self, f: impl FnOnce() -> T) -> T {
        f()
    }
}

/// Decodes a whole stream of either profile with the default settings: a thin alias for
/// `Decoder::builder().build().decode(data)`.
///
/// ```
/// let path = concat!(env!("CARGO_MANIFEST_DIR"), "/conformance/vectors/g-sh3-rates.salvq");
/// let stream = std::fs::read(path).expect("a conformance vector");
/// let scene = salvq::decode(&stream)?;
/// assert!(scene.gaussians().is_some());
/// # Ok::<(), salvq::Error>(())
/// ```
pub fn decode(data: &[u8]) -> Result<Scene> {
    Decoder::default().decode(data)
}
