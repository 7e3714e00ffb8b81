//! Decoding an explicit-profile stream (spec §3.7): the chunk order, the selected layer, and
//! the tiles of its `GATT` decoded in parallel.

use crate::par::*;

use crate::container::chunk::{ChunkReader, ChunkTag};
use crate::container::payload::{apos_bodies, body, read_apos, read_apos_tile, METHOD_CODED};
use crate::container::signature::{Signature, SIGNATURE_LEN};
use crate::entropy::{GaussianTables, SymbolReader};
use crate::error::{Error, Result};
use crate::explicit::attributes::{walk, BitEvent, Events, TileSymbols};
use crate::explicit::groups::{read_gqua, Group};
use crate::explicit::header::GaussianHeader;
use crate::explicit::layer::Layer;
use crate::explicit::reconstruct::reconstruct_tile;
use crate::explicit::Gaussians;
use crate::limits::Limits;
use crate::tiles::{split_bodies, TileTable};

/// A decoded explicit-profile stream: the Gaussians of the selected layer and the integer
/// results conformance compares (§11).
#[derive(Debug, Clone, PartialEq)]
pub struct DecodedGaussians {
    /// The preflight (§3.2).
    pub header: GaussianHeader,
    /// The attribute groups (§3.3).
    pub groups: Vec<Group>,
    /// The decoded rate.
    pub rate: u8,
    /// The decoded layer's grid and prior (§3.4).
    pub layer: Layer,
    /// Voxel of every Gaussian decoded (all, or the selected tiles'), in stream order.
    pub voxels: Vec<[u32; 3]>,
    /// Every decoded tile's symbols, in order.
    pub symbols: TileSymbols,
    /// The layer's tile table (every tile, decoded or not).
    pub tiles: TileTable,
    /// The Gaussians, in stream order.
    pub gaussians: Gaussians,
}

/// §3.7 Table 3-2: the explicit profile's critical chunk types.
pub const CRITICAL_CHUNKS: [ChunkTag; 7] = [
    ChunkTag::GHED,
    ChunkTag::GQUA,
    ChunkTag::GLAY,
    ChunkTag::TILS,
    ChunkTag::APOS,
    ChunkTag::GATT,
    ChunkTag::SEND,
];

/// §3.7 Table 3-2: the critical chunk due at position `i` (0 = `GHED`) of a stream with
/// `layers` layers.
pub fn expected_critical(i: usize, layers: usize) -> ChunkTag {
    const LAYER: [ChunkTag; 4] = [
        ChunkTag::GLAY,
        ChunkTag::TILS,
        ChunkTag::APOS,
        ChunkTag::GATT,
    ];
    match i {
        0 => ChunkTag::GHED,
        1 => ChunkTag::GQUA,
        i if i - 2 < 4 * layers => LAYER[(i - 2) % 4],
        _ => ChunkTag::SEND,
    }
}

struct Reader<'a> {
    symbols: SymbolReader<'a>,
}

impl Events for Reader<'_> {
    fn bit(&mut self, freq_one: u32, _: usize, _: BitEvent) -> Result<bool> {
        self.symbols.bit(freq_one)
    }
    fn symbol(&mut self, k: u8, _: usize, _: usize, _: i64) -> Result<i64> {
        self.symbols.symbol(k)
    }
}

/// §3.5: decodes one tile's body of `GATT`; `voxels` are the tile's.
pub(crate) fn decode_tile(
    layer: &Layer,
    groups: &[Group],
    voxels: &[[u32; 3]],
    body: &[u8],
    tables: &GaussianTables,
) -> Result<TileSymbols> {
    let mut reader = Reader {
        symbols: SymbolReader::new(ChunkTag::GATT, body, tables)?,
    };
    let symbols = walk(layer, groups, voxels, &mut reader)?;
    reader.symbols.finish()?;
    Ok(symbols)
}

/// A decoded tile: its symbols (§3.5) and its Gaussians (§3.6).
pub type DecodedTile = (TileSymbols, Gaussians);

