//! The decoder (spec §1.5 decoding process): signature, then chunks in order, each payload
//! decoded against the preflight; the anchor attributes are decoded together once `SEND`
//! has been read (§6.6.2). It never panics on any input, sizes every allocation from a
//! preflight that passed [`Limits`], and reports the first broken rule.

use crate::par::*;

use crate::attributes::{read_masks, Symbols};
use crate::options::DecodeOptions;
#[cfg(feature = "test-hooks")]
use crate::options::Fault;
use std::borrow::Cow;

use crate::container::chunk::{peek_critical, ChunkReader, ChunkTag};
use crate::container::order::{ChunkOrder, Position, Profile};
use crate::container::payload;
use crate::container::preflight::Preflight;
use crate::container::signature::{Signature, SIGNATURE_LEN};
use crate::entropy::GaussianTables;
use crate::error::{Error, Result};
use crate::hyperprior::{GridLayout, IntMlp};
use crate::limits::Limits;
use crate::model::{GroupQuantizer, HashGrid, Mlp, SceneModel};
use crate::tiles::TileTable;

mod assemble;

use assemble::assemble;

/// Parts of the model decoded so far, filled chunk by chunk.
#[derive(Default)]
struct Partial<'a> {
    head: Option<Preflight>,
    mlps: Option<(IntMlp, [Mlp; 3])>,
    quan: Option<[GroupQuantizer; 3]>,
    voxel: Option<Vec<[u32; 3]>>,
    touched: Option<[Vec<bool>; 4]>,
    grid: Option<HashGrid>,
    tiles: Option<TileTable>,
    selected: Vec<bool>,
    mask: Option<Vec<u8>>,
    /// `AMSK`'s outcome where it was decoded alongside `GRID` (see the `GRID` step), reported
    /// when its own position in the stream is reached.
    early_mask: Option<Result<Vec<u8>>>,
    attributes: [&'a [u8]; 3],
    /// The rate being decoded.
    rate: u8,
    /// The index of its layer (§7.4).
    selected_layer: usize,
}

fn missing(tag: ChunkTag) -> Error {
    ChunkOrder::missing(tag)
}

/// Decodes an anchors-profile stream's selected symbol layer (§7.4): every chunk's framing,
/// CRC and order is checked, the shared chunks and the selected layer are decoded, other
/// layers' payloads are not parsed. With `keep_symbols`, also the selected layer's symbols
/// (the lattice coordinates, §6.6.2), which the canonical decoded form hashes (§11.1);
/// keeping them needs `8·N·(F + S + 3K)` bytes more, checked against the allocation limit on
/// top of the decoded size.
pub(crate) fn decode_anchors(
    data: &[u8],
    options: &DecodeOptions,
    keep_symbols: bool,
) -> Result<(SceneModel, Option<Symbols>)> {
    decode_stream(data, options, keep_symbols)
}

pub(crate) fn decode_stream(
    data: &[u8],
    options: &DecodeOptions,
    keep_symbols: bool,
) -> Result<(SceneModel, Option<Symbols>)> {
    let limits = &options.limits;
    // §1.2: signature and version.
    let (_sig, rest) = Signature::parse(data)?;
    let mut reader = ChunkReader::new(rest, SIGNATURE_LEN as u64, limits);
    let mut order = ChunkOrder::new(Profile::Anchors);
    let mut p = Partial::default();
    let tables = tables(options);
    loop {
        // §1.5 rule 4: the stream ends only with SEND.
        let chunk = reader.next_before_send()?;
        // §1.5 rules 0 – 3: ancillary chunks after HEAD are skipped.
        let Position::Critical { layer, .. } = order.step(chunk.tag)? else {
            continue;
        };
        match chunk.tag {
            ChunkTag::HEAD => {
                let head = Preflight::parse(chunk.payload, limits)?;
                let layers;
                (p.rate, p.selected_layer, layers) = head.select_layer(options.rate)?;
                order.set_layers(layers, false);
                p.head = Some(head);
            }
            // §7.4: another layer's attributes are not parsed.
            ChunkTag::AFEA | ChunkTag::ASCL | ChunkTag::AOFF if layer != Some(p.selected_layer) => {
            }
            ChunkTag::SEND => {
                // Empty, last, nothing after it (§1.5 rules 4 – 5).
                crate::container::chunk::check_send(chunk.payload, reader.remaining())?;
                return assemble(p, &tables, keep_symbols.then_some(&options.limits));
            }
            tag => p.read(tag, chunk.payload, reader.remaining(), options, &tables)?,
        }
    }
}

