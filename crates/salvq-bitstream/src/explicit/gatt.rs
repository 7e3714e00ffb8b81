//! `GATT` (spec §3.5, §3.6) decoded tile by tile: each tile's symbols and Gaussians written
//! straight into the layer's output, so that tiles decoded on different threads need no
//! concatenation afterwards.

use std::cell::RefCell;

use crate::par::*;

use crate::container::chunk::ChunkTag;
use crate::container::payload::{body, METHOD_CODED};
use crate::entropy::{GaussianTables, SymbolReader};
use crate::error::Result;
use crate::explicit::attributes::{walk_into, BitEvent, Events, TileSymbols, TileSymbolsMut};
use crate::explicit::gaussians::GaussiansMut;
use crate::explicit::groups::Group;
use crate::explicit::header::GaussianHeader;
use crate::explicit::layer::Layer;
use crate::explicit::reconstruct::reconstruct_tile_into;
use crate::explicit::refinement::{refine_walk, Precision, Refinement};
use crate::explicit::Gaussians;
use crate::quantizer::LatticeMatrix;
use crate::tiles::{split_bodies, TileTable};

thread_local! {
    /// A thread's buffer for the symbols of the `GATT` tiles it decodes without keeping them.
    static GATT_SCRATCH: RefCell<TileSymbols> = RefCell::default();
}

struct Reader<'a> {
    symbols: SymbolReader<'a>,
}

impl Events for Reader<'_> {
    // Inlined into the walk, as the octree's reader is into its walk: a call per symbol cost
    // more than the symbol's table lookup.
    #[inline(always)]
    fn bit(&mut self, freq_one: u32, _: usize, _: BitEvent) -> Result<bool> {
        self.symbols.bit(freq_one)
    }
    #[inline(always)]
    fn symbol(&mut self, k: u8, _: usize, _: usize, _: i64) -> Result<i64> {
        self.symbols.symbol(k)
    }
}

/// §3.5: decodes one tile's body of `GATT`; `voxels` are the tile's.
pub fn decode_tile(
    layer: &Layer,
    groups: &[Group],
    voxels: &[[u32; 3]],
    body: &[u8],
    tables: &GaussianTables,
) -> Result<TileSymbols> {
    let values = groups.iter().map(|g| g.dim).sum();
    let mut out = TileSymbols::zeroed(voxels.len(), values);
    decode_tile_into(layer, groups, voxels, body, tables, &mut out.as_mut())?;
    Ok(out)
}

/// [`decode_tile`], writing the symbols into `out`.
fn decode_tile_into(
    layer: &Layer,
    groups: &[Group],
    voxels: &[[u32; 3]],
    body: &[u8],
    tables: &GaussianTables,
    out: &mut TileSymbolsMut,
) -> Result<()> {
    read_body(ChunkTag::GATT, body, tables, |reader| {
        walk_into(layer, groups, voxels, reader, out)
    })
}

/// Decodes one tile's ANS body of chunk `tag` with `walk`, then checks that the body ends
/// where its events do (§6.2.6 step 5).
fn read_body(
    tag: ChunkTag,
    body: &[u8],
    tables: &GaussianTables,
    walk: impl FnOnce(&mut Reader) -> Result<()>,
) -> Result<()> {
    let mut reader = Reader {
        symbols: SymbolReader::new(tag, body, tables)?,
    };
    walk(&mut reader)?;
    reader.symbols.finish()
}

/// §3.8: refines one tile's symbols `out` in place from its body of `GRSY`; `voxels` are the
/// tile's.
pub fn refine_tile(
    refinement: &Refinement,
    groups: &[Group],
    voxels: &[[u32; 3]],
    body: &[u8],
    tables: &GaussianTables,
    out: &mut TileSymbolsMut,
) -> Result<()> {
    read_body(ChunkTag::GRSY, body, tables, |reader| {
        refine_walk(refinement, groups, voxels, reader, out)
    })
}

/// The selected tiles of a layer's `GATT`, decoded: their symbols (§3.5) and Gaussians
/// (§3.6), each concatenated in tile order.
#[derive(Debug)]
pub struct DecodedTiles {
    /// The decoded tiles' symbols (§3.5), concatenated in tile order.
    pub symbols: TileSymbols,
    /// The decoded tiles' reconstructed Gaussians (§3.6), concatenated in tile order.
    pub gaussians: Gaussians,
    /// Where each tile's Gaussians start in both (`None`: a tile not decoded).
    pub starts: Vec<Option<usize>>,
    /// Whether the symbols are kept (else `symbols` is empty).
    pub keep_symbols: bool,
}

/// One selected tile's place in [`DecodedTiles`]: its symbols (where they are kept) and
/// Gaussians, to write.
pub type TileOutput<'a> = (Option<TileSymbolsMut<'a>>, GaussiansMut<'a>);

