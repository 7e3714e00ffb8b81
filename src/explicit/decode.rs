//! Decoding an explicit-profile stream (spec §3.7): the chunk order, the selected layer, and
//! the tiles of its `GATT` decoded in parallel.

use crate::par::*;

use crate::container::chunk::{ChunkReader, ChunkTag};
use crate::container::payload::{body, read_apos, METHOD_CODED};
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
    pub header: GaussianHeader,
    pub groups: Vec<Group>,
    /// The decoded rate.
    pub rate: u8,
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

/// §3.5: decodes `GATT` of a layer whose geometry is `voxels` cut by `tiles`.
pub fn read_gatt(
    payload: &[u8],
    layer: &Layer,
    groups: &[Group],
    tiles: &TileTable,
    voxels: &[[u32; 3]],
    selected: &[bool],
    tables: &GaussianTables,
) -> Result<Vec<Option<TileSymbols>>> {
    let tag = ChunkTag::GATT;
    let words = body(tag, payload, METHOD_CODED)?;
    let bodies = split_bodies(tag, 1, words, tiles.len())?;
    let decoded: Vec<Result<Option<TileSymbols>>> = bodies
        .into_par_iter()
        .enumerate()
        .map(|(t, b)| {
            if !selected.get(t).copied().unwrap_or(true) {
                return Ok(None);
            }
            let mut reader = Reader {
                symbols: SymbolReader::new(tag, b, tables)?,
            };
            let symbols = walk(layer, groups, &voxels[tiles.range(t)], &mut reader)?;
            reader.symbols.finish()?;
            Ok(Some(symbols))
        })
        .collect();
    // §10.3: the lowest tile's error is reported.
    decoded.into_iter().collect()
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
    region: Option<[f64; 6]>,
) -> Result<DecodedGaussians> {
    let tables = GaussianTables::standard();
    let (_sig, rest) = Signature::parse(data)?;
    let mut reader = ChunkReader::new(rest, SIGNATURE_LEN as u64, limits);
    let mut next = 0usize;
    let mut header: Option<GaussianHeader> = None;
    let mut groups: Option<Vec<Group>> = None;
    let (mut selected, mut layers, mut rate_chosen) = (0usize, 0usize, 0u8);
    let mut layer: Option<Layer> = None;
    let mut tiles: Option<TileTable> = None;
    let mut voxels: Option<Vec<[u32; 3]>> = None;
    let mut symbols: Option<Vec<Option<TileSymbols>>> = None;
    let missing = |tag| Error::ChunkOrder {
        found: ChunkTag::SEND,
        expected: tag,
    };
    loop {
        // §1.5 rule 4: the stream ends only with SEND.
        let chunk = reader.next_before_send()?;
        let tag = chunk.tag;
        if !tag.is_critical() {
            if header.is_none() {
                return Err(Error::ChunkOrder {
                    found: tag,
                    expected: ChunkTag::GHED,
                });
            }
            continue;
        }
        if !CRITICAL_CHUNKS.contains(&tag) {
            return Err(Error::UnknownCriticalChunk { tag });
        }
        let expected = expected_critical(next, layers);
        if tag != expected {
            return Err(Error::ChunkOrder {
                found: tag,
                expected,
            });
        }
        let position = next;
        next += 1;
        let bytes = chunk.payload;
        // The layer a layer chunk belongs to.
        let in_layer = position.checked_sub(2).map(|p| p / 4);
        if matches!(in_layer, Some(l) if l < layers && l != selected) {
            continue;
        }
        match tag {
            ChunkTag::GHED => {
                let h = GaussianHeader::parse(bytes, limits)?;
                (rate_chosen, selected, layers) = h.select_layer(rate)?;
                header = Some(h);
            }
            ChunkTag::GQUA => {
                let h = header.as_ref().ok_or(missing(ChunkTag::GHED))?;
                groups = Some(read_gqua(bytes, h.sh_degree, h.rate_count)?);
            }
            ChunkTag::GLAY => {
                let g = groups.as_ref().ok_or(missing(ChunkTag::GQUA))?;
                let values = g.iter().map(|g| g.dim).sum();
                layer = Some(Layer::parse(bytes, g.len(), values)?);
            }
            ChunkTag::TILS => {
                let h = header.as_ref().ok_or(missing(ChunkTag::GHED))?;
                let l = layer.as_ref().ok_or(missing(ChunkTag::GLAY))?;
                tiles = Some(TileTable::parse(bytes, h.count, l.coord_bits)?);
            }
            ChunkTag::APOS => {
                let t = tiles.as_ref().ok_or(missing(ChunkTag::TILS))?;
                voxels = Some(read_apos(bytes, t, tables)?);
            }
            ChunkTag::GATT => {
                let (l, g) = (
                    layer.as_ref().ok_or(missing(ChunkTag::GLAY))?,
                    groups.as_ref().ok_or(missing(ChunkTag::GQUA))?,
                );
                let t = tiles.as_ref().ok_or(missing(ChunkTag::TILS))?;
                let v = voxels.as_ref().ok_or(missing(ChunkTag::APOS))?;
                let h = header.as_ref().ok_or(missing(ChunkTag::GHED))?;
                let selected = t.select(h.origin, l.voxel_size, region);
                symbols = Some(read_gatt(bytes, l, g, t, v, &selected, tables)?);
            }
            _ => {
                // SEND: empty, last, nothing after it.
                crate::container::chunk::check_send(bytes, reader.remaining())?;
                break;
            }
        }
    }
    let header = header.ok_or(missing(ChunkTag::GHED))?;
    let groups = groups.ok_or(missing(ChunkTag::GQUA))?;
    let layer = layer.ok_or(missing(ChunkTag::GLAY))?;
    let tiles = tiles.ok_or(missing(ChunkTag::TILS))?;
    let voxels = voxels.ok_or(missing(ChunkTag::APOS))?;
    let per_tile = symbols.ok_or(missing(ChunkTag::GATT))?;
    let mut gaussians = Gaussians {
        sh_degree: header.sh_degree,
        ..Gaussians::default()
    };
    let mut all = TileSymbols::default();
    let mut kept = Vec::new();
    for (t, s) in per_tile.iter().enumerate() {
        let Some(s) = s else { continue };
        kept.extend_from_slice(&voxels[tiles.range(t)]);
        reconstruct_tile(
            header.origin,
            &layer,
            &groups,
            rate_chosen,
            &voxels[tiles.range(t)],
            s,
            &mut gaussians,
        );
        all.coords.extend_from_slice(&s.coords);
        all.rotation_index.extend_from_slice(&s.rotation_index);
        all.size_class.extend_from_slice(&s.size_class);
        all.refinement.extend_from_slice(&s.refinement);
    }
    Ok(DecodedGaussians {
        header,
        groups,
        rate: rate_chosen,
        layer,
        voxels: kept,
        symbols: all,
        tiles,
        gaussians,
    })
}
