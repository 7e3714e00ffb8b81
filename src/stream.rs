//! Decoding as the bytes arrive (spec §1.5, §3.7, §10.2): a viewer feeds the stream in pieces
//! and draws each tile of an explicit-profile stream as soon as its `GATT` body is complete.
//!
//! The result, and the error of a broken stream, are those of the whole-buffer decoder
//! ([`crate::Decoder::decode`]) on the same bytes:
//! - a chunk is decoded once it is complete and its CRC checked, in stream order, so an error
//!   found in it is the one the whole-buffer decoder reports (everything before it passed);
//! - the selected layer's `GATT` is the exception: its tiles are decoded as their bodies
//!   arrive, before the chunk's CRC can be checked, so the tiles handed out are provisional
//!   until the chunk is complete. A fault in a tile is held until then; a CRC mismatch (which
//!   the whole-buffer decoder checks first) takes precedence. Anything unusual in the chunk
//!   (a length table that does not add up, say) is left to the whole-chunk decoder once the
//!   chunk is complete, so the error is the same;
//! - a truncated stream is reported by [`StreamDecoder::finish`], which is the only place
//!   that knows no more bytes are coming.
//!
//! The anchors profile cannot show a tile early: a tile's attributes are spread over `AMSK`,
//! `AFEA`, `ASCL` and `AOFF`, which come one after another (§6.6), so its stream is decoded
//! whole when [`StreamDecoder::finish`] is called.

use std::ops::Range;

use crate::container::chunk::{Chunk, ChunkReader, ChunkTag, CHUNK_CRC_LEN, CHUNK_HEADER_LEN};
use crate::container::method::METHOD_CODED;
use crate::container::signature::{Signature, SIGNATURE_LEN};
use crate::entropy::GaussianTables;
use crate::error::{Error, Result};
use crate::explicit::attributes::{TileSymbols, TileSymbolsRef};
use crate::explicit::gatt::decode_tile;
use crate::explicit::Gaussians;
use crate::gaussians::{Due, ExplicitDecoder};
use crate::limits::LimitKind;
use crate::options::DecodeOptions;
use crate::scene::{decode_scene, Scene};

/// A decoder fed a stream in pieces ([`Self::feed`]); [`Self::finish`] gives what the
/// whole-buffer decoder gives for the same bytes.
///
/// ```
/// use salvq::Decoder;
/// let path = concat!(env!("CARGO_MANIFEST_DIR"), "/conformance/vectors/g-sh3-rates.salvq");
/// let stream = std::fs::read(path).expect("a conformance vector");
/// let mut decoder = Decoder::builder().build().stream();
/// for piece in stream.chunks(1000) {
///     decoder.feed(piece)?;
///     for tile in decoder.new_tiles() {
///         let _drawable = &decoder.gaussians().positions[tile.gaussians.clone()];
///     }
/// }
/// let decoded = decoder.finish()?;
/// assert_eq!(decoded, salvq::decode(&stream)?);
/// # Ok::<(), salvq::Error>(())
/// ```
pub struct StreamDecoder {
    options: DecodeOptions,
    buf: Vec<u8>,
    /// Offset of the next chunk not yet decoded (0 until the signature is read).
    at: usize,
    profile: Profile,
    /// The Gaussians of the tiles decoded so far, in stream order (explicit profile).
    gaussians: Gaussians,
    tiles: Vec<DecodedTile>,
    /// Tiles already returned by [`Self::new_tiles`].
    handed_out: usize,
    /// How many of `tiles` are the first layer's (set when its `GATT` is complete).
    first_layer_tiles: usize,
    /// The error reported, kept so that later calls report it again.
    error: Option<Error>,
    /// Offset just past `SEND`, once it is decoded.
    end: Option<usize>,
}

/// A tile whose Gaussians are ready (§10): its index in the layer's tile table and the range
/// it occupies in [`StreamDecoder::gaussians`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DecodedTile {
    /// The tile's index in `TILS` (§10.1).
    pub index: usize,
    /// Its Gaussians in [`StreamDecoder::gaussians`].
    pub gaussians: Range<usize>,
    /// The rate they are at: in a progressive stream (§3.8), the coarsest first, and the
    /// same tile again, at the same place, as each refinement takes it to a finer rate.
    pub rate: u8,
}

enum Profile {
    /// The first chunk is not complete yet.
    Unknown,
    /// Decoded whole by `finish`.
    Anchors,
    Explicit(Box<Explicit>),
}

struct Explicit {
    decoder: ExplicitDecoder,
    gatt: Option<Gatt>,
}

