//! Decoding an explicit-profile stream (spec §3.7): the chunk order, the selected layer, and
//! the tiles of its `GATT` decoded in parallel.

use std::cell::RefCell;

use crate::par::*;

use crate::container::chunk::{peek_critical, ChunkReader, ChunkTag};
use crate::container::payload::{apos_bodies, body, read_apos_of, read_apos_tile, METHOD_CODED};
use crate::container::signature::{Signature, SIGNATURE_LEN};
use crate::entropy::GaussianTables;
use crate::error::{Error, Result};
use crate::explicit::attributes::{TileSymbols, TileSymbolsRef};
use crate::explicit::gatt::{decode_and_reconstruct, read_gatt, DecodedTiles};
use crate::explicit::groups::{read_gqua, Group};
use crate::explicit::header::GaussianHeader;
use crate::explicit::layer::Layer;
use crate::explicit::reconstruct::reconstruct_tile_into;
use crate::explicit::refinement::{Precision, Refinement};
use crate::explicit::Gaussians;
use crate::geometry::WalkScratch;
use crate::limits::{LimitKind, Limits};
use crate::options::DecodeOptions;
use crate::quantizer::LatticeMatrix;
use crate::tiles::{split_bodies, TileTable};

mod progressive;

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
    /// The grid and prior of the decoded layer, or of a progressive stream's first layer
    /// (§3.4).
    pub layer: Layer,
    /// The precision of the decoded Gaussians (§3.6, §3.8).
    pub precision: Precision,
    /// A progressive stream's refinements decoded after the first layer, in stream order
    /// (§3.8.1).
    pub refinements: Vec<Refinement>,
    /// Whether the stream ended before `SEND` (a progressive stream's prefix accepted with
    /// [`crate::DecoderBuilder::accept_prefix`], §3.8): the Gaussians are those of its last complete
    /// layer, which [`Self::rate`] names.
    pub truncated: bool,
    /// Voxel of every Gaussian decoded (all, or the selected tiles'), in stream order.
    pub voxels: Vec<[u32; 3]>,
    /// Every decoded tile's symbols, in order.
    pub symbols: TileSymbols,
    /// The layer's tile table (every tile, decoded or not).
    pub tiles: TileTable,
    /// The Gaussians, in stream order.
    pub gaussians: Gaussians,
}

thread_local! {
    /// A thread's buffers for the tiles it decodes with `APOS` and `GATT` together.
    static FUSED_SCRATCH: RefCell<(WalkScratch, TileSymbols)> = RefCell::default();
}

use crate::container::order::{ChunkOrder, Position, Profile};