/// §3.5, §3.6: decodes `GATT` of a layer whose geometry is `voxels` cut by `tiles`, and
/// reconstructs each selected tile's Gaussians in the same task (tiles are independent, so
/// the reconstruction runs on every thread rather than after the last tile).
#[allow(clippy::too_many_arguments)]
pub fn read_gatt(
    payload: &[u8],
    header: &GaussianHeader,
    rate: u8,
    layer: &Layer,
    groups: &[Group],
    tiles: &TileTable,
    voxels: &[[u32; 3]],
    selected: &[bool],
    tables: &GaussianTables,
) -> Result<Vec<Option<DecodedTile>>> {
    let tag = ChunkTag::GATT;
    let words = body(tag, payload, METHOD_CODED)?;
    let bodies = split_bodies(tag, 1, words, tiles.len())?;
    let decoded: Vec<Result<Option<DecodedTile>>> = bodies
        .into_par_iter()
        .enumerate()
        .map(|(t, b)| {
            if !selected.get(t).copied().unwrap_or(true) {
                return Ok(None);
            }
            let tile_voxels = &voxels[tiles.range(t)];
            decode_and_reconstruct(header, rate, layer, groups, tile_voxels, b, tables)
        })
        .collect();
    // §10.3: the lowest tile's error is reported.
    decoded.into_iter().collect()
}

/// §3.5, §3.6: one tile's symbols from its `GATT` body and its Gaussians from them.
fn decode_and_reconstruct(
    header: &GaussianHeader,
    rate: u8,
    layer: &Layer,
    groups: &[Group],
    voxels: &[[u32; 3]],
    body: &[u8],
    tables: &GaussianTables,
) -> Result<Option<DecodedTile>> {
    let symbols = decode_tile(layer, groups, voxels, body, tables)?;
    let mut gaussians = Gaussians::with_capacity(header.sh_degree, voxels.len());
    reconstruct_tile(
        header.origin,
        layer,
        groups,
        rate,
        voxels,
        &symbols,
        &mut gaussians,
    );
    Ok(Some((symbols, gaussians)))
}

/// The payload of the next critical chunk in `rest` if it is `GATT` and every chunk before it
/// is framed and CRC-checked (`None` otherwise, or where `rest` ends first: the chunks are
/// then decoded one at a time, and report their own errors at their own positions).
fn next_gatt<'a>(rest: &'a [u8], limits: &Limits) -> Option<&'a [u8]> {
    let mut reader = ChunkReader::new(rest, 0, limits);
    // Every chunk read takes at least its 12 bytes of framing, so this ends.
    while let Ok(Some(chunk)) = reader.next_chunk() {
        if chunk.tag.is_critical() {
            return (chunk.tag == ChunkTag::GATT).then_some(chunk.payload);
        }
    }
    None
}

/// Decodes an explicit-profile stream at `rate` (default: the lowest coded rate), §3.7.
pub fn decode_gaussians(
    data: &[u8],
    limits: &Limits,
    rate: Option<u8>,
) -> Result<DecodedGaussians> {
    decode_gaussians_in(data, limits, rate, None)
}

/// [`decode_gaussians`], keeping only the tiles whose boxes meet `region` (world
/// coordinates `x0, y0, z0, x1, y1, z1`; §10.3).
pub fn decode_gaussians_in(
    data: &[u8],
    limits: &Limits,
    rate: Option<u8>,
    region: Option<crate::tiles::RegionBox>,
) -> Result<DecodedGaussians> {
    let (_sig, rest) = Signature::parse(data)?;
    let mut reader = ChunkReader::new(rest, SIGNATURE_LEN as u64, limits);
    let mut state = ExplicitDecoder::new(limits, rate, region);
    loop {
        // §1.5 rule 4: the stream ends only with SEND.
        let chunk = reader.next_before_send()?;
        if state.chunk(chunk.tag, chunk.payload, reader.remaining())? {
            break;
        }
    }
    state.finish()
}

/// What the critical chunk at the current position does (§3.7): which check failed, or
/// whether it is decoded or skipped (another layer's).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Due {
    /// An ancillary chunk after `GHED`: ignored.
    Ancillary,
    /// A layer chunk of a layer that is not decoded.
    Skipped,
    /// A chunk to decode.
    Decoded,
}