impl DecodedTiles {
    /// Room for the Gaussians of the tiles `selected` keeps, and each tile's place in it
    /// (`None` for a tile not kept), so that tiles decoded on different threads write
    /// straight into the output rather than into buffers concatenated afterwards.
    pub fn allocate(
        tiles: &TileTable,
        selected: &[bool],
        groups: &[Group],
        sh_degree: u8,
        keep_symbols: bool,
    ) -> (Self, usize) {
        let mut starts = Vec::with_capacity(tiles.len());
        let mut total = 0;
        for t in 0..tiles.len() {
            if selected.get(t).copied().unwrap_or(true) {
                starts.push(Some(total));
                total += tiles.range(t).len();
            } else {
                starts.push(None);
            }
        }
        let values = groups.iter().map(|g| g.dim).sum();
        let decoded = DecodedTiles {
            symbols: TileSymbols::zeroed(if keep_symbols { total } else { 0 }, values),
            gaussians: Gaussians::zeroed(sh_degree, total),
            starts,
            keep_symbols,
        };
        (decoded, values)
    }

    /// Each tile's place to write ([`DecodedTiles::allocate`]).
    pub fn outputs(&mut self, tiles: &TileTable, values: usize) -> Vec<Option<TileOutput<'_>>> {
        let keep_symbols = self.keep_symbols;
        let (mut symbols, mut gaussians) = (self.symbols.as_mut(), self.gaussians.as_mut());
        let mut out = Vec::with_capacity(self.starts.len());
        for (t, start) in self.starts.iter().enumerate() {
            if start.is_none() {
                out.push(None);
                continue;
            }
            let n = tiles.range(t).len();
            let kept = if keep_symbols { n } else { 0 };
            let (s, s_rest) = symbols.split_at(kept, values);
            let (g, g_rest) = gaussians.split_at(n);
            (symbols, gaussians) = (s_rest, g_rest);
            out.push(Some((keep_symbols.then_some(s), g)));
        }
        out
    }
}

/// §3.5, §3.6: decodes `GATT` of a layer whose geometry is `voxels` cut by `tiles`, and
/// reconstructs each selected tile's Gaussians in the same task (tiles are independent, so
/// the reconstruction runs on every thread rather than after the last tile).
pub fn read_gatt(
    payload: &[u8],
    inputs: LayerInputs,
    tiles: &TileTable,
    voxels: &[[u32; 3]],
    selected: &[bool],
    keep_symbols: bool,
) -> Result<DecodedTiles> {
    let tag = ChunkTag::GATT;
    let words = body(tag, payload, METHOD_CODED)?;
    let bodies = split_bodies(tag, 1, words, tiles.len())?;
    let (header, _, _, groups, _, _) = inputs;
    let (mut decoded, values) =
        DecodedTiles::allocate(tiles, selected, groups, header.sh_degree, keep_symbols);
    let outputs = decoded.outputs(tiles, values);
    let jobs: Vec<_> = bodies.into_iter().zip(outputs).collect();
    let size = |t: usize| tiles.range(t).len();
    let results = map_largest_first(jobs, size, |t, (b, output)| match output {
        Some(out) => with_thread_scratch(&GATT_SCRATCH, |scratch| {
            let tile_voxels = &voxels[tiles.range(t)];
            decode_and_reconstruct(inputs, tile_voxels, b, out, scratch)
        }),
        None => Ok(()),
    });
    // §10.3: the lowest tile's error is reported.
    results.into_iter().collect::<Result<()>>()?;
    Ok(decoded)
}

/// What decoding any tile of a layer's `GATT` reads: the preflight, the rate, the layer, its
/// groups and their matrices ([`Group::matrix`]), and the ANS tables.
pub type LayerInputs<'a> = (
    &'a GaussianHeader,
    u8,
    &'a Layer,
    &'a [Group],
    &'a [LatticeMatrix],
    &'a GaussianTables,
);

/// §3.5, §3.6: one tile's symbols from its `GATT` body and its Gaussians from them, written
/// into `out`; where the symbols are not kept, they go to `scratch` (a worker's, reused from
/// tile to tile) instead.
pub fn decode_and_reconstruct(
    (header, rate, layer, groups, matrices, tables): LayerInputs,
    voxels: &[[u32; 3]],
    body: &[u8],
    (symbols, gaussians): TileOutput,
    scratch: &mut TileSymbols,
) -> Result<()> {
    let values = groups.iter().map(|g| g.dim).sum::<usize>();
    let mut symbols = symbols.unwrap_or_else(|| scratch.resized(voxels.len(), values));
    decode_tile_into(layer, groups, voxels, body, tables, &mut symbols)?;
    let precision = Precision::of_layer(layer, groups, rate);
    reconstruct_tile_into(
        header.origin,
        layer.voxel_size,
        &precision,
        groups,
        matrices,
        voxels,
        symbols.as_ref(),
        gaussians,
    );
    Ok(())
}