/// Decodes an explicit-profile stream (§3.7) with `options`: its rate, region, part and
/// limits, keeping the symbols unless `gaussians_only` (on the caller's pool).
pub(crate) fn decode_explicit(data: &[u8], options: &DecodeOptions) -> Result<DecodedGaussians> {
    let (_sig, rest) = Signature::parse(data)?;
    let mut reader = ChunkReader::new(rest, SIGNATURE_LEN as u64, &options.limits);
    let mut state = ExplicitDecoder::new(options);
    loop {
        // §1.5 rule 4: the stream ends only with SEND; §3.8: a progressive stream's prefix
        // decodes to its last complete layer where the caller accepts it.
        let chunk = match reader.next_before_send() {
            Ok(chunk) => chunk,
            Err(e) if options.accept_prefix && e.is_truncation() && state.prefix_decodes() => {
                return state.finish_prefix();
            }
            Err(e) => return Err(e),
        };
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
    part: Option<crate::tiles::TilePart>,
    /// The walk through the chunk order (§3.7).
    order: ChunkOrder,
    header: Option<GaussianHeader>,
    groups: Option<Vec<Group>>,
    /// The groups' lattice matrices (§3.3), once `GQUA` is read.
    matrices: Vec<LatticeMatrix>,
    selected_layer: usize,
    rate_chosen: u8,
    /// Rates of the coded layers in stream order.
    stream_rates: Vec<u8>,
    progressive: bool,
    layer: Option<Layer>,
    /// The precision of the symbols decoded so far (§3.8), once the first layer's `GATT` is.
    precision: Option<Precision>,
    /// The refinement whose `GRSY` comes next.
    refinement: Option<Refinement>,
    /// The refinements decoded, in stream order.
    refinements: Vec<Refinement>,
    /// Layers whose symbols are decoded.
    layers_done: usize,
    /// The layer (in stream order) whose precision the Gaussians decoded so far are at.
    gaussians_at: Option<usize>,
    /// Whether the stream ended before `SEND` (a progressive stream's prefix, §3.8).
    truncated: bool,
    /// Whether each refinement's Gaussians are reconstructed, not only the selected
    /// rate's (a viewer shows each rate as it arrives).
    pub(crate) reconstruct_each_layer: bool,
    tiles: Option<TileTable>,
    voxels: Option<Vec<[u32; 3]>>,
    /// Which tiles the region keeps (set with the selected layer's `GATT`).
    selected: Vec<bool>,
    /// Whether the symbols are kept (`gaussians_only` off).
    pub(crate) keep_symbols: bool,
    /// The selected tiles' symbols, once `GATT` is decoded, and their Gaussians where it was
    /// decoded whole (empty where the caller reconstructs them).
    decoded: Option<DecodedTiles>,
    /// `GATT`'s outcome where it was decoded with `APOS` (see [`ExplicitDecoder::fused`]),
    /// reported when its own position in the stream is reached.
    early_gatt: Option<Result<DecodedTiles>>,
}

fn missing(tag: ChunkTag) -> Error {
    Error::ChunkOrder {
        found: ChunkTag::SEND,
        expected: tag,
    }
}

impl ExplicitDecoder {
    /// A decoder with `options`' limits, rate, region, part and symbols choice.
    pub(crate) fn new(options: &DecodeOptions) -> Self {
        ExplicitDecoder {
            limits: options.limits,
            rate: options.rate,
            region: options.region,
            part: options.part,
            order: ChunkOrder::new(Profile::Explicit),
            header: None,
            groups: None,
            matrices: Vec::new(),
            selected_layer: 0,
            rate_chosen: 0,
            stream_rates: Vec::new(),
            progressive: false,
            layer: None,
            precision: None,
            refinement: None,
            refinements: Vec::new(),
            layers_done: 0,
            gaussians_at: None,
            truncated: false,
            reconstruct_each_layer: false,
            tiles: None,
            voxels: None,
            selected: Vec::new(),
            keep_symbols: !options.gaussians_only,
            decoded: None,
            early_gatt: None,
        }
    }

    /// §1.5, §3.7: whether a chunk tagged `tag` may come next, and what is done with it.
    pub(crate) fn due(&self, tag: ChunkTag) -> Result<Due> {
        // The layers decoded: the selected one, and in a progressive stream every one
        // before it.
        Ok(match self.order.check(tag)? {
            Position::Ancillary => Due::Ancillary,
            Position::Critical { layer: Some(l), .. } if l > self.selected_layer => Due::Skipped,
            Position::Critical { layer: Some(l), .. }
                if l < self.selected_layer && !self.progressive =>
            {
                Due::Skipped
            }
            Position::Critical { .. } => Due::Decoded,
        })
    }

    /// Decodes one chunk; `rest` is what follows it in the stream. Returns whether it was
    /// `SEND`.
    pub(crate) fn chunk(&mut self, tag: ChunkTag, bytes: &[u8], rest: &[u8]) -> Result<bool> {
        let due = self.due(tag)?;
        if due == Due::Ancillary {
            return Ok(false);
        }
        self.order.step(tag)?;
        if due == Due::Skipped {
            return Ok(false);
        }
        let tables = GaussianTables::standard();
        match tag {
            ChunkTag::GHED => {
                let h = GaussianHeader::parse(bytes, &self.limits)?;
                let layers;
                (self.rate_chosen, self.selected_layer, layers) = h.select_layer(self.rate)?;
                self.order.set_layers(layers, h.progressive);
                self.stream_rates = h.stream_rates();
                self.progressive = h.progressive;
                // A refinement refines the symbols in place.
                self.keep_symbols |= h.progressive && self.selected_layer > 0;
                // §9.1: the allocation limit bounds what the decode holds, not only its output.
                let held = h.working_bytes(self.keep_symbols);
                self.limits.check(
                    LimitKind::AllocationBytes,
                    h.decoded_bytes().saturating_add(held),
                )?;
                self.header = Some(h);
            }
            ChunkTag::GQUA => {
                let h = self.header.as_ref().ok_or(missing(ChunkTag::GHED))?;
                let groups = read_gqua(bytes, h.sh_degree, h.rate_count)?;
                self.matrices = groups.iter().map(Group::matrix).collect();
                self.groups = Some(groups);
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
            ChunkTag::APOS => match peek_critical(rest, ChunkTag::GATT, &self.limits) {
                Some(gatt) => self.fused(bytes, gatt, tables)?,
                None => {
                    let only = self.geometry_only()?;
                    let t = self.tiles.as_ref().ok_or(missing(ChunkTag::TILS))?;
                    self.voxels = Some(read_apos_of(bytes, t, tables, only.as_deref())?);
                }
            },
            ChunkTag::GATT => {
                let decoded = match self.early_gatt.take() {
                    Some(decoded) => decoded?,
                    None => {
                        self.select_tiles()?;
                        let (l, g, t, v) = self.tile_inputs()?;
                        let h = self.header.as_ref().ok_or(missing(ChunkTag::GHED))?;
                        let rate = self.layer_rate();
                        let keep = self.keep_symbols;
                        let inputs = (h, rate, l, g, &self.matrices[..], tables);
                        read_gatt(bytes, inputs, t, v, &self.selected, keep)?
                    }
                };
                self.decoded = Some(decoded);
                self.layer_decoded();
            }
            ChunkTag::GREF => {
                let g = self.groups.as_ref().ok_or(missing(ChunkTag::GQUA))?;
                let l = self.layer.as_ref().ok_or(missing(ChunkTag::GLAY))?;
                let before = self.precision.as_ref().ok_or(missing(ChunkTag::GATT))?;
                let values = g.iter().map(|g| g.dim).sum();
                let r = Refinement::parse(bytes, g.len(), values, l.coord_bits, before)?;
                self.refinement = Some(r);
            }
            ChunkTag::GRSY => {
                self.refine(bytes, tables)?;
                self.layer_decoded();
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
        let only = self.geometry_only()?;
        let h = self.header.as_ref().ok_or(missing(ChunkTag::GHED))?;
        let l = self.layer.as_ref().ok_or(missing(ChunkTag::GLAY))?;
        let g = self.groups.as_deref().ok_or(missing(ChunkTag::GQUA))?;
        let tiles = self.tiles.as_ref().ok_or(missing(ChunkTag::TILS))?;
        let attributes = body(ChunkTag::GATT, gatt, METHOD_CODED)
            .and_then(|words| split_bodies(ChunkTag::GATT, 1, words, tiles.len()));
        let rate = self.layer_rate();
        let keep = self.keep_symbols;
        let (mut decoded, values) =
            DecodedTiles::allocate(tiles, &self.selected, g, h.sh_degree, keep);
        let outputs = decoded.outputs(tiles, values);
        // Per tile: its voxels, and where `GATT` was framed, its outcome.
        type Fused = (Result<Vec<[u32; 3]>>, Option<Result<()>>);
        let inputs = (h, rate, l, g, &self.matrices[..], tables);
        let jobs: Vec<_> = geometry.into_iter().zip(outputs).collect();
        let size = |t: usize| tiles.range(t).len();
        let results: Vec<Fused> = map_largest_first(jobs, size, |t, (b, output)| {
            if only.as_ref().is_some_and(|o| !o[t]) {
                // Another part's tile (§10.3.2): neither its geometry nor its attributes.
                return (Ok(vec![[0; 3]; tiles.range(t).len()]), Some(Ok(())));
            }
            with_thread_scratch(&FUSED_SCRATCH, |scratch| {
                let voxels = read_apos_tile(b, t, tiles, tables, &mut scratch.0);
                let tile = match (&voxels, &attributes, output) {
                    (Ok(v), Ok(bodies), Some(out)) => Some(decode_and_reconstruct(
                        inputs,
                        v,
                        bodies[t],
                        out,
                        &mut scratch.1,
                    )),
                    (Ok(_), Ok(_), None) => Some(Ok(())),
                    _ => None,
                };
                (voxels, tile)
            })
        });
        let mut voxels = Vec::with_capacity(tiles.anchors as usize);
        let mut outcomes = Vec::with_capacity(results.len());
        for (v, tile) in results {
            voxels.extend_from_slice(&v?);
            outcomes.push(tile);
        }
        tiles.check_geometry_of(&voxels, only.as_deref())?;
        self.voxels = Some(voxels);
        // Every tile's geometry decoded, so every tile has an outcome where `GATT` was
        // framed; the lowest tile's error is reported (§10.3).
        self.early_gatt = Some(attributes.and_then(|_| {
            outcomes
                .into_iter()
                .try_for_each(|tile| tile.unwrap_or(Ok(())))
                .map(|()| decoded)
        }));
        Ok(())
    }

    /// The tiles whose geometry (`APOS`) is decoded, where not all of them: a part decode's
    /// own tiles (§10.3.2). A region decode reads every tile's (§10.3.1 step 3). Fixes the
    /// selection ([`Self::select_tiles`]).
    fn geometry_only(&mut self) -> Result<Option<Vec<bool>>> {
        let part = self.part.is_some();
        let selected = self.select_tiles()?;
        Ok(part.then(|| selected.to_vec()))
    }

    /// The tiles the region and part keep (§10.3), fixed before the selected layer's `GATT` is decoded
    /// (with `APOS` where the two are decoded together).
    pub(crate) fn select_tiles(&mut self) -> Result<&[bool]> {
        let h = self.header.as_ref().ok_or(missing(ChunkTag::GHED))?;
        let l = self.layer.as_ref().ok_or(missing(ChunkTag::GLAY))?;
        let t = self.tiles.as_ref().ok_or(missing(ChunkTag::TILS))?;
        self.selected = t.select(h.origin, l.voxel_size, self.region, self.part);
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

    /// Tile `t`'s symbols, once `GATT` is decoded (`None`: a tile not decoded).
    pub(crate) fn tile_symbols(&self, t: usize) -> Option<TileSymbolsRef<'_>> {
        let d = self.decoded.as_ref()?;
        let start = (*d.starts.get(t)?)?;
        let (_, _, tiles, _) = self.tile_inputs().ok()?;
        let n = tiles.range(t).len();
        let values = self.groups.as_ref()?.iter().map(|g| g.dim).sum::<usize>();
        let s = &d.symbols;
        Some(TileSymbolsRef {
            coords: s.coords.get(start * values..(start + n) * values)?,
            rotation_index: s.rotation_index.get(start..start + n)?,
            size_class: s.size_class.get(start..start + n)?,
            refinement: s.refinement.get(start..start + n)?,
        })
    }

    /// The stream's preflight, once `GHED` is decoded.
    pub(crate) fn header(&self) -> Option<&GaussianHeader> {
        self.header.as_ref()
    }

    /// §3.6: the Gaussians of tile `t` from its symbols, appended to `out`.
    pub(crate) fn reconstruct(
        &self,
        t: usize,
        s: TileSymbolsRef,
        out: &mut Gaussians,
    ) -> Result<()> {
        let h = self.header.as_ref().ok_or(missing(ChunkTag::GHED))?;
        let (l, g, tiles, v) = self.tile_inputs()?;
        let voxels = &v[tiles.range(t)];
        let tile = out.extend_zeroed(voxels.len());
        let m = &self.matrices;
        let precision = Precision::of_layer(l, g, self.layer_rate());
        reconstruct_tile_into(h.origin, l.voxel_size, &precision, g, m, voxels, s, tile);
        Ok(())
    }

    /// Records the selected layer's `GATT` as decoded elsewhere (tile by tile, as its bytes
    /// arrived, each tile's Gaussians reconstructed there): its position is taken and its
    /// symbols kept.
    pub(crate) fn gatt_decoded(&mut self, per_tile: Vec<Option<TileSymbols>>) -> Result<()> {
        self.order.step(ChunkTag::GATT)?;
        let mut symbols = TileSymbols::default();
        let mut starts = Vec::with_capacity(per_tile.len());
        for tile in per_tile {
            starts.push(tile.map(|s| {
                let start = symbols.size_class.len();
                symbols.coords.extend_from_slice(&s.coords);
                symbols.rotation_index.extend_from_slice(&s.rotation_index);
                symbols.size_class.extend_from_slice(&s.size_class);
                symbols.refinement.extend_from_slice(&s.refinement);
                start
            }));
        }
        self.decoded = Some(DecodedTiles {
            symbols,
            gaussians: Gaussians::default(),
            starts,
            keep_symbols: true,
        });
        self.layer_decoded();
        Ok(())
    }

    /// §3.6, after `SEND`: the Gaussians of every decoded tile, in stream order.
    pub(crate) fn finish(self) -> Result<DecodedGaussians> {
        self.finish_with(None)
    }

    /// [`Self::finish`] with the Gaussians reconstructed by the caller tile by tile, in
    /// order (`None`: those decoded with `GATT`).
    pub(crate) fn finish_with(
        mut self,
        reconstructed: Option<Gaussians>,
    ) -> Result<DecodedGaussians> {
        let last = self.layers_done.checked_sub(1);
        let (reconstructed, stale) = match reconstructed {
            // The caller's are the full layer's: right where no refinement followed.
            Some(g) if !self.progressive || last == Some(0) => (Some(g), false),
            _ => (None, self.gaussians_at != last),
        };
        if stale {
            self.reconstruct_all()?;
        }
        let decoded = self.decoded.take().ok_or(missing(ChunkTag::GATT))?;
        let (_, _, tiles, voxels) = self.tile_inputs()?;
        let kept = if decoded.starts.iter().all(Option::is_some) {
            self.voxels.take().unwrap_or_default()
        } else {
            let mut kept = Vec::with_capacity(decoded.symbols.size_class.len());
            for (t, start) in decoded.starts.iter().enumerate() {
                if start.is_some() {
                    kept.extend_from_slice(&voxels[tiles.range(t)]);
                }
            }
            kept
        };
        let missing_part = |tag| missing(tag);
        let rate = self
            .layers_done
            .checked_sub(1)
            .map_or(self.rate_chosen, |l| {
                self.stream_rates
                    .get(l)
                    .copied()
                    .unwrap_or(self.rate_chosen)
            });
        Ok(DecodedGaussians {
            header: self.header.ok_or(missing_part(ChunkTag::GHED))?,
            groups: self.groups.ok_or(missing_part(ChunkTag::GQUA))?,
            rate,
            layer: self.layer.ok_or(missing_part(ChunkTag::GLAY))?,
            precision: self.precision.ok_or(missing_part(ChunkTag::GATT))?,
            refinements: self.refinements,
            truncated: self.truncated,
            voxels: kept,
            symbols: decoded.symbols,
            tiles: self.tiles.ok_or(missing_part(ChunkTag::TILS))?,
            gaussians: reconstructed.unwrap_or(decoded.gaussians),
        })
    }
}