/// The explicit profile's decoding process (§3.7) driven one chunk at a time, so that the
/// whole-buffer decoder and the streaming one ([`crate::stream`]) apply the same rules in the
/// same order. Chunks arrive framed and CRC-checked (§1.3).
pub(crate) struct ExplicitDecoder {
    limits: Limits,
    rate: Option<u8>,
    region: Option<crate::tiles::RegionBox>,
    /// Position of the next critical chunk (0 = `GHED`).
    next: usize,
    header: Option<GaussianHeader>,
    groups: Option<Vec<Group>>,
    selected_layer: usize,
    layers: usize,
    rate_chosen: u8,
    layer: Option<Layer>,
    tiles: Option<TileTable>,
    voxels: Option<Vec<[u32; 3]>>,
    /// Which tiles the region keeps (set with the selected layer's `GATT`).
    selected: Vec<bool>,
    /// Every tile's symbols once `GATT` is decoded (`None`: not selected).
    per_tile: Option<Vec<Option<TileSymbols>>>,
    /// The selected tiles' Gaussians, in order, where `GATT` was decoded whole.
    reconstructed: Option<Gaussians>,
    /// `GATT`'s outcome where it was decoded with `APOS` (see [`ExplicitDecoder::fused`]),
    /// reported when its own position in the stream is reached.
    early_gatt: Option<Result<Vec<Option<DecodedTile>>>>,
}

fn missing(tag: ChunkTag) -> Error {
    Error::ChunkOrder {
        found: ChunkTag::SEND,
        expected: tag,
    }
}

impl ExplicitDecoder {
    pub(crate) fn new(
        limits: &Limits,
        rate: Option<u8>,
        region: Option<crate::tiles::RegionBox>,
    ) -> Self {
        ExplicitDecoder {
            limits: *limits,
            rate,
            region,
            next: 0,
            header: None,
            groups: None,
            selected_layer: 0,
            layers: 0,
            rate_chosen: 0,
            layer: None,
            tiles: None,
            voxels: None,
            selected: Vec::new(),
            per_tile: None,
            reconstructed: None,
            early_gatt: None,
        }
    }

    /// §1.5, §3.7: whether a chunk tagged `tag` may come next, and what is done with it.
    pub(crate) fn due(&self, tag: ChunkTag) -> Result<Due> {
        if !tag.is_critical() {
            if self.header.is_none() {
                return Err(Error::ChunkOrder {
                    found: tag,
                    expected: ChunkTag::GHED,
                });
            }
            return Ok(Due::Ancillary);
        }
        if !CRITICAL_CHUNKS.contains(&tag) {
            return Err(Error::UnknownCriticalChunk { tag });
        }
        let expected = expected_critical(self.next, self.layers);
        if tag != expected {
            return Err(Error::ChunkOrder {
                found: tag,
                expected,
            });
        }
        // The layer a layer chunk belongs to.
        let in_layer = self.next.checked_sub(2).map(|p| p / 4);
        Ok(match in_layer {
            Some(l) if l < self.layers && l != self.selected_layer => Due::Skipped,
            _ => Due::Decoded,
        })
    }

    /// Decodes one chunk; `rest` is what follows it in the stream. Returns whether it was
    /// `SEND`.
    pub(crate) fn chunk(&mut self, tag: ChunkTag, bytes: &[u8], rest: &[u8]) -> Result<bool> {
        let due = self.due(tag)?;
        if due == Due::Ancillary {
            return Ok(false);
        }
        self.next += 1;
        if due == Due::Skipped {
            return Ok(false);
        }
        let tables = GaussianTables::standard();
        match tag {
            ChunkTag::GHED => {
                let h = GaussianHeader::parse(bytes, &self.limits)?;
                (self.rate_chosen, self.selected_layer, self.layers) = h.select_layer(self.rate)?;
                self.header = Some(h);
            }
            ChunkTag::GQUA => {
                let h = self.header.as_ref().ok_or(missing(ChunkTag::GHED))?;
                self.groups = Some(read_gqua(bytes, h.sh_degree, h.rate_count)?);
            }
            ChunkTag::GLAY => {
                let g = self.groups.as_ref().ok_or(missing(ChunkTag::GQUA))?;
                let values = g.iter().map(|g| g.dim).sum();
                self.layer = Some(Layer::parse(bytes, g.len(), values)?);
            }
            ChunkTag::TILS => {
                let h = self.header.as_ref().ok_or(missing(ChunkTag::GHED))?;
                let l = self.layer.as_ref().ok_or(missing(ChunkTag::GLAY))?;
                self.tiles = Some(TileTable::parse(bytes, h.count, l.coord_bits)?);
            }
            ChunkTag::APOS => match next_gatt(rest, &self.limits) {
                Some(gatt) => self.fused(bytes, gatt, tables)?,
                None => {
                    let t = self.tiles.as_ref().ok_or(missing(ChunkTag::TILS))?;
                    self.voxels = Some(read_apos(bytes, t, tables)?);
                }
            },
            ChunkTag::GATT => {
                let decoded = match self.early_gatt.take() {
                    Some(decoded) => decoded?,
                    None => {
                        self.select_tiles()?;
                        let (l, g, t, v) = self.tile_inputs()?;
                        let h = self.header.as_ref().ok_or(missing(ChunkTag::GHED))?;
                        let rate = self.rate_chosen;
                        read_gatt(bytes, h, rate, l, g, t, v, &self.selected, tables)?
                    }
                };
                let h = self.header.as_ref().ok_or(missing(ChunkTag::GHED))?;
                let mut gaussians = Gaussians {
                    sh_degree: h.sh_degree,
                    ..Gaussians::default()
                };
                let mut per_tile = Vec::with_capacity(decoded.len());
                for tile in decoded {
                    per_tile.push(tile.map(|(symbols, g)| {
                        gaussians.append(g);
                        symbols
                    }));
                }
                self.per_tile = Some(per_tile);
                self.reconstructed = Some(gaussians);
            }
            _ => {
                // SEND: empty, last, nothing after it.
                crate::container::chunk::check_send(bytes, rest)?;
                return Ok(true);
            }
        }
        Ok(false)
    }