/// The selected layer's `GATT` while its bytes arrive.
struct Gatt {
    /// Offset of the payload in the stream and its length.
    payload_at: usize,
    len: usize,
    /// The tile bodies' lengths, once the table has arrived and adds up.
    lens: Option<Vec<usize>>,
    /// Offset of the next tile's body.
    body_at: usize,
    next_tile: usize,
    per_tile: Vec<Option<TileSymbols>>,
    /// The tiles could not all be decoded as they arrived: the whole chunk is decoded once
    /// complete (which reports the error, if there is one).
    whole: bool,
}

impl Gatt {
    /// The selected layer's `GATT`, its payload at `payload_at`, of `len` bytes, with
    /// `tile_count` tiles (0: the layer's parts are missing, and the whole-chunk decoder
    /// reports what is).
    fn new(payload_at: usize, len: usize, tile_count: usize) -> Gatt {
        Gatt {
            payload_at,
            len,
            lens: None,
            body_at: 0,
            next_tile: 0,
            per_tile: vec![None; tile_count],
            whole: tile_count == 0,
        }
    }

    /// §10.2: the method byte, then the T body lengths, which must add up to the payload;
    /// `payload` is what has arrived of it. Anything else leaves the chunk to the
    /// whole-chunk decoder.
    fn read_lengths(&mut self, payload: &[u8]) {
        let table_end = 1 + 4 * self.per_tile.len();
        if self.len < table_end {
            self.whole = true;
        } else if !self.whole && self.lens.is_none() && payload.len() >= table_end {
            let lens: Vec<usize> = payload[1..table_end]
                .chunks_exact(4)
                .map(|w| u32::from_le_bytes([w[0], w[1], w[2], w[3]]) as usize)
                .collect();
            let total = lens.iter().try_fold(0usize, |a, &l| a.checked_add(l));
            if payload[0] != METHOD_CODED || total != Some(self.len - table_end) {
                self.whole = true;
            } else {
                self.body_at = self.payload_at + table_end;
                self.lens = Some(lens);
            }
        }
    }

    /// Decodes and hands out the selected tiles whose bodies lie in `arrived` (the stream
    /// so far); the first that fails leaves the rest to the whole-chunk decoder.
    fn decode_arrived(
        &mut self,
        arrived: &[u8],
        decoder: &ExplicitDecoder,
        gaussians: &mut Gaussians,
        ready: &mut Vec<DecodedTile>,
    ) {
        let tables = GaussianTables::standard();
        let (false, Some(lens)) = (self.whole, &self.lens) else {
            return;
        };
        let tile_count = self.per_tile.len();
        while self.next_tile < tile_count && self.body_at + lens[self.next_tile] <= arrived.len() {
            let t = self.next_tile;
            let body = &arrived[self.body_at..self.body_at + lens[t]];
            self.body_at += lens[t];
            self.next_tile += 1;
            let (selected, inputs) = (decoder.is_selected(t), decoder.tile_inputs());
            if !selected {
                continue;
            }
            let Ok((layer, groups, tiles, voxels)) = inputs else {
                self.whole = true;
                break;
            };
            let decoded = decode_tile(layer, groups, &voxels[tiles.range(t)], body, tables)
                .and_then(|symbols| {
                    hand_out(decoder, t, symbols.as_ref(), gaussians, ready)?;
                    Ok(symbols)
                });
            match decoded {
                Ok(symbols) => self.per_tile[t] = Some(symbols),
                Err(_) => {
                    self.whole = true;
                    break;
                }
            }
        }
    }

    /// The chunk has arrived whole and its CRC holds: the tiles not decoded yet are, or the
    /// whole-chunk decoder reports the error.
    fn finish(
        self,
        decoder: &mut ExplicitDecoder,
        chunk: Chunk<'_>,
        gaussians: &mut Gaussians,
        ready: &mut Vec<DecodedTile>,
    ) -> Result<()> {
        if self.whole || self.next_tile < self.per_tile.len() {
            // The whole-chunk decoder gives the error, or (if the tiles could not be taken
            // one by one for another reason) the symbols; tiles not yet reconstructed are.
            decoder.chunk(chunk.tag, chunk.payload, &[])?;
            // The tiles handed out already are those `self.per_tile` holds: a prefix, in order.
            for (t, handed_out) in self.per_tile.iter().enumerate() {
                if let (Some(s), None) = (decoder.tile_symbols(t), handed_out) {
                    hand_out(decoder, t, s, gaussians, ready)?;
                }
            }
        } else {
            decoder.gatt_decoded(self.per_tile)?;
        }
        Ok(())
    }
}