/// The frequency tables (§6.3), or with the `test-hooks` feature the deliberately wrong ones
/// a conformance run asks for.
fn tables(options: &DecodeOptions) -> Cow<'static, GaussianTables> {
    #[cfg(feature = "test-hooks")]
    if let Some(Fault::FrequencyTable { scale }) = options.fault {
        return Cow::Owned(GaussianTables::standard().with_one_wrong_entry(scale));
    }
    let _ = options;
    Cow::Borrowed(GaussianTables::standard())
}

impl<'a> Partial<'a> {
    /// Decodes the model chunk `tag` (§1.6, §6.6.1, §8, §10.1) or keeps the selected layer's
    /// attribute chunk for [`assemble()`]; `rest` is what follows it in the stream.
    fn read(
        &mut self,
        tag: ChunkTag,
        bytes: &'a [u8],
        rest: &[u8],
        options: &DecodeOptions,
        tables: &GaussianTables,
    ) -> Result<()> {
        let head = self.head.as_ref().ok_or(missing(ChunkTag::HEAD))?;
        let d = &head.dims;
        match tag {
            ChunkTag::MLPS => self.mlps = Some(payload::read_mlps(bytes, d)?),
            ChunkTag::QUAN => self.quan = Some(payload::read_quan(bytes, d)?),
            ChunkTag::APOS => {
                let tiles = self.tiles.as_ref().ok_or(missing(ChunkTag::TILS))?;
                let voxel = payload::read_apos(bytes, tiles, tables)?;
                // §5.2: the touched grid entries follow from the voxels.
                let layout = GridLayout::new(d, head.coord_bits);
                self.touched = Some(layout.touched(&voxel, d.entries_3d(), d.entries_2d()));
                self.voxel = Some(voxel);
            }
            ChunkTag::TILS => {
                let tiles = TileTable::parse(bytes, d.anchors, head.coord_bits)?;
                self.selected =
                    tiles.select(head.origin, head.voxel_size, options.region, options.part);
                self.tiles = Some(tiles);
            }
            ChunkTag::GRID => self.read_grid(bytes, rest, &options.limits, tables)?,
            ChunkTag::AMSK => {
                let mask = match self.early_mask.take() {
                    Some(mask) => mask?,
                    None => {
                        let tiles = self.tiles.as_ref().ok_or(missing(ChunkTag::TILS))?;
                        read_masks(bytes, d, tables, tiles, &self.selected)?
                    }
                };
                self.mask = Some(mask);
            }
            ChunkTag::AFEA => self.attributes[0] = bytes,
            ChunkTag::ASCL => self.attributes[1] = bytes,
            ChunkTag::AOFF => self.attributes[2] = bytes,
            // The walk lets no other tag through (§1.5 Table 1-3).
            found => {
                return Err(Error::ChunkOrder {
                    found,
                    expected: ChunkTag::SEND,
                })
            }
        }
        Ok(())
    }

    /// `GRID` (§1.6.1). The grid is one coded body, decoded on one thread; the masks need
    /// only the tiles (§6.6.1), so the next critical chunk, if it is a framed `AMSK`, is
    /// decoded alongside. Its outcome waits for its own position (§1.5): this chunk's error,
    /// and the chunks between, come first.
    fn read_grid(
        &mut self,
        bytes: &[u8],
        rest: &[u8],
        limits: &Limits,
        tables: &GaussianTables,
    ) -> Result<()> {
        let head = self.head.as_ref().ok_or(missing(ChunkTag::HEAD))?;
        let d = &head.dims;
        let touched = self.touched.as_ref().ok_or(missing(ChunkTag::APOS))?;
        let tiles = self.tiles.as_ref().ok_or(missing(ChunkTag::TILS))?;
        let decode_grid = || payload::read_grid(bytes, d, touched);
        match peek_critical(rest, ChunkTag::AMSK, limits) {
            Some(amsk) => {
                let (grid, mask) = join(decode_grid, || {
                    read_masks(amsk, d, tables, tiles, &self.selected)
                });
                self.grid = Some(grid?);
                self.early_mask = Some(mask);
            }
            None => self.grid = Some(decode_grid()?),
        }
        Ok(())
    }
}