    /// `APOS` and the `GATT` that follows it (`gatt`, already framed and CRC-checked) decoded
    /// together: each tile's geometry, attributes and Gaussians in one task, so that no
    /// thread waits for the slowest tile's geometry before starting on attributes. The
    /// outcome is the two chunks' in stream order: `APOS`'s errors (the lowest tile's), then
    /// the tiles' boxes and order (§10), are reported now; `GATT`'s outcome is kept for its
    /// own position, after whatever chunks come between.
    fn fused(&mut self, apos: &[u8], gatt: &[u8], tables: &GaussianTables) -> Result<()> {
        let tiles = self.tiles.as_ref().ok_or(missing(ChunkTag::TILS))?;
        let geometry = apos_bodies(apos, tiles)?;
        self.select_tiles()?;
        let h = self.header.as_ref().ok_or(missing(ChunkTag::GHED))?;
        let l = self.layer.as_ref().ok_or(missing(ChunkTag::GLAY))?;
        let g = self.groups.as_deref().ok_or(missing(ChunkTag::GQUA))?;
        let tiles = self.tiles.as_ref().ok_or(missing(ChunkTag::TILS))?;
        let attributes = body(ChunkTag::GATT, gatt, METHOD_CODED)
            .and_then(|words| split_bodies(ChunkTag::GATT, 1, words, tiles.len()));
        let (rate, selected) = (self.rate_chosen, &self.selected);
        type Fused = (Result<Vec<[u32; 3]>>, Option<Result<Option<DecodedTile>>>);
        let decoded: Vec<Fused> = geometry
            .into_par_iter()
            .enumerate()
            .map(|(t, b)| {
                let voxels = read_apos_tile(b, t, tiles, tables);
                let tile = match (&voxels, &attributes) {
                    (Ok(v), Ok(bodies)) if selected.get(t).copied().unwrap_or(true) => {
                        Some(decode_and_reconstruct(h, rate, l, g, v, bodies[t], tables))
                    }
                    (Ok(_), Ok(_)) => Some(Ok(None)),
                    _ => None,
                };
                (voxels, tile)
            })
            .collect();
        let mut voxels = Vec::with_capacity(tiles.anchors as usize);
        let mut per_tile = Vec::with_capacity(decoded.len());
        for (v, tile) in decoded {
            voxels.extend_from_slice(&v?);
            per_tile.push(tile);
        }
        tiles.check_geometry(&voxels)?;
        self.voxels = Some(voxels);
        // Every tile's geometry decoded, so every tile has an outcome where `GATT` was
        // framed; the lowest tile's error is reported (§10.3).
        self.early_gatt = Some(attributes.and_then(|_| {
            per_tile
                .into_iter()
                .map(|tile| tile.unwrap_or(Ok(None)))
                .collect()
        }));
        Ok(())
    }

    /// The tiles the region keeps (§10.3), fixed before the selected layer's `GATT` is decoded
    /// (with `APOS` where the two are decoded together).
    pub(crate) fn select_tiles(&mut self) -> Result<&[bool]> {
        let h = self.header.as_ref().ok_or(missing(ChunkTag::GHED))?;
        let l = self.layer.as_ref().ok_or(missing(ChunkTag::GLAY))?;
        let t = self.tiles.as_ref().ok_or(missing(ChunkTag::TILS))?;
        self.selected = t.select(h.origin, l.voxel_size, self.region);
        Ok(&self.selected)
    }