impl StreamDecoder {
    /// A decoder with these options (`threads` does not apply: pieces are decoded on the
    /// caller's thread).
    pub(crate) fn new(options: DecodeOptions) -> Self {
        StreamDecoder {
            options,
            buf: Vec::new(),
            at: 0,
            profile: Profile::Unknown,
            gaussians: Gaussians::default(),
            tiles: Vec::new(),
            handed_out: 0,
            first_layer_tiles: 0,
            error: None,
            end: None,
        }
    }

    /// Takes the next bytes of the stream and decodes what they complete. An error is final
    /// (the stream is broken whatever follows) and is reported again by every later call.
    pub fn feed(&mut self, bytes: &[u8]) -> Result<()> {
        if let Some(e) = &self.error {
            return Err(e.clone());
        }
        self.buf.extend_from_slice(bytes);
        let advanced = self.advance();
        if let Err(e) = &advanced {
            self.error = Some(e.clone());
        }
        advanced
    }

    /// The tiles completed since the last call.
    pub fn new_tiles(&mut self) -> Vec<DecodedTile> {
        let from = self.handed_out;
        self.handed_out = self.tiles.len();
        self.tiles[from..].to_vec()
    }

    /// Every tile completed so far, in stream order (a progressive stream's tiles again
    /// after each refinement, §3.8).
    pub fn tiles(&self) -> &[DecodedTile] {
        &self.tiles
    }

    /// The Gaussians of every tile completed so far (explicit profile; empty otherwise).
    pub fn gaussians(&self) -> &Gaussians {
        &self.gaussians
    }

    /// The explicit profile's preflight (§3.2), once its chunk is decoded.
    pub fn gaussian_header(&self) -> Option<&crate::explicit::GaussianHeader> {
        match &self.profile {
            Profile::Explicit(e) => e.decoder.header(),
            _ => None,
        }
    }

    /// Bytes received so far.
    pub fn received(&self) -> usize {
        self.buf.len()
    }

    /// Ends the stream: what [`crate::Decoder::decode`] gives for the bytes fed.
    pub fn finish(self) -> Result<Scene> {
        if let Some(e) = self.error {
            return Err(e);
        }
        let (Profile::Explicit(explicit), Some(end)) = (self.profile, self.end) else {
            // Not decoded to SEND: the whole-buffer decoder reports what is missing (or
            // decodes an anchors-profile stream).
            return decode_scene(&self.buf, &self.options);
        };
        if self.buf.len() > end {
            return Err(Error::TrailingData {
                bytes: (self.buf.len() - end) as u64,
            });
        }
        let gaussians = self.gaussians;
        explicit
            .decoder
            .finish_with(Some(gaussians))
            .map(|d| Scene::Gaussians(Box::new(d)))
    }

    fn advance(&mut self) -> Result<()> {
        if self.at == 0 {
            if self.buf.len() < SIGNATURE_LEN {
                return Ok(());
            }
            Signature::parse(&self.buf)?;
            self.at = SIGNATURE_LEN;
        }
        while self.end.is_none() {
            let rest = &self.buf[self.at..];
            let [l0, l1, l2, l3, t0, t1, t2, t3, ..] = *rest else {
                return Ok(());
            };
            let (tag, len) = (
                ChunkTag([t0, t1, t2, t3]),
                u32::from_le_bytes([l0, l1, l2, l3]),
            );
            match self.profile {
                // Until the first chunk is decoded, the profile is unknown, and so is which
                // decoder reports a fault: `finish` leaves it to the whole-buffer one.
                Profile::Anchors => return Ok(()),
                Profile::Unknown => {
                    if !tag.is_valid()
                        || self
                            .options
                            .limits
                            .check(LimitKind::ChunkBytes, len.into())
                            .is_err()
                    {
                        self.profile = Profile::Anchors;
                        return Ok(());
                    }
                }
                // §1.3: the tag and the length are checked before the payload is read.
                Profile::Explicit(_) => {
                    if !tag.is_valid() {
                        return Err(Error::ChunkTagInvalid { tag: tag.0 });
                    }
                    self.options
                        .limits
                        .check(LimitKind::ChunkBytes, len.into())?;
                }
            }
            let len = len as usize;
            if let Profile::Explicit(e) = &mut self.profile {
                if tag == ChunkTag::GATT && matches!(e.decoder.due(tag), Ok(Due::Decoded)) {
                    let at = self.at;
                    if !self.gatt_progress(at, len)? {
                        return Ok(());
                    }
                    continue;
                }
            }
            let complete = CHUNK_HEADER_LEN + len + CHUNK_CRC_LEN;
            if rest.len() < complete {
                return Ok(());
            }
            let mut reader =
                ChunkReader::new(&rest[..complete], self.at as u64, &self.options.limits);
            if matches!(self.profile, Profile::Unknown) {
                // §3: the first chunk fixes the profile: a framed, CRC-checked `GHED` is the
                // explicit one (as `decoder::is_explicit` decides).
                let first = reader.next_chunk();
                if !matches!(first, Ok(Some(ref c)) if c.tag == ChunkTag::GHED) {
                    self.profile = Profile::Anchors;
                    return Ok(());
                }
                let mut decoder = ExplicitDecoder::new(&self.options);
                // A viewer shows each rate of a progressive stream as it completes.
                decoder.reconstruct_each_layer = true;
                self.profile = Profile::Explicit(Box::new(Explicit {
                    decoder,
                    gatt: None,
                }));
                reader = ChunkReader::new(&rest[..complete], self.at as u64, &self.options.limits);
            }
            let Some(chunk) = reader.next_chunk()? else {
                return Ok(());
            };
            let Profile::Explicit(e) = &mut self.profile else {
                return Ok(());
            };
            // What follows SEND is checked by `finish`, once no more bytes can come.
            if e.decoder.chunk(chunk.tag, chunk.payload, &[])? {
                self.end = Some(self.at + complete);
            }
            self.at += complete;
            // §3.8: a refinement took every decoded tile to a finer rate, in place.
            if let Some((rate, refined)) = e.decoder.refined_gaussians() {
                if chunk.tag == ChunkTag::GRSY {
                    self.gaussians.clone_from(refined);
                    let first: Vec<DecodedTile> = self.tiles[..self.first_layer_tiles].to_vec();
                    self.tiles
                        .extend(first.into_iter().map(|t| DecodedTile { rate, ..t }));
                }
            }
        }
        Ok(())
    }

    /// Decodes the tiles of the selected layer's `GATT` (at `at`, payload `len` bytes) whose
    /// bodies have arrived; returns whether the whole chunk has been decoded.
    fn gatt_progress(&mut self, at: usize, len: usize) -> Result<bool> {
        let Profile::Explicit(e) = &mut self.profile else {
            return Ok(false);
        };
        if e.gatt.is_none() {
            let tile_count = e.decoder.select_tiles().map_or(0, |s| s.len());
            self.gaussians.sh_degree = e.decoder.header().map_or(0, |h| h.sh_degree);
            e.gatt = Some(Gatt::new(at + CHUNK_HEADER_LEN, len, tile_count));
        }
        let Some(g) = e.gatt.as_mut() else {
            return Ok(false);
        };
        let arrived = self.buf.len().min(g.payload_at + g.len);
        g.read_lengths(&self.buf[g.payload_at..arrived]);
        g.decode_arrived(
            &self.buf[..arrived],
            &e.decoder,
            &mut self.gaussians,
            &mut self.tiles,
        );
        let complete = CHUNK_HEADER_LEN + g.len + CHUNK_CRC_LEN;
        if self.buf.len() < at + complete {
            return Ok(false);
        }
        // The chunk is complete: its framing and CRC first (§1.3), as the whole-buffer
        // decoder checks them.
        let mut reader = ChunkReader::new(
            &self.buf[at..at + complete],
            at as u64,
            &self.options.limits,
        );
        let Some(chunk) = reader.next_chunk()? else {
            return Ok(false);
        };
        let Some(g) = e.gatt.take() else {
            return Ok(false);
        };
        g.finish(&mut e.decoder, chunk, &mut self.gaussians, &mut self.tiles)?;
        self.first_layer_tiles = self.tiles.len();
        self.at = at + complete;
        Ok(true)
    }
}

/// §3.6: reconstructs tile `t` from its symbols onto `gaussians` and records it as ready.
fn hand_out(
    decoder: &ExplicitDecoder,
    t: usize,
    symbols: TileSymbolsRef,
    gaussians: &mut Gaussians,
    tiles: &mut Vec<DecodedTile>,
) -> Result<()> {
    let from = gaussians.len();
    decoder.reconstruct(t, symbols, gaussians)?;
    tiles.push(DecodedTile {
        index: t,
        gaussians: from..gaussians.len(),
        rate: decoder.layer_rate(),
    });
    Ok(())
}