    /// What decoding a tile of `GATT` reads: the layer, groups, tile table and voxels.
    #[allow(clippy::type_complexity)]
    pub(crate) fn tile_inputs(&self) -> Result<(&Layer, &[Group], &TileTable, &[[u32; 3]])> {
        Ok((
            self.layer.as_ref().ok_or(missing(ChunkTag::GLAY))?,
            self.groups.as_deref().ok_or(missing(ChunkTag::GQUA))?,
            self.tiles.as_ref().ok_or(missing(ChunkTag::TILS))?,
            self.voxels.as_deref().ok_or(missing(ChunkTag::APOS))?,
        ))
    }

    /// Whether the region keeps tile `t` ([`Self::select_tiles`] first).
    pub(crate) fn is_selected(&self, t: usize) -> bool {
        self.selected.get(t).copied().unwrap_or(false)
    }

    /// Every tile's symbols, once `GATT` is decoded.
    pub(crate) fn decoded_tiles(&self) -> Option<&[Option<TileSymbols>]> {
        self.per_tile.as_deref()
    }

    /// The stream's preflight, once `GHED` is decoded.
    pub(crate) fn header(&self) -> Option<&GaussianHeader> {
        self.header.as_ref()
    }

    /// §3.6: the Gaussians of tile `t` from its symbols, appended to `out`.
    pub(crate) fn reconstruct(&self, t: usize, s: &TileSymbols, out: &mut Gaussians) -> Result<()> {
        let h = self.header.as_ref().ok_or(missing(ChunkTag::GHED))?;
        let (l, g, tiles, v) = self.tile_inputs()?;
        reconstruct_tile(h.origin, l, g, self.rate_chosen, &v[tiles.range(t)], s, out);
        Ok(())
    }

    /// Records the selected layer's `GATT` as decoded elsewhere (tile by tile, as its bytes
    /// arrived): its position is taken and its symbols kept.
    pub(crate) fn gatt_decoded(&mut self, per_tile: Vec<Option<TileSymbols>>) {
        self.next += 1;
        self.per_tile = Some(per_tile);
    }

    /// §3.6, after `SEND`: the Gaussians of every decoded tile, in stream order.
    pub(crate) fn finish(mut self) -> Result<DecodedGaussians> {
        let reconstructed = self.reconstructed.take();
        self.finish_with(reconstructed)
    }

    /// [`Self::finish`] with the Gaussians already reconstructed tile by tile, in order
    /// (`None`: reconstruct them now).
    pub(crate) fn finish_with(self, reconstructed: Option<Gaussians>) -> Result<DecodedGaussians> {
        let per_tile = self.per_tile.as_ref().ok_or(missing(ChunkTag::GATT))?;
        let done = reconstructed.is_some();
        let mut gaussians = reconstructed.unwrap_or_else(|| Gaussians {
            sh_degree: self.header.as_ref().map_or(0, |h| h.sh_degree),
            ..Gaussians::default()
        });
        let mut all = TileSymbols::default();
        let mut kept = Vec::new();
        let (_, _, tiles, voxels) = self.tile_inputs()?;
        for (t, s) in per_tile.iter().enumerate() {
            let Some(s) = s else { continue };
            kept.extend_from_slice(&voxels[tiles.range(t)]);
            if !done {
                self.reconstruct(t, s, &mut gaussians)?;
            }
            all.coords.extend_from_slice(&s.coords);
            all.rotation_index.extend_from_slice(&s.rotation_index);
            all.size_class.extend_from_slice(&s.size_class);
            all.refinement.extend_from_slice(&s.refinement);
        }
        let missing_part = |tag| missing(tag);
        Ok(DecodedGaussians {
            header: self.header.ok_or(missing_part(ChunkTag::GHED))?,
            groups: self.groups.ok_or(missing_part(ChunkTag::GQUA))?,
            rate: self.rate_chosen,
            layer: self.layer.ok_or(missing_part(ChunkTag::GLAY))?,
            voxels: kept,
            symbols: all,
            tiles: self.tiles.ok_or(missing_part(ChunkTag::TILS))?,
            gaussians,
        })
    }
}
